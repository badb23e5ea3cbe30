//! Sim-to-real gap diagnosis: given a model and logs from a real robot, **where** the gap lies,
//! **which** unmodelled effect causes it, and **how far** it shrinks once that effect is added,
//! measured on held-out runs the fit never saw.
//!
//! 1. Each fit log is aligned to the model by joint name, smoothed and differentiated
//!    ([`differentiate`]), and the nominal inverse-dynamics residual
//!    `r = τ_cmd − (H q̈ + C q̇ + g)` is formed ([`dataset`]).
//! 2. Every effect of BRIEF §3.2 is a family of candidate terms linear in its parameters, or
//!    searched on a grid where it is not ([`terms`]); terms are fitted by weighted least
//!    squares and compared by cross-validation over contiguous blocks of every fit run
//!    ([`fit`]); a forward stepwise selection with backward pruning picks the set
//!    ([`select`]); block bootstrap gives the uncertainties.
//! 3. Every held-out run is re-simulated in closed loop with the nominal model, with each
//!    candidate alone and with the selected set ([`resim`]); the L² index (eq. 127) before and
//!    after is the answer to "how far". Held-out runs are never used to fit or to select.

pub mod bench;
pub mod dataset;
pub mod differentiate;
pub mod effects;
pub mod error;
pub mod fit;
pub mod html;
pub mod inertial;
pub mod locate;
pub mod pitfalls;
pub mod report;
pub mod resim;
pub mod select;
pub mod selfcheck;
pub mod terms;

use rayon::prelude::*;
use simgap_core::{Formulation, Model};
use simgap_sim::{Effect, Run};

pub use dataset::{align_run, FitData, PrepareOptions};
pub use effects::{EffectReport, FittedTerm, Param};
pub use error::{Error, Result};
pub use report::{Alternative, Candidate, Decision, Gap, KStep, Report, RunKStep};
pub use select::SelectOptions;

use crate::fit::{bootstrap_std, fit_terms, fitted_terms};
use crate::select::{families, select, Context};
use crate::terms::Term;

/// Options of [`diagnose`].
#[derive(Clone, Debug, Default)]
pub struct DiagnoseOptions {
    /// Data preparation.
    pub prepare: PrepareOptions,
    /// Selection thresholds.
    pub select: SelectOptions,
}

/// Progress of a diagnosis, for a progress bar.
#[derive(Clone, Debug)]
pub struct Progress {
    /// What is being done.
    pub stage: &'static str,
    /// Steps done.
    pub done: usize,
    /// Steps in all.
    pub total: usize,
}

/// Everything [`diagnose`] produced: the report and the runs behind its figures.
#[derive(Clone, Debug)]
pub struct Diagnosis {
    /// The report (BRIEF §3.3).
    pub report: Report,
    /// The selected effects, as simulator effects.
    pub effects: Vec<Effect>,
    /// Held-out runs as measured (model-aligned).
    pub holdout: Vec<Run>,
    /// Their nominal closed-loop simulations.
    pub holdout_nominal: Vec<Option<Run>>,
    /// Their simulations with the selected effects.
    pub holdout_corrected: Vec<Option<Run>>,
    /// Fit data (smoothed states and residuals), for plots.
    pub fit_data: Vec<FitData>,
}

fn sample_period(runs: &[Run]) -> f64 {
    runs.iter()
        .find_map(|r| r.experiment.as_ref().map(|e| e.sample_period))
        .filter(|t| t.is_finite() && *t > 0.0)
        .unwrap_or_else(|| runs.first().map_or(0.0025, |r| r.duration() / (r.len().max(2) - 1) as f64))
}

/// Diagnoses the gap between `model` (in `formulation`) and logged runs.
///
/// `fit` runs are used to fit and select; `holdout` runs only to measure how far the gap
/// shrinks. Both must carry their experiment (`simgap.experiment`) to be re-simulated.
///
/// # Errors
/// [`Error::Input`] with no fit or no held-out run; [`Error::Log`] for logs whose joints do
/// not match the model, too short logs, or logs without experiment.
pub fn diagnose(model: &Model, formulation: Formulation, fit: &[Run], holdout: &[Run], options: &DiagnoseOptions, progress: &mut dyn FnMut(Progress)) -> Result<Diagnosis> {
    if fit.is_empty() {
        return Err(Error::Input("no fit log given; expected at least one".into()));
    }
    if holdout.is_empty() {
        return Err(Error::Input("no held-out log given; expected at least one (held-out runs measure how far the gap shrinks)".into()));
    }
    let joints: Vec<String> = model.joint_names().iter().map(|s| s.to_string()).collect();
    let fit_runs: Vec<Run> = fit.iter().map(|r| align_run(model, r)).collect::<Result<_>>()?;
    let hold_runs: Vec<Run> = holdout.iter().map(|r| align_run(model, r)).collect::<Result<_>>()?;
    for r in fit_runs.iter().chain(&hold_runs) {
        if r.experiment.is_none() {
            return Err(Error::Log { log: r.source.clone(), message: "no simgap.experiment metadata (controller, joints, kp, kv, sample_period); expected it to re-simulate the closed loop".into() });
        }
    }
    progress(Progress { stage: "preparing logs", done: 0, total: fit_runs.len() });
    let data: Vec<FitData> = fit_runs.iter().map(|r| FitData::new(model, formulation, r.clone(), &options.prepare)).collect::<Result<_>>()?;
    let moving = data.iter().any(|d| d.qd.iter().any(|v| v.abs() > 1e-3));
    let scales = select::parameter_scales(model);
    let ctx = Context::new(&data, sample_period(&fit_runs), &scales);
    let p = &ctx.problem;

    // nominal closed loop: fit runs (for "where") and held-out runs (the gap before)
    // every effect of the vocabulary as a candidate, fitted alone on the nominal residual
    let groups = candidate_groups(&ctx, &p.y);
    let total_sims = fit_runs.len() + hold_runs.len() * (groups.len() + 2);
    let mut sims_done = 0;
    let mut tick = |progress: &mut dyn FnMut(Progress), n: usize| {
        sims_done += n;
        progress(Progress { stage: "re-simulating", done: sims_done, total: total_sims });
    };
    let fit_nominal: Vec<(resim::RunGap, Option<Run>)> = fit_runs.par_iter().map(|r| resim::gap(model, formulation, &[], r)).collect();
    tick(progress, fit_runs.len());
    let hold_nominal: Vec<(resim::RunGap, Option<Run>)> = hold_runs.par_iter().map(|r| resim::gap(model, formulation, &[], r)).collect();
    tick(progress, hold_runs.len());
    let before_runs: Vec<resim::RunGap> = hold_nominal.iter().map(|g| g.0.clone()).collect();
    let (before, before_joint) = resim::combine(&before_runs, &hold_runs);
    let fit_before = resim::combine(&fit_nominal.iter().map(|g| g.0.clone()).collect::<Vec<_>>(), &fit_runs).0;
    let nominal_sims: Vec<Option<Run>> = fit_nominal.into_iter().map(|g| g.1).collect();
    let location = locate::locate(&joints, &data, &fit_runs, &nominal_sims);

    // which: the stepwise selection
    progress(Progress { stage: "selecting", done: 0, total: 1 });
    let mut selection = if moving { select(&ctx, &options.select) } else { select_nothing(&ctx) };
    // closed-loop check on the fit runs (never the held-out ones): a term whose removal does not
    // worsen the fit runs' simulated gap by the entry threshold changes nothing that matters
    progress(Progress { stage: "checking in closed loop", done: 0, total: selection.terms.len() });
    closed_loop_prune(model, formulation, &ctx, &fit_runs, &mut selection, options.select.min_relative_gain);
    let (_, sel_grams, _) = fit_terms(p, &data, &selection.terms);
    let sel_std = bootstrap_std(&sel_grams, 100, 7);
    let fitted = fitted_terms(&selection.terms, &selection.designs, &selection.fit.theta, Some(&sel_std));
    let selected_effects = effects::to_reports(model, &fitted);
    let sel_effects = effects::to_effects(model, &fitted);

    // how far: the selected set on held-out runs, and every candidate alone
    let hold_after: Vec<(resim::RunGap, Option<Run>)> = hold_runs.par_iter().map(|r| resim::gap(model, formulation, &sel_effects, r)).collect();
    tick(progress, hold_runs.len());
    let after_runs: Vec<resim::RunGap> = hold_after.iter().map(|g| g.0.clone()).collect();
    let (after, after_joint) = if sel_effects.is_empty() { (before, before_joint.clone()) } else { resim::combine(&after_runs, &hold_runs) };
    let fit_after = if sel_effects.is_empty() {
        fit_before
    } else {
        let g: Vec<resim::RunGap> = fit_runs.par_iter().map(|r| resim::gap(model, formulation, &sel_effects, r).0).collect();
        resim::combine(&g, &fit_runs).0
    };

    let mut candidates = Vec::new();
    for (name, terms) in groups {
        let (designs, gr, f) = fit_terms(p, &data, &terms);
        let std = bootstrap_std(&gr, 50, 11);
        let fitted_c = fitted_terms(&terms, &designs, &f.theta, Some(&std));
        let rep = effects::to_reports(model, &fitted_c).into_iter().next();
        // a candidate whose fit is not physical (negative friction, rotor inertia, mass, a gain
        // out of range) is reported but not simulated
        let unphysical: Vec<String> = fitted_c.iter().filter(|f| !select::physical(&f.term, &f.theta)).map(|f| describe_term(&f.term, &joints)).collect();
        let l2 = if unphysical.is_empty() {
            let eff = effects::to_effects(model, &fitted_c);
            let gaps: Vec<resim::RunGap> = hold_runs.par_iter().map(|r| resim::gap(model, formulation, &eff, r).0).collect();
            resim::combine(&gaps, &hold_runs).0
        } else {
            f64::NAN
        };
        tick(progress, hold_runs.len());
        let selected = selection.terms.iter().any(|t| t.effect_name() == name);
        let reason = if selected && !unphysical.is_empty() {
            format!("selected; fitted alone (without the other selected effects) it is not physical ({}), so it is not simulated alone", unphysical.join(", "))
        } else if selected {
            "selected".to_string()
        } else if !unphysical.is_empty() {
            format!("fitted alone it is not physical ({}): not simulated", unphysical.join(", "))
        } else {
            selection
                .log
                .iter()
                .find(|s| s.term.effect_name() == name)
                .map(|s| s.reason.clone())
                .unwrap_or_else(|| "not among the best terms of any selection step".to_string())
        };
        let (joints_c, parameters, uncertainty) = match rep {
            Some(r) => (r.joints, r.parameters, r.uncertainty),
            None => (vec![], Default::default(), Default::default()),
        };
        candidates.push(Candidate {
            rank: 0,
            effect: name.to_string(),
            joints: joints_c,
            parameters,
            uncertainty,
            cv_residual_reduction: if selection.nominal_cv_mse > 0.0 { 1.0 - f.cv_mse / selection.nominal_cv_mse } else { 0.0 },
            holdout_l2_after: l2,
            holdout_ratio: if before > 0.0 { l2 / before } else { f64::NAN },
            holdout_kstep_after: vec![],
            fit_kstep_cv: vec![],
            selected,
            reason,
        });
    }
    candidates.sort_by(|a, b| b.cv_residual_reduction.total_cmp(&a.cv_residual_reduction));
    for (i, c) in candidates.iter_mut().enumerate() {
        c.rank = i + 1;
    }

    let verdict = if !moving {
        "cannot tell: the fit logs show no motion (all velocities below 1e-3 rad/s), so no effect can be told apart".to_string()
    } else if selected_effects.is_empty() {
        format!("nothing significant: no candidate removes enough of the torque residual; held-out L2 {before:.3e} rad")
    } else {
        let names: Vec<String> = selected_effects.iter().map(|e| if e.joints.is_empty() { e.effect.clone() } else { format!("{} on {}", e.effect, e.joints.join(", ")) }).collect();
        format!("the gap is explained by {}; held-out L2 {:.3e} → {:.3e} rad ({:.1} % of before)", names.join("; "), before, after, 100.0 * after / before)
    };
    let selection_log = selection
        .log
        .iter()
        .map(|s| Decision { effect: s.term.effect_name().into(), joint: s.term.joint().map(|j| joints[j].clone()), cv_mse: s.cv_mse, accepted: s.accepted, reason: s.reason.clone() })
        .collect();
    let report = Report {
        simgap_version: env!("CARGO_PKG_VERSION").into(),
        model: model.name().into(),
        formulation: formulation.as_str().into(),
        joints: joints.clone(),
        fit_logs: fit_runs.iter().map(|r| r.source.clone()).collect(),
        holdout_logs: hold_runs.iter().map(|r| r.source.clone()).collect(),
        verdict,
        selected_effects,
        candidates,
        alternatives: vec![],
        notes: vec![],
        gap: Gap {
            headline: "closed_loop".into(),
            headline_reason: String::new(),
            kstep: KStep::default(),
            holdout_l2_before: before,
            holdout_l2_after: after,
            ratio: if before > 0.0 { after / before } else { f64::NAN },
            per_joint_before: before_joint,
            per_joint_after: after_joint,
            runs_before: before_runs,
            runs_after: after_runs,
            fit_l2_before: fit_before,
            fit_l2_after: fit_after,
        },
        location,
        selection_log,
        nominal_cv_mse: selection.nominal_cv_mse,
    };
    Ok(Diagnosis {
        report,
        effects: sel_effects,
        holdout: hold_runs,
        holdout_nominal: hold_nominal.into_iter().map(|g| g.1).collect(),
        holdout_corrected: hold_after.into_iter().map(|g| g.1).collect(),
        fit_data: data,
    })
}

/// Closed-loop L² over the fit runs with `terms` fitted and added.
fn fit_gap(model: &Model, formulation: Formulation, ctx: &Context<'_>, runs: &[Run], terms: &[Term]) -> f64 {
    let (designs, _, f) = fit_terms(&ctx.problem, ctx.data, terms);
    let fitted = fitted_terms(terms, &designs, &f.theta, None);
    let eff = effects::to_effects(model, &fitted);
    let gaps: Vec<resim::RunGap> = runs.par_iter().map(|r| resim::gap(model, formulation, &eff, r).0).collect();
    resim::combine(&gaps, runs).0
}

/// Backward elimination on the fit runs' closed-loop gap.
fn closed_loop_prune(model: &Model, formulation: Formulation, ctx: &Context<'_>, runs: &[Run], sel: &mut select::Selection, threshold: f64) {
    if sel.terms.is_empty() {
        return;
    }
    let mut current = fit_gap(model, formulation, ctx, runs, &sel.terms);
    loop {
        let mut best: Option<(usize, f64)> = None;
        let gaps: Vec<f64> = (0..sel.terms.len())
            .into_par_iter()
            .map(|i| {
                let mut rest = sel.terms.clone();
                rest.remove(i);
                fit_gap(model, formulation, ctx, runs, &rest)
            })
            .collect();
        for (i, g) in gaps.into_iter().enumerate() {
            if g <= current * (1.0 + threshold) + 1e-12 && best.is_none_or(|b| g < b.1) {
                best = Some((i, g));
            }
        }
        let Some((i, g)) = best else { break };
        let term = sel.terms.remove(i);
        sel.log.push(select::Step {
            term,
            cv_mse: f64::NAN,
            accepted: false,
            reason: format!("pruned in closed loop: without it the fit runs' simulated gap is {g:.3e} rad (with it {current:.3e} rad)"),
        });
        current = g;
    }
    let (designs, _, f) = fit_terms(&ctx.problem, ctx.data, &sel.terms);
    sel.designs = designs;
    sel.fit = f;
}

fn describe_term(t: &Term, joints: &[String]) -> String {
    match t.joint() {
        Some(j) => format!("{} on {}", t.effect_name(), joints[j]),
        None => t.effect_name().to_string(),
    }
}

fn select_nothing(ctx: &Context<'_>) -> select::Selection {
    let (designs, _, f) = fit_terms(&ctx.problem, ctx.data, &[]);
    select::Selection { terms: vec![], nominal_cv_mse: f.cv_mse, fit: f, designs, log: vec![] }
}

/// Every effect of the vocabulary as one candidate: per-joint families on every joint (best
/// grid member per joint against the nominal residual), whole-robot ones once.
fn candidate_groups(ctx: &Context<'_>, resid: &terms::Column) -> Vec<(&'static str, Vec<Term>)> {
    let dof = ctx.problem.dof;
    let mut groups: Vec<(&'static str, Vec<Term>)> = Vec::new();
    let fams = families(dof);
    for f in &fams {
        let t = ctx.best_of(f, resid);
        let name = t.effect_name();
        match groups.iter_mut().find(|g| g.0 == name) {
            Some(g) => g.1.push(t),
            None => groups.push((name, vec![t])),
        }
    }
    if ctx.inertial_basis.ncols() > 0 {
        groups.push(("inertial_error", vec![ctx.inertial_term()]));
    }
    groups
}
