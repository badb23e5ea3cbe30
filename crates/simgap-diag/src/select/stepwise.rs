//! The stepwise selection on the torque residual: forward steps by block cross-validation,
//! an exchange of one selected term for another that fits the residual better, and the polish
//! of searched parameters (Stribeck velocity, saturation limit, delay, payload centre of mass).

use rayon::prelude::*;

use super::{admissible, cv_of, families, residual_after, slot_taken, term_torque_rms, Context, Family, SelectOptions, Selection, Step};
use crate::lsq::Fit;
use crate::vocabulary::{n_params, Slot, Term, TermDesign};

/// Extra relative gain demanded of a term found by a large grid search (selection bias: the
/// best of many columns explains some noise).
fn grid_penalty(t: &Term) -> f64 {
    match t {
        Term::Cogging { .. } => 2.0,
        _ => 1.0,
    }
}

/// A swap of the exchange moves: the selected term's index, the term taking its place, the fit
/// and the designs after the swap.
type Swap = (usize, Term, Fit, Vec<TermDesign>);

/// A candidate of a forward step: the term, the set with it, their designs.
type Candidate = (Term, Vec<Term>, Vec<TermDesign>);

/// The set `terms` with the candidate `c` after them, and their designs.
fn with_candidate(ctx: &Context<'_>, terms: &[Term], designs: &[TermDesign], c: &Term) -> (Vec<Term>, Vec<TermDesign>) {
    let mut all = terms.to_vec();
    all.push(c.clone());
    let mut ds = designs.to_vec();
    ds.push(ctx.design(c));
    (all, ds)
}

/// One pass of exchange moves; true when a swap was made.
#[allow(clippy::too_many_arguments)]
fn exchange_by_residual(
    ctx: &Context<'_>,
    fams: &[Family],
    terms: &mut Vec<Term>,
    designs: &mut Vec<TermDesign>,
    current: &mut Fit,
    nominal: &Fit,
    opts: &SelectOptions,
    log: &mut Vec<Step>,
) -> bool {
    let p = &ctx.problem;
    // every selected term's exchanges evaluated in parallel, each term's acceptable swaps in
    // candidate order; the best is then taken in that order (the first of equal residuals)
    let (terms_now, designs_now, current_now) = (&*terms, &*designs, &*current);
    let swaps: Vec<Vec<Swap>> = (0..terms_now.len())
        .into_par_iter()
        .map(|i| {
            let mut rest_terms = terms_now.to_vec();
            rest_terms.remove(i);
            let mut rest = designs_now.to_vec();
            rest.remove(i);
            let resid = residual_after(p, &rest, &ctx.theta_of_set(&rest_terms, &rest));
            // (a family whose slot is taken is not searched: its best member could not join)
            let mut cands: Vec<Term> = fams
                .par_iter()
                .filter(|f| !slot_taken(&rest_terms, &f.member()))
                .map(|f| ctx.best_of_with(f, &resid, &rest))
                .filter(|t| !slot_taken(&rest_terms, t) && *t != terms_now[i])
                .collect();
            if ctx.inertial_basis.ncols() > 0 && !rest_terms.iter().any(|t| t.slot().0 == Slot::Inertia) && !matches!(terms_now[i], Term::InertialError { .. }) {
                let t = ctx.inertial_term();
                if !slot_taken(&rest_terms, &t) {
                    cands.push(t);
                }
            }
            // (the candidates in parallel, their acceptable swaps in candidate order)
            cands
                .into_par_iter()
                .filter_map(|c| {
                    let (all, ds) = with_candidate(ctx, &rest_terms, &rest, &c);
                    // a swap must lower the residual, or keep it (within 1 %) with fewer parameters
                    let simpler = n_params(&c, ds.last().unwrap()) < n_params(&terms_now[i], &designs_now[i]);
                    let same_joint_simpler = simpler && c.joint() == terms_now[i].joint();
                    // the residual a swap needs: within 1 % for a simpler term on the same joint;
                    // a visible gain, also against the nominal, for a term as complex or more (a
                    // set whose residual is known to be above it is not cross-validated)
                    let reject_at = if same_joint_simpler {
                        current_now.cv_mse * 1.01 * (1.0 + f64::EPSILON)
                    } else {
                        (current_now.cv_mse * (1.0 - 0.5 * opts.min_relative_gain)).min(current_now.cv_mse - opts.min_nominal_gain * nominal.cv_mse)
                    };
                    // (a swap to a term as complex or more passes with its residual below that level)
                    let f = ctx.fit_set_below(&all, &ds, reject_at)?;
                    if !admissible(&ds, &all, &f.theta) {
                        return None;
                    }
                    // a simpler term on the same joint must keep that joint's residual within 1 %
                    let ok = !same_joint_simpler || (cv_of(&f, &c) <= cv_of(current_now, &c) * 1.01 && f.cv_mse <= current_now.cv_mse * 1.01);
                    ok.then_some((i, c, f, ds))
                })
                .collect::<Vec<Swap>>()
        })
        .collect();
    let mut best: Option<Swap> = None;
    for swap in swaps.into_iter().flatten() {
        if best.as_ref().is_none_or(|b| swap.2.cv_mse < b.2.cv_mse) {
            best = Some(swap);
        }
    }
    match best {
        Some((i, c, f, ds)) => {
            log.push(Step {
                term: c.clone(),
                cv_mse: f.cv_mse,
                accepted: true,
                reason: format!("exchanged for {} (cross-validated residual {:.3e} → {:.3e})", describe(&terms[i]), current.cv_mse, f.cv_mse),
            });
            terms.remove(i);
            terms.push(c);
            *designs = ds;
            *current = f;
            true
        }
        None => false,
    }
}

fn describe(t: &Term) -> String {
    match t.joint() {
        Some(j) => format!("{} on joint {j}", t.effect_name()),
        None => t.effect_name().to_string(),
    }
}

/// The candidates of a forward step that can be its choice, each fitted and cross-validated
/// with the set (`sets`: candidate, set with it, their designs), in candidate order; the
/// inadmissible left out. The step chooses among those whose gain over `current_cv` is within
/// a factor (1 − ½ `min_relative_gain`) of the best gain; a candidate whose least-squares floor
/// (a lower bound of its cross-validated residual, [`Context::residual_floor`]) leaves more
/// than the best gain allows is not cross-validated. The two most promising by that floor are
/// cross-validated first; their best gain bounds the rest.
fn fit_candidates(ctx: &Context<'_>, sets: Vec<Candidate>, current_cv: f64, opts: &SelectOptions) -> Vec<(Term, Fit, Vec<TermDesign>)> {
    let factor = 1.0 - 0.5 * opts.min_relative_gain;
    // a lower bound of every set's cross-validated residual
    let floor: Vec<f64> = sets.par_iter().map(|(_, all, ds)| ctx.residual_floor(all, ds)).collect();
    let mut order: Vec<usize> = (0..sets.len()).collect();
    order.sort_by(|&a, &b| floor[a].total_cmp(&floor[b]).then(a.cmp(&b)));
    let full = |&i: &usize| -> (usize, Option<Fit>) {
        let (_, all, ds) = &sets[i];
        let f = ctx.fit_set(all, ds);
        (i, admissible(ds, all, &f.theta).then_some(f))
    };
    let (first, others) = order.split_at(order.len().min(2));
    let mut fits: Vec<Option<Fit>> = vec![None; sets.len()];
    for (i, f) in first.par_iter().map(full).collect::<Vec<_>>() {
        fits[i] = f;
    }
    let best_gain = fits.iter().flatten().map(|f| current_cv - f.cv_mse).fold(f64::NEG_INFINITY, f64::max);
    // a candidate can be chosen only with a gain of at least `best_gain × factor` (a bound that
    // holds while the tolerance grows with the best gain: factor > 0)
    let reject_at = if factor > 0.0 { current_cv - best_gain * factor } else { f64::INFINITY };
    let in_play: Vec<usize> = others.iter().copied().filter(|&i| floor[i] <= reject_at || !reject_at.is_finite()).collect();
    for (i, f) in in_play.par_iter().map(full).collect::<Vec<_>>() {
        fits[i] = f;
    }
    sets.into_iter().zip(fits).filter_map(|((c, _, ds), f)| f.map(|f| (c, f, ds))).collect()
}

/// Forward stepwise selection with cross-validation, then backward pruning.
pub(crate) fn select(ctx: &Context<'_>, opts: &SelectOptions) -> Selection {
    let p = &ctx.problem;
    let (_, _, nominal) = ctx.fit_terms(&[]);
    let mut terms: Vec<Term> = Vec::new();
    let mut current = nominal.clone();
    let mut designs: Vec<TermDesign> = Vec::new();
    let mut log = Vec::new();
    let fams = families(ctx.data);
    while terms.len() < opts.max_terms {
        let resid = residual_after(p, &designs, &current.theta);
        // best member of every family, then the inertial error, evaluated jointly with the set
        let mut cands: Vec<Term> =
            fams.par_iter().filter(|f| !slot_taken(&terms, &f.member())).map(|f| ctx.best_of_with(f, &resid, &designs)).filter(|t| !slot_taken(&terms, t)).collect();
        if ctx.inertial_basis.ncols() > 0 && !terms.iter().any(|t| t.slot().0 == Slot::Inertia) {
            cands.push(ctx.inertial_term());
        }
        // every candidate fitted jointly with the set, in parallel (in candidate order)
        let (terms_now, designs_now) = (&terms, &designs);
        let sets: Vec<Candidate> = cands
            .into_iter()
            .map(|c| {
                let (all, ds) = with_candidate(ctx, terms_now, designs_now, &c);
                (c, all, ds)
            })
            .collect();
        let evaluated = fit_candidates(ctx, sets, current.cv_mse, opts);
        // the best candidate by the whole-robot gain, then parsimony: the fewest parameters
        // among candidates whose gain is within a tolerance of the best
        let rel = |e: &(Term, Fit, Vec<TermDesign>)| current.cv_mse - e.1.cv_mse;
        let Some(best_rel) = evaluated.iter().map(rel).max_by(f64::total_cmp) else { break };
        let tol = best_rel * (1.0 - 0.5 * opts.min_relative_gain);
        let Some((term, f, ds)) = evaluated.into_iter().filter(|e| rel(e) >= tol).min_by(|a, b| {
            let (pa, pb) = (n_params(&a.0, a.2.last().unwrap()), n_params(&b.0, b.2.last().unwrap()));
            pa.cmp(&pb).then(a.1.cv_mse.total_cmp(&b.1.cv_mse))
        }) else {
            break;
        };
        let (now_t, new_t, nominal_t) = (cv_of(&current, &term), cv_of(&f, &term), cv_of(&nominal, &term));
        let gain = now_t - new_t;
        let k0: usize = designs.iter().map(|d| d.cols.len()).sum();
        let th: Vec<f64> = f.theta.iter().skip(k0).copied().collect();
        let torque = term_torque_rms(p, ds.last().unwrap(), &th);
        let share = match term.joint() {
            Some(j) => torque[j] / p.tau_rms[j].max(1e-12),
            None => (0..p.dof).map(|j| torque[j] / p.tau_rms[j].max(1e-12)).fold(0.0, f64::max),
        };
        let reason;
        let accept = if f.cv_mse >= current.cv_mse || gain < grid_penalty(&term) * opts.min_relative_gain * now_t {
            reason = format!("cross-validated residual falls by {:.1} % (< {:.0} %)", 100.0 * gain / now_t, 100.0 * grid_penalty(&term) * opts.min_relative_gain);
            false
        } else if gain < opts.min_nominal_gain * nominal_t {
            reason = format!("explains {:.2} % of the nominal residual (< {:.1} %)", 100.0 * gain / nominal_t, 100.0 * opts.min_nominal_gain);
            false
        } else if share < opts.min_torque_share {
            reason = format!("torque {:.2} % of the commanded torque (< {:.0} %): too small to matter", 100.0 * share, 100.0 * opts.min_torque_share);
            false
        } else {
            reason = format!("cross-validated residual falls by {:.1} %", 100.0 * gain / now_t);
            true
        };
        log.push(Step { term: term.clone(), cv_mse: f.cv_mse, accepted: accept, reason });
        if !accept {
            break;
        }
        terms.push(term);
        designs = ds;
        current = f;
        polish(ctx, &mut terms, &mut designs, &mut current);
        // exchange moves: swap a selected term for a candidate while that lowers the CV residual
        for _ in 0..4 {
            if !exchange_by_residual(ctx, &fams, &mut terms, &mut designs, &mut current, &nominal, opts, &mut log) {
                break;
            }
        }
    }
    // backward pruning: drop a term whose removal costs less than the entry threshold
    let mut changed = true;
    while changed && terms.len() > 1 {
        changed = false;
        for i in 0..terms.len() {
            let mut ds = designs.clone();
            ds.remove(i);
            let mut rest = terms.clone();
            rest.remove(i);
            // (a set whose residual on all the data already costs more is not cross-validated)
            let reject_at = if opts.min_relative_gain < 1.0 { current.cv_mse / (1.0 - opts.min_relative_gain) } else { f64::INFINITY };
            let Some(f) = ctx.fit_set_below(&rest, &ds, reject_at) else { continue };
            if !admissible(&ds, &rest, &f.theta) {
                continue;
            }
            if f.cv_mse - current.cv_mse < opts.min_relative_gain * f.cv_mse {
                log.push(Step { term: terms[i].clone(), cv_mse: f.cv_mse, accepted: false, reason: "pruned: the others explain it".into() });
                terms.remove(i);
                designs = ds;
                current = f;
                changed = true;
                break;
            }
        }
    }
    polish(ctx, &mut terms, &mut designs, &mut current);
    Selection { terms, fit: current, designs, nominal_cv_mse: nominal.cv_mse, log }
}

/// Re-searches the nonlinear parameter of every term of `terms` (payload centre of mass,
/// Stribeck velocity, saturation limit, cogging periods, delay) jointly with the others, on the
/// torque residual: a set assembled one whole effect at a time (the prediction stage's
/// completion) otherwise keeps the value each term took when it was fitted without the rest,
/// e.g. a payload's centre of mass pulled toward the friction it was standing in for.
pub(crate) fn repolish(ctx: &Context<'_>, terms: &[Term]) -> Vec<Term> {
    if !terms.iter().any(|t| family_of(t).is_some()) {
        return terms.to_vec();
    }
    let mut terms = terms.to_vec();
    let mut designs: Vec<TermDesign> = terms.iter().map(|t| ctx.design(t)).collect();
    let mut current = ctx.fit_set(&terms, &designs);
    polish(ctx, &mut terms, &mut designs, &mut current);
    terms
}

/// The family a term belongs to.
fn family_of(t: &Term) -> Option<Family> {
    match *t {
        Term::Coulomb { joint, .. } => Some(Family::Coulomb(joint)),
        Term::Stribeck { joint, .. } => Some(Family::Stribeck(joint)),
        Term::Saturation { joint, .. } => Some(Family::Saturation(joint)),
        Term::Cogging { joint, .. } => Some(Family::Cogging(joint)),
        Term::Delay { .. } => Some(Family::Delay),
        Term::Payload { .. } => Some(Family::Payload),
        _ => None,
    }
}

/// Re-searches the nonlinear parameter of each selected term against the residual of all the
/// others (two rounds of coordinate descent), keeping a change only when the CV residual falls.
fn polish(ctx: &Context<'_>, terms: &mut [Term], designs: &mut [TermDesign], current: &mut Fit) {
    let p = &ctx.problem;
    for _ in 0..2 {
        for i in 0..terms.len() {
            let Some(family) = family_of(&terms[i]) else { continue };
            let mut rest = designs.to_vec();
            rest.remove(i);
            let mut rest_terms = terms.to_vec();
            rest_terms.remove(i);
            let resid = residual_after(p, &rest, &ctx.theta_of_set(&rest_terms, &rest));
            let cand = ctx.best_of_with(&family, &resid, &rest);
            let mut ds = designs.to_vec();
            ds[i] = ctx.design(&cand);
            let mut all = terms.to_vec();
            all[i] = cand.clone();
            let Some(f) = ctx.fit_set_below(&all, &ds, current.cv_mse) else { continue };
            if f.cv_mse < current.cv_mse && admissible(&ds, &all, &f.theta) {
                terms[i] = cand;
                designs[i] = ds.swap_remove(i);
                *current = f;
            }
        }
    }
}
