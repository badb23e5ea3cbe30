//! Unmodelled effects: friction, actuator errors, inertial errors, delays.
//!
//! An [`Effect`] is something the real robot has and the nominal [`Model`] lacks. A
//! [`Plant`](crate::plant::Plant) is the nominal model plus a list of effects; the simulator
//! integrates
//!
//! ```text
//! (H(q̄) + diag(ia)) q̈ = τ_applied + τ_friction(q, q̇) − C(q̄, q̇) q̇ − g(q̄),   q̄ = q + δ
//! τ_applied(t)        = k · clamp(τ_cmd(t − delay), ±limit) + offset
//! ```
//!
//! with `q` the measured positions (the state, what the controller and the log see), `δ` the
//! [`Effect::EncoderOffset`] (0 without one), `H`, `C`, `g` those of the model after
//! [`Effect::Payload`] and [`Effect::InertialError`] were applied, and `C` of the other
//! [`Formulation`](simgap_core::Formulation) when [`Effect::CoriolisStructure`] is present.
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
//!
//! Each effect's simulation is one file of this folder (`viscous_friction.rs`, ...,
//! `back_emf.rs`): a view of its variant's parameters implementing the private trait
//! `Simulated` (its torque, slopes, stiff band, dry levels, drive and actuator parts, armature,
//! inertia, validation), and the reading of its spelling. `Effect::simulated` is the one table
//! from a variant to its file; the functions here fold every effect's part. A new effect is one
//! file, one variant, and one line in that table and in the parser's (`parse.rs`).

use simgap_core::Model;

use crate::error::{Error, Result};
use crate::kind::EffectKind;

mod armature;
mod back_emf;
mod backlash;
mod cogging;
mod coriolis_structure;
mod coulomb_friction;
mod directional_friction;
mod encoder_offset;
mod inertial_error;
mod joint_spring;
mod load_friction;
mod load_stribeck_friction;
mod parse;
mod payload;
mod spelling;
mod stribeck_friction;
mod time_delay;
mod torque_gain;
mod torque_offset;
mod torque_saturation;
mod viscous_friction;

pub use inertial_error::LinkDelta;

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
    /// The joint's measured zero is not the model's: the joint is at `q_measured + offset`
    /// [rad or m]. The simulator's state, controller and log are in measured positions; the
    /// plant evaluates `H`, `C q̇` and `g` at `q + offset` (gravity and inertia act at the true
    /// angle, the controller sees the measured one).
    EncoderOffset {
        /// Offsets: true position minus measured position.
        offset: Vec<f64>,
    },
    /// Free play of total width `width` [rad or m] between the drive and the link (gear
    /// backlash): the drive's torque reaches the link only while the play is taken up. The
    /// drive's side carries the joint's rotor inertia (its [`Effect::Armature`]) and moves
    /// freely inside the gap under the drive's torque; when it reaches the other side it takes
    /// the link along in a plastic impact. With no rotor inertia on the joint the drive's side
    /// follows the torque's sign at once and the link's motion is the one without play (the
    /// state and the log are the link's: a servo's encoder sits on its output shaft). Integrated
    /// by the [`Stepper`](crate::step::Stepper), which holds the drive side's state (see
    /// [`crate::backlash`]).
    Backlash {
        /// Total widths of the play, `>= 0`.
        width: Vec<f64>,
    },
}

/// How the simulator applies one kind of effect. Each effect's file implements it once, over a
/// view of its variant's parameters ([`Effect::simulated`] builds the view); every method but
/// the first three defaults to the neutral effect, which adds nothing there. Per-joint methods
/// take the joint `i` (model order).
trait Simulated {
    /// The effect's kind (its name in the vocabulary).
    fn kind(&self) -> EffectKind;

    /// Checks the parameters against `dof`: see [`Effect::validate`].
    fn validate(&self, dof: usize) -> Result<()>;

    /// The joints where the effect is not neutral: see [`Effect::joints_acted`].
    fn joints_acted(&self) -> Vec<usize>;

    /// Adds the friction, cogging or spring torque at `(q, q̇)` to `out` [N·m or N]; `exact`:
    /// with the dry frictions of width `w = 0` (see [`friction_torque`]).
    fn add_friction_torque(&self, _q: &[f64], _qd: &[f64], _exact: bool, _out: &mut [f64]) {}

    /// Bound of the slope `−∂τ_i/∂q̇_i` on joint `i` with the dry steps' slopes scaled by `dry`
    /// and the Stribeck humps' by `hump_scale` [N·m·s/rad or N·s/m] (see [`friction_slope_bound`]).
    fn slope(&self, _i: usize, _dry: f64, _hump_scale: f64) -> f64 {
        0.0
    }

    /// The speed below which the smoothed dry friction is stiff on joint `i` [rad/s or m/s]
    /// (see [`stiff_band`]).
    fn stiff_band(&self, _i: usize) -> f64 {
        0.0
    }

    /// The levels forward and back of a dry friction of width `w = 0` on joint `i` at velocity
    /// `qd` with the drive's torque `tau_drive` [N·m or N] (see [`exact_dry_levels`]).
    fn exact_dry_levels(&self, _i: usize, _qd: f64, _tau_drive: f64) -> (f64, f64) {
        (0.0, 0.0)
    }

    /// Whether a dry friction of width `w = 0` acts on some joint (see [`has_exact_dry_friction`]).
    fn has_exact_dry_friction(&self) -> bool {
        false
    }

    /// Whether the drive's torque or enable state changes the effect (see [`has_drive_effects`]).
    fn acts_through_drive(&self) -> bool {
        false
    }

    /// The level of a load-dependent friction: see [`Effect::load_level`].
    fn load_level(&self, _i: usize, _qd: f64, _tau_drive: f64) -> f64 {
        0.0
    }

    /// Adds the effect's part of the drive torque at velocity `qd` to `drive` [N·m or N]
    /// (the back-EMF, see [`drive_torque`]).
    fn add_drive_torque(&self, _qd: &[f64], _drive: &mut [f64]) {}

    /// Adds the smooth (`w > 0`) load friction for the drive torque `drive` at velocity `qd`
    /// to `out` [N·m or N] (see [`drive_torque`]).
    fn add_load_friction(&self, _qd: &[f64], _drive: &[f64], _out: &mut [f64]) {}

    /// Folds the effect into joint `i`'s actuator: its gain, offset or limit (see
    /// [`applied_torque`]).
    fn actuate(&self, _i: usize, _actuator: &mut Actuator) {}

    /// The effect's time delay [s] (see [`total_delay`]).
    fn delay(&self) -> f64 {
        0.0
    }

    /// Adds the effect's armature to `out` [kg·m² or kg] (see [`armature`]).
    fn add_armature(&self, _out: &mut [f64]) {}

    /// Adds the effect's encoder offset to `out` [rad or m] (see [`encoder_offset`]).
    fn add_encoder_offset(&self, _out: &mut [f64]) {}

    /// Adds the effect's backlash width to `out` [rad or m] (see [`backlash`]).
    fn add_backlash(&self, _out: &mut [f64]) {}

    /// Applies the effect to the link inertias of `model` (see [`apply_inertial_effects`]).
    fn apply_to_model(&self, _model: &mut Model) -> Result<()> {
        Ok(())
    }
}

/// One joint's actuator as the effects shape it: `τ_applied = k · clamp(τ_cmd, ±limit) + offset`.
struct Actuator {
    /// Gain `k` [–] (gains multiply).
    k: f64,
    /// Offset [N·m or N] (offsets add).
    offset: f64,
    /// Saturation limit [N·m or N] (the smallest holds; `+∞` for none).
    limit: f64,
}

/// Whether a dry friction of width `w` is in the torque: always with `exact`, else only where
/// it is smoothed (`w > 0`).
fn dry_included(exact: bool, w: f64) -> bool {
    exact || w > 0.0
}

/// The velocity band [rad/s or m/s] around rest where a dry friction of sign width `w` is stiff:
/// [`STIFF_WIDTHS`] widths, none for the exact sign (`w = 0`).
fn dry_stiff_band(w: f64) -> f64 {
    if w > 0.0 {
        STIFF_WIDTHS * w
    } else {
        0.0
    }
}

/// The slope `dry · level / w` of a smoothed dry step of `level` [N·m or N] and width `w`
/// [rad/s or m/s]; 0 for the exact sign (`w = 0`, a jump, not a slope).
fn dry_slope(dry: f64, level: f64, w: f64) -> f64 {
    if w > 0.0 {
        dry * level / w
    } else {
        0.0
    }
}

/// The joints (ascending) where `v` is not 0.
fn nonzero(v: &[f64]) -> Vec<usize> {
    v.iter().enumerate().filter(|(_, x)| **x != 0.0).map(|(i, _)| i).collect()
}

/// Checks one parameter of effect `name`: `dof` values, not NaN, finite unless `allow_inf`,
/// `>= 0` when `nonneg`.
///
/// # Errors
/// [`Error::Invalid`] naming the effect, the parameter and the value.
fn check(name: &str, param: &str, v: &[f64], dof: usize, nonneg: bool, allow_inf: bool) -> Result<()> {
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
}

fn invalid(what: &str, message: String) -> Error {
    Error::Invalid { what: what.to_string(), message }
}

impl Effect {
    /// Calls `f` with the effect's view in its own file: the one table from a variant to its
    /// simulation.
    fn simulated<R>(&self, f: impl FnOnce(&dyn Simulated) -> R) -> R {
        match self {
            Effect::ViscousFriction { b } => f(&viscous_friction::ViscousFriction { b }),
            Effect::CoulombFriction { fc, w } => f(&coulomb_friction::CoulombFriction { fc, w }),
            Effect::StribeckFriction { fc, fs, vs, w } => f(&stribeck_friction::StribeckFriction { fc, fs, vs, w }),
            Effect::Armature { ia } => f(&armature::Armature { ia }),
            Effect::Payload { mass, com } => f(&payload::Payload { mass: *mass, com: *com }),
            Effect::InertialError { deltas } => f(&inertial_error::InertialError { deltas }),
            Effect::TorqueGain { k } => f(&torque_gain::TorqueGain { k }),
            Effect::TorqueOffset { offset } => f(&torque_offset::TorqueOffset { offset }),
            Effect::TorqueSaturation { limit } => f(&torque_saturation::TorqueSaturation { limit }),
            Effect::TimeDelay { delay } => f(&time_delay::TimeDelay { delay: *delay }),
            Effect::Cogging { amplitude, periods_per_rev } => f(&cogging::Cogging { amplitude, periods_per_rev }),
            Effect::CoriolisStructure => f(&coriolis_structure::CoriolisStructure),
            Effect::JointSpring { k, q0 } => f(&joint_spring::JointSpring { k, q0 }),
            Effect::DirectionalFriction { fc_pos, fc_neg, b_pos, b_neg, w } => f(&directional_friction::DirectionalFriction { fc_pos, fc_neg, b_pos, b_neg, w }),
            Effect::LoadFriction { fc, mu, w } => f(&load_friction::LoadFriction { fc, mu, w }),
            Effect::LoadStribeckFriction { fc, mu, fs, mus, vs, w } => f(&load_stribeck_friction::LoadStribeckFriction { fc, mu, fs, mus, vs, w }),
            Effect::BackEmf { kb } => f(&back_emf::BackEmf { kb }),
            Effect::EncoderOffset { offset } => f(&encoder_offset::EncoderOffset { offset }),
            Effect::Backlash { width } => f(&backlash::Backlash { width }),
        }
    }

    /// The effect's kind (its name in the vocabulary).
    pub fn kind(&self) -> EffectKind {
        self.simulated(|e| e.kind())
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
        self.simulated(|e| e.load_level(i, qd, tau_drive))
    }

    /// Joints (model indices, ascending) where a per-joint effect is not neutral; the joints
    /// of the changed links for an inertial error; an empty list for the whole-robot effects
    /// (payload, time delay, Coriolis structure), which act on every joint.
    pub fn joints_acted(&self) -> Vec<usize> {
        self.simulated(|e| e.joints_acted())
    }

    /// Makes the dry frictions of the joints where `exact[i]` holds the exact sign (`w = 0`,
    /// integrated as stick–slip): Coulomb, Stribeck and directional friction, and the load
    /// frictions (load-dependent and rising at rest) where `held_drive`: where the drive's torque
    /// is held over each sample ([`ControllerKind::holds_torque_over_sample`](crate::ControllerKind::holds_torque_over_sample)),
    /// their level is constant within it, while a servo's follows its back-EMF. Any other effect
    /// is left as it is.
    ///
    /// # Panics
    /// If `exact` is shorter than a friction's vector of widths.
    pub fn make_sign_exact(&mut self, exact: &[bool], held_drive: bool) {
        let w = match self {
            Effect::CoulombFriction { w, .. } | Effect::StribeckFriction { w, .. } | Effect::DirectionalFriction { w, .. } => w,
            Effect::LoadFriction { w, .. } | Effect::LoadStribeckFriction { w, .. } if held_drive => w,
            _ => return,
        };
        for (wi, e) in w.iter_mut().zip(exact) {
            if *e {
                *wi = 0.0;
            }
        }
    }

    /// Checks lengths against `dof` and signs (friction levels, armature, limits, delay `>= 0`,
    /// numbers finite except saturation limits).
    ///
    /// # Errors
    /// [`Error::Invalid`] naming the effect and parameter.
    pub fn validate(&self, dof: usize) -> Result<()> {
        self.simulated(|e| e.validate(dof))
    }
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
        e.simulated(|e| {
            for i in 0..out.len() {
                out[i] = out[i].max(e.stiff_band(i));
            }
        });
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
    for e in effects {
        e.simulated(|e| {
            for i in 0..out.len() {
                out[i] += e.slope(i, dry, hump_scale);
            }
        });
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
        e.simulated(|e| {
            for i in 0..qd.len() {
                let (p, n) = e.exact_dry_levels(i, qd[i], tau_drive[i]);
                pos[i] += p;
                neg[i] += n;
            }
        });
    }
}

/// Whether any dry friction of the effects has width `w = 0` on a joint where it acts (the
/// simulator then integrates stick–slip).
pub fn has_exact_dry_friction(effects: &[Effect]) -> bool {
    effects.iter().any(|e| e.simulated(|e| e.has_exact_dry_friction()))
}

/// Whether the effects hold a term the drive's torque or enable state changes (back-EMF,
/// load friction): the simulator then evaluates the drive torque at every stage.
pub fn has_drive_effects(effects: &[Effect]) -> bool {
    effects.iter().any(|e| e.simulated(|e| e.acts_through_drive()))
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
    // the command less the controller's own back-EMF, through the actuators and the limits
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
    // the back-EMF, then the enable
    for e in effects {
        e.simulated(|e| e.add_drive_torque(qd, drive));
    }
    for (d, e) in drive.iter_mut().zip(enabled) {
        *d *= e;
    }
    // the smooth load friction, which grows with the drive's torque
    out.copy_from_slice(drive);
    for e in effects {
        e.simulated(|e| e.add_load_friction(qd, drive, out));
    }
}

/// The friction torque, with (`exact`) or without the dry frictions of width 0.
fn friction_torque_parts(effects: &[Effect], q: &[f64], qd: &[f64], exact: bool, out: &mut [f64]) {
    assert!(q.len() == out.len() && qd.len() == out.len(), "friction_torque: q, qd and out must have the same length");
    out.fill(0.0);
    for e in effects {
        e.simulated(|e| e.add_friction_torque(q, qd, exact, out));
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
        let mut actuator = Actuator { k: 1.0, offset: 0.0, limit: f64::INFINITY };
        for e in effects {
            e.simulated(|e| e.actuate(i, &mut actuator));
        }
        out[i] = actuator.k * tau_cmd[i].clamp(-actuator.limit, actuator.limit) + actuator.offset;
    }
}

/// Total time delay of the effects [s] (sum of every [`Effect::TimeDelay`]).
pub fn total_delay(effects: &[Effect]) -> f64 {
    effects.iter().map(|e| e.simulated(|e| e.delay())).sum()
}

/// Total armature per joint (sum of every [`Effect::Armature`]) into `out` (overwritten).
///
/// # Panics
/// If an effect's vector is shorter than `out`.
pub fn armature(effects: &[Effect], out: &mut [f64]) {
    out.fill(0.0);
    for e in effects {
        e.simulated(|e| e.add_armature(out));
    }
}

/// Total encoder offset per joint (sum of every [`Effect::EncoderOffset`]) into `out`
/// (overwritten) [rad or m]: the true position is the measured one plus it.
///
/// # Panics
/// If an effect's vector is shorter than `out`.
pub fn encoder_offset(effects: &[Effect], out: &mut [f64]) {
    out.fill(0.0);
    for e in effects {
        e.simulated(|e| e.add_encoder_offset(out));
    }
}

/// Total backlash width per joint (sum of every [`Effect::Backlash`]) into `out` (overwritten)
/// [rad or m].
///
/// # Panics
/// If an effect's vector is shorter than `out`.
pub fn backlash(effects: &[Effect], out: &mut [f64]) {
    out.fill(0.0);
    for e in effects {
        e.simulated(|e| e.add_backlash(out));
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
        e.simulated(|e| e.apply_to_model(&mut m))?;
    }
    Ok(m)
}
