//! On a one-joint servo arm, the drive's torque gain and rotor inertia in place of an inertial
//! correction ([`drive_in_place_of_inertia`]).

use crate::error::Result;
use crate::options::DiagnoseOptions;
use crate::select::prediction::PRUNE_TOLERANCE;
use crate::select::scorer::Scorer;
use crate::vocabulary::fitted_terms;
use crate::vocabulary::{effects, Term, TermDesign};

use super::cross_validation::{shooting_options, transfer, try_set};
use super::final_fit::{finish, Refined};
use super::refit::as_tried;

/// On a one-joint servo arm, the set of `r` with the drive's torque gain and rotor inertia in
/// place of its inertial correction, fitted by multiple shooting, when it predicts the fit runs
/// as well (its two-fold cross-validated score within [`PRUNE_TOLERANCE`] of `r`'s). On one
/// turning joint the two are the same dynamics up to friction and a turn of the weight's
/// direction ([`crate::select::alternatives::one_joint_equivalent`]); on a servo the drive's
/// terms are the likelier story: its motor constants were fitted from the logs (or taken from a
/// datasheet), while the URDF's mass and inertia were measured or computed. Each half starts
/// also from the gain and rotor inertia its own answer's inertial correction is, with that
/// answer's other parameters. Returns the swapped set, or none (another arm, no servo, no
/// inertial correction, a rotor inertia that would be negative, or a swap that predicts worse),
/// and notes of what was tried.
///
/// On the Rhoban XL330 logs with the `sin_sin` logs held out, the inertial correction (the
/// weight's moment about the axis ×0.53) simulated as its equivalent gain 1.886 and rotor
/// inertia 0.00174 kg·m², without a refit, predicted the held-out logs as well (k-step 13.4 /
/// 31.5 / 39.5 mrad against 13.4 / 31.9 / 38.3); fitted, the swapped set predicts the fit runs
/// at 0.3172 against 0.3065 (the 1.2° turn of the weight it cannot hold), so the inertial
/// correction stays there. In the test suite's servo scenario 3 (`tests/selfcheck_small.rs`)
/// the drive's terms take the place of an inertial correction that was a gain of 1.018.
///
/// # Errors
/// As [`refine_by_shooting`](super::refine_by_shooting).
pub(crate) fn drive_in_place_of_inertia(scorer: &Scorer<'_>, r: &Refined, options: &DiagnoseOptions) -> Result<(Option<Refined>, Vec<String>)> {
    let model = scorer.model;
    let is_inertial = |t: &Term| matches!(t, Term::InertialError { .. });
    if scorer.prep.servo.is_none() || model.dof() != 1 || scorer.prep.passive.first().copied().unwrap_or(true) || !r.terms.iter().any(is_inertial) {
        return Ok((None, Vec::new()));
    }
    let equivalent = |terms: &[Term], designs: &[TermDesign], theta: &nalgebra::DVector<f64>| {
        crate::select::alternatives::one_joint_equivalent(model, &effects::to_effects(model, &fitted_terms(terms, designs, theta, None)))
    };
    let Some(whole) = equivalent(&r.terms, &r.designs, &r.shot.theta) else { return Ok((None, Vec::new())) };
    let mut terms: Vec<Term> = r.terms.iter().filter(|t| !is_inertial(t)).cloned().collect();
    for t in [Term::Gain(0), Term::Armature(0)] {
        if !terms.contains(&t) {
            terms.push(t);
        }
    }
    // each half also from its own answer's equivalent: the gain and rotor inertia set, the
    // other shared terms at that answer's values
    let before = as_tried(r);
    let earlier = |half: usize, designs: &[TermDesign]| -> Vec<nalgebra::DVector<f64>> {
        let Some(answer) = before.halves.get(half) else { return Vec::new() };
        let mut start = transfer(&before, answer, &terms, designs);
        let mut from = vec![start.clone()];
        if let Some(e) = equivalent(&before.terms, &before.designs, answer) {
            // `k τ = (H + ia) q̈ + g + k F`: the torques that act beside the drive (frictions,
            // cogging) scale by k; a load friction's share of the drive's torque and the
            // drive's own back-EMF do not
            let mut c = 0;
            for (t, d) in terms.iter().zip(designs) {
                let k = d.cols.len();
                match t {
                    Term::Gain(_) if k == 1 => start[c] = 1.0 - e.k,
                    Term::Armature(_) if k == 1 => start[c] = e.k * start[c] + e.ia,
                    Term::LoadFriction { .. } if k >= 1 => start[c] *= e.k,
                    // (fc, mu, fs − fc, mus − mu): the load-independent levels
                    Term::LoadStribeck { .. } if k == 4 => [c, c + 2].into_iter().for_each(|i| start[i] *= e.k),
                    Term::BackEmf(_) | Term::LoadFriction { .. } | Term::LoadStribeck { .. } => {}
                    _ => (c..c + k).for_each(|i| start[i] *= e.k),
                }
                c += k;
            }
            from.push(start);
        }
        from
    };
    let sopts = shooting_options(scorer);
    let name = "the selected set with the drive's torque gain and rotor inertia in place of the inertial correction";
    let tried = try_set(scorer, &r.runs, &sopts, name, &terms, &earlier, options.stop.as_deref())?;
    let head = format!(
        "on this one-joint servo arm the inertial correction is a torque gain k = {:.3} with a rotor inertia of {} kg·m² (the same dynamics up to friction): {name}, fitted by multiple shooting, predicts the fit runs at {:.4} of the nominal model's k-step error against {:.4}",
        whole.k,
        crate::vocabulary::effects::sig3(whole.ia),
        tried.score,
        r.score
    );
    if !(tried.score <= r.score * (1.0 + PRUNE_TOLERANCE)) {
        return Ok((None, vec![format!("{head}: worse by more than {:.0} %, so the inertial correction is kept", 100.0 * PRUNE_TOLERANCE)]));
    }
    let what =
        "the drive's torque gain and rotor inertia in place of the inertial correction (the motor constants were fitted, the URDF's inertia is as published), the parameters";
    let (refined, mut notes) = finish(scorer, &r.runs, &sopts, tried, what, options)?;
    notes.insert(0, format!("{head}: within {:.0} %, so the drive's terms are selected", 100.0 * PRUNE_TOLERANCE));
    Ok((Some(refined), notes))
}
