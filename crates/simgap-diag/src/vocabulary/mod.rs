//! Candidate terms: each unmodelled effect of the vocabulary, as columns of a linear model of the
//! nominal residual `r = τ_cmd − (H q̈ + C q̇ + g)`, each with the bounds physics puts on its
//! parameters (b, fc, fs − fc, ia, payload mass ≥ 0; a gain within [`actuator::GAIN_RANGE`]).
//!
//! With the effect present, the robot obeys `(H + diag(ia)) q̈ + C q̇ + g = τ_applied + τ_eff`, so
//!
//! ```text
//! viscous        r_j ∋  b_j q̇_j                        coulomb  r_j ∋ fc_j tanh(q̇_j / w_j)
//! stribeck       r_j ∋  (fc + (fs − fc) e^{−(q̇/vs)²}) tanh(q̇/w)
//! armature       r_j ∋  ia_j q̈_j                       gain     r_j ∋ (1 − k_j) τ_j
//! offset         r_j ∋ −offset_j                        cogging  r_j ∋ A_j sin(N_j q_j)
//! saturation     r_j ∋  τ_j − clamp(τ_j, ±L_j)          (fixed coefficient, L searched)
//! time_delay     r   ∋  τ(t) − τ(t − d)                 (fixed coefficient, d searched)
//! coriolis       r   ∋  (C_other − C) q̇                 (fixed coefficient, no parameter)
//! joint_spring   r_j ∋  k_j q_j − k_j q0_j              (k ≥ 0, k q0 free)
//! load_friction  r_j ∋  (fc + mu |τ_j|) tanh(q̇_j / w)   (fc ≥ 0, 0 ≤ mu ≤ 1)
//! load_stribeck  r_j ∋  (fc + mu |τ| + ((fs − fc) + (mus − mu) |τ|) e^{−(q̇/vs)²}) tanh(q̇/w)
//!                                                       (rises at rest: fs ≥ fc, mus ≥ mu)
//! back_emf       r_j ∋  kb_j en_j q̇_j                   (en the drive's enable)
//! directional    r_j ∋  s⁺ (fc⁺ + b⁺ q̇) − s⁻ (fc⁻ − b⁻ q̇) (s± = (1 ± tanh(q̇/w)) / 2, all ≥ 0)
//! payload        r   ∋  m Y_last π_point(c)             (m linear, c searched)
//! inertial_error r   ∋  Y Δπ                            (Δπ physically consistent, see inertial)
//! encoder_offset r   ∋  ∂(H q̈ + C q̇ + g)/∂q_j δ_j       (|δ| ≤ OFFSET_MAX, first order in δ)
//! backlash       (no column: the width searched by prediction through the simulator)
//! ```

mod actuator;
pub(crate) mod back_emf;
pub(crate) mod backlash;
mod cogging;
mod coriolis;
mod delay;
mod directional;
pub(crate) mod effects;
mod encoder;
mod friction;
mod inertial;
mod load_friction;
mod load_stribeck;
mod payload;
pub(crate) mod rotor;
mod spring;

pub use effects::{EffectReport, Param};

pub(crate) use crate::lsq::design::{Column, TermDesign};
pub(crate) use encoder::OFFSET_MAX;
pub(crate) use friction::resolvable as stribeck_resolvable;
pub(crate) use load_stribeck::VS_GRID as LOAD_STRIBECK_VS_GRID;
pub(crate) use payload::{largest_command, payload_basis_rows, payload_linear_design, payload_mass_bound, point_mass_parameters};

use std::sync::Arc;

use simgap_core::Model;
use simgap_sim::{Effect, EffectKind};

use crate::lsq::inertial::InertialPrior;
use crate::lsq::{fit, grams, Fit, Grams, Problem};
use crate::prepare::dataset::FitData;
use effects::{Entry, FittedTerm};
use nalgebra::DVector;

/// One candidate term.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Term {
    /// Viscous friction on a joint.
    Viscous(usize),
    /// Coulomb friction on a joint, its sign smoothed as tanh(q̇ / w).
    Coulomb {
        /// Joint index.
        joint: usize,
        /// Width of the smoothed sign [rad/s or m/s], searched within what the data allow
        /// ([`FitData::dry_width`]).
        w: f64,
    },
    /// Stribeck friction on a joint with Stribeck velocity `vs`, its sign smoothed as
    /// tanh(q̇ / w).
    Stribeck {
        /// Joint index.
        joint: usize,
        /// Stribeck velocity [rad/s or m/s].
        vs: f64,
        /// Width of the smoothed sign [rad/s or m/s] ([`FitData::dry_width`]).
        w: f64,
    },
    /// Load-dependent dry friction on a joint, its sign smoothed as tanh(q̇ / w).
    LoadFriction {
        /// Joint index.
        joint: usize,
        /// Width of the smoothed sign [rad/s or m/s] ([`FitData::dry_width`]).
        w: f64,
    },
    /// Load-dependent dry friction on a joint whose level rises at rest below a Stribeck
    /// velocity `vs`, its sign smoothed as tanh(q̇ / w).
    LoadStribeck {
        /// Joint index.
        joint: usize,
        /// Stribeck velocity [rad/s or m/s].
        vs: f64,
        /// Width of the smoothed sign [rad/s or m/s] ([`FitData::dry_width`]).
        w: f64,
    },
    /// Back-EMF on a joint while its drive is enabled.
    BackEmf(usize),
    /// Friction that differs with the direction of motion on a joint (levels and slopes per
    /// direction), its switch smoothed as tanh(q̇ / w).
    Directional {
        /// Joint index.
        joint: usize,
        /// Width of the smoothed switch [rad/s or m/s].
        w: f64,
    },
    /// Rotor inertia on a joint.
    Armature(usize),
    /// Torque gain on a joint.
    Gain(usize),
    /// Torque offset on a joint.
    Offset(usize),
    /// Torque saturation on a joint.
    Saturation {
        /// Joint index.
        joint: usize,
        /// Limit [N·m].
        limit: f64,
    },
    /// A spring on a joint, −k (q − q0).
    Spring(usize),
    /// Cogging on a joint.
    Cogging {
        /// Joint index.
        joint: usize,
        /// Periods per revolution.
        periods: f64,
    },
    /// An encoder offset on a joint: the joint is at its measured position plus the offset.
    EncoderOffset(usize),
    /// Free play between a joint's drive and its link (searched by prediction, no column).
    Backlash {
        /// Joint index.
        joint: usize,
        /// Total width of the play [rad or m].
        width: f64,
    },
    /// Whole-robot actuation delay.
    Delay {
        /// Delay [s].
        delay: f64,
    },
    /// The other formulation of C.
    CoriolisStructure,
    /// A point mass on the last link at a searched centre of mass (its mass is the fitted
    /// parameter).
    Payload {
        /// Centre of mass [m], last link frame.
        com: [f64; 3],
        /// Largest plausible mass [kg] (twice the chain's mass: heavier is no payload).
        max_mass: f64,
    },
    /// Corrections of every link's inertial parameters, physically consistent and regularised
    /// toward the URDF (see [`crate::lsq::inertial`]); its parameters are the stacked corrections
    /// Δπ in units of `prior.scales`.
    InertialError {
        /// URDF parameters, scales, reach of every link and prior weight.
        prior: Arc<InertialPrior>,
    },
}

impl Term {
    /// The effect of the vocabulary the term belongs to.
    pub(crate) fn kind(&self) -> EffectKind {
        match self {
            Term::Viscous(_) => EffectKind::ViscousFriction,
            Term::Coulomb { .. } => EffectKind::CoulombFriction,
            Term::Stribeck { .. } => EffectKind::StribeckFriction,
            Term::LoadFriction { .. } => EffectKind::LoadFriction,
            Term::LoadStribeck { .. } => EffectKind::LoadStribeckFriction,
            Term::BackEmf(_) => EffectKind::BackEmf,
            Term::Directional { .. } => EffectKind::DirectionalFriction,
            Term::Armature(_) => EffectKind::Armature,
            Term::Gain(_) => EffectKind::TorqueGain,
            Term::Offset(_) => EffectKind::TorqueOffset,
            Term::Saturation { .. } => EffectKind::TorqueSaturation,
            Term::Cogging { .. } => EffectKind::Cogging,
            Term::Spring(_) => EffectKind::JointSpring,
            Term::Delay { .. } => EffectKind::TimeDelay,
            Term::CoriolisStructure => EffectKind::CoriolisStructure,
            Term::Payload { .. } => EffectKind::Payload,
            Term::InertialError { .. } => EffectKind::InertialError,
            Term::EncoderOffset(_) => EffectKind::EncoderOffset,
            Term::Backlash { .. } => EffectKind::Backlash,
        }
    }

    /// The effect's contract name.
    pub(crate) fn effect_name(&self) -> &'static str {
        self.kind().as_str()
    }

    /// Whether the term corrects a servo's motor law (its drive gain kt/R, its back-EMF kt²/R)
    /// rather than adding a mechanical effect: the report folds these into the motor constants
    /// it states.
    pub(crate) fn corrects_motor_constants(&self) -> bool {
        matches!(self, Term::Gain(_) | Term::BackEmf(_))
    }

    /// The joint of a per-joint term.
    pub(crate) fn joint(&self) -> Option<usize> {
        match *self {
            Term::Viscous(j) | Term::Armature(j) | Term::Gain(j) | Term::Offset(j) | Term::Spring(j) | Term::BackEmf(j) | Term::EncoderOffset(j) => Some(j),
            Term::Coulomb { joint, .. }
            | Term::Stribeck { joint, .. }
            | Term::LoadFriction { joint, .. }
            | Term::LoadStribeck { joint, .. }
            | Term::Directional { joint, .. }
            | Term::Saturation { joint, .. }
            | Term::Cogging { joint, .. }
            | Term::Backlash { joint, .. } => Some(joint),
            _ => None,
        }
    }

    /// Whether the term and `other` occupy a slot in common ([`Term::slot`], and the torque
    /// offset's slot a spring also occupies on its joint: both hold a constant; the viscous
    /// slot a directional friction also occupies: it holds a slope per direction).
    pub(crate) fn shares_slot(&self, other: &Term) -> bool {
        let also = |t: &Term| match t {
            Term::Spring(j) => Some((Slot::Effect(EffectKind::TorqueOffset), Some(*j))),
            Term::Directional { joint, .. } => Some((Slot::Effect(EffectKind::ViscousFriction), Some(*joint))),
            _ => None,
        };
        let (a, b) = (self.slot(), other.slot());
        a == b || also(self) == Some(b) || also(other) == Some(a) || (also(self).is_some() && also(self) == also(other))
    }

    /// The slot the term occupies: at most one term per slot is selected (Coulomb and
    /// Stribeck friction share one; a payload and an inertial error share one; see also
    /// [`Term::shares_slot`]).
    pub(crate) fn slot(&self) -> (Slot, Option<usize>) {
        let slot = match self {
            Term::Coulomb { .. } | Term::Stribeck { .. } | Term::LoadFriction { .. } | Term::LoadStribeck { .. } | Term::Directional { .. } => Slot::DryFriction,
            Term::Payload { .. } | Term::InertialError { .. } => Slot::Inertia,
            other => Slot::Effect(other.kind()),
        };
        (slot, self.joint())
    }

    /// The term in words for the selection log: "viscous_friction on elbow".
    pub(crate) fn describe(&self, joints: &[String]) -> String {
        match self.joint() {
            Some(j) => format!("{} on {}", self.effect_name(), joints.get(j).map_or("?", String::as_str)),
            None => self.effect_name().to_string(),
        }
    }
}

/// The identity of a term as a hashable key (its effect, joint and searched parameter's bits; an
/// inertial error by its prior), for caches keyed by sets of terms.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub(crate) struct TermKey(EffectKind, usize, u64, [u64; 3]);

impl Term {
    /// The term's key (see [`TermKey`]).
    pub(crate) fn key(&self) -> TermKey {
        let joint = self.joint().unwrap_or(usize::MAX);
        let k = self.kind();
        match self {
            Term::Saturation { limit: x, .. }
            | Term::Cogging { periods: x, .. }
            | Term::Delay { delay: x }
            | Term::Coulomb { w: x, .. }
            | Term::LoadFriction { w: x, .. }
            | Term::Directional { w: x, .. }
            | Term::Backlash { width: x, .. } => TermKey(k, joint, x.to_bits(), [0; 3]),
            Term::Stribeck { vs, w, .. } | Term::LoadStribeck { vs, w, .. } => TermKey(k, joint, vs.to_bits(), [w.to_bits(), 0, 0]),
            Term::Payload { com, max_mass } => TermKey(k, joint, max_mass.to_bits(), com.map(f64::to_bits)),
            Term::InertialError { prior } => TermKey(k, joint, Arc::as_ptr(prior) as usize as u64, [0; 3]),
            _ => TermKey(k, joint, 0, [0; 3]),
        }
    }
}

/// What a selected term occupies (see [`Term::slot`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Slot {
    /// Its own effect.
    Effect(EffectKind),
    /// Dry friction: Coulomb, Stribeck, load-dependent (either form) or directional.
    DryFriction,
    /// The rigid-body parameters: a payload or an inertial error.
    Inertia,
}

/// Concatenation of a per-joint signal over runs.
pub(crate) fn per_joint(data: &[FitData], j: usize, f: impl Fn(&FitData, usize) -> f64) -> Column {
    let mut v = Vec::new();
    for d in data {
        for s in 0..d.len() {
            v.push(f(d, s * d.dof + j));
        }
    }
    Column::new(Some(j), v)
}

/// Concatenation over runs of a function of joint `j`'s velocity filtered like the torque
/// ([`FitData::filtered_velocity_map`]): the column of a torque that steps with the direction
/// of motion.
pub(crate) fn filtered_per_joint(data: &[FitData], j: usize, f: impl Fn(f64) -> f64) -> Column {
    Column::new(Some(j), data.iter().flat_map(|d| d.filtered_velocity_map(j, &f)).collect())
}

/// The design of a term over all runs: its columns and the bounds physics puts on them.
pub(crate) fn design(term: &Term, data: &[FitData]) -> TermDesign {
    match term {
        Term::Viscous(_) | Term::Coulomb { .. } | Term::Stribeck { .. } => friction::design(term, data),
        Term::LoadFriction { joint, w } => load_friction::design(*joint, *w, data),
        Term::LoadStribeck { joint, vs, w } => load_stribeck::design(*joint, *vs, *w, data),
        Term::BackEmf(j) => back_emf::design(*j, data),
        Term::Directional { joint, w } => directional::design(*joint, *w, data),
        Term::Armature(j) => rotor::design(*j, data),
        Term::Gain(_) | Term::Offset(_) | Term::Saturation { .. } => actuator::design(term, data),
        Term::Cogging { joint, periods } => cogging::design(*joint, *periods, data),
        Term::Spring(j) => spring::design(*j, data),
        Term::Delay { delay } => delay::design(*delay, data),
        Term::CoriolisStructure => coriolis::design(data),
        Term::Payload { com, max_mass } => payload::design(*com, *max_mass, data),
        Term::InertialError { prior } => inertial::design(prior, data),
        Term::EncoderOffset(j) => encoder::design(*j, data),
        Term::Backlash { .. } => backlash::design(),
    }
}

/// Whether fitted parameters (as the effect states them, see [`contract_parameters`]) are
/// physical: dissipative friction (b, fc ≥ 0, fs ≥ fc), non-negative rotor inertia and
/// payload mass, a gain within [`actuator::GAIN_RANGE`], and every corrected link with mass > 0, a
/// positive-definite pseudo-inertia and its centre of mass within reach. The bounded fits of
/// [`crate::lsq`] always give physical parameters; a parameter at its bound (fc = 0) is
/// physical.
pub(crate) fn physical(term: &Term, theta: &[f64]) -> bool {
    match term {
        Term::Viscous(_) | Term::Coulomb { .. } | Term::Stribeck { .. } => friction::physical(term, theta),
        Term::LoadFriction { .. } => load_friction::physical(theta),
        Term::LoadStribeck { .. } => load_stribeck::physical(theta),
        Term::Directional { .. } => directional::physical(theta),
        Term::Armature(_) => rotor::physical(theta),
        Term::Gain(_) | Term::Offset(_) | Term::Saturation { .. } => actuator::physical(term, theta),
        Term::Payload { .. } => payload::physical(theta),
        Term::Spring(_) => spring::physical(theta),
        Term::InertialError { prior } => prior.is_physical(theta),
        Term::Cogging { .. } | Term::Delay { .. } | Term::CoriolisStructure | Term::BackEmf(_) | Term::EncoderOffset(_) | Term::Backlash { .. } => true,
    }
}

/// Number of parameters a term fits, counting those searched on a grid.
pub(crate) fn n_params(term: &Term, d: &TermDesign) -> usize {
    d.cols.len()
        + match term {
            Term::Stribeck { .. } | Term::LoadStribeck { .. } | Term::Saturation { .. } | Term::Delay { .. } | Term::Cogging { .. } | Term::Backlash { .. } => 1,
            Term::Payload { .. } => 3,
            _ => 0,
        }
}

/// Adds the simulator effect of a fitted term to `out`, merging per-joint terms of one effect.
fn apply(model: &Model, f: &FittedTerm, out: &mut Vec<Effect>) {
    let n = model.dof();
    match &f.term {
        Term::Viscous(_) | Term::Coulomb { .. } | Term::Stribeck { .. } => friction::apply(f, n, out),
        Term::LoadFriction { .. } => load_friction::apply(f, n, out),
        Term::LoadStribeck { .. } => load_stribeck::apply(f, n, out),
        Term::BackEmf(j) => back_emf::apply(*j, &f.theta, n, out),
        Term::Directional { .. } => directional::apply(f, n, out),
        Term::Armature(j) => rotor::apply(*j, &f.theta, n, out),
        Term::Gain(_) | Term::Offset(_) | Term::Saturation { .. } => actuator::apply(f, n, out),
        Term::Cogging { joint, periods } => cogging::apply(*joint, *periods, &f.theta, n, out),
        Term::Spring(j) => spring::apply(*j, &f.theta, n, out),
        Term::Delay { delay } => out.push(Effect::TimeDelay { delay: *delay }),
        Term::CoriolisStructure => out.push(Effect::CoriolisStructure),
        Term::Payload { com, .. } => out.push(Effect::Payload { mass: f.theta[0], com: *com }),
        Term::InertialError { prior } => out.push(inertial::apply(model, prior, &f.theta)),
        Term::EncoderOffset(j) => encoder::apply(*j, &f.theta, n, out),
        Term::Backlash { joint, width } => backlash::apply(*joint, *width, n, out),
    }
}

/// Writes a fitted term's parameters (95 % half-widths beside them) into its report entry.
fn report(model: &Model, f: &FittedTerm, entry: &mut Entry<'_>) {
    let ci = |s: f64| 1.96 * s;
    let (th, sd) = (&f.theta, &f.std);
    match &f.term {
        Term::Viscous(_) | Term::Coulomb { .. } | Term::Stribeck { .. } => friction::report(f, entry),
        Term::LoadFriction { .. } => load_friction::report(f, entry),
        Term::LoadStribeck { .. } => load_stribeck::report(f, entry),
        Term::BackEmf(_) => entry.push("kb", th[0], ci(sd[0])),
        Term::Directional { .. } => directional::report(f, entry),
        Term::Armature(_) => entry.push("ia", th[0], ci(sd[0])),
        Term::Gain(_) | Term::Offset(_) | Term::Saturation { .. } => actuator::report(f, entry),
        Term::Cogging { periods, .. } => cogging::report(*periods, th, sd, entry),
        Term::Spring(_) => spring::report(th, sd, entry),
        Term::Delay { delay } => entry.number("delay", *delay, f64::NAN),
        Term::CoriolisStructure => {}
        Term::Payload { com, .. } => payload::report(*com, th, sd, entry),
        Term::InertialError { prior } => inertial::report(model, prior, f, entry),
        Term::EncoderOffset(_) => entry.push("offset", th[0], ci(sd[0])),
        Term::Backlash { width, .. } => entry.push("width", *width, f64::NAN),
    }
}

/// The effect of a report entry in words (its `description`).
fn describe(model: &Model, e: &EffectReport) -> String {
    match e.effect {
        EffectKind::ViscousFriction | EffectKind::CoulombFriction | EffectKind::StribeckFriction => friction::describe(e),
        EffectKind::LoadFriction => load_friction::describe(e),
        EffectKind::LoadStribeckFriction => load_stribeck::describe(e),
        EffectKind::BackEmf => back_emf::describe(e),
        EffectKind::Armature => rotor::describe(e),
        EffectKind::TorqueGain | EffectKind::TorqueOffset | EffectKind::TorqueSaturation => actuator::describe(e),
        EffectKind::Cogging => cogging::describe(e),
        EffectKind::JointSpring => spring::describe(e),
        EffectKind::TimeDelay => delay::describe(e),
        EffectKind::CoriolisStructure => coriolis::describe(),
        EffectKind::Payload => payload::describe(model, e),
        EffectKind::DirectionalFriction => directional::describe(e),
        EffectKind::EncoderOffset => encoder::describe(e),
        EffectKind::Backlash => backlash::describe(e),
        // an inertial error states its changes per link
        EffectKind::InertialError => String::new(),
    }
}

/// Completes the descriptions that read several report entries together, once every entry is
/// described: a torque limit selected with a torque gain states the most the drive delivers
/// ([`actuator::describe_limit_with_gain`]).
fn describe_together(entries: &mut [EffectReport]) {
    actuator::describe_limit_with_gain(entries);
}

/// A simpler effect nested in a richer one: the richer with its extra parameters at their
/// neutral values is the simpler (a Stribeck friction with fs = fc is Coulomb friction).
#[derive(Clone, Debug)]
pub(crate) struct Nested {
    /// The simpler terms that replace the richer one.
    pub terms: Vec<Term>,
    /// The richer term's columns the simpler lacks (their coefficients are 0 in the simpler);
    /// the others are the simpler terms' columns, in order.
    pub extra: Vec<usize>,
    /// Why these runs cannot resolve the richer shape at all, whatever its fit (a Stribeck
    /// velocity below what they resolve), if so.
    pub unresolved: Option<String>,
}

/// The simpler effect nested in `term`, if its family has one (see [`Nested`]).
pub(crate) fn simpler(term: &Term, data: &[FitData]) -> Option<Nested> {
    match term {
        Term::Stribeck { .. } => friction::simpler(term, data),
        Term::LoadFriction { joint, w } => Some(load_friction::simpler(*joint, *w)),
        Term::LoadStribeck { joint, vs, w } => Some(load_stribeck::simpler(*joint, *vs, *w)),
        Term::Spring(j) => Some(spring::simpler(*j)),
        _ => None,
    }
}

/// A term's parameters as the effect states them, from its fitted column coefficients: the
/// same numbers except for Stribeck friction, fitted as `(fc, fs − fc)` (both ≥ 0, so that
/// `fs ≥ fc ≥ 0` is a box) and stated as `(fc, fs)` (the load Stribeck friction likewise), and
/// a spring's rest position.
pub(crate) fn contract_parameters(term: &Term, raw: &[f64]) -> Vec<f64> {
    match term {
        Term::Stribeck { .. } => friction::contract_stribeck(raw),
        Term::LoadStribeck { .. } => load_stribeck::contract(raw),
        Term::Spring(_) => spring::contract(raw),
        _ => raw.to_vec(),
    }
}

/// Splits a joint parameter vector (and its standard deviations, if any) per term.
pub(crate) fn fitted_terms(terms: &[Term], designs: &[TermDesign], theta: &DVector<f64>, std: Option<&DVector<f64>>) -> Vec<FittedTerm> {
    let mut out = Vec::with_capacity(terms.len());
    let mut c = 0;
    for (t, d) in terms.iter().zip(designs) {
        let k = d.cols.len();
        let mut sd = std.map_or_else(|| vec![0.0; k], |s| s.as_slice()[c..c + k].to_vec());
        let th = contract_parameters(t, &theta.as_slice()[c..c + k]);
        if matches!(t, Term::Stribeck { .. }) {
            // fs = fc + (fs − fc): the spread of a sum, its covariance ignored
            sd[1] = sd[0].hypot(sd[1]);
        }
        if matches!(t, Term::Spring(_)) {
            spring::contract_std(&th, &mut sd);
        }
        if matches!(t, Term::LoadStribeck { .. }) {
            load_stribeck::contract_std(&mut sd);
        }
        out.push(FittedTerm { term: t.clone(), theta: th, std: sd });
        c += k;
    }
    out
}

/// Designs and fits a list of terms in one go.
pub(crate) fn fit_terms(p: &Problem, data: &[FitData], terms: &[Term]) -> (Vec<TermDesign>, Grams, Fit) {
    fit_designs(p, terms.iter().map(|t| design(t, data)).collect())
}

/// The Grams of `designs` and their fit, with the designs.
pub(crate) fn fit_designs(p: &Problem, designs: Vec<TermDesign>) -> (Vec<TermDesign>, Grams, Fit) {
    let refs: Vec<&TermDesign> = designs.iter().collect();
    let gr = grams(p, &refs);
    let f = fit(p, &gr);
    (designs, gr, f)
}
