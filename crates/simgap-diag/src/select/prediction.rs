//! Selection by prediction: the torque-residual selection pruned by backward elimination and
//! completed with whole effects by cross-validated k-step prediction of the fit runs, the
//! exchange of one effect for another, and the null test of an effect prediction alone supports.

use rayon::prelude::*;

use crate::error::Result;
use crate::options::{check_stop, DiagnoseOptions, Progress};
use crate::prediction::kstep;
use crate::prepare::{prepare, sample_period};
use crate::select::scorer::Scorer;
use crate::select::uncertainty;
use crate::select::{self, Context};
use crate::vocabulary::fitted_terms;
use crate::vocabulary::{effects, EffectReport, Term};
use simgap_sim::EffectKind;

/// Removing a term keeps it out when prediction worsens by less than this (relative).
pub(crate) const PRUNE_TOLERANCE: f64 = 0.02;
/// An effect joins the set when it improves prediction by at least this (relative).
pub(crate) const ADD_GAIN: f64 = 0.02;
/// The forward path from the nominal model is also tried when the torque-residual path
/// predicts the fit runs at more than this fraction of the nominal model's error.
pub(crate) const SECOND_PATH_ABOVE: f64 = 0.5;
/// Two sets whose prediction scores differ by less than this (relative) are a tie.
pub(crate) const TIE_TOLERANCE: f64 = 0.02;

/// Whether `t` fits in `terms`: one term per slot.
pub(crate) fn fits_in(terms: &[Term], t: &Term) -> bool {
    !select::slot_taken(terms, t)
}

/// The prune stage: two paths, the better kept. (a) The torque-residual selection pruned by
/// backward elimination and completed with whole effects, by cross-validated prediction;
/// (b) forward selection of whole effects by prediction from the nominal model, then pruned
/// (only when (a) does not reach [`SECOND_PATH_ABOVE`]).
/// A set that does not beat the nominal model's prediction by [`ADD_GAIN`] is emptied: the
/// data then support no effect.
pub(crate) fn prune_and_complete(
    scorer: &Scorer<'_>,
    groups: &[(&'static str, Vec<Term>)],
    alone_score: &[f64],
    sel: &mut select::Selection,
    progress: &mut dyn FnMut(Progress),
    options: &DiagnoseOptions,
) -> Result<()> {
    let mut path_a = (sel.terms.clone(), Vec::new());
    let score_a = refine_by_prediction(scorer, groups, alone_score, &mut path_a.0, &mut path_a.1, progress, options)?;
    // the second path only where the first does not already halve the nominal error
    let mut path_b = (Vec::new(), Vec::new());
    let score_b = if score_a > SECOND_PATH_ABOVE { refine_by_prediction(scorer, groups, alone_score, &mut path_b.0, &mut path_b.1, progress, options)? } else { f64::INFINITY };
    let (best, score) = if score_b < score_a * (1.0 - PRUNE_TOLERANCE) { (path_b, score_b) } else { (path_a, score_a) };
    let (mut terms, mut log) = best;
    let mut score = score;
    // exchange: an effect replaced by another that predicts clearly better, then pruned and
    // completed again (at most twice)
    for _ in 0..2 {
        check_stop(options)?;
        let Some((set, s, out, into)) = exchange_by_prediction(scorer, groups, alone_score, &terms, score) else { break };
        for t in terms.iter().filter(|t| t.effect_name() == out.as_str()) {
            log.push(select::Step {
                term: t.clone(),
                cv_mse: f64::NAN,
                accepted: false,
                reason: format!("exchanged for {into}: the fit runs' cross-validated k-step error is {s:.4} of the nominal model's with it in place of {out} ({score:.4} before), better in every part of the fit runs"),
            });
        }
        for t in set.iter().filter(|t| !terms.contains(t)) {
            log.push(select::Step {
                term: t.clone(),
                cv_mse: f64::NAN,
                accepted: true,
                reason: format!("exchanged in place of {out}: the fit runs' cross-validated k-step error is {s:.4} of the nominal model's ({score:.4} with {out})"),
            });
        }
        terms = set;
        score = refine_by_prediction(scorer, groups, alone_score, &mut terms, &mut log, progress, options)?;
    }
    // friction that differs with the direction of motion, tried in place of a joint's selected
    // Coulomb and viscous friction (the symmetric pair it nests) where it is tried at all
    // (`families::directional_tried`): kept only when it predicts the fit runs better by
    // ADD_GAIN in every part of them, so symmetric friction stays the pair
    let tried = |j: usize| crate::select::families::directional_tried(scorer.model.joints()[j].kind, options);
    for j in (0..scorer.ctx.problem.dof).filter(|&j| tried(j)) {
        check_stop(options)?;
        let dry_w = terms.iter().find_map(|t| match *t {
            Term::Coulomb { joint, w } if joint == j => Some(w),
            _ => None,
        });
        let viscous = terms.contains(&Term::Viscous(j));
        if dry_w.is_none() && !viscous {
            continue;
        }
        let w = dry_w.unwrap_or_else(|| scorer.ctx.dry_width[j].mid());
        let directional = Term::Directional { joint: j, w };
        let mut set: Vec<Term> = terms.iter().filter(|t| !(t.joint() == Some(j) && matches!(t, Term::Coulomb { .. } | Term::Viscous(_)))).cloned().collect();
        if !fits_in(&set, &directional) {
            continue;
        }
        set.push(directional.clone());
        let set = select::repolish(scorer.ctx, &set);
        let s = scorer.score(&set);
        if s.is_finite() && s < score * (1.0 - ADD_GAIN) && scorer.gain_test(&set, &terms).holds(PRUNE_TOLERANCE, ADD_GAIN) {
            log.push(select::Step {
                term: directional,
                cv_mse: f64::NAN,
                accepted: true,
                reason: format!(
                    "in place of the symmetric friction on its joint: the fit runs' cross-validated k-step error is {s:.4} of the nominal model's ({score:.4} with Coulomb and viscous friction), better in every part of them"
                ),
            });
            terms = set;
            score = s;
            // its asymmetry of dry friction is a constant torque on the joint (−s⁺ fc_pos +
            // s⁻ fc_neg = −(fc_pos + fc_neg)/2 sgn − (fc_pos − fc_neg)/2): an offset beside it
            // says the same, and the simpler set without it is kept when it predicts as well
            if terms.contains(&Term::Offset(j)) {
                let without: Vec<Term> = terms.iter().filter(|t| **t != Term::Offset(j)).cloned().collect();
                let without = select::repolish(scorer.ctx, &without);
                let s = scorer.score(&without);
                if s.is_finite() && s <= score * (1.0 + TIE_TOLERANCE) {
                    log.push(select::Step {
                        term: Term::Offset(j),
                        cv_mse: f64::NAN,
                        accepted: false,
                        reason: format!(
                            "dropped beside the directional friction on its joint, whose asymmetry is a constant torque: the fit runs' cross-validated k-step error is {s:.4} of the nominal model's without it ({score:.4} with it)"
                        ),
                    });
                    terms = without;
                    score = s;
                }
            }
        }
    }
    // the improvement must be large enough and hold across the folds of the fit runs
    let test = scorer.cv_errors(&terms).map_or_else(|| kstep::FoldTest::of(&[]), |e| scorer.against_nominal(&e));
    let why = if score >= 1.0 - ADD_GAIN {
        Some(format!(
            "dropped: the best set found predicts the fit runs at {score:.4} of the nominal model's cross-validated k-step error, not better by {:.0} %",
            100.0 * ADD_GAIN
        ))
    } else if !terms.is_empty() && !test.holds(PRUNE_TOLERANCE, ADD_GAIN) {
        Some(format!(
            "dropped: the best set found predicts the fit runs at {score:.4} of the nominal model's cross-validated k-step error, but not in every part of them: fold by fold, the upper 2-standard-error bound of that ratio is {:.3} and the worst fold's {:.3}",
            test.bound, test.worst
        ))
    } else {
        None
    };
    if let Some(why) = why {
        for t in terms.drain(..) {
            log.push(select::Step { term: t, cv_mse: f64::NAN, accepted: false, reason: why.clone() });
        }
    }
    sel.log.extend(log);
    sel.terms = terms;
    Ok(())
}

/// Backward elimination, then forward completion with whole effects (at most three), repeated;
/// returns the final prediction score.
pub(crate) fn refine_by_prediction(
    scorer: &Scorer<'_>,
    groups: &[(&'static str, Vec<Term>)],
    alone_score: &[f64],
    terms: &mut Vec<Term>,
    log: &mut Vec<select::Step>,
    progress: &mut dyn FnMut(Progress),
    options: &DiagnoseOptions,
) -> Result<f64> {
    let mut current = scorer.score(terms);
    let mut added = 0;
    loop {
        // backward: a term whose removal does not worsen prediction goes
        loop {
            check_stop(options)?;
            if terms.is_empty() {
                break;
            }
            progress(Progress { stage: "pruning by prediction", done: 0, total: terms.len() });
            let before = terms.clone();
            let without: Vec<f64> = (0..terms.len())
                .into_par_iter()
                .map(|i| {
                    let mut rest = terms.clone();
                    rest.remove(i);
                    scorer.score(&rest)
                })
                .collect();
            let (i, best) = without.iter().copied().enumerate().min_by(|a, b| a.1.total_cmp(&b.1)).expect("non-empty");
            // a term that helps, but not in every part of the fit runs, goes too
            let weak = best <= current * (1.0 + PRUNE_TOLERANCE);
            let test = (!weak).then(|| {
                let mut rest = terms.clone();
                rest.remove(i);
                scorer.gain_test(terms, &rest)
            });
            let inconsistent = test.filter(|t| !t.holds(PRUNE_TOLERANCE, ADD_GAIN));
            if weak || inconsistent.is_some() {
                let term = terms.remove(i);
                let reason = if let Some(t) = inconsistent {
                    format!(
                        "pruned by prediction: with it the fit runs' cross-validated k-step error is {current:.4} of the nominal model's (without it {best:.4}), but not in every part of them: fold by fold, the upper 2-standard-error bound of that gain is {:.3} and the worst fold's {:.3}",
                        t.bound, t.worst
                    )
                } else {
                    format!("pruned by prediction: without it the fit runs' cross-validated k-step error is {best:.4} of the nominal model's (with it {current:.4})")
                };
                log.push(select::Step { term, cv_mse: f64::NAN, accepted: false, reason });
                current = best;
                // the other terms this pass found weak, in the order of their scores: each is
                // scored again without the terms removed since, and removed while it stays weak
                // (a full pass follows, so no weak term is left; it saves re-scoring every
                // term after each removal)
                if weak {
                    let mut order: Vec<(usize, f64)> = without.iter().copied().enumerate().filter(|&(j, s)| j != i && s <= current * (1.0 + PRUNE_TOLERANCE)).collect();
                    order.sort_by(|a, b| a.1.total_cmp(&b.1));
                    for cand in order.iter().map(|&(j, _)| &before[j]) {
                        check_stop(options)?;
                        let Some(k) = terms.iter().position(|t| t == cand) else { continue };
                        let mut rest = terms.clone();
                        rest.remove(k);
                        let s = scorer.score(&rest);
                        if s > current * (1.0 + PRUNE_TOLERANCE) {
                            break;
                        }
                        let term = terms.remove(k);
                        log.push(select::Step {
                            term,
                            cv_mse: f64::NAN,
                            accepted: false,
                            reason: format!("pruned by prediction: without it the fit runs' cross-validated k-step error is {s:.4} of the nominal model's (with it {current:.4})"),
                        });
                        current = s;
                    }
                }
            } else {
                break;
            }
        }
        if added >= 3 {
            break;
        }
        // forward: the whole effect (all joints) that improves prediction most
        check_stop(options)?;
        progress(Progress { stage: "completing by prediction", done: 0, total: groups.len() });
        let tries: Vec<(usize, Vec<Term>)> = groups
            .iter()
            .enumerate()
            .filter(|(i, _)| alone_score[*i] < 1.0 - ADD_GAIN)
            .map(|(i, (_, g))| (i, g.iter().filter(|t| fits_in(terms, t)).cloned().collect::<Vec<_>>()))
            .filter(|(_, g)| !g.is_empty())
            .collect();
        // each completed set with its nonlinear parameters re-searched jointly
        let scored: Vec<(Vec<Term>, f64)> = tries
            .par_iter()
            .map(|(_, g)| {
                let mut with = terms.clone();
                with.extend(g.iter().cloned());
                let with = select::repolish(scorer.ctx, &with);
                let s = scorer.score(&with);
                (with, s)
            })
            .collect();
        let Some((k, best)) = scored.iter().map(|s| s.1).enumerate().min_by(|a, b| a.1.total_cmp(&b.1)) else { break };
        // an effect that the torque residual did not select must beat what it gains on the fit
        // runs re-simulated with the set before it (the pipeline's own bias, e.g. restart states
        // smoothed across torque steps, which a delay compensates)
        if best < current * (1.0 - ADD_GAIN) {
            if let Some(null) = null_ratio(scorer, terms, &scored[k].0, options) {
                if best / current > null * (1.0 - ADD_GAIN) {
                    log.push(select::Step {
                        term: tries[k].1[0].clone(),
                        cv_mse: f64::NAN,
                        accepted: false,
                        reason: format!(
                            "not added: {} improves prediction of the fit runs to {:.4} of the set without it, and of the same runs re-simulated with that set to {null:.4}: the gain is the pipeline's, not the robot's",
                            groups[tries[k].0].0,
                            best / current
                        ),
                    });
                    break;
                }
            }
        }
        // what the effect adds must hold fold by fold (the backward step would prune it)
        if best < current * (1.0 - ADD_GAIN) && !scorer.gain_test(&scored[k].0, terms).holds(PRUNE_TOLERANCE, ADD_GAIN) {
            break;
        }
        if best < current * (1.0 - ADD_GAIN) {
            let (gi, g) = &tries[k];
            for t in g {
                log.push(select::Step {
                    term: t.clone(),
                    cv_mse: f64::NAN,
                    accepted: true,
                    reason: format!(
                        "added by prediction: with {} the fit runs' cross-validated k-step error is {best:.4} of the nominal model's (without it {current:.4})",
                        groups[*gi].0
                    ),
                });
            }
            *terms = scored[k].0.clone();
            current = best;
            added += 1;
        } else {
            break;
        }
    }
    Ok(current)
}

/// The null test of an effect added by prediction: how much the set `with` improves on the set
/// `base` (the ratio of their cross-validated k-step scores) on the fit runs re-simulated with
/// `base`'s effects fitted on the fit runs (the same torques, references and sensors, and
/// nothing else hidden). An effect that improves those runs as much compensates a bias of the
/// pipeline, not of the robot. `None` when a run cannot be re-simulated.
pub(crate) fn null_ratio(scorer: &Scorer<'_>, base: &[Term], with: &[Term], options: &DiagnoseOptions) -> Option<f64> {
    let effects = if base.is_empty() {
        Vec::new()
    } else {
        let (designs, _, f) = scorer.ctx.fit_terms(base);
        effects::to_effects(scorer.model, &fitted_terms(base, &designs, &f.theta, None))
    };
    // re-simulated as logged (an open-loop replay open loop): a tracking loop's correction holds
    // what `base` lacks, and the recorded torque would carry it into these runs
    let synthetic = uncertainty::synthetic_runs(scorer.model, scorer.formulation, &effects, &scorer.prep.fit_runs, false);
    if synthetic.len() != scorer.prep.fit_runs.len() {
        return None;
    }
    let prep = prepare(scorer.model, scorer.formulation, &synthetic, &scorer.prep.hold_runs, &options.prepare, &options.horizons).ok()?;
    let scales = select::parameter_scales(scorer.model);
    let ctx = Context::new(&prep.data, sample_period(&prep.fit_runs), &scales);
    let null = Scorer::new(scorer.model, scorer.formulation, &ctx, &prep);
    let r = null.score(with) / null.score(base);
    r.is_finite().then_some(r)
}

/// Orders the selected effects by how much prediction worsens without each (most needed first).
pub(crate) fn rank_selected(scorer: &Scorer<'_>, terms: &[Term], reports: &mut [EffectReport]) {
    if reports.len() < 2 {
        return;
    }
    let loss: Vec<(EffectKind, f64)> = reports
        .par_iter()
        .map(|r| {
            let rest: Vec<Term> = terms.iter().filter(|t| t.kind() != r.effect).cloned().collect();
            (r.effect, scorer.score(&rest))
        })
        .collect();
    let of = |kind: EffectKind| loss.iter().find(|l| l.0 == kind).map_or(0.0, |l| l.1);
    reports.sort_by(|a, b| of(b.effect).total_cmp(&of(a.effect)));
}

/// The candidates (indices into `groups`) tried in place of the selected effect `name`: the two
/// best alone among those scoring alone at most `within` times `name`'s own score, and, for an
/// inertial correction, its exact equivalents (a payload: a point mass on the last link; a
/// torque gain: all links scaled) whatever they score alone.
pub(crate) fn swap_candidates(groups: &[(&'static str, Vec<Term>)], alone_score: &[f64], names: &[String], name: &str, within: f64) -> Vec<usize> {
    let Some(si) = groups.iter().position(|g| g.0 == name) else { return Vec::new() };
    let mut others: Vec<usize> = (0..groups.len()).filter(|&i| i != si && !names.iter().any(|n| n == groups[i].0) && alone_score[i] <= alone_score[si] * within).collect();
    others.sort_by(|a, b| alone_score[*a].total_cmp(&alone_score[*b]));
    others.truncate(2);
    if name == EffectKind::InertialError.as_str() {
        for partner in [EffectKind::Payload.as_str(), EffectKind::TorqueGain.as_str()] {
            if let Some(i) = groups.iter().position(|g| g.0 == partner) {
                if !others.contains(&i) && !names.iter().any(|n| n == partner) {
                    others.push(i);
                }
            }
        }
    }
    others
}

/// `terms` with the effect `name` replaced by the terms `with` (those that fit beside the rest).
pub(crate) fn swapped(terms: &[Term], name: &str, with: &[Term]) -> Vec<Term> {
    let mut set: Vec<Term> = terms.iter().filter(|t| t.effect_name() != name).cloned().collect();
    set.extend(with.iter().filter(|t| fits_in(&set, t)).cloned().collect::<Vec<_>>());
    set
}

/// The exchange step of the selection: one selected effect replaced by another candidate
/// ([`swap_candidates`]) when that predicts the fit runs better by [`ADD_GAIN`] and the gain
/// holds fold by fold. A stepwise selection that took an effect first (e.g. an inertial
/// correction, which absorbs most of what per-joint torque gains do to the torque residual)
/// cannot otherwise undo it. Returns the new set, its score and what was swapped for what.
pub(crate) fn exchange_by_prediction(
    scorer: &Scorer<'_>,
    groups: &[(&'static str, Vec<Term>)],
    alone_score: &[f64],
    terms: &[Term],
    current: f64,
) -> Option<(Vec<Term>, f64, String, &'static str)> {
    let mut names: Vec<String> = terms.iter().map(|t| t.effect_name().to_string()).collect();
    names.sort();
    names.dedup();
    let swaps: Vec<(String, usize)> = names.iter().flat_map(|n| swap_candidates(groups, alone_score, &names, n, f64::INFINITY).into_iter().map(move |i| (n.clone(), i))).collect();
    let scored: Vec<(Vec<Term>, f64, String, usize)> = swaps
        .par_iter()
        .map(|(name, i)| {
            let set = select::repolish(scorer.ctx, &swapped(terms, name, &groups[*i].1));
            let s = scorer.score(&set);
            (set, s, name.clone(), *i)
        })
        .collect();
    let best = scored.into_iter().filter(|c| c.1.is_finite()).min_by(|a, b| a.1.total_cmp(&b.1))?;
    (best.1 < current * (1.0 - ADD_GAIN) && scorer.gain_test(&best.0, terms).holds(PRUNE_TOLERANCE, ADD_GAIN)).then(|| (best.0, best.1, best.2, groups[best.3].0))
}
