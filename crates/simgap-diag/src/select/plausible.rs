//! Parsimony and plausibility of the selected set: what a finding must be besides a better fit.
//!
//! - **Parsimony.** Of two nested effects that predict alike, the simpler is selected and the
//!   richer named as an alternative: a Stribeck friction whose hump the runs do not resolve, or
//!   whose prediction the Coulomb friction nested in it matches within the cross-validation's
//!   tie tolerance, is Coulomb friction ([`parsimony`], on the prediction score, before the
//!   parameters are refined). An inertial correction whose torque on some joints is mostly a
//!   constant is, in the same way, torque offsets on those joints where they predict as well: a
//!   torque sensor's bias on a gravity-loaded joint, which a shifted centre of mass mimics over a
//!   motion of modest range, is one parameter, not a correction of every link.
//! - **Plausibility.** Every family bounds its parameters by their physical range in its design
//!   (an armature by a hundred times the link inertia its joint moves, an offset by the torques
//!   commanded on its joint, a gain by [`crate::vocabulary`]'s gain range, a payload by the
//!   torques delivered). A term fitted at the edge of that range, or whose 95 % interval holds
//!   its neutral value in every parameter, is no finding; a richer term whose extra parameters'
//!   intervals hold their neutral values is its simpler nested term ([`judge`], on the final
//!   fit and its intervals).

use crate::report::Alternative;
use crate::select::prediction::TIE_TOLERANCE;
use crate::select::scorer::Scorer;
use crate::select::{self, Step};
use crate::vocabulary::{simpler, Term, TermDesign};

/// What the plausibility check concludes of one selected term.
#[derive(Clone, Debug)]
pub(crate) enum Judgment {
    /// A finding.
    Finding,
    /// The simpler nested terms say the same: they replace it.
    Simpler {
        /// The replacing terms.
        terms: Vec<Term>,
        /// The richer term's columns they lack (see [`crate::vocabulary::Nested::extra`]).
        extra: Vec<usize>,
        /// Why, in words.
        why: String,
    },
    /// No finding: it leaves the set.
    NoFinding(String),
}

/// A richer term replaced by the simpler terms nested in it, and why.
pub(crate) type Replacement = (Term, Vec<Term>, String);

/// Half-widths of 95 % intervals are this many standard deviations.
const Z95: f64 = 1.96;

/// Whether a coefficient is consistent with 0: its 95 % interval holds 0 (exactly 0 counts as
/// consistent whatever its spread; an unknown spread decides nothing).
fn holds_zero(theta: f64, std: f64) -> bool {
    theta == 0.0 || (std.is_finite() && theta.abs() <= Z95 * std)
}

/// Whether `theta` sits on a bound `b` of its range (relative tolerance 1e-6).
fn on_bound(theta: f64, b: f64) -> bool {
    b.is_finite() && (theta - b).abs() <= 1e-6 * b.abs().max(1e-12)
}

/// The smallest share of its joint's commanded torque (RMS) a selected term explains to be a
/// finding: [`crate::select::SelectOptions::min_torque_share`]'s default.
const MIN_TORQUE_SHARE: f64 = 0.01;

/// Judges one selected term from its column coefficients `theta` and their standard deviations
/// (the design's coordinates, see [`TermDesign`]): `std`, the data's own spread, decides whether
/// the term is there at all; `shape_std`, which may add the pipeline's shared error, whether a
/// richer shape's extra parameters are resolved beyond the simpler nested term (a shape must
/// stand out of the pipeline's own error, which trades one friction shape for another).
pub(crate) fn judge(term: &Term, design: &TermDesign, theta: &[f64], std: &[f64], shape_std: &[f64], data: &[crate::prepare::dataset::FitData], joints: &[String]) -> Judgment {
    // an inertial correction is judged by its physical consistency (its own solver), and a
    // term without free parameters (a grid member, the other formulation of C) by prediction
    if design.inertial.is_some() || design.cols.is_empty() || theta.len() != design.cols.len() {
        return Judgment::Finding;
    }
    let name = term.describe(joints);
    // too small to matter: the torque it explains on its joint is below the share of the
    // commanded torque the stepwise selection asks of every term (a term a multiple-shooting
    // set brought in was never asked)
    if let (Some(j), Some(d0)) = (term.joint(), data.first()) {
        let dof = d0.dof;
        let samples = design.cols.first().map_or(0, |c| if c.joint.is_some() { c.values.len() } else { c.values.len() / dof.max(1) });
        let explained: f64 = (0..samples).map(|s| design.cols.iter().zip(theta).map(|(c, th)| th * c.at(s, j, dof)).sum::<f64>().powi(2)).sum();
        let commanded: f64 = data.iter().flat_map(|d| d.tau.iter().skip(j).step_by(d.dof)).map(|t| t * t).sum();
        if samples > 0 && commanded > 0.0 {
            let share = (explained / commanded).sqrt();
            if share < MIN_TORQUE_SHARE {
                return Judgment::NoFinding(format!("not a finding: {name} explains {:.2} % of the commanded torque on its joint (RMS): too small to matter", 100.0 * share));
            }
        }
    }
    // at the edge of its physical range (a bound other than the neutral 0)
    for (c, &th) in theta.iter().enumerate() {
        for b in [design.lo.get(c).copied().unwrap_or(f64::NEG_INFINITY), design.hi.get(c).copied().unwrap_or(f64::INFINITY)] {
            if b != 0.0 && on_bound(th, b) {
                return Judgment::NoFinding(format!(
                    "not a finding: {name} is fitted at the edge of its physical range (coefficient {} at its bound {}): the data push it beyond what the robot can have",
                    crate::vocabulary::effects::sig3(th),
                    crate::vocabulary::effects::sig3(b)
                ));
            }
        }
    }
    // every parameter consistent with its neutral value
    if theta.iter().zip(std).all(|(t, s)| holds_zero(*t, *s)) && std.iter().any(|s| s.is_finite()) {
        return Judgment::NoFinding(format!("not a finding: the 95 % interval of {name} holds its neutral value (no effect) in every parameter"));
    }
    // a richer shape whose extra parameters are consistent with the simpler one
    if let Some(nested) = simpler(term, data) {
        let why = match nested.unresolved {
            Some(u) => Some(u),
            None if nested.extra.iter().all(|&c| c < theta.len() && c < shape_std.len() && holds_zero(theta[c], shape_std[c])) => {
                Some("the 95 % intervals of its extra parameters hold the values of the simpler effect".to_string())
            }
            None => None,
        };
        if let Some(why) = why {
            return Judgment::Simpler { terms: nested.terms, extra: nested.extra, why };
        }
    }
    Judgment::Finding
}

/// Parsimony by prediction: every selected term with a simpler nested form is replaced by it
/// where the runs do not resolve the richer shape, or where the simpler predicts the fit runs
/// as well (cross-validated k-step score within [`TIE_TOLERANCE`]). Logs each replacement and
/// returns the new score and the replacements (see [`richer_alternatives`]).
pub(crate) fn parsimony(scorer: &Scorer<'_>, terms: &mut Vec<Term>, current: f64, log: &mut Vec<Step>, joints: &[String]) -> (f64, Vec<Replacement>) {
    let mut score = current;
    let mut replacements = Vec::new();
    let mut i = 0;
    while i < terms.len() {
        let Some(nested) = simpler(&terms[i], scorer.ctx.data) else {
            i += 1;
            continue;
        };
        let mut with: Vec<Term> = terms.clone();
        let richer = with.remove(i);
        for t in &nested.terms {
            if !with.contains(t) && !select::slot_taken(&with, t) {
                with.push(t.clone());
            }
        }
        let s = scorer.score(&with);
        let ties = s <= score * (1.0 + TIE_TOLERANCE);
        let why = match (&nested.unresolved, ties) {
            (Some(u), _) => Some(format!("{u} (cross-validated k-step score {s:.4} with the simpler effect against {score:.4})")),
            (None, true) => {
                Some(format!("the simpler effect predicts the fit runs as well (cross-validated k-step score {s:.4} against {score:.4}, within {:.0} %)", 100.0 * TIE_TOLERANCE))
            }
            (None, false) => None,
        };
        let Some(why) = why else {
            i += 1;
            continue;
        };
        let simpler_names: Vec<String> = nested.terms.iter().map(|t| t.effect_name().to_string()).collect();
        log.push(Step { term: richer.clone(), cv_mse: f64::NAN, accepted: false, reason: format!("replaced by the simpler {} nested in it: {why}", simpler_names.join(" + ")) });
        for t in with.iter().filter(|t| !terms.contains(t)) {
            log.push(Step {
                term: t.clone(),
                cv_mse: f64::NAN,
                accepted: true,
                reason: format!("in place of {}, which it is with its extra parameters neutral: {why}", richer.describe(joints)),
            });
        }
        replacements.push((richer.clone(), nested.terms.clone(), why));
        *terms = with;
        score = s;
    }
    // an inertial correction whose torque is, on some joints, mostly a constant: torque offsets
    // there may say the same with a parameter each (a sensor's bias on a gravity-loaded joint,
    // which a shifted centre of mass mimics over a motion of modest range)
    if let Some(i) = terms.iter().position(|t| matches!(t, Term::InertialError { .. })) {
        let (designs, _, fit) = scorer.ctx.fit_terms(terms);
        let c0: usize = designs[..i].iter().map(|d| d.cols.len()).sum();
        let k = designs[i].cols.len();
        let constant: Vec<usize> = if fit.theta.len() >= c0 + k {
            constant_torque_joints(&designs[i], &fit.theta.as_slice()[c0..c0 + k], scorer.ctx.data).into_iter().filter(|&j| !scorer.prep.passive[j]).collect()
        } else {
            Vec::new()
        };
        let offsets: Vec<Term> = constant.iter().map(|&j| Term::Offset(j)).filter(|t| !terms.contains(t)).collect();
        if !offsets.is_empty() {
            let mut with: Vec<Term> = terms.clone();
            let richer = with.remove(i);
            with.extend(offsets.iter().cloned());
            let s = scorer.score(&with);
            if s <= score * (1.0 + TIE_TOLERANCE) {
                let on: Vec<&str> = constant.iter().map(|&j| joints[j].as_str()).collect();
                let why = format!(
                    "its torque on {} is mostly a constant, and torque offsets there predict the fit runs as well or better (cross-validated k-step score {s:.4} against {score:.4}, within {:.0} %) with a parameter each",
                    on.join(", "),
                    100.0 * TIE_TOLERANCE
                );
                log.push(Step { term: richer.clone(), cv_mse: f64::NAN, accepted: false, reason: format!("replaced by torque offsets: {why}") });
                for t in &offsets {
                    log.push(Step { term: t.clone(), cv_mse: f64::NAN, accepted: true, reason: format!("in place of the inertial correction: {why}") });
                }
                replacements.push((richer, offsets, why));
                *terms = with;
                score = s;
            }
        }
    }
    (score, replacements)
}

/// The joints on which the torque of a fitted term (`design` at coefficients `theta`) is mostly
/// a constant: over the fit samples its mean is at least [`CONSTANT_SHARE`] of its RMS, and its
/// RMS at least [`MIN_TORQUE_SHARE`] of the joint's commanded torque.
fn constant_torque_joints(design: &TermDesign, theta: &[f64], data: &[crate::prepare::dataset::FitData]) -> Vec<usize> {
    let Some(dof) = data.first().map(|d| d.dof) else { return Vec::new() };
    let samples = design.cols.first().map_or(0, |c| if c.joint.is_some() { c.values.len() } else { c.values.len() / dof.max(1) });
    if samples == 0 {
        return Vec::new();
    }
    (0..dof)
        .filter(|&j| {
            let (mut sum, mut sq) = (0.0, 0.0);
            for s in 0..samples {
                let v: f64 = design.cols.iter().zip(theta).map(|(c, th)| th * c.at(s, j, dof)).sum();
                sum += v;
                sq += v * v;
            }
            let (mean, rms) = (sum / samples as f64, (sq / samples as f64).sqrt());
            let commanded = (data.iter().flat_map(|d| d.tau.iter().skip(j).step_by(d.dof)).map(|t| t * t).sum::<f64>() / samples as f64).sqrt();
            rms > 0.0 && mean.abs() >= CONSTANT_SHARE * rms && rms >= MIN_TORQUE_SHARE * commanded
        })
        .collect()
}

/// The share of its RMS a term's mean torque on a joint reaches for that torque to be "mostly a
/// constant" ([`constant_torque_joints`]): a constant part of 0.9 leaves a varying part of
/// √(1 − 0.9²) ≈ 0.44 of the RMS.
const CONSTANT_SHARE: f64 = 0.9;

/// The alternatives parsimony replacements leave: per richer effect, the final set `set` with
/// the richer effect back in place of the simpler terms it was replaced by (`replacements`:
/// the richer term, its simpler terms, why).
pub(crate) fn richer_alternatives(set: &[Term], replacements: &[Replacement]) -> Vec<Alternative> {
    let mut out: Vec<Alternative> = Vec::new();
    let mut richer_names: Vec<&str> = replacements.iter().map(|r| r.0.effect_name()).collect();
    richer_names.dedup();
    for richer in richer_names {
        let of: Vec<&Replacement> = replacements.iter().filter(|r| r.0.effect_name() == richer).collect();
        let replaced: Vec<&Term> = of.iter().flat_map(|r| r.1.iter()).collect();
        let mut effects: Vec<String> = Vec::new();
        for t in set.iter().filter(|t| !replaced.contains(t)) {
            if !effects.iter().any(|n| n == t.effect_name()) {
                effects.push(t.effect_name().to_string());
            }
        }
        if !effects.iter().any(|n| n == richer) {
            effects.push(richer.to_string());
        }
        let mut simpler_names: Vec<&str> = replaced.iter().map(|t| t.effect_name()).collect();
        simpler_names.dedup();
        let why = of.first().map_or("", |r| r.2.as_str());
        if out.iter().all(|a| a.effects != effects) {
            out.push(Alternative { effects, why: format!("{richer} is the richer effect in place of the selected {}; the simpler is selected: {why}", simpler_names.join(" + ")) });
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lsq::design::Column;

    fn design(lo: f64, hi: f64) -> TermDesign {
        TermDesign { cols: vec![Column::new(Some(0), vec![1.0])], lo: vec![lo], hi: vec![hi], ..Default::default() }
    }

    #[test]
    fn an_armature_at_the_edge_of_its_range_is_no_finding() {
        let j = judge(&Term::Armature(0), &design(0.0, 2.0), &[2.0], &[0.1], &[0.1], &[], &["a".into()]);
        assert!(matches!(j, Judgment::NoFinding(ref w) if w.contains("edge")), "{j:?}");
        let j = judge(&Term::Armature(0), &design(0.0, 2.0), &[1.0], &[0.1], &[0.1], &[], &["a".into()]);
        assert!(matches!(j, Judgment::Finding), "{j:?}");
    }

    #[test]
    fn an_interval_that_holds_the_neutral_value_is_no_finding() {
        let j = judge(&Term::Offset(0), &design(-5.0, 5.0), &[0.3], &[0.2], &[0.2], &[], &["a".into()]);
        assert!(matches!(j, Judgment::NoFinding(ref w) if w.contains("neutral")), "{j:?}");
        let j = judge(&Term::Offset(0), &design(-5.0, 5.0), &[0.5], &[0.2], &[0.2], &[], &["a".into()]);
        assert!(matches!(j, Judgment::Finding), "{j:?}");
    }

    #[test]
    fn an_unknown_spread_decides_nothing() {
        let j = judge(&Term::Offset(0), &design(-5.0, 5.0), &[0.3], &[f64::NAN], &[f64::NAN], &[], &["a".into()]);
        assert!(matches!(j, Judgment::Finding), "{j:?}");
    }
}
