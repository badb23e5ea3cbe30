//! Parsimony and plausibility of the selected set: what a finding must be besides a better fit.
//!
//! - **Parsimony.** Of two nested effects that predict alike, the simpler is selected and the
//!   richer named as an alternative: a Stribeck friction whose hump the runs do not resolve, or
//!   whose prediction the Coulomb friction nested in it matches within the cross-validation's
//!   tie tolerance, is Coulomb friction ([`parsimony`], on the prediction score, before the
//!   parameters are refined). An inertial correction whose torque on some joints is mostly a
//!   constant, or a constant and a multiple of the joint's acceleration, is, in the same way,
//!   torque offsets (and rotor inertias) on those joints where they predict as well: a torque
//!   sensor's bias on a gravity-loaded joint, which a shifted centre of mass mimics over a
//!   motion of modest range, is one parameter, not a correction of every link; so is the first
//!   link's inertia about a vertical first axis, which acts exactly as the first joint's rotor
//!   inertia.
//! - **Plausibility.** Every family bounds its parameters by their physical range in its design
//!   (an armature by a hundred times the link inertia its joint moves, an offset by the torques
//!   commanded on its joint, a gain by [`crate::vocabulary`]'s gain range, a payload by the
//!   torques delivered). A term fitted at the edge of that range, or whose 95 % interval holds
//!   its neutral value in every parameter, is no finding; a richer term whose extra parameters'
//!   intervals hold their neutral values is its simpler nested term ([`judge`], on the final
//!   fit and its intervals).

use crate::prediction::kstep::FoldTest;
use crate::report::Alternative;
use crate::select::prediction::{PRUNE_TOLERANCE, TIE_TOLERANCE};
use crate::select::scorer::Scorer;
use crate::select::{self, Step};
use crate::vocabulary::{simpler, Term, TermDesign};
use simgap_sim::EffectKind;

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
    /// No finding by `rule`: it leaves the set (`why` in words).
    NoFinding(Rule, String),
}

impl Judgment {
    /// Whether this is no finding because every 95 % interval of the term holds its neutral
    /// value (not because the term is too small to matter or at the edge of its range): the
    /// fit runs' cross-validated prediction then decides ([`needed_by_prediction`]).
    pub(crate) fn holds_no_effect(&self) -> bool {
        matches!(self, Judgment::NoFinding(Rule::NotEstablished, _))
    }
}

/// The rule by which a fitted term is no finding (the report's `dropped_effects[].rule`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Rule {
    /// It explains less than 1 % of its joint's commanded torque (RMS).
    TooSmall,
    /// A coefficient sits on a bound of its physical range other than the neutral 0.
    AtEdge,
    /// Its 95 % interval holds its neutral value, and the fit runs are not predicted worse
    /// without it by more than the prune tolerance ([`needed_by_prediction`]).
    NotEstablished,
    /// The others left, and the set it was part of no longer predicts the fit runs better than
    /// the nominal model by 2 %, in every part of them (the prune stage's test of its set).
    SetNoBetter,
}

impl Rule {
    /// The rule's name in the report.
    pub(crate) fn as_str(self) -> &'static str {
        match self {
            Rule::TooSmall => "too_small",
            Rule::AtEdge => "at_edge_of_range",
            Rule::NotEstablished => "not_established",
            Rule::SetNoBetter => "set_no_better_than_nominal",
        }
    }
}

/// The fit runs' verdict on a term whose 95 % interval holds its neutral value: the set
/// without it (`without_score`, its cross-validated k-step score) predicts them worse than the
/// set with it (`with_score`) by more than the prune tolerance, the margin by which the prune
/// stage calls a stepwise term weak; and, when it is worse by less than [`CLEAR_GAIN`], the
/// gain holds fold by fold (`test`, with against without: [`FoldTest::holds`] with the prune
/// tolerance). A set that cannot do without it (no prediction without it) needs it.
///
/// A gain of a few per cent is within what two multiple-shooting fits of nearly the same set
/// make of the same runs: on a simulated servo whose only hidden mechanical effect is Coulomb
/// friction, the set without a viscous friction (which trades with the back-EMF) scored 1.8 %
/// better than the set with it in one build and 3.3 % worse in another whose forward dynamics
/// differed in rounding only; the folds held no gain in either (upper bound of the ratio
/// with/without 1.30 and 1.29, worst fold 1.95 and 2.07). A clear gain needs no fold
/// test: a member's fold ratios, each fold fitted again by multiple shooting, are
/// heavy-tailed. (On the Rhoban XL330 logs, `lift_and_drop` held out, the servo's set predicts
/// the fit runs at 0.265 of the nominal model's error and at 0.551 without its torque gain,
/// whose interval holds 1; one fold of ten was 60 times worse with it, so the fold test
/// failed, and the gain dropped by it took the held-out 0.5 s error from 46.9 to 105.8 mrad.)
pub(crate) fn needed_by_prediction(with_score: f64, without_score: f64, test: &FoldTest) -> bool {
    if !without_score.is_finite() {
        return true;
    }
    gain_is_a_need(without_score / with_score - 1.0, test)
}

/// The relative loss `gain` of prediction without a term is a need: above the prune tolerance
/// and, below [`CLEAR_GAIN`], held fold by fold (`test`, with against without). From
/// [`CLEAR_GAIN`] on, the folds need not hold it, but the typical fold (the geometric mean of
/// the fold ratios) must not be worse with it by as much: a pooled gain that the typical fold
/// contradicts is carried by a few folds' large errors. (On a simulated double pendulum replayed
/// open loop, whose trajectories diverge, a rotor inertia cut the pooled error by a third while
/// the fold ratios' geometric mean was 5.8; on the XL330 logs every clear gain has a mean of
/// 0.58–0.70, the torque gain with one fold of ten 60 times worse included.)
fn gain_is_a_need(gain: f64, test: &FoldTest) -> bool {
    gain > PRUNE_TOLERANCE && ((gain >= CLEAR_GAIN && !typical_fold_contradicts(test)) || test.holds(PRUNE_TOLERANCE, PRUNE_TOLERANCE))
}

/// Whether the typical fold contradicts a gain (`test`: with the term against without it): the
/// geometric mean of the fold ratios is above 1 by more than [`CLEAR_GAIN`], so that whatever the
/// pooled score gains is carried by a few folds' large errors.
pub(crate) fn typical_fold_contradicts(test: &FoldTest) -> bool {
    test.mean > 1.0 + CLEAR_GAIN
}

/// How the fit runs' prediction of the one joint a term acts on changes without it, on a chain
/// of several joints.
#[derive(Clone, Copy, Debug)]
pub(crate) struct OnItsJoint {
    /// That joint's cross-validated k-step error without the term over with it (the geometric
    /// mean over horizons of the RMS ratios; above 1: predicted worse without it).
    pub ratio: f64,
    /// The fold test of that joint's error with the term against without it.
    pub test: FoldTest,
}

/// On a chain of several joints, a term acting on one joint is also needed when that joint's
/// prediction needs it by the standard of [`needed_by_prediction`] and the chain as a whole is
/// not predicted worse with it (`with_score` ≤ `without_score`). The pooled score sums every
/// joint's error, so a light joint's need is diluted by the loaded joints' errors: on a
/// five-servo arm, a Coulomb friction on its base joint cut the pooled cross-validated error by
/// 1.2 % (below the prune tolerance) and, on held-out runs, that joint's error by about half
/// and the pooled error at every horizon.
pub(crate) fn needed_on_its_joint(with_score: f64, without_score: f64, on: &OnItsJoint) -> bool {
    with_score <= without_score && on.ratio.is_finite() && gain_is_a_need(on.ratio - 1.0, &on.test)
}

/// [`needed_by_prediction`]'s condition in words, after "the fit runs are".
pub(crate) fn need_in_words() -> String {
    format!(
        "predicted worse without it by more than {:.0} % (and, by less than {:.0} %, in every part of them: the folds' test; by more, the typical fold not worse with it by {:.0} %), over every joint or, the whole no better without it, on the joint it acts on",
        100.0 * PRUNE_TOLERANCE,
        100.0 * CLEAR_GAIN,
        100.0 * CLEAR_GAIN
    )
}

/// The relative loss of prediction without a term (see [`needed_by_prediction`]) from which it
/// is needed without asking the folds: beyond the few per cent by which two shooting fits of
/// nearly the same set differ.
const CLEAR_GAIN: f64 = 0.10;

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

/// Whether the 95 % intervals `std` of a term's coefficients `theta` hold its neutral value in
/// every coefficient (the terms [`judge`] examines: not an inertial correction, with free
/// parameters, and with some finite spread).
pub(crate) fn interval_holds_no_effect(design: &TermDesign, theta: &[f64], std: &[f64]) -> bool {
    design.inertial.is_none()
        && !design.cols.is_empty()
        && theta.len() == design.cols.len()
        && std.len() == theta.len()
        && std.iter().any(|s| s.is_finite())
        && theta.iter().zip(std).all(|(t, s)| holds_zero(*t, *s))
}

/// The smallest share of its joint's commanded torque (RMS) a selected term explains to be a
/// finding: [`crate::select::SelectOptions::min_torque_share`]'s default.
const MIN_TORQUE_SHARE: f64 = 0.01;

/// The torque the columns `cols` of a term explain on its joint with coefficients `theta`, as a
/// share of the joint's commanded torque (RMS over the fit data); `None` for a term of no single
/// joint or without data.
fn torque_share(term: &Term, design: &TermDesign, theta: &[f64], cols: &[usize], data: &[crate::prepare::dataset::FitData]) -> Option<f64> {
    let (j, d0) = (term.joint()?, data.first()?);
    let dof = d0.dof;
    let samples = design.cols.first().map_or(0, |c| if c.joint.is_some() { c.values.len() } else { c.values.len() / dof.max(1) });
    let explained: f64 = (0..samples).map(|s| cols.iter().filter_map(|&c| Some(theta.get(c)? * design.cols.get(c)?.at(s, j, dof))).sum::<f64>().powi(2)).sum();
    let commanded: f64 = data.iter().flat_map(|d| d.tau.iter().skip(j).step_by(d.dof)).map(|t| t * t).sum();
    (samples > 0 && commanded > 0.0).then(|| (explained / commanded).sqrt())
}

/// The first coefficient of `theta` fitted at a bound of its physical range other than the
/// neutral 0, with that bound: a term the data push beyond what the robot can have.
pub(crate) fn at_edge(design: &TermDesign, theta: &[f64]) -> Option<(f64, f64)> {
    theta.iter().enumerate().find_map(|(c, &th)| {
        [design.lo.get(c).copied().unwrap_or(f64::NEG_INFINITY), design.hi.get(c).copied().unwrap_or(f64::INFINITY)]
            .into_iter()
            .find(|&b| b != 0.0 && on_bound(th, b))
            .map(|b| (th, b))
    })
}

/// How [`judge`] ends the reason of a term whose every interval holds its neutral value
/// ([`Judgment::holds_no_effect`]).
const HOLDS_NO_EFFECT: &str = "holds its neutral value (no effect) in every parameter";

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
    let all: Vec<usize> = (0..theta.len()).collect();
    if let Some(share) = torque_share(term, design, theta, &all, data).filter(|s| *s < MIN_TORQUE_SHARE) {
        return Judgment::NoFinding(
            Rule::TooSmall,
            format!("not a finding: {name} explains {:.2} % of the commanded torque on its joint (RMS): too small to matter", 100.0 * share),
        );
    }
    // at the edge of its physical range (a bound other than the neutral 0)
    if let Some((th, b)) = at_edge(design, theta) {
        return Judgment::NoFinding(
            Rule::AtEdge,
            format!(
                "not a finding: {name} is fitted at the edge of its physical range (coefficient {} at its bound {}): the data push it beyond what the robot can have",
                crate::vocabulary::effects::sig3(th),
                crate::vocabulary::effects::sig3(b)
            ),
        );
    }
    // every parameter consistent with its neutral value
    if theta.iter().zip(std).all(|(t, s)| holds_zero(*t, *s)) && std.iter().any(|s| s.is_finite()) {
        return Judgment::NoFinding(Rule::NotEstablished, format!("not a finding: the 95 % interval of {name} {HOLDS_NO_EFFECT}"));
    }
    // a richer shape whose extra parameters are consistent with the simpler one
    if let Some(nested) = simpler(term, data) {
        // (the torque its extra parameters add, beyond the simpler effect, measured as a whole
        // term's is: a load-dependent friction of 1e-4 × |τ| beside 1.6 N·m of dry friction,
        // resolved on noise-free synthetic logs, is a Coulomb friction)
        let extra_share = torque_share(term, design, theta, &nested.extra, data);
        let why = match nested.unresolved {
            Some(u) => Some(u),
            None if nested.extra.iter().all(|&c| c < theta.len() && c < shape_std.len() && holds_zero(theta[c], shape_std[c])) => {
                Some("the 95 % intervals of its extra parameters hold the values of the simpler effect".to_string())
            }
            None => extra_share
                .filter(|s| *s < MIN_TORQUE_SHARE)
                .map(|s| format!("its extra parameters add {:.2} % of the commanded torque on its joint (RMS) to the simpler effect: too small to matter", 100.0 * s)),
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
    // an inertial correction whose torque is, on some joints, mostly a constant, or a constant
    // and a multiple of the joint's own acceleration: torque offsets (a sensor's bias on a
    // gravity-loaded joint, which a shifted centre of mass mimics over a motion of modest range)
    // and rotor inertias (the first link's inertia about a vertical first axis is exactly one)
    // may say the same with a parameter each
    if let Some(i) = terms.iter().position(|t| matches!(t, Term::InertialError { .. })) {
        let (designs, _, fit) = scorer.ctx.fit_terms(terms);
        let c0 = crate::vocabulary::TermDesign::first_column(&designs, i);
        let k = designs[i].cols.len();
        let parts: Vec<AffineTorque> = if fit.theta.len() >= c0 + k {
            affine_torque_joints(&designs[i], &fit.theta.as_slice()[c0..c0 + k], scorer.ctx.data).into_iter().filter(|p| !scorer.prep.passive[p.joint]).collect()
        } else {
            Vec::new()
        };
        // the offsets alone where the torque is mostly a constant; offsets and rotor inertias
        // where it is mostly a constant and an acceleration term
        let offsets_only: Vec<Term> = parts.iter().filter(|p| p.constant).map(|p| Term::Offset(p.joint)).collect();
        // (no rotor inertia where the effort was measured on the link side of the gearbox)
        let rotor = crate::vocabulary::rotor::visible(scorer.ctx.data);
        let mut with_rotor: Vec<Term> = Vec::new();
        for p in &parts {
            if p.offset {
                with_rotor.push(Term::Offset(p.joint));
            }
            if p.rotor && rotor {
                with_rotor.push(Term::Armature(p.joint));
            }
        }
        // and with a rotor inertia on every actuated joint (an inertial correction spreads a
        // rotor inertia over the links the joint moves, so its torque shows it only in part)
        let actuated: Vec<usize> = (0..scorer.prep.passive.len()).filter(|&j| !scorer.prep.passive[j]).collect();
        let mut every_rotor = with_rotor.clone();
        if rotor {
            every_rotor.extend(actuated.iter().map(|&j| Term::Armature(j)).filter(|t| !with_rotor.contains(t)));
        }
        // encoder offsets on every joint: a joint turned from its measured angle moves the
        // links after it as a rotated centre of mass does (on the last joint, exactly)
        let encoder: Vec<Term> = (0..scorer.prep.passive.len()).map(Term::EncoderOffset).collect();
        // and with a rotor inertia on every actuated joint (the correction may have taken a
        // rotor inertia's part as well) and, on servo logs, whose motor constants were fitted
        // with the nominal model (an offset biases them), a torque gain there as well
        let mut encoder_rotor = encoder.clone();
        if rotor {
            encoder_rotor.extend(actuated.iter().map(|&j| Term::Armature(j)));
        }
        if scorer.prep.servo.is_some() {
            encoder_rotor.extend(actuated.iter().map(|&j| Term::Gain(j)));
        }
        // the simplest replacement that predicts as well, or a richer one that predicts better
        // than it by more than the tie tolerance
        let mut chosen: Option<(Vec<Term>, Vec<Term>, f64, &str)> = None;
        let candidates = [
            (offsets_only, "mostly a constant"),
            (encoder, "that of joints turned from their measured angles"),
            (encoder_rotor, "that of joints turned from their measured angles, with rotor inertias (and drive gains on servo logs)"),
            (with_rotor, "mostly a constant and a multiple of the joint's acceleration"),
            (every_rotor, "in part a constant and a multiple of a joint's acceleration"),
        ];
        let mut seen: Vec<Vec<Term>> = Vec::new();
        for (replacing, shape) in candidates {
            let replacing: Vec<Term> = replacing.into_iter().filter(|t| !terms.contains(t)).collect();
            if replacing.is_empty() || seen.contains(&replacing) {
                continue;
            }
            seen.push(replacing.clone());
            let mut with: Vec<Term> = terms.clone();
            with.remove(i);
            with.extend(replacing.iter().cloned());
            let s = scorer.score(&with);
            // encoder offsets stand for a turned centre of mass exactly: they predict as well when
            // the correction's other parameters add no more than ENCODER_TIE of the nominal error
            // (on servo logs those fit the bias of motor constants fitted with the nominal model)
            let tie = if replacing.iter().any(|t| matches!(t, Term::EncoderOffset(_))) { score + ENCODER_TIE } else { score * (1.0 + TIE_TOLERANCE) };
            let bar = chosen.as_ref().map_or(tie, |c| c.2 * (1.0 - TIE_TOLERANCE));
            if s <= bar {
                chosen = Some((replacing, with, s, shape));
            }
        }
        if let Some((replacing, with, s, shape)) = chosen {
            let mut on: Vec<&str> = Vec::new();
            for j in replacing.iter().filter_map(|t| t.joint()) {
                if !on.contains(&joints[j].as_str()) {
                    on.push(joints[j].as_str());
                }
            }
            let encoder = replacing.iter().any(|t| matches!(t, Term::EncoderOffset(_)));
            let by = replaced_by(&replacing);
            let how = if s < score * (1.0 - TIE_TOLERANCE) {
                format!("better (cross-validated k-step score {s:.4} against {score:.4})")
            } else if encoder {
                format!("as well (cross-validated k-step score {s:.4} against {score:.4}, within {ENCODER_TIE} of the nominal error)")
            } else {
                format!("as well (cross-validated k-step score {s:.4} against {score:.4}, within {:.0} %)", 100.0 * TIE_TOLERANCE)
            };
            let why = format!("its torque on {} is {shape}, and {by} there predict the fit runs {how} with a parameter each", on.join(", "));
            let richer = terms[i].clone();
            log.push(Step { term: richer.clone(), cv_mse: f64::NAN, accepted: false, reason: format!("replaced by {by}: {why}") });
            for t in &replacing {
                log.push(Step { term: t.clone(), cv_mse: f64::NAN, accepted: true, reason: format!("in place of the inertial correction: {why}") });
            }
            replacements.push((richer, replacing, why));
            *terms = with;
            score = s;
        }
    }
    (score, replacements)
}

/// The terms replacing an inertial correction in words: "torque offsets", "encoder offsets,
/// rotor inertias and torque gains", … (their kinds, in the order of the vocabulary).
fn replaced_by(replacing: &[Term]) -> String {
    let names: Vec<&str> = [
        (EffectKind::EncoderOffset, "encoder offsets"),
        (EffectKind::TorqueOffset, "torque offsets"),
        (EffectKind::Armature, "rotor inertias"),
        (EffectKind::TorqueGain, "torque gains"),
    ]
    .into_iter()
    .filter(|(k, _)| replacing.iter().any(|t| t.kind() == *k))
    .map(|(_, name)| name)
    .collect();
    match names.split_last() {
        Some((last, [])) => last.to_string(),
        Some((last, rest)) => format!("{} and {last}", rest.join(", ")),
        None => String::new(),
    }
}

/// Where encoder offsets replace an inertial correction ([`parsimony`]), the k-step score (a
/// share of the nominal model's error) by which they may fall short of it and still predict as
/// well: half a percent of the nominal error (in place of the relative tie tolerance: a
/// correction that explains half the nominal error is not matched within 1 % of it).
const ENCODER_TIE: f64 = 0.005;

/// How a fitted term's torque on one joint decomposes ([`affine_torque_joints`]).
struct AffineTorque {
    joint: usize,
    /// Mostly a constant: its mean is at least [`CONSTANT_SHARE`] of its RMS.
    constant: bool,
    /// The constant of its least-squares fit by `c + ia q̈_j` is at least [`PART_SHARE`] of its RMS.
    offset: bool,
    /// The acceleration term `ia q̈_j` of that fit, with `ia > 0`, is at least [`PART_SHARE`] of
    /// its RMS.
    rotor: bool,
}

/// The joints on which the torque of a fitted term (`design` at coefficients `theta`) is mostly
/// a constant, or a constant and a multiple of the joint's acceleration `q̈_j` (the column of a
/// rotor inertia): its least-squares fit by `c + ia q̈_j` over the fit samples leaves at most
/// `1 − CONSTANT_SHARE²` of its mean square (the share a constant alone leaves when it is
/// [`CONSTANT_SHARE`] of the RMS), and its RMS reaches [`MIN_TORQUE_SHARE`] of the joint's
/// commanded torque.
fn affine_torque_joints(design: &TermDesign, theta: &[f64], data: &[crate::prepare::dataset::FitData]) -> Vec<AffineTorque> {
    let Some(dof) = data.first().map(|d| d.dof) else { return Vec::new() };
    let samples = design.cols.first().map_or(0, |c| if c.joint.is_some() { c.values.len() } else { c.values.len() / dof.max(1) });
    if samples == 0 {
        return Vec::new();
    }
    let mut out = Vec::new();
    for j in 0..dof {
        let rotor = crate::vocabulary::design(&Term::Armature(j), data);
        let Some(acc) = rotor.cols.first().filter(|c| c.values.len() == samples) else { continue };
        // sums of the normal equations of τ ≈ c + a x, x = q̈_j
        let (mut st, mut stt, mut sx, mut sxx, mut sxt) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for s in 0..samples {
            let v: f64 = design.cols.iter().zip(theta).map(|(c, th)| th * c.at(s, j, dof)).sum();
            let x = acc.values[s];
            st += v;
            stt += v * v;
            sx += x;
            sxx += x * x;
            sxt += x * v;
        }
        let m = samples as f64;
        let (mean, rms) = (st / m, (stt / m).sqrt());
        let commanded = (data.iter().flat_map(|d| d.tau.iter().skip(j).step_by(d.dof)).map(|t| t * t).sum::<f64>() / m).sqrt();
        if !(rms > 0.0 && rms >= MIN_TORQUE_SHARE * commanded) {
            continue;
        }
        let det = m * sxx - sx * sx;
        let (c, a) = if det > 0.0 { ((sxx * st - sx * sxt) / det, (m * sxt - sx * st) / det) } else { (mean, 0.0) };
        // what the fit leaves: Σ(τ − c − a x)²
        let left = stt - 2.0 * c * st - 2.0 * a * sxt + c * c * m + 2.0 * c * a * sx + a * a * sxx;
        let constant = mean.abs() >= CONSTANT_SHARE * rms;
        let affine = a > 0.0 && left <= (1.0 - CONSTANT_SHARE * CONSTANT_SHARE) * stt;
        if constant || affine {
            let rotor_part = a * (sxx / m).sqrt();
            out.push(AffineTorque { joint: j, constant, offset: constant || c.abs() >= PART_SHARE * rms, rotor: affine && !constant && rotor_part >= PART_SHARE * rms });
        }
    }
    out
}

/// The share of a term's RMS torque on a joint that the constant or the acceleration part of
/// its decomposition ([`affine_torque_joints`]) reaches for a torque offset or a rotor inertia to
/// stand for it.
const PART_SHARE: f64 = 0.25;

/// The share of its RMS a term's mean torque on a joint reaches for that torque to be "mostly a
/// constant" ([`constant_torque_joints`]): a constant part of 0.9 leaves a varying part of
/// √(1 − 0.9²) ≈ 0.44 of the RMS.
const CONSTANT_SHARE: f64 = 0.9;

/// The alternatives parsimony replacements leave: per richer effect, the final set `set` with
/// the richer effect back in place of the simpler terms it was replaced by (`replacements`:
/// the richer term, its simpler terms, why). A replacement a later stage undid (none of its
/// simpler terms is in the final set, or the richer term is back in it) leaves none: the set it
/// would name is not the one selected.
pub(crate) fn richer_alternatives(set: &[Term], replacements: &[Replacement]) -> Vec<Alternative> {
    let mut out: Vec<Alternative> = Vec::new();
    let replacements: Vec<&Replacement> = replacements.iter().filter(|r| !set.contains(&r.0) && r.1.iter().any(|t| set.contains(t))).collect();
    let mut richer_names: Vec<&str> = replacements.iter().map(|r| r.0.effect_name()).collect();
    richer_names.dedup();
    for richer in richer_names {
        let of: Vec<&Replacement> = replacements.iter().copied().filter(|r| r.0.effect_name() == richer).collect();
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
        let mut simpler_names: Vec<&str> = Vec::new();
        for t in &replaced {
            if !simpler_names.contains(&t.effect_name()) {
                simpler_names.push(t.effect_name());
            }
        }
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
    use simgap_sim::EffectKind;

    fn design(lo: f64, hi: f64) -> TermDesign {
        TermDesign { cols: vec![Column::new(Some(0), vec![1.0])], lo: vec![lo], hi: vec![hi], ..Default::default() }
    }

    #[test]
    fn an_armature_at_the_edge_of_its_range_is_no_finding() {
        let j = judge(&Term::Armature(0), &design(0.0, 2.0), &[2.0], &[0.1], &[0.1], &[], &["a".into()]);
        assert!(matches!(j, Judgment::NoFinding(Rule::AtEdge, ref w) if w.contains("edge")), "{j:?}");
        let j = judge(&Term::Armature(0), &design(0.0, 2.0), &[1.0], &[0.1], &[0.1], &[], &["a".into()]);
        assert!(matches!(j, Judgment::Finding), "{j:?}");
    }

    #[test]
    fn an_interval_that_holds_the_neutral_value_is_no_finding() {
        let j = judge(&Term::Offset(0), &design(-5.0, 5.0), &[0.3], &[0.2], &[0.2], &[], &["a".into()]);
        assert!(matches!(j, Judgment::NoFinding(Rule::NotEstablished, ref w) if w.contains("neutral")), "{j:?}");
        let j = judge(&Term::Offset(0), &design(-5.0, 5.0), &[0.5], &[0.2], &[0.2], &[], &["a".into()]);
        assert!(matches!(j, Judgment::Finding), "{j:?}");
    }

    #[test]
    fn a_reported_interval_holds_no_effect_only_when_every_coefficient_holds_zero() {
        let two = TermDesign { cols: vec![Column::new(Some(0), vec![1.0]), Column::new(Some(0), vec![1.0])], lo: vec![0.0, 0.0], hi: vec![9.0, 9.0], ..Default::default() };
        assert!(interval_holds_no_effect(&two, &[0.3, 0.1], &[0.2, 0.1]));
        assert!(!interval_holds_no_effect(&two, &[0.3, 0.5], &[0.2, 0.1]), "one coefficient resolved");
        assert!(!interval_holds_no_effect(&two, &[0.3, 0.1], &[f64::NAN, f64::NAN]), "an unknown spread decides nothing");
        assert!(!interval_holds_no_effect(&design(0.0, 2.0), &[0.3, 0.1], &[0.2, 0.1]), "coefficients that are not the design's");
        let prior = crate::lsq::inertial::InertialPrior::new(&simgap_core::Model::paper_arm());
        let inertial = TermDesign { inertial: Some(std::sync::Arc::new(prior)), ..design(0.0, 2.0) };
        assert!(!interval_holds_no_effect(&inertial, &[0.3], &[0.2]), "an inertial correction is judged by its consistency");
    }

    #[test]
    fn a_spring_whose_stiffness_holds_zero_is_the_torque_offset_nested_in_it() {
        // columns (q, −1), coefficients (k, k q0): k = 0.13 ± 0.17 about q0 = −4.5 rad, a rest
        // position far outside the motion, is a constant torque of 0.6 N·m
        let spring = TermDesign {
            cols: vec![Column::new(Some(0), vec![0.2]), Column::new(Some(0), vec![-1.0])],
            lo: vec![0.0, f64::NEG_INFINITY],
            hi: vec![f64::INFINITY; 2],
            ..Default::default()
        };
        let j = judge(&Term::Spring(0), &spring, &[0.13, -0.6], &[0.01, 0.01], &[0.087, 0.01], &[], &["a".into()]);
        match j {
            Judgment::Simpler { terms, extra, .. } => {
                assert_eq!(terms, [Term::Offset(0)]);
                assert_eq!(extra, [0], "the stiffness column is what the offset lacks; the constant is shared");
            }
            other => panic!("{other:?}"),
        }
        // a stiffness the runs resolve is a spring
        let j = judge(&Term::Spring(0), &spring, &[2.0, -0.6], &[0.01, 0.01], &[0.087, 0.01], &[], &["a".into()]);
        assert!(matches!(j, Judgment::Finding), "{j:?}");
    }

    /// The fit data of the paper arm's first demo run, simulated without effects.
    fn demo_fit_data() -> Vec<crate::prepare::dataset::FitData> {
        use crate::check::bench::{demo_specs, generate};
        use crate::prepare::dataset::{align_run, FitData, PrepareOptions};
        use simgap_core::{Formulation, Model};
        let model = Model::paper_arm();
        let (fit, _) = demo_specs(1);
        let run = generate(&model, Formulation::EulerLagrange, &[], &fit[0], 0.0025, 1_024_000.0).unwrap();
        vec![FitData::new(&model, Formulation::EulerLagrange, align_run(&model, &run).unwrap(), &PrepareOptions::default()).unwrap()]
    }

    #[test]
    fn a_load_friction_whose_load_share_is_too_small_to_matter_is_the_coulomb_friction_nested_in_it() {
        let data = demo_fit_data();
        let term = Term::LoadFriction { joint: 1, w: 0.01 };
        let d = crate::vocabulary::design(&term, &data);
        let names = ["a".to_string(), "b".to_string()];
        // resolved (its interval far from 0), but 1e-4 × |τ| is nothing beside the commanded
        // torque: a Coulomb friction of the same fc
        match judge(&term, &d, &[1.0, 1e-4], &[0.01, 1e-6], &[0.01, 1e-6], &data, &names) {
            Judgment::Simpler { terms, extra, why } => {
                assert_eq!(terms, [Term::Coulomb { joint: 1, w: 0.01 }]);
                assert_eq!(extra, [1]);
                assert!(why.contains("too small to matter"), "{why}");
            }
            other => panic!("{other:?}"),
        }
        // a quarter of the drive's torque lost in the gearbox is a finding
        let j = judge(&term, &d, &[1.0, 0.25], &[0.01, 0.01], &[0.01, 0.01], &data, &names);
        assert!(matches!(j, Judgment::Finding), "{j:?}");
    }

    #[test]
    fn a_load_friction_whose_rise_at_rest_is_too_small_to_matter_is_the_load_friction_nested_in_it() {
        let data = demo_fit_data();
        let term = Term::LoadStribeck { joint: 1, vs: 0.1, w: 0.01 };
        let d = crate::vocabulary::design(&term, &data);
        let names = ["a".to_string(), "b".to_string()];
        // columns (fc, mu, fs − fc, mus − mu): a rise of 1e-4 N·m and 1e-5 × |τ| is nothing
        let small = [1.0, 0.25, 1e-4, 1e-5];
        match judge(&term, &d, &small, &[0.01; 4], &[0.01, 0.01, 1e-6, 1e-7], &data, &names) {
            Judgment::Simpler { terms, extra, why } => {
                assert_eq!(terms, [Term::LoadFriction { joint: 1, w: 0.01 }]);
                assert_eq!(extra, [2, 3]);
                assert!(why.contains("too small to matter"), "{why}");
            }
            other => panic!("{other:?}"),
        }
        // a breakaway a third above the moving level, load-dependent, is a finding
        let j = judge(&term, &d, &[1.0, 0.25, 0.5, 0.3], &[0.01; 4], &[0.01; 4], &data, &names);
        assert!(matches!(j, Judgment::Finding), "{j:?}");
        // a Stribeck velocity within twice the sign's width is no rise the runs resolve
        let narrow = Term::LoadStribeck { joint: 1, vs: 0.015, w: 0.01 };
        let d = crate::vocabulary::design(&narrow, &data);
        let j = judge(&narrow, &d, &[1.0, 0.25, 0.5, 0.3], &[0.01; 4], &[0.01; 4], &data, &names);
        assert!(matches!(j, Judgment::Simpler { .. }), "{j:?}");
    }

    #[test]
    fn a_term_is_needed_when_the_fit_runs_are_predicted_worse_without_it_by_the_prune_tolerance() {
        let every_fold = FoldTest::of(&[0.9, 0.92, 0.95, 0.88]);
        let one_fold = FoldTest::of(&[0.7, 0.8, 2.07, 0.9]);
        // 10 % worse without it, every fold better with it
        assert!(needed_by_prediction(0.90, 0.99, &every_fold));
        // twice as bad without it, whatever one fold of a noisy shooting refit says
        assert!(needed_by_prediction(0.265, 0.551, &one_fold));
        // within the prune tolerance of 2 %
        assert!(!needed_by_prediction(0.90, 0.915, &every_fold));
        // predicted better without it
        assert!(!needed_by_prediction(0.171, 0.161, &every_fold));
        // a set that cannot predict without it
        assert!(needed_by_prediction(0.90, f64::INFINITY, &one_fold));
    }

    #[test]
    fn a_clear_gain_the_typical_fold_contradicts_is_no_need() {
        // a third better pooled, but most folds far worse with it (a few diverging windows
        // carry the pooled gain): not needed
        let contradicted = FoldTest::of(&[7408.0, 3.0, 2.5, 4.0, 0.02]);
        assert!(contradicted.mean > 1.1);
        assert!(!needed_by_prediction(0.5417, 0.8225, &contradicted));
        // twice as bad without it, one fold of ten 60 times worse with it, the rest better
        let one_bad = FoldTest::of(&[60.0, 0.4, 0.45, 0.5, 0.4, 0.35, 0.5, 0.45, 0.4, 0.5]);
        assert!(one_bad.mean < 1.0);
        assert!(needed_by_prediction(0.265, 0.551, &one_bad));
        // fewer than two folds: no mean, no contradiction
        assert!(needed_by_prediction(0.265, 0.551, &FoldTest::of(&[0.5])));
    }

    #[test]
    fn a_term_on_a_light_joint_is_needed_by_its_joint_when_the_whole_is_no_worse() {
        let every_fold = FoldTest::of(&[0.6, 0.55, 0.7, 0.62]);
        let one_fold = FoldTest::of(&[0.8, 0.85, 2.07, 0.9, 0.95]);
        // 1.2 % on the pooled score, its joint twice as far off without it: needed
        let on = OnItsJoint { ratio: 1.9, test: every_fold };
        assert!(!needed_by_prediction(0.4282, 0.4332, &every_fold));
        assert!(needed_on_its_joint(0.4282, 0.4332, &on));
        // the whole predicted better without it: not needed, whatever its joint says
        assert!(!needed_on_its_joint(0.4332, 0.4282, &on));
        // its joint 3 % better with it, one fold twice as bad: not needed
        assert!(!needed_on_its_joint(0.4282, 0.4332, &OnItsJoint { ratio: 1.03, test: one_fold }));
        // no figure for its joint
        assert!(!needed_on_its_joint(0.4282, 0.4332, &OnItsJoint { ratio: f64::NAN, test: every_fold }));
    }

    #[test]
    fn a_small_gain_is_a_need_only_when_the_folds_hold_it() {
        // 3.3 % worse without it on average, one fold twice as bad with it (the servo's viscous
        // friction beside its back-EMF): not needed; the same gain in every fold is
        let one_fold = FoldTest::of(&[0.8, 0.85, 2.07, 0.9, 0.95]);
        assert!(!needed_by_prediction(0.000495, 0.000511, &one_fold));
        assert!(needed_by_prediction(0.000495, 0.000511, &FoldTest::of(&[0.96, 0.97, 0.95, 0.96])));
    }

    #[test]
    fn an_unknown_spread_decides_nothing() {
        let j = judge(&Term::Offset(0), &design(-5.0, 5.0), &[0.3], &[f64::NAN], &[f64::NAN], &[], &["a".into()]);
        assert!(matches!(j, Judgment::Finding), "{j:?}");
    }

    #[test]
    fn a_torque_that_is_a_constant_and_an_acceleration_term_is_an_offset_and_a_rotor_inertia() {
        let data = demo_fit_data();
        let qdd = |j: usize| crate::vocabulary::design(&Term::Armature(j), &data).cols[0].values.clone();
        let (a0, a1) = (qdd(0), qdd(1));
        let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
        // a term whose torque is, on the shoulder, an offset and a rotor inertia of equal RMS
        // (plus 5 % of a term neither makes), and on the elbow a sinusoid of the shoulder's
        // acceleration, which is no constant and not the elbow's own acceleration
        let ia = 0.4 / rms(&a0);
        let shoulder: Vec<f64> = a0.iter().enumerate().map(|(s, x)| 0.4 + ia * x + 0.02 * (s as f64 * 0.01).sin()).collect();
        let elbow: Vec<f64> = a0.iter().map(|x| 0.5 * (x / rms(&a0)).sin()).collect();
        let term = TermDesign { cols: vec![Column::new(Some(0), shoulder), Column::new(Some(1), elbow)], ..Default::default() };
        let parts = affine_torque_joints(&term, &[1.0, 1.0], &data);
        assert_eq!(parts.len(), 1, "only the shoulder decomposes");
        let p = &parts[0];
        assert!(p.joint == 0 && !p.constant && p.offset && p.rotor, "joint {} constant {} offset {} rotor {}", p.joint, p.constant, p.offset, p.rotor);
        // a constant torque on the elbow is an offset alone
        let term = TermDesign { cols: vec![Column::new(Some(1), vec![0.3; a1.len()])], ..Default::default() };
        let parts = affine_torque_joints(&term, &[1.0], &data);
        assert!(parts.len() == 1 && parts[0].joint == 1 && parts[0].constant && parts[0].offset && !parts[0].rotor);
        // and a pure acceleration term a rotor inertia alone; a negative one nothing
        let term = TermDesign { cols: vec![Column::new(Some(1), a1.to_vec())], ..Default::default() };
        let parts = affine_torque_joints(&term, &[0.05], &data);
        assert!(parts.len() == 1 && parts[0].rotor && !parts[0].offset);
        assert!(affine_torque_joints(&term, &[-0.05], &data).is_empty());
    }

    #[test]
    fn a_replacement_a_later_stage_undid_names_no_alternative() {
        let (coulomb, load, viscous) = (Term::Coulomb { joint: 0, w: 0.01 }, Term::LoadFriction { joint: 0, w: 0.01 }, Term::Viscous(0));
        let replaced: Replacement = (load.clone(), vec![coulomb.clone()], "the simpler predicts as well".into());
        // the simpler term selected: the richer one is the alternative
        let a = richer_alternatives(&[coulomb.clone(), viscous.clone()], std::slice::from_ref(&replaced));
        assert_eq!(a.len(), 1);
        assert_eq!(a[0].effects, vec![EffectKind::ViscousFriction.to_string(), EffectKind::LoadFriction.to_string()]);
        assert!(a[0].why.contains("in place of the selected coulomb_friction"), "{}", a[0].why);
        // a later stage selected the richer term again, or dropped the simpler one: none
        assert!(richer_alternatives(&[load, viscous.clone()], std::slice::from_ref(&replaced)).is_empty());
        assert!(richer_alternatives(&[viscous], std::slice::from_ref(&replaced)).is_empty());
    }
}
