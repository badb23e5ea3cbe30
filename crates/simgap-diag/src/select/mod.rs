//! Which effect: candidate families, screening, forward stepwise selection validated by
//! cross-validation across runs and time blocks, backward pruning.
//!
//! A term enters when it lowers the cross-validated residual by at least
//! [`SelectOptions::min_relative_gain`] of the current value and
//! [`SelectOptions::min_nominal_gain`] of the nominal one, and when the torque it explains is
//! at least [`SelectOptions::min_torque_share`] of the commanded torque (RMS) on its joint:
//! effects too small to matter are reported, not selected.

pub(crate) mod alternatives;
pub(crate) mod backlash;
mod context;
pub(crate) mod families;
mod payload;
pub(crate) mod plausible;
pub(crate) mod prediction;
pub(crate) mod refine;
mod residual;
pub(crate) mod scorer;
pub(crate) mod screen;
pub(crate) mod shooting;
mod stepwise;
pub(crate) mod uncertainty;

use nalgebra::DVector;

use crate::lsq::Fit;
pub use crate::options::SelectOptions;
use crate::vocabulary::{contract_parameters, physical, Term, TermDesign};

pub(crate) use context::{parameter_scales, Context};
pub(crate) use families::{families, Family};
pub(crate) use residual::{residual_after, term_torque_rms};

/// One step of the selection log.
#[derive(Clone, Debug)]
pub(crate) struct Step {
    /// The term considered.
    pub term: Term,
    /// Cross-validated MSE with it (weighted).
    pub cv_mse: f64,
    /// Whether it entered.
    pub accepted: bool,
    /// Why (not).
    pub reason: String,
}

/// Outcome of the selection.
#[derive(Clone, Debug)]
pub(crate) struct Selection {
    /// Selected terms.
    pub terms: Vec<Term>,
    /// Their joint fit.
    pub fit: Fit,
    /// Designs of the selected terms.
    pub designs: Vec<TermDesign>,
    /// Cross-validated MSE of the nominal model.
    pub nominal_cv_mse: f64,
    /// The log of decisions.
    pub log: Vec<Step>,
}

/// Whether `t` may join `terms`: one term per slot, and no torque gain together with an
/// inertial error (a gain on every joint and scaled inertial parameters are the same robot, so
/// together they admit the trivial fit k = 0, π = 0).
pub(crate) fn slot_taken(terms: &[Term], t: &Term) -> bool {
    let gain_vs_inertia = |a: &Term, b: &Term| matches!(a, Term::Gain(_)) && matches!(b, Term::InertialError { .. });
    terms.iter().any(|s| s.shares_slot(t) || gain_vs_inertia(s, t) || gain_vs_inertia(t, s))
}

/// Whether a fitted parameter of a term sits at a plausibility bound other than zero (a payload
/// at its largest mass, a torque gain at an end of [`GAIN_RANGE`], a corrected link's mass at a
/// factor [`crate::lsq::inertial::MASS_FACTOR`] of the URDF's): the data pull further than the
/// effect can go, so the term stands in for something else and is not an answer. A parameter
/// at zero (no friction) is an absent effect, not a stand-in.
pub(crate) fn at_plausibility_bound(d: &TermDesign, theta: &[f64]) -> bool {
    if let Some(prior) = &d.inertial {
        return prior.at_mass_bound(theta);
    }
    let tol = |b: f64| 1e-6 * b.abs().max(1e-9);
    theta.iter().enumerate().any(|(k, &x)| {
        let (lo, hi) = (d.lo.get(k).copied().unwrap_or(f64::NEG_INFINITY), d.hi.get(k).copied().unwrap_or(f64::INFINITY));
        (hi.is_finite() && hi != 0.0 && x >= hi - tol(hi)) || (lo.is_finite() && lo != 0.0 && x <= lo + tol(lo))
    })
}

/// Whether every term of a set (its designs and joint parameters, as [`Context::fit_terms`] gives them)
/// is physical and none stands at a plausibility bound.
pub(crate) fn admissible(designs: &[TermDesign], terms: &[Term], theta: &DVector<f64>) -> bool {
    let mut c = 0;
    for (t, d) in terms.iter().zip(designs) {
        let k = d.cols.len();
        let th = &theta.as_slice()[c..c + k];
        if !physical(t, &contract_parameters(t, th)) || at_plausibility_bound(d, th) {
            return false;
        }
        c += k;
    }
    true
}

/// The cross-validated figure a term is judged on: its joint's for a per-joint term, the
/// whole robot's otherwise.
fn cv_of(f: &Fit, t: &Term) -> f64 {
    match t.joint() {
        Some(j) => f.cv_joint[j],
        None => f.cv_mse,
    }
}

pub(crate) use stepwise::{repolish, select};
