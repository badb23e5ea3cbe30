//! Unmodelled effects: friction, actuator errors, inertial errors, delays.
//!
//! An [`Effect`] is something the real robot has and the nominal [`Model`] lacks. A
//! [`Plant`](crate::plant::Plant) is the nominal model plus a list of effects; the simulator
//! integrates
//!
//! ```text
//! (H(q) + diag(ia)) q̈ = τ_applied + τ_friction(q, q̇) − C(q, q̇) q̇ − g(q)
//! τ_applied(t)        = k · clamp(τ_cmd(t − delay), ±limit) + offset
//! ```
//!
//! with `H`, `C`, `g` those of the model after [`Effect::Payload`] and [`Effect::InertialError`]
//! were applied, and `C` of the other [`Formulation`](simgap_core::Formulation) when
//! [`Effect::CoriolisStructure`] is present.
//!
//! Per-joint parameters are `Vec<f64>` of length `model.dof()` in model joint order. A joint an
//! effect does not act on holds the neutral value: 0 for friction, armature, offset and cogging
//! amplitude, 1 for a gain, `+∞` for a saturation limit. Several effects of one kind compose:
//! frictions, armatures and offsets add, gains multiply, limits take the smallest, delays add.
//!
//! `sign(q̇)` in every dry-friction effect (Coulomb, Stribeck) is smoothed as `tanh(q̇ / w)`
//! with `w` [rad/s or m/s] a per-joint parameter of the effect itself, so that the effect holds
//! the model it is simulated with: `w > 0` keeps the right-hand side Lipschitz and RK4
//! convergent; `w = 0` is the exact sign (stick–slip, discontinuous at q̇ = 0). A spelling that
//! leaves `w` out takes [`DEFAULT_COULOMB_WIDTH`] ([`Effect::parse`]) or the caller's default
//! ([`Effect::parse_with_width`]).

use nalgebra::{Matrix3, Vector3};
use simgap_core::{Model, SpatialInertia};

use crate::error::{Error, Result};
use crate::kind::EffectKind;

/// Default smoothing width `w` of `sign(q̇)` [rad/s or m/s] for an effect spelled without one
/// ([`Effect::parse`]): `sign(q̇) ≈ tanh(q̇ / 0.01)`.
///
/// Below about 0.01 rad/s (0.6 °/s) Coulomb friction acts as a steep viscous law of slope
/// `fc / w`. The width trades the sharpness of the sign against stiffness: the slope makes the
/// ODE stiff near q̇ = 0, and explicit RK4 needs `h · slope / inertia ≲ 2.8`. With 0.01 rad/s
/// the paper arm with its reported Coulomb friction (7.17 and 1.734 N·m) needs about 3 RK4
/// steps per 2.5 ms sample; with 1e-3 it would need about 25. The simulator raises the number
/// of substeps automatically to stay stable
/// ([`effective_substeps`](crate::simulate::effective_substeps)).
pub const DEFAULT_COULOMB_WIDTH: f64 = TYPICAL_WIDTH_REVOLUTE;

/// Typical width `w` of the sign of a turning joint's dry friction [rad/s] (0.6 °/s): the
/// width [`Effect::parse_for_model`] gives a revolute or continuous joint whose spelling leaves
/// `w` out, and the diagnosis's starting width (`prepare/width.rs` in simgap-diag).
pub const TYPICAL_WIDTH_REVOLUTE: f64 = 0.01;

/// Typical width `w` of the sign of a linear joint's dry friction [m/s] (2 mm/s: linear axes
/// move at a fifth of the speeds, in their units, that arms turn at; 0.01 m/s would be 1 cm/s).
pub const TYPICAL_WIDTH_PRISMATIC: f64 = 0.002;

/// The typical dry-friction width of a joint type [rad/s or m/s]: [`TYPICAL_WIDTH_REVOLUTE`]
/// for revolute and continuous joints, [`TYPICAL_WIDTH_PRISMATIC`] for prismatic ones.
pub fn typical_width(kind: simgap_core::JointKind) -> f64 {
    if kind.is_rotational() {
        TYPICAL_WIDTH_REVOLUTE
    } else {
        TYPICAL_WIDTH_PRISMATIC
    }
}

/// Upper bound of the derivative `−∂τ_friction,i/∂q̇_i` of every friction effect on each
/// joint (viscous `b`, Coulomb `fc / w`, Stribeck `max(fc, fs) / w` plus its hump, directional
/// `max(b_pos, b_neg) + (fc_pos + fc_neg) / 2w + |b_pos − b_neg| / 4`, each with
/// the effect's own width `w`), into `out` (overwritten) [N·m·s/rad or N·s/m].
///
/// A dry friction with `w = 0` (the exact sign) is a jump, not a slope: it adds nothing here,
/// so that it never asks for infinitely many substeps (no step size makes RK4 converge on a
/// discontinuity; the run then chatters near q̇ = 0 as a stick–slip simulation does).
///
/// # Panics
/// If an effect's vector is shorter than `out`.
pub fn friction_slope_bound(effects: &[Effect], out: &mut [f64]) {
    slope_bound(effects, 1.0, 1.0, out);
}

/// Multiples of its width `w` beyond which a smoothed dry friction is no longer stiff: there
/// `sech²(q̇/w) ≤ sech²(4) = 1.3e-3` of its slope at rest.
pub const STIFF_WIDTHS: f64 = 4.0;

/// Multiples of its Stribeck velocity `vs` beyond which the hump's slope is below `1e-3` of its
/// bound `2 |fs − fc| / vs`.
pub const STIFF_STRIBECK_VELOCITIES: f64 = 3.0;

/// Per joint, the speed below which its smoothed dry frictions are stiff, `|q̇| <` `band` [rad/s
/// or m/s]: the largest of [`STIFF_WIDTHS`] `· w` and [`STIFF_STRIBECK_VELOCITIES`] `· vs` over
/// its Coulomb, Stribeck, directional and load frictions of width `w > 0` (0 without any), into `out`
/// (overwritten). Above it, [`moving_friction_slope_bound`] bounds the friction's slope.
///
/// # Panics
/// If an effect's vector is shorter than `out`.
pub fn stiff_band(effects: &[Effect], out: &mut [f64]) {
    out.fill(0.0);
    for e in effects {
        for i in 0..out.len() {
            let band = match e {
                Effect::CoulombFriction { w, .. } | Effect::DirectionalFriction { w, .. } | Effect::LoadFriction { w, .. } if w[i] > 0.0 => STIFF_WIDTHS * w[i],
                Effect::StribeckFriction { vs, w, .. } | Effect::LoadStribeckFriction { vs, w, .. } if w[i] > 0.0 => {
                    (STIFF_WIDTHS * w[i]).max(STIFF_STRIBECK_VELOCITIES * vs[i].max(0.0))
                }
                _ => 0.0,
            };
            out[i] = out[i].max(band);
        }
    }
}

/// [`friction_slope_bound`] for joints moving faster than their [`stiff_band`]: the dry parts'
/// slopes scaled by `sech²(4)` and the Stribeck hump's by `1e-3` (the smooth parts, viscous and
/// back-EMF, as they are) [N·m·s/rad or N·s/m].
///
/// # Panics
/// If an effect's vector is shorter than `out`.
pub fn moving_friction_slope_bound(effects: &[Effect], out: &mut [f64]) {
    let sech = 1.0 / STIFF_WIDTHS.cosh();
    slope_bound(effects, sech * sech, 1e-3, out);
}

/// The slope bound of [`friction_slope_bound`] with the dry steps' slopes scaled by `dry` and
/// the Stribeck humps' by `hump`.
fn slope_bound(effects: &[Effect], dry: f64, hump_scale: f64, out: &mut [f64]) {
    out.fill(0.0);
    let over = |level: f64, w: f64| if w > 0.0 { dry * level / w } else { 0.0 };
    for e in effects {
        for i in 0..out.len() {
            out[i] += match e {
                Effect::ViscousFriction { b } => b[i].abs(),
                Effect::CoulombFriction { fc, w } => over(fc[i].abs(), w[i]),
                // a load Stribeck friction's load-independent levels as a Stribeck friction's;
                // its load part is bounded as a load friction's (below)
                Effect::StribeckFriction { fc, fs, vs, w } | Effect::LoadStribeckFriction { fc, fs, vs, w, .. } => {
                    let hump = if vs[i] > 0.0 { hump_scale * 2.0 * (fs[i] - fc[i]).abs() / vs[i] } else { 0.0 };
                    over(fc[i].abs().max(fs[i].abs()), w[i]) + hump
                }
                // the viscous parts, the dry step (fc_pos + fc_neg) / 2 over w, and the switch
                // between the viscous slopes (|Δb| q̇ sech²(q̇/w) / 2w ≤ 0.23 |Δb|)
                Effect::DirectionalFriction { fc_pos, fc_neg, b_pos, b_neg, w } => {
                    b_pos[i].abs().max(b_neg[i].abs()) + over(0.5 * (fc_pos[i].abs() + fc_neg[i].abs()), w[i]) + 0.25 * (b_pos[i] - b_neg[i]).abs()
                }
                Effect::BackEmf { kb } => kb[i].abs(),
                // the load-independent level; the load part is bounded by the simulator from
                // the effort limits (it scales with the drive's torque)
                Effect::LoadFriction { fc, w, .. } => over(fc[i].abs(), w[i]),
                _ => 0.0,
            };
        }
    }
}

/// A change to one link's inertia: `new = old + delta` (see [`Effect::InertialError`]).
#[derive(Clone, Debug, PartialEq)]
pub struct LinkDelta {
    /// Index of the joint whose child link changes (model order).
    pub joint: usize,
    /// Added mass [kg].
    pub mass: f64,
    /// Displacement of the centre of mass, in the link frame [m].
    pub com: [f64; 3],
    /// Added rotational inertia about the (new) centre of mass, `ixx ixy ixz iyy iyz izz`
    /// [kg·m²], in the link frame.
    pub inertia: [f64; 6],
}

/// One unmodelled effect. Per-joint vectors have length `model.dof()`.
#[derive(Clone, Debug, PartialEq)]
pub enum Effect {
    /// `τ += −b q̇`; `b` [N·m·s/rad].
    ViscousFriction {
        /// Viscous coefficients.
        b: Vec<f64>,
    },
    /// `τ += −fc tanh(q̇ / w)`; `fc` [N·m or N], `w` [rad/s or m/s] (`w = 0`: the exact sign).
    CoulombFriction {
        /// Coulomb levels.
        fc: Vec<f64>,
        /// Widths of the smoothed sign, `>= 0`.
        w: Vec<f64>,
    },
    /// `τ += −(fc + (fs − fc) e^{−(q̇/vs)²}) tanh(q̇ / w)`; `fc`, `fs` [N·m or N], `vs`, `w`
    /// [rad/s or m/s] (`vs ≤ 0` drops the Stribeck term; `w = 0`: the exact sign).
    StribeckFriction {
        /// Coulomb levels.
        fc: Vec<f64>,
        /// Static (breakaway) levels.
        fs: Vec<f64>,
        /// Stribeck velocities.
        vs: Vec<f64>,
        /// Widths of the smoothed sign, `>= 0`.
        w: Vec<f64>,
    },
    /// Rotor inertia `ia` [kg·m²] added to the diagonal of H.
    Armature {
        /// Reflected rotor inertias.
        ia: Vec<f64>,
    },
    /// A point mass rigidly attached to the last link of the chain.
    Payload {
        /// Mass [kg].
        mass: f64,
        /// Position in the last link's frame [m].
        com: [f64; 3],
    },
    /// Wrong link parameters: each link listed becomes `old + delta`: mass `m + Δm`, centre of
    /// mass `c + Δc`, rotational inertia about the new centre of mass `I_c + ΔI`.
    InertialError {
        /// One entry per changed link.
        deltas: Vec<LinkDelta>,
    },
    /// `τ_applied = k τ_cmd` [–].
    TorqueGain {
        /// Gains.
        k: Vec<f64>,
    },
    /// `τ_applied = τ_cmd + offset` [N·m].
    TorqueOffset {
        /// Offsets.
        offset: Vec<f64>,
    },
    /// `τ_applied = clamp(τ_cmd, ±limit)` [N·m].
    TorqueSaturation {
        /// Limits (`+∞` for none).
        limit: Vec<f64>,
    },
    /// `τ_applied(t) = τ_cmd(t − delay)` for the whole robot [s].
    TimeDelay {
        /// Delay [s], `>= 0`.
        delay: f64,
    },
    /// `τ += −A sin(N q)`; `amplitude` [N·m], `periods_per_rev` N [–].
    Cogging {
        /// Amplitudes A.
        amplitude: Vec<f64>,
        /// Periods per revolution N.
        periods_per_rev: Vec<f64>,
    },
    /// The plant uses the other formulation of C than the model under test.
    CoriolisStructure,
    /// `τ += −k (q − q0)`; `k` [N·m/rad or N/m] `>= 0`, `q0` [rad or m] the rest position.
    JointSpring {
        /// Stiffnesses.
        k: Vec<f64>,
        /// Rest positions.
        q0: Vec<f64>,
    },
    /// Friction that differs with the direction of motion: `τ += −s⁺ (fc_pos + b_pos q̇) +
    /// s⁻ (fc_neg − b_neg q̇)` with `s± = (1 ± tanh(q̇ / w)) / 2` (`w = 0`: the exact sign), i.e.
    /// `−(fc_pos + b_pos q̇)` moving forward and `fc_neg − b_neg q̇` moving back; `fc_pos`,
    /// `fc_neg` [N·m or N], `b_pos`, `b_neg` [N·m·s/rad or N·s/m], `w` [rad/s or m/s], all `>= 0`.
    DirectionalFriction {
        /// Dry friction levels moving forward (q̇ > 0).
        fc_pos: Vec<f64>,
        /// Dry friction levels moving back (q̇ < 0).
        fc_neg: Vec<f64>,
        /// Viscous coefficients moving forward.
        b_pos: Vec<f64>,
        /// Viscous coefficients moving back.
        b_neg: Vec<f64>,
        /// Widths of the smoothed sign.
        w: Vec<f64>,
    },
    /// Dry friction that grows with the torque the drive applies through its gearbox:
    /// `τ += −(fc + mu |τ_drive|) tanh(q̇ / w)`, `τ_drive` the applied torque (after gain,
    /// offset and back-EMF; 0 while the drive is disabled); `fc` [N·m or N], `mu` [–], `w`
    /// [rad/s or m/s] (`w = 0`: the exact sign, integrated as stick–slip), all `>= 0`.
    /// Applied by the [`Stepper`](crate::step::Stepper), which knows the drive torque.
    LoadFriction {
        /// Load-independent levels.
        fc: Vec<f64>,
        /// Friction per unit of drive torque.
        mu: Vec<f64>,
        /// Widths of the smoothed sign.
        w: Vec<f64>,
    },
    /// Load-dependent friction whose level at rest rises above its level in motion (a gear
    /// train's breakaway, as in BAM's load-dependent Stribeck models): `τ += −(fc + mu |τ_drive|
    /// + ((fs − fc) + (mus − mu) |τ_drive|) e^{−(q̇/vs)²}) tanh(q̇ / w)`, `τ_drive` as in
    /// [`Effect::LoadFriction`]; `fc`, `fs` [N·m or N], `mu`, `mus` [–], `vs`, `w` [rad/s or
    /// m/s] (`vs ≤ 0` drops the rise; `w = 0`: the exact sign, integrated as stick–slip, the
    /// joint held while the torque that would move it is below `fs + mus |τ_drive|`), all `>= 0`.
    /// Applied by the [`Stepper`](crate::step::Stepper), which knows the drive torque.
    LoadStribeckFriction {
        /// Load-independent levels in motion.
        fc: Vec<f64>,
        /// Friction per unit of drive torque in motion.
        mu: Vec<f64>,
        /// Load-independent levels at rest.
        fs: Vec<f64>,
        /// Friction per unit of drive torque at rest.
        mus: Vec<f64>,
        /// Stribeck velocities.
        vs: Vec<f64>,
        /// Widths of the smoothed sign.
        w: Vec<f64>,
    },
    /// Back-EMF: `τ += −kb q̇` while the drive is enabled (absent with torque off, which tells
    /// it from viscous friction); `kb` [N·m·s/rad or N·s/m] (a motor's `kt²/R` through its
    /// gearbox) may be negative as a correction of a servo's own back-EMF. Applied by the
    /// [`Stepper`](crate::step::Stepper), which knows whether the drive is enabled.
    BackEmf {
        /// Back-EMF coefficients.
        kb: Vec<f64>,
    },
}

impl Effect {
    /// The effect's kind (its name in the vocabulary).
    pub fn kind(&self) -> EffectKind {
        match self {
            Effect::ViscousFriction { .. } => EffectKind::ViscousFriction,
            Effect::CoulombFriction { .. } => EffectKind::CoulombFriction,
            Effect::StribeckFriction { .. } => EffectKind::StribeckFriction,
            Effect::Armature { .. } => EffectKind::Armature,
            Effect::Payload { .. } => EffectKind::Payload,
            Effect::InertialError { .. } => EffectKind::InertialError,
            Effect::TorqueGain { .. } => EffectKind::TorqueGain,
            Effect::TorqueOffset { .. } => EffectKind::TorqueOffset,
            Effect::TorqueSaturation { .. } => EffectKind::TorqueSaturation,
            Effect::TimeDelay { .. } => EffectKind::TimeDelay,
            Effect::Cogging { .. } => EffectKind::Cogging,
            Effect::CoriolisStructure => EffectKind::CoriolisStructure,
            Effect::JointSpring { .. } => EffectKind::JointSpring,
            Effect::DirectionalFriction { .. } => EffectKind::DirectionalFriction,
            Effect::LoadFriction { .. } => EffectKind::LoadFriction,
            Effect::LoadStribeckFriction { .. } => EffectKind::LoadStribeckFriction,
            Effect::BackEmf { .. } => EffectKind::BackEmf,
        }
    }

    /// The contract name (`viscous_friction`, ..., `coriolis_structure`).
    pub fn name(&self) -> &'static str {
        self.kind().as_str()
    }

    /// The level of a load-dependent friction on joint `i` at velocity `qd` with the drive's
    /// torque `tau_drive` [N·m or N]: `fc + mu |τ_drive|` ([`Effect::LoadFriction`]), `fc + mu
    /// |τ_drive| + ((fs − fc) + (mus − mu) |τ_drive|) e^{−(q̇/vs)²}`
    /// ([`Effect::LoadStribeckFriction`]); 0 for any other effect.
    ///
    /// # Panics
    /// If `i` is not a joint of the effect's vectors.
    pub fn load_level(&self, i: usize, qd: f64, tau_drive: f64) -> f64 {
        let load = tau_drive.abs();
        match self {
            Effect::LoadFriction { fc, mu, .. } => fc[i] + mu[i] * load,
            Effect::LoadStribeckFriction { fc, mu, fs, mus, vs, .. } => {
                let rise = if vs[i] > 0.0 { (-(qd / vs[i]).powi(2)).exp() } else { 0.0 };
                fc[i] + mu[i] * load + rise * ((fs[i] - fc[i]) + (mus[i] - mu[i]) * load)
            }
            _ => 0.0,
        }
    }

    /// Joints (model indices, ascending) where a per-joint effect is not neutral; the joints
    /// of the changed links for an inertial error; an empty list for the whole-robot effects
    /// (payload, time delay, Coriolis structure), which act on every joint.
    pub fn joints_acted(&self) -> Vec<usize> {
        let nonzero = |v: &[f64]| v.iter().enumerate().filter(|(_, x)| **x != 0.0).map(|(i, _)| i).collect::<Vec<_>>();
        match self {
            Effect::ViscousFriction { b } => nonzero(b),
            Effect::CoulombFriction { fc, .. } => nonzero(fc),
            Effect::StribeckFriction { fc, fs, .. } => (0..fc.len()).filter(|&i| fc[i] != 0.0 || fs.get(i).is_some_and(|x| *x != 0.0)).collect(),
            Effect::Armature { ia } => nonzero(ia),
            Effect::TorqueOffset { offset } => nonzero(offset),
            Effect::Cogging { amplitude, .. } => nonzero(amplitude),
            Effect::JointSpring { k, .. } => nonzero(k),
            Effect::BackEmf { kb } => nonzero(kb),
            Effect::LoadFriction { fc, mu, .. } => (0..fc.len()).filter(|&i| fc[i] != 0.0 || mu.get(i).is_some_and(|x| *x != 0.0)).collect(),
            Effect::LoadStribeckFriction { fc, mu, fs, mus, .. } => (0..fc.len()).filter(|&i| [fc, mu, fs, mus].iter().any(|v| v.get(i).is_some_and(|x| *x != 0.0))).collect(),
            Effect::DirectionalFriction { fc_pos, fc_neg, b_pos, b_neg, .. } => {
                (0..fc_pos.len()).filter(|&i| [fc_pos, fc_neg, b_pos, b_neg].iter().any(|v| v.get(i).is_some_and(|x| *x != 0.0))).collect()
            }
            Effect::TorqueGain { k } => k.iter().enumerate().filter(|(_, x)| **x != 1.0).map(|(i, _)| i).collect(),
            Effect::TorqueSaturation { limit } => limit.iter().enumerate().filter(|(_, x)| x.is_finite()).map(|(i, _)| i).collect(),
            Effect::InertialError { deltas } => {
                let mut j: Vec<usize> = deltas.iter().map(|d| d.joint).collect();
                j.sort_unstable();
                j.dedup();
                j
            }
            Effect::Payload { .. } | Effect::TimeDelay { .. } | Effect::CoriolisStructure => Vec::new(),
        }
    }

    /// Checks lengths against `dof` and signs (friction levels, armature, limits, delay `>= 0`,
    /// numbers finite except saturation limits).
    ///
    /// # Errors
    /// [`Error::Invalid`] naming the effect and parameter.
    pub fn validate(&self, dof: usize) -> Result<()> {
        let name = self.name();
        let check = |param: &str, v: &[f64], nonneg: bool, allow_inf: bool| -> Result<()> {
            if v.len() != dof {
                return Err(invalid(name, format!("parameter '{param}' has {} values; expected {dof} (one per joint)", v.len())));
            }
            for x in v {
                if x.is_nan() || (!allow_inf && x.is_infinite()) || (nonneg && *x < 0.0) {
                    let what = if nonneg { "a finite number >= 0" } else { "a finite number" };
                    return Err(invalid(name, format!("parameter '{param}' has value {x}; expected {what}")));
                }
            }
            Ok(())
        };
        match self {
            Effect::ViscousFriction { b } => check("b", b, true, false),
            Effect::CoulombFriction { fc, w } => {
                check("fc", fc, true, false)?;
                check("w", w, true, false)
            }
            Effect::StribeckFriction { fc, fs, vs, w } => {
                check("fc", fc, true, false)?;
                check("fs", fs, true, false)?;
                check("vs", vs, true, false)?;
                check("w", w, true, false)
            }
            Effect::Armature { ia } => check("ia", ia, false, false),
            Effect::Payload { mass, com } => {
                if !mass.is_finite() || com.iter().any(|c| !c.is_finite()) {
                    return Err(invalid(name, "mass and com must be finite".into()));
                }
                Ok(())
            }
            Effect::InertialError { deltas } => {
                for d in deltas {
                    if d.joint >= dof {
                        return Err(invalid(name, format!("link delta for joint {}; the model has {dof} joints", d.joint)));
                    }
                    if !d.mass.is_finite() || d.com.iter().chain(d.inertia.iter()).any(|x| !x.is_finite()) {
                        return Err(invalid(name, format!("link delta for joint {} has a non-finite number", d.joint)));
                    }
                }
                Ok(())
            }
            Effect::TorqueGain { k } => check("k", k, false, false),
            Effect::TorqueOffset { offset } => check("offset", offset, false, false),
            Effect::TorqueSaturation { limit } => check("limit", limit, true, true),
            Effect::TimeDelay { delay } => {
                if !(delay.is_finite() && *delay >= 0.0) {
                    return Err(invalid(name, format!("delay = {delay}; expected a finite number >= 0 [s]")));
                }
                Ok(())
            }
            Effect::Cogging { amplitude, periods_per_rev } => {
                check("amplitude", amplitude, false, false)?;
                check("periods_per_rev", periods_per_rev, false, false)
            }
            Effect::CoriolisStructure => Ok(()),
            Effect::JointSpring { k, q0 } => {
                check("k", k, true, false)?;
                check("q0", q0, false, false)
            }
            Effect::DirectionalFriction { fc_pos, fc_neg, b_pos, b_neg, w } => {
                check("fc_pos", fc_pos, true, false)?;
                check("fc_neg", fc_neg, true, false)?;
                check("b_pos", b_pos, true, false)?;
                check("b_neg", b_neg, true, false)?;
                check("w", w, true, false)
            }
            Effect::LoadFriction { fc, mu, w } => {
                check("fc", fc, true, false)?;
                check("mu", mu, true, false)?;
                check("w", w, true, false)
            }
            Effect::LoadStribeckFriction { fc, mu, fs, mus, vs, w } => {
                check("fc", fc, true, false)?;
                check("mu", mu, true, false)?;
                check("fs", fs, true, false)?;
                check("mus", mus, true, false)?;
                check("vs", vs, true, false)?;
                check("w", w, true, false)
            }
            Effect::BackEmf { kb } => check("kb", kb, false, false),
        }
    }

    /// Parses the command-line spelling `name[:param=v1,v2,...[;param=...]]`, e.g.
    /// `viscous_friction:b=2.288,0.175`, `stribeck_friction:fc=1,1;fs=2,2;vs=0.1,0.1`,
    /// `payload:mass=0.5;com=0,0,-0.1`, `time_delay:delay=0.005`, `coriolis_structure`,
    /// `inertial_error:joint=1;mass=0.2;com=0,0,0.01;inertia=0,0,0,0,0,0`.
    /// Per-joint parameters take one value per joint (`dof` values), or a single value used for
    /// every joint. A dry friction's width `w` [rad/s or m/s] may be given
    /// (`coulomb_friction:fc=7.17,1.734;w=0.01,0.02`); left out, it is
    /// [`DEFAULT_COULOMB_WIDTH`] on every joint (with the model known, use
    /// [`Effect::parse_for_model`]: the joint type's typical width).
    ///
    /// # Errors
    /// [`Error::Invalid`] for an unknown name, a missing or unknown parameter, or a bad number.
    pub fn parse(spec: &str, dof: usize) -> Result<Effect> {
        Effect::parse_with_width(spec, dof, DEFAULT_COULOMB_WIDTH)
    }

    /// [`Effect::parse`], with `default_w` [rad/s or m/s] the width `w` of a dry friction whose
    /// spelling leaves it out (e.g. the Python `simulate(..., coulomb_width=...)`).
    ///
    /// # Errors
    /// As [`Effect::parse`]; also [`Error::Invalid`] for a `default_w` that is needed and is not
    /// a finite number `>= 0`.
    pub fn parse_with_width(spec: &str, dof: usize, default_w: f64) -> Result<Effect> {
        if !(default_w.is_finite() && default_w >= 0.0) {
            // refused only where a dry friction needs it (below)
            return Effect::parse_with_widths(spec, dof, &[default_w]);
        }
        Effect::parse_with_widths(spec, dof, &vec![default_w; dof])
    }

    /// [`Effect::parse`] for `model`'s joints: a dry friction whose spelling leaves `w` out
    /// gets each joint type's typical width ([`typical_width`]: 0.01 rad/s on a revolute
    /// joint, 0.002 m/s on a prismatic one), the width the diagnosis starts from. This is how
    /// `simgap simulate --effect` and `simgap predict --effect` read their effects.
    ///
    /// # Errors
    /// As [`Effect::parse`].
    pub fn parse_for_model(spec: &str, model: &Model) -> Result<Effect> {
        let widths: Vec<f64> = model.joints().iter().map(|j| typical_width(j.kind)).collect();
        Effect::parse_with_widths(spec, model.dof(), &widths)
    }

    /// The parser: `default_w` the widths of a dry friction whose spelling leaves `w` out, one
    /// per joint (or a single value, refused as not a width where one is needed).
    fn parse_with_widths(spec: &str, dof: usize, default_w: &[f64]) -> Result<Effect> {
        let (name, rest) = match spec.split_once(':') {
            Some((n, r)) => (n.trim(), r.trim()),
            None => (spec.trim(), ""),
        };
        let kind: EffectKind = name.parse()?;
        let mut params: Vec<(String, Vec<f64>)> = Vec::new();
        for part in rest.split(';').map(str::trim).filter(|p| !p.is_empty()) {
            let (k, v) = part.split_once('=').ok_or_else(|| invalid(name, format!("'{part}' is not param=values")))?;
            let vals = v
                .split(',')
                .map(|x| {
                    let x = x.trim();
                    match x {
                        "inf" | "+inf" => Ok(f64::INFINITY),
                        _ => x.parse::<f64>().map_err(|_| invalid(name, format!("'{x}' in parameter '{}' is not a number", k.trim()))),
                    }
                })
                .collect::<Result<Vec<f64>>>()?;
            params.push((k.trim().to_string(), vals));
        }
        // the command line names the inertial error's link by its joint, and its deltas as
        // `mass`, `com`, `inertia`: the spellings of one link's change
        let known: Vec<&str> = match kind {
            EffectKind::InertialError => vec!["joint", "mass", "com", "inertia"],
            k => k.parameters().iter().map(|p| p.name).collect(),
        };
        if let Some((k, _)) = params.iter().find(|(k, _)| !known.contains(&k.as_str())) {
            return Err(invalid(name, format!("unknown parameter '{k}'; expected {}", if known.is_empty() { "none".into() } else { known.join(", ") })));
        }
        let get = |k: &str| -> Result<Vec<f64>> { params.iter().find(|(p, _)| p == k).map(|(_, v)| v.clone()).ok_or_else(|| invalid(name, format!("missing parameter '{k}'"))) };
        let per_joint = |k: &str| -> Result<Vec<f64>> {
            let v = get(k)?;
            match v.len() {
                1 => Ok(vec![v[0]; dof]),
                n if n == dof => Ok(v),
                n => Err(invalid(name, format!("parameter '{k}' has {n} values; expected {dof} (one per joint) or 1"))),
            }
        };
        // the dry friction's width: given, or the caller's default on every joint
        let width = |k: &str| -> Result<Vec<f64>> {
            if params.iter().any(|(p, _)| p == k) {
                return per_joint(k);
            }
            if let Some(w) = default_w.iter().find(|w| !(w.is_finite() && **w >= 0.0)) {
                return Err(invalid(name, format!("default width w = {w}; expected a finite number >= 0 [rad/s or m/s] (0: the exact sign)")));
            }
            if default_w.len() != dof {
                return Err(invalid(name, format!("{} default widths for {dof} joints", default_w.len())));
            }
            Ok(default_w.to_vec())
        };
        let scalar = |k: &str| -> Result<f64> {
            let v = get(k)?;
            if v.len() != 1 {
                return Err(invalid(name, format!("parameter '{k}' takes one number, got {}", v.len())));
            }
            Ok(v[0])
        };
        let triple = |k: &str| -> Result<[f64; 3]> {
            let v = get(k)?;
            <[f64; 3]>::try_from(v.as_slice()).map_err(|_| invalid(name, format!("parameter '{k}' takes 3 numbers, got {}", v.len())))
        };
        let effect = match kind {
            EffectKind::ViscousFriction => Effect::ViscousFriction { b: per_joint("b")? },
            EffectKind::CoulombFriction => Effect::CoulombFriction { fc: per_joint("fc")?, w: width("w")? },
            EffectKind::StribeckFriction => Effect::StribeckFriction { fc: per_joint("fc")?, fs: per_joint("fs")?, vs: per_joint("vs")?, w: width("w")? },
            EffectKind::Armature => Effect::Armature { ia: per_joint("ia")? },
            EffectKind::Payload => Effect::Payload { mass: scalar("mass")?, com: triple("com")? },
            EffectKind::InertialError => {
                let joint = scalar("joint")?;
                if joint < 0.0 || joint.fract() != 0.0 {
                    return Err(invalid(name, format!("joint = {joint}; expected a joint index")));
                }
                let inertia = match get("inertia") {
                    Ok(v) => <[f64; 6]>::try_from(v.as_slice()).map_err(|_| invalid(name, format!("parameter 'inertia' takes 6 numbers, got {}", v.len())))?,
                    Err(_) => [0.0; 6],
                };
                let delta = LinkDelta { joint: joint as usize, mass: scalar("mass").unwrap_or(0.0), com: triple("com").unwrap_or([0.0; 3]), inertia };
                Effect::InertialError { deltas: vec![delta] }
            }
            EffectKind::TorqueGain => Effect::TorqueGain { k: per_joint("k")? },
            EffectKind::TorqueOffset => Effect::TorqueOffset { offset: per_joint("offset")? },
            EffectKind::TorqueSaturation => Effect::TorqueSaturation { limit: per_joint("limit")? },
            EffectKind::TimeDelay => Effect::TimeDelay { delay: scalar("delay")? },
            EffectKind::Cogging => Effect::Cogging { amplitude: per_joint("amplitude")?, periods_per_rev: per_joint("periods_per_rev")? },
            EffectKind::CoriolisStructure => Effect::CoriolisStructure,
            EffectKind::JointSpring => Effect::JointSpring { k: per_joint("k")?, q0: per_joint("q0")? },
            EffectKind::DirectionalFriction => {
                Effect::DirectionalFriction { fc_pos: per_joint("fc_pos")?, fc_neg: per_joint("fc_neg")?, b_pos: per_joint("b_pos")?, b_neg: per_joint("b_neg")?, w: width("w")? }
            }
            EffectKind::LoadFriction => Effect::LoadFriction { fc: per_joint("fc")?, mu: per_joint("mu")?, w: width("w")? },
            EffectKind::LoadStribeckFriction => {
                Effect::LoadStribeckFriction { fc: per_joint("fc")?, mu: per_joint("mu")?, fs: per_joint("fs")?, mus: per_joint("mus")?, vs: per_joint("vs")?, w: width("w")? }
            }
            EffectKind::BackEmf => Effect::BackEmf { kb: per_joint("kb")? },
        };
        effect.validate(dof)?;
        Ok(effect)
    }
}

fn invalid(what: &str, message: String) -> Error {
    Error::Invalid { what: what.to_string(), message }
}

/// Validates every effect against `dof`.
///
/// # Errors
/// As [`Effect::validate`].
pub fn validate_effects(effects: &[Effect], dof: usize) -> Result<()> {
    effects.iter().try_for_each(|e| e.validate(dof))
}

/// `sign(q̇)` smoothed: `tanh(q̇ / width)` (the exact sign for `width <= 0`).
#[inline]
pub fn smooth_sign(qd: f64, width: f64) -> f64 {
    if width > 0.0 {
        // beyond |x| = 19.1, tanh(x) rounds to ±1 in f64 (libm returns exactly that): the
        // exponential is skipped on most samples of a moving joint, with the same result
        let x = qd / width;
        if x.abs() >= 20.0 {
            1.0f64.copysign(x)
        } else {
            x.tanh()
        }
    } else if qd > 0.0 {
        1.0
    } else if qd < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// Sum of the friction, cogging and spring torques the effects ADD to the model at `(q, q̇)`
/// [N·m or N]: `out = −b q̇ − fc s − (fc + (fs − fc) e^{−(q̇/vs)²}) s − A sin(N q) − k (q − q0)`
/// with `s = tanh(q̇ / w)` (and the directional friction of [`Effect::DirectionalFriction`]),
/// `w` each dry friction's own width [rad/s or m/s] (the exact sign where `w = 0`). Negative
/// for dissipation. Overwrites `out`; never allocates. Load friction and back-EMF depend on the
/// drive and are not in it (see [`drive_torque`]).
///
/// `q`, `qd`, `out`: length `dof` (model order).
///
/// # Panics
/// If the lengths differ or an effect's vector is shorter than `out`.
pub fn friction_torque(effects: &[Effect], q: &[f64], qd: &[f64], out: &mut [f64]) {
    friction_torque_parts(effects, q, qd, true, out);
}

/// [`friction_torque`] without the dry frictions of width `w = 0` (the exact sign), which the
/// simulator integrates as stick–slip from their levels ([`exact_dry_levels`]). Load friction
/// and back-EMF are not in either: they need the drive's torque and enable state, which the
/// [`Stepper`](crate::step::Stepper) applies.
///
/// # Panics
/// As [`friction_torque`].
pub fn friction_torque_smooth(effects: &[Effect], q: &[f64], qd: &[f64], out: &mut [f64]) {
    friction_torque_parts(effects, q, qd, false, out);
}

/// The levels [N·m or N] of the dry frictions of width `w = 0` at velocity `qd`, for motion
/// forward (`pos`) and back (`neg`), into `pos` and `neg` (overwritten): Coulomb `fc`,
/// Stribeck `fc + (fs − fc) e^{−(q̇/vs)²}`, directional `fc_pos` / `fc_neg`, load friction
/// `fc + mu |τ_drive|` with `tau_drive` the drive's torque (and its Stribeck form, see
/// [`Effect::load_level`]). The simulator holds a joint at rest while the torque that would
/// move it is below the level (stick–slip).
///
/// # Panics
/// If a length differs from `qd.len()`.
pub fn exact_dry_levels(effects: &[Effect], qd: &[f64], tau_drive: &[f64], pos: &mut [f64], neg: &mut [f64]) {
    pos.fill(0.0);
    neg.fill(0.0);
    for e in effects {
        for i in 0..qd.len() {
            let (p, n) = match e {
                Effect::CoulombFriction { fc, w } if w[i] <= 0.0 => (fc[i], fc[i]),
                Effect::StribeckFriction { fc, fs, vs, w } if w[i] <= 0.0 => {
                    let level = fc[i] + if vs[i] > 0.0 { (fs[i] - fc[i]) * (-(qd[i] / vs[i]).powi(2)).exp() } else { 0.0 };
                    (level, level)
                }
                Effect::DirectionalFriction { fc_pos, fc_neg, w, .. } if w[i] <= 0.0 => (fc_pos[i], fc_neg[i]),
                Effect::LoadFriction { w, .. } | Effect::LoadStribeckFriction { w, .. } if w[i] <= 0.0 => {
                    let level = e.load_level(i, qd[i], tau_drive[i]);
                    (level, level)
                }
                _ => (0.0, 0.0),
            };
            pos[i] += p;
            neg[i] += n;
        }
    }
}

/// Whether any dry friction of the effects has width `w = 0` on a joint where it acts (the
/// simulator then integrates stick–slip).
pub fn has_exact_dry_friction(effects: &[Effect]) -> bool {
    effects.iter().any(|e| match e {
        Effect::CoulombFriction { fc, w } => fc.iter().zip(w).any(|(f, w)| *f != 0.0 && *w <= 0.0),
        Effect::StribeckFriction { fc, fs, w, .. } => (0..fc.len()).any(|i| (fc[i] != 0.0 || fs[i] != 0.0) && w[i] <= 0.0),
        Effect::DirectionalFriction { fc_pos, fc_neg, w, .. } => (0..w.len()).any(|i| (fc_pos[i] != 0.0 || fc_neg[i] != 0.0) && w[i] <= 0.0),
        Effect::LoadFriction { w, .. } | Effect::LoadStribeckFriction { w, .. } => e.joints_acted().iter().any(|&i| w[i] <= 0.0),
        _ => false,
    })
}

/// Whether the effects hold a term the drive's torque or enable state changes (back-EMF,
/// load friction): the simulator then evaluates the drive torque at every stage.
pub fn has_drive_effects(effects: &[Effect]) -> bool {
    effects.iter().any(|e| matches!(e, Effect::BackEmf { .. } | Effect::LoadFriction { .. } | Effect::LoadStribeckFriction { .. }))
}

/// The torque of the drive and the load friction at velocity `qd` [N·m or N], into `out`:
/// `τ_drive = en (applied(τ_cmd − emf q̇) − kb q̇)` (the command's voltage part `tau_cmd` less the
/// controller's own back-EMF `emf`, through [`applied_torque`] and the effort `limits`, then
/// the [`Effect::BackEmf`] `kb`, all times the enable `en`), plus the smooth (`w > 0`) load
/// friction `−(fc + mu |τ_drive|) tanh(q̇/w)`. `drive` receives `τ_drive` alone (for the levels
/// of an exact load friction). `scratch`, `drive`, `out`: length `dof`. Never allocates.
///
/// # Panics
/// If a length differs.
#[allow(clippy::too_many_arguments)]
pub fn drive_torque(
    effects: &[Effect],
    limits: Option<&[f64]>,
    tau_cmd: &[f64],
    emf: &[f64],
    enabled: &[f64],
    qd: &[f64],
    scratch: &mut [f64],
    drive: &mut [f64],
    out: &mut [f64],
) {
    let n = out.len();
    for i in 0..n {
        scratch[i] = tau_cmd[i] - emf[i] * qd[i];
    }
    applied_torque(effects, scratch, drive);
    if let Some(l) = limits {
        for i in 0..n {
            drive[i] = drive[i].clamp(-l[i], l[i]);
        }
    }
    for e in effects {
        if let Effect::BackEmf { kb } = e {
            for i in 0..n {
                drive[i] -= kb[i] * qd[i];
            }
        }
    }
    for (d, e) in drive.iter_mut().zip(enabled) {
        *d *= e;
    }
    out.copy_from_slice(drive);
    for e in effects {
        if let Effect::LoadFriction { w, .. } | Effect::LoadStribeckFriction { w, .. } = e {
            for i in 0..n {
                if w[i] > 0.0 {
                    let level = e.load_level(i, qd[i], drive[i]);
                    if level != 0.0 {
                        out[i] -= level * smooth_sign(qd[i], w[i]);
                    }
                }
            }
        }
    }
}

/// The friction torque, with (`exact`) or without the dry frictions of width 0.
fn friction_torque_parts(effects: &[Effect], q: &[f64], qd: &[f64], exact: bool, out: &mut [f64]) {
    assert!(q.len() == out.len() && qd.len() == out.len(), "friction_torque: q, qd and out must have the same length");
    out.fill(0.0);
    let dry = |w: f64| exact || w > 0.0;
    for e in effects {
        match e {
            Effect::ViscousFriction { b } => {
                for i in 0..out.len() {
                    out[i] -= b[i] * qd[i];
                }
            }
            Effect::CoulombFriction { fc, w } => {
                for i in 0..out.len() {
                    if fc[i] != 0.0 && dry(w[i]) {
                        out[i] -= fc[i] * smooth_sign(qd[i], w[i]);
                    }
                }
            }
            Effect::StribeckFriction { fc, fs, vs, w } => {
                for i in 0..out.len() {
                    if (fc[i] == 0.0 && fs[i] == 0.0) || !dry(w[i]) {
                        continue;
                    }
                    let stribeck = if vs[i] > 0.0 { (fs[i] - fc[i]) * (-(qd[i] / vs[i]).powi(2)).exp() } else { 0.0 };
                    out[i] -= (fc[i] + stribeck) * smooth_sign(qd[i], w[i]);
                }
            }
            Effect::Cogging { amplitude, periods_per_rev } => {
                for i in 0..out.len() {
                    if amplitude[i] != 0.0 {
                        out[i] -= amplitude[i] * (periods_per_rev[i] * q[i]).sin();
                    }
                }
            }
            Effect::JointSpring { k, q0 } => {
                for i in 0..out.len() {
                    out[i] -= k[i] * (q[i] - q0[i]);
                }
            }
            Effect::DirectionalFriction { fc_pos, fc_neg, b_pos, b_neg, w } => {
                for i in 0..out.len() {
                    let s = smooth_sign(qd[i], w[i]);
                    let (pos, neg) = (0.5 * (1.0 + s), 0.5 * (1.0 - s));
                    // at w = 0 without `exact` only the viscous parts (continuous at rest)
                    let (fp, fn_) = if dry(w[i]) { (fc_pos[i], fc_neg[i]) } else { (0.0, 0.0) };
                    out[i] += -pos * (fp + b_pos[i] * qd[i]) + neg * (fn_ - b_neg[i] * qd[i]);
                }
            }
            _ => {}
        }
    }
}

/// The torque the actuators apply for a command: `out = k · clamp(τ_cmd, ±limit) + offset`
/// (saturation first, then gain, then offset), with gains multiplied, limits reduced to the
/// smallest and offsets summed over the effects. The time delay is not applied here (the
/// simulator delays `τ_cmd` before calling this). Overwrites `out`; never allocates.
///
/// # Panics
/// If `tau_cmd` and `out` differ in length or an effect's vector is shorter.
pub fn applied_torque(effects: &[Effect], tau_cmd: &[f64], out: &mut [f64]) {
    assert_eq!(tau_cmd.len(), out.len(), "applied_torque: tau_cmd and out must have the same length");
    for i in 0..out.len() {
        let (mut k, mut offset, mut limit) = (1.0, 0.0, f64::INFINITY);
        for e in effects {
            match e {
                Effect::TorqueGain { k: g } => k *= g[i],
                Effect::TorqueOffset { offset: o } => offset += o[i],
                Effect::TorqueSaturation { limit: l } => limit = limit.min(l[i]),
                _ => {}
            }
        }
        out[i] = k * tau_cmd[i].clamp(-limit, limit) + offset;
    }
}

/// Total time delay of the effects [s] (sum of every [`Effect::TimeDelay`]).
pub fn total_delay(effects: &[Effect]) -> f64 {
    effects.iter().map(|e| if let Effect::TimeDelay { delay } = e { *delay } else { 0.0 }).sum()
}

/// Total armature per joint (sum of every [`Effect::Armature`]) into `out` (overwritten).
///
/// # Panics
/// If an effect's vector is shorter than `out`.
pub fn armature(effects: &[Effect], out: &mut [f64]) {
    out.fill(0.0);
    for e in effects {
        if let Effect::Armature { ia } = e {
            for i in 0..out.len() {
                out[i] += ia[i];
            }
        }
    }
}

/// The model with the payload and inertial-error effects applied to its link inertias.
///
/// # Errors
/// [`Error::Invalid`] for a bad effect; [`Error::Model`] when a changed link is not physical
/// (negative mass, inertia not positive semi-definite or violating the triangle inequality).
pub fn apply_inertial_effects(model: &Model, effects: &[Effect]) -> Result<Model> {
    validate_effects(effects, model.dof())?;
    let mut m = model.clone();
    for e in effects {
        match e {
            Effect::Payload { mass, com } => {
                let last = m.dof() - 1;
                let point = SpatialInertia::from_com(*mass, Vector3::from(*com), Matrix3::zeros());
                let old = m.joints()[last].inertia;
                let new = SpatialInertia { mass: old.mass + point.mass, first_moment: old.first_moment + point.first_moment, rotational: old.rotational + point.rotational };
                m.set_link_inertia(last, new)?;
            }
            Effect::InertialError { deltas } => {
                for d in deltas {
                    let old = m.joints()[d.joint].inertia;
                    let [ixx, ixy, ixz, iyy, iyz, izz] = d.inertia;
                    let di = Matrix3::new(ixx, ixy, ixz, ixy, iyy, iyz, ixz, iyz, izz);
                    let new_mass = old.mass + d.mass;
                    let new_com = old.com() + Vector3::from(d.com);
                    let new = SpatialInertia::from_com(new_mass, new_com, old.inertia_about_com() + di);
                    m.set_link_inertia(d.joint, new)?;
                }
            }
            _ => {}
        }
    }
    Ok(m)
}
