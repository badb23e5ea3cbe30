//! Sim-to-real gap diagnosis: given a model and logs from a real robot, **where** the gap lies,
//! **which** unmodelled effect causes it, and **how far** it shrinks once that effect is added,
//! measured on held-out runs the fit never saw.
//!
//! [`diagnose`] runs in named stages:
//!
//! 1. **prepare**: each log is aligned to the model by joint name; glitch samples are found and
//!    kept out ([`robust`]); the sample period is checked against the stamps; the sensors are
//!    inferred from the samples ([`resim::infer_sensors`]); fit logs are smoothed and
//!    differentiated ([`differentiate`]) and the nominal inverse-dynamics residual
//!    `r = τ_cmd − (H q̈ + C q̇ + g)` is formed ([`dataset`]); a held-out log that repeats a fit
//!    log is refused.
//! 2. **locate**: where the gap lies ([`locate`]).
//! 3. **select**: every effect of the vocabulary is a family of candidate terms ([`terms`]),
//!    fitted by weighted least squares and compared by cross-validation of the torque residual
//!    over contiguous blocks of every fit run ([`fit`]); a forward stepwise selection proposes a
//!    set ([`select`]).
//! 4. **prune by prediction**: the set is pruned, and completed with whole effects, by the
//!    cross-validated k-step prediction error on the fit runs ([`kstep`]): each fold of each fit
//!    run is predicted by the effects fitted without it. A term stays only if prediction needs
//!    it; the whole-run closed-loop gap never drives selection.
//! 5. **refine by multiple shooting** (open-loop fit runs): the selected set, the selected set
//!    with an inertial correction in place of a payload, and the natural set of a system-
//!    identification run (inertial error of every link, Coulomb and viscous friction and rotor
//!    inertia on every joint) are fitted to k-step prediction ([`shooting`]) and scored by
//!    two-fold cross-validated prediction of the fit runs; the best replaces the selection when it
//!    predicts better.
//! 6. **screen**: every candidate alone, scored by prediction on the fit runs and, for the
//!    report, on the held-out runs.
//! 7. **how far**: the held-out runs, never used to fit or to select, are predicted k steps
//!    ahead and re-simulated in closed loop ([`resim`]) with the nominal model and with the
//!    selected set; `gap.headline` says which of the two figures answers "how far" for them.
//! 8. **report**: alternatives the data cannot tell apart, notes, the verdict ([`report`]).

pub mod bench;
pub mod dataset;
pub mod differentiate;
pub mod effects;
pub mod error;
pub mod export;
pub mod fit;
pub mod html;
pub mod inertial;
pub mod kstep;
pub mod locate;
pub mod pitfalls;
pub mod report;
pub mod residual;
pub mod resim;
pub mod robust;
pub mod select;
pub mod selfcheck;
pub mod shooting;
pub mod terms;
pub mod uncertainty;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use rayon::prelude::*;
use simgap_core::{Formulation, Model};
use simgap_sim::{ControllerKind, Effect, Run};

pub use dataset::{align_run, FitData, PrepareOptions};
pub use effects::{EffectReport, FittedTerm, Param};
pub use error::{Error, Result};
pub use report::{Alternative, Candidate, Decision, Gap, KStep, Report, RunKStep};
pub use select::SelectOptions;

use crate::fit::{bootstrap_std, fit_terms, fitted_terms, Grams};
use crate::kstep::{PredictionRun, FOLDS_PER_RUN};
use crate::select::{families, select, Context};
use crate::terms::{Term, TermDesign};

/// Options of [`diagnose`].
#[derive(Clone, Debug, Default)]
pub struct DiagnoseOptions {
    /// Data preparation.
    pub prepare: PrepareOptions,
    /// Selection thresholds.
    pub select: SelectOptions,
    /// Prediction horizons [s] of the k-step figures; empty = [`kstep::DEFAULT_HORIZONS`].
    pub horizons: Vec<f64>,
    /// When set (e.g. by Ctrl-C), the diagnosis stops at its next step with
    /// [`Error::Interrupted`].
    pub stop: Option<Arc<AtomicBool>>,
}

/// Progress of a diagnosis, for a progress bar.
#[derive(Clone, Debug)]
pub struct Progress {
    /// What is being done (the stage, and the candidate when there is one).
    pub stage: &'static str,
    /// Steps done.
    pub done: usize,
    /// Steps in all.
    pub total: usize,
}

/// Everything [`diagnose`] produced: the report and the runs behind its figures.
#[derive(Clone, Debug)]
pub struct Diagnosis {
    /// The report (see [`Report`]).
    pub report: Report,
    /// The selected effects, as simulator effects.
    pub effects: Vec<Effect>,
    /// Held-out runs as measured (model-aligned, glitches repaired).
    pub holdout: Vec<Run>,
    /// Their nominal closed-loop simulations.
    pub holdout_nominal: Vec<Option<Run>>,
    /// Their simulations with the selected effects.
    pub holdout_corrected: Vec<Option<Run>>,
    /// Fit data (smoothed states and residuals), for plots.
    pub fit_data: Vec<FitData>,
    /// The selected effects with the 95 % half-widths of each interval method on its own
    /// (`block_bootstrap`, `fold_jackknife`, `resampling` = the larger of the two; the report
    /// adds the pipeline's shared error, [`uncertainty`]), for the self-check's coverage
    /// comparison.
    pub interval_variants: Vec<(&'static str, Vec<EffectReport>)>,
}

/// Removing a term keeps it out when prediction worsens by less than this (relative).
const PRUNE_TOLERANCE: f64 = 0.02;
/// An effect joins the set when it improves prediction by at least this (relative).
const ADD_GAIN: f64 = 0.02;
/// The forward path from the nominal model is also tried when the torque-residual path
/// predicts the fit runs at more than this fraction of the nominal model's error.
const SECOND_PATH_ABOVE: f64 = 0.5;
/// Two sets whose prediction scores differ by less than this (relative) are a tie.
const TIE_TOLERANCE: f64 = 0.02;

/// The verdict says "explained" only when the selected effects leave at most this fraction of
/// the held-out gap (and no horizon gets worse); above it, "partly explained".
const EXPLAINED_BELOW: f64 = 0.5;

/// Above this fraction of the held-out gap left, the verdict says "barely explained" (the HTML
/// banner's "barely change" uses the same figure).
const BARELY_ABOVE: f64 = 0.9;

/// Everything the stages share: the model, the prepared runs, the fit context.
struct Prepared {
    fit_runs: Vec<Run>,
    hold_runs: Vec<Run>,
    data: Vec<FitData>,
    fit_pred: Vec<PredictionRun>,
    hold_pred: Vec<PredictionRun>,
    horizons: Vec<f64>,
    notes: Vec<String>,
    sensors: Vec<resim::InferredSensors>,
    passive: Vec<bool>,
}

/// Scores sets of terms by cross-validated prediction on the fit runs: the one helper for
/// "fit → effects → predict → combine".
struct Scorer<'a> {
    model: &'a Model,
    formulation: Formulation,
    ctx: &'a Context<'a>,
    prep: &'a Prepared,
    nominal: Vec<f64>,
    /// The fold of every fit window, in the order of [`Scorer::cv_errors`].
    folds: Vec<usize>,
    /// Cross-validated errors of the sets scored so far (the selection revisits sets); `None`
    /// for a set that is no answer (inadmissible, or a prediction that failed).
    memo: std::sync::Mutex<std::collections::HashMap<String, Option<std::sync::Arc<kstep::Errors>>>>,
}

impl Scorer<'_> {
    fn new<'a>(model: &'a Model, formulation: Formulation, ctx: &'a Context<'a>, prep: &'a Prepared) -> Scorer<'a> {
        let folds = prep.fit_pred.iter().flat_map(|pr| pr.fold.iter().copied()).collect();
        let mut s = Scorer { model, formulation, ctx, prep, nominal: Vec::new(), folds, memo: Default::default() };
        s.nominal = s.cv(&[]);
        s
    }

    /// Cross-validated k-step RMS per horizon on the fit runs: each fold predicted by the terms
    /// fitted without it (infinite for a set that is no answer).
    fn cv(&self, terms: &[Term]) -> Vec<f64> {
        self.cv_errors(terms).map_or_else(|| vec![f64::INFINITY; self.prep.horizons.len()], |e| e.rms())
    }

    /// The cross-validated errors of every fit window (see [`Scorer::cv`]), memoised.
    fn cv_errors(&self, terms: &[Term]) -> Option<std::sync::Arc<kstep::Errors>> {
        let mut key: Vec<String> = terms.iter().map(|t| format!("{t:?}")).collect();
        key.sort();
        let key = key.join("|");
        if let Some(v) = self.memo.lock().ok().and_then(|m| m.get(&key).cloned()) {
            return v;
        }
        let v = self.cv_uncached(terms).map(std::sync::Arc::new);
        if let Ok(mut m) = self.memo.lock() {
            m.insert(key, v.clone());
        }
        v
    }

    fn cv_uncached(&self, terms: &[Term]) -> Option<kstep::Errors> {
        let folds = self.prep.fit_runs.len() * FOLDS_PER_RUN;
        if terms.is_empty() {
            return kstep::predict_cv(self.model, self.formulation, &self.prep.fit_pred, &self.prep.horizons, folds, &|_| Vec::new()).ok();
        }
        let (designs, gr, all) = fit_terms(&self.ctx.problem, self.ctx.data, terms);
        // a set whose fit on all the fit data leaves an effect at a plausibility bound (a
        // payload at its largest mass) is no answer, however well it predicts
        if !select::admissible(&designs, terms, &all.theta) {
            return None;
        }
        let effects_of = |f: usize| -> Vec<Effect> {
            let theta = fold_theta(&gr, f);
            effects::to_effects(self.model, &fitted_terms(terms, &designs, &theta, None))
        };
        kstep::predict_cv(self.model, self.formulation, &self.prep.fit_pred, &self.prep.horizons, folds, &effects_of).ok()
    }

    /// The fold test ([`kstep::FoldTest`]) of windows' errors `errors` against the nominal
    /// model's.
    fn against_nominal(&self, errors: &kstep::Errors) -> kstep::FoldTest {
        match self.cv_errors(&[]) {
            Some(nominal) => kstep::FoldTest::of(&kstep::fold_ratios(errors, &nominal, &self.folds)),
            None => kstep::FoldTest::of(&[]),
        }
    }

    /// The fold test of the set `with` against the set `without`: whether what `with` adds
    /// helps in every part of the fit runs, not in a few windows only.
    fn gain_test(&self, with: &[Term], without: &[Term]) -> kstep::FoldTest {
        match (self.cv_errors(with), self.cv_errors(without)) {
            (Some(a), Some(b)) => kstep::FoldTest::of(&kstep::fold_ratios(&a, &b, &self.folds)),
            _ => kstep::FoldTest::of(&[]),
        }
    }

    /// One number per set: the geometric mean over horizons of its cross-validated k-step error
    /// relative to the nominal model's (lower is better).
    fn score(&self, terms: &[Term]) -> f64 {
        kstep::score(&self.cv(terms), &self.nominal)
    }
}

/// Parameters fitted without fold `f` (contiguous fifth of a fit run), under the terms'
/// physical constraints.
fn fold_theta(gr: &Grams, f: usize) -> nalgebra::DVector<f64> {
    fit::theta_without(gr, &|g| g == f)
}

fn check_stop(options: &DiagnoseOptions) -> Result<()> {
    match &options.stop {
        Some(s) if s.load(Ordering::Relaxed) => Err(Error::Interrupted),
        _ => Ok(()),
    }
}

/// Diagnoses the gap between `model` (in `formulation`) and logged runs.
///
/// `fit` runs are used to fit and select; `holdout` runs only to measure how far the gap
/// shrinks. Every run must carry its experiment (controller, gains, sample period): a replay
/// experiment for open-loop runs and for any controller that cannot be reproduced.
///
/// # Errors
/// [`Error::Input`] with no fit or no held-out run, or a held-out run that repeats a fit run;
/// [`Error::Log`] for logs whose joints do not match the model, too short logs, logs without
/// experiment or with a sample period the stamps contradict; [`Error::Interrupted`] when
/// `options.stop` is set.
pub fn diagnose(model: &Model, formulation: Formulation, fit: &[Run], holdout: &[Run], options: &DiagnoseOptions, progress: &mut dyn FnMut(Progress)) -> Result<Diagnosis> {
    // prepare
    progress(Progress { stage: "preparing logs", done: 0, total: fit.len() + holdout.len() });
    let prep = prepare(model, formulation, fit, holdout, options)?;
    check_stop(options)?;
    let joints: Vec<String> = model.joint_names().iter().map(|s| s.to_string()).collect();
    let data = &prep.data;
    let moving = data.iter().any(|d| d.qd.iter().any(|v| v.abs() > 1e-3));
    let scales = select::parameter_scales(model);
    let ctx = Context::new(data, sample_period(&prep.fit_runs), &scales);
    let p = &ctx.problem;
    let horizons = prep.horizons.clone();

    // locate: the nominal closed loop on the fit runs
    progress(Progress { stage: "locating the gap", done: 0, total: prep.fit_runs.len() });
    let fit_nominal: Vec<(resim::RunGap, Option<Run>)> = prep.fit_runs.par_iter().map(|r| resim::gap(model, formulation, &[], r)).collect();
    let nominal_sims: Vec<Option<Run>> = fit_nominal.iter().map(|g| g.1.clone()).collect();
    let location = locate::locate(&joints, data, &prep.fit_runs, &nominal_sims);
    check_stop(options)?;

    // select: stepwise on the torque residual
    progress(Progress { stage: "selecting on the torque residual", done: 0, total: 1 });
    let mut selection = if moving { select(&ctx, &options.select) } else { select_nothing(&ctx) };
    drop_passive_actuator_terms(&mut selection.terms, &prep.passive);
    check_stop(options)?;

    // candidates: every effect of the vocabulary alone
    let groups: Vec<(&'static str, Vec<Term>)> = candidate_groups(&ctx, &p.y)
        .into_iter()
        .map(|(n, mut t)| {
            drop_passive_actuator_terms(&mut t, &prep.passive);
            (n, t)
        })
        .filter(|(_, t)| !t.is_empty())
        .collect();

    // prune by prediction: cross-validated k-step error on the fit runs
    let scorer = Scorer::new(model, formulation, &ctx, &prep);
    let total_steps = groups.len() * 2 + selection.terms.len() + 4;
    let mut step = 0usize;
    let mut tick = |progress: &mut dyn FnMut(Progress), stage: &'static str| {
        step += 1;
        progress(Progress { stage, done: step.min(total_steps), total: total_steps });
    };
    let alone_cv: Vec<Vec<f64>> = groups
        .iter()
        .map(|(_, t)| {
            tick(progress, "scoring candidates by prediction");
            if options.stop.as_ref().is_some_and(|s| s.load(Ordering::Relaxed)) {
                return vec![f64::NAN; horizons.len()];
            }
            scorer.cv(t)
        })
        .collect();
    check_stop(options)?;
    let alone_score: Vec<f64> = alone_cv.iter().map(|v| kstep::score(v, &scorer.nominal)).collect();
    if moving {
        prune_and_complete(&scorer, &groups, &alone_score, &mut selection, progress, options)?;
    }
    check_stop(options)?;
    let final_score = scorer.score(&selection.terms);
    let final_cv = scorer.cv(&selection.terms);

    // refine by multiple shooting: parameters fitted to k-step prediction, kept when the
    // cross-validated prediction of the fit runs says so
    let (refined, shooting_notes) = if moving { refine_by_shooting(&scorer, &selection.terms, final_score, progress, options)? } else { (None, Vec::new()) };
    check_stop(options)?;
    let (final_score, final_cv) = match &refined {
        Some(r) => {
            let before: Vec<Term> = selection.terms.clone();
            for t in before.iter().filter(|t| !r.terms.contains(t)) {
                selection.log.push(select::Step {
                    term: t.clone(),
                    cv_mse: f64::NAN,
                    accepted: false,
                    reason: format!("replaced by {}, fitted by multiple shooting (cross-validated k-step score {:.4} against {final_score:.4})", r.name, r.score),
                });
            }
            for t in &r.terms {
                let how = if before.contains(t) { "parameters refitted by multiple shooting" } else { "added by multiple shooting" };
                selection.log.push(select::Step {
                    term: t.clone(),
                    cv_mse: f64::NAN,
                    accepted: true,
                    reason: format!(
                        "{how} as part of {}: the fit runs' cross-validated k-step error is {:.4} of the nominal model's (torque-residual fit of the set before: {final_score:.4})",
                        r.name, r.score
                    ),
                });
            }
            selection.terms = r.terms.clone();
            (r.score, r.cv.clone())
        }
        None => (final_score, final_cv),
    };

    // the selected set, fitted on all fit data, with uncertainties
    let (designs, sel_grams, sel_fit) = fit_terms(p, data, &selection.terms);
    selection.designs = designs;
    selection.fit = sel_fit;
    let (fitted, interval_variants) = match &refined {
        // shooting's own spread (see [`shooting::Shot::std`])
        Some(r) => {
            let fitted = fitted_terms(&r.terms, &r.designs, &r.shot.theta, Some(&r.shot.std));
            let own = fitted_terms(&r.terms, &r.designs, &r.shot.theta, Some(&r.own_std));
            let variants = vec![("multiple_shooting", effects::to_reports(model, &own))];
            (fitted, variants)
        }
        None => {
            let boot_std = bootstrap_std(&sel_grams, 100, 7);
            let jack_std = fit::jackknife_std(&sel_grams);
            let sel_effects = effects::to_effects(model, &fitted_terms(&selection.terms, &selection.designs, &selection.fit.theta, None));
            // the pipeline's shared error, from the fit runs re-simulated with the fitted effects
            let synthetic = if sel_effects.is_empty() { Vec::new() } else { uncertainty::synthetic_runs(model, formulation, &sel_effects, &prep.fit_runs) };
            let bias = uncertainty::pipeline_bias(model, formulation, &synthetic, &selection.terms, &selection.fit.theta, &options.prepare);
            let sel_std = uncertainty::interval_std(&boot_std, &jack_std, bias.as_ref());
            let fitted = fitted_terms(&selection.terms, &selection.designs, &selection.fit.theta, Some(&sel_std));
            // the same effects with the half-widths of each interval method alone, for the self-check
            let resampling = fit::larger_spread(&boot_std, &jack_std);
            let variants: Vec<(&'static str, Vec<EffectReport>)> = [("block_bootstrap", &boot_std), ("fold_jackknife", &jack_std), ("resampling", &resampling)]
                .into_iter()
                .map(|(name, sd)| (name, effects::to_reports(model, &fitted_terms(&selection.terms, &selection.designs, &selection.fit.theta, Some(sd)))))
                .collect();
            (fitted, variants)
        }
    };
    let sel_effects = effects::to_effects(model, &fitted);
    let mut selected_effects = effects::to_reports(model, &fitted);
    // report order: by how much each effect's removal would worsen prediction
    rank_selected(&scorer, &selection.terms, &mut selected_effects);

    // how far: held-out runs, k-step and closed loop, before and after
    progress(Progress { stage: "predicting held-out runs", done: 0, total: 3 });
    let (floor_all, floor_runs) = kstep::floor_all(&prep.hold_pred, &horizons, model.dof());
    let (before_k, before_runs_k) = kstep::predict_all(model, formulation, &[], &prep.hold_pred, &horizons)?;
    let (after_k, after_runs_k) =
        if sel_effects.is_empty() { (before_k.clone(), before_runs_k.clone()) } else { kstep::predict_all(model, formulation, &sel_effects, &prep.hold_pred, &horizons)? };
    check_stop(options)?;
    progress(Progress { stage: "re-simulating held-out runs", done: 1, total: 3 });
    let hold_nominal: Vec<(resim::RunGap, Option<Run>)> = prep.hold_runs.par_iter().map(|r| resim::gap(model, formulation, &[], r)).collect();
    let hold_after: Vec<(resim::RunGap, Option<Run>)> =
        if sel_effects.is_empty() { hold_nominal.clone() } else { prep.hold_runs.par_iter().map(|r| resim::gap(model, formulation, &sel_effects, r)).collect() };
    let before_runs: Vec<resim::RunGap> = hold_nominal.iter().map(|g| g.0.clone()).collect();
    let after_runs: Vec<resim::RunGap> = hold_after.iter().map(|g| g.0.clone()).collect();
    let (before, before_joint) = resim::combine(&before_runs, &prep.hold_runs);
    let (after, after_joint) = resim::combine(&after_runs, &prep.hold_runs);
    let fit_before = resim::combine(&fit_nominal.iter().map(|g| g.0.clone()).collect::<Vec<_>>(), &prep.fit_runs).0;
    let fit_after = if sel_effects.is_empty() {
        fit_before
    } else {
        let g: Vec<resim::RunGap> = prep.fit_runs.par_iter().map(|r| resim::gap(model, formulation, &sel_effects, r).0).collect();
        resim::combine(&g, &prep.fit_runs).0
    };
    check_stop(options)?;

    // screen: every candidate alone on the held-out runs (k-step and closed loop)
    let mut candidates = Vec::new();
    for (gi, (name, terms)) in groups.iter().enumerate() {
        tick(progress, "screening candidates on held-out runs");
        check_stop(options)?;
        let (designs, gr, f) = fit_terms(p, data, terms);
        // resampling spread only: the pipeline's shared error is measured for the selected set
        let std = fit::resampling_std(&gr, &bootstrap_std(&gr, 50, 11));
        let fitted_c = fitted_terms(terms, &designs, &f.theta, Some(&std));
        let rep = effects::to_reports(model, &fitted_c).into_iter().next();
        let eff = effects::to_effects(model, &fitted_c);
        let unphysical: Vec<String> = fitted_c.iter().filter(|f| !select::physical(&f.term, &f.theta)).map(|f| describe_term(&f.term, &joints)).collect();
        let kstep_after = kstep::predict_all(model, formulation, &eff, &prep.hold_pred, &horizons).map(|e| e.0.rms()).unwrap_or_else(|_| vec![f64::NAN; horizons.len()]);
        let gaps: Vec<resim::RunGap> = prep.hold_runs.par_iter().map(|r| resim::gap(model, formulation, &eff, r).0).collect();
        let l2 = resim::combine(&gaps, &prep.hold_runs).0;
        let selected = selection.terms.iter().any(|t| t.effect_name() == *name);
        let reason = if selected {
            "selected".to_string()
        } else if let Some(s) = selection.log.iter().rev().find(|s| s.term.effect_name() == *name) {
            s.reason.clone()
        } else if !unphysical.is_empty() {
            format!("fitted alone it is not physical ({})", unphysical.join(", "))
        } else {
            format!(
                "alone it predicts the fit runs at {:.3} of the nominal model's k-step error (cross-validated); not among the best terms of any selection step",
                alone_score[gi]
            )
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
            holdout_kstep_after: kstep_after,
            fit_kstep_cv: alone_cv[gi].clone(),
            selected,
            reason,
        });
    }
    // rank: by cross-validated prediction on the fit runs, then by torque residual removed
    let score_of = |c: &Candidate| kstep::score(&c.fit_kstep_cv, &scorer.nominal);
    candidates.sort_by(|a, b| score_of(a).total_cmp(&score_of(b)).then(b.cv_residual_reduction.total_cmp(&a.cv_residual_reduction)));
    for (i, c) in candidates.iter_mut().enumerate() {
        c.rank = i + 1;
    }

    // report: headline, alternatives, notes, verdict
    let kstep_report = KStep {
        horizons_s: horizons.clone(),
        before: before_k.rms(),
        after: after_k.rms(),
        floor: floor_all.rms(),
        per_joint_before: before_k.rms_per_joint(),
        per_joint_after: after_k.rms_per_joint(),
        runs: prep
            .hold_pred
            .iter()
            .enumerate()
            .map(|(i, pr)| RunKStep { log: pr.run.source.clone(), windows: pr.windows(), before: before_runs_k[i].rms(), after: after_runs_k[i].rms(), floor: floor_runs[i].rms() })
            .collect(),
    };
    let (headline, headline_reason) = headline(&prep, &before_runs, &after_runs, before);
    let alternatives = if moving { alternatives(&scorer, &groups, &alone_score, &selection.terms, final_score, &selected_effects) } else { Vec::new() };
    let mut notes = prep.notes.clone();
    notes.extend(shooting_notes);
    if moving {
        // a pitfall is named with what prediction says of the matching correction; a rotor
        // inertia that does not improve prediction is not named at all
        let alone = |effect: &str| groups.iter().position(|g| g.0 == effect).map(|i| alone_score[i]);
        for note in pitfalls::urdf_pitfalls(model, data) {
            let effect = if note.contains("rotor inertia") {
                Some("armature")
            } else if note.contains("inertia about") {
                Some("inertial_error")
            } else {
                None
            };
            // a correction that the selected set already makes needless (its data explained
            // otherwise) is not named: it must improve the selected set's prediction too
            let needless = |e: &str| {
                if selection.terms.iter().any(|t| t.effect_name() == e) {
                    return false;
                }
                let Some(g) = groups.iter().find(|g| g.0 == e) else { return false };
                let mut with = selection.terms.clone();
                with.extend(g.1.iter().filter(|t| fits_in(&selection.terms, t)).cloned());
                scorer.score(&with) >= final_score * (1.0 - ADD_GAIN)
            };
            let selected_it = |e: &str| selection.terms.iter().any(|t| t.effect_name() == e);
            match effect.and_then(|e| alone(e).map(|a| (e, a))) {
                Some((e, _)) if selected_it(e) => notes.push(format!("{note}; the selected {e} corrects it")),
                Some(("armature", a)) if a >= 1.0 - ADD_GAIN => {}
                Some((e, _)) if !selection.terms.is_empty() && needless(e) => {}
                Some((e, a)) => notes.push(format!("{note}; fitted alone, {e} predicts the fit runs at {a:.2} of the nominal model's cross-validated k-step error")),
                None => notes.push(note),
            }
        }
    }
    for j in &location.per_joint {
        if let (Some(a), Some(m)) = (j.actuator_residual_l2, j.mechanics_residual_l2) {
            let (part, other) =
                if a > m { ("the actuator (commanded → delivered torque)", "the mechanics") } else { ("the mechanics (delivered torque → motion)", "the actuator") };
            notes.push(format!(
                "{}: with the measured torque the gap splits into actuator {a:.3e} N·m and mechanics {m:.3e} N·m (RMS): most of it lies in {part}, less in {other}",
                j.joint
            ));
        }
    }
    notes.extend(residual_notes(&kstep_report, &final_cv, &scorer.nominal, &horizons));
    // what is left: the torque residual after the selected effects, joint by joint
    let residual_tests = if moving { residual::test(p, data, &select::residual_after(p, &selection.designs, &selection.fit.theta), &joints) } else { Vec::new() };
    notes.extend(residual_tests.iter().filter(|t| t.kind != "negligible").map(|t| t.sentence()));
    let verdict = verdict(moving, &selected_effects, &headline, &kstep_report, before, after, &before_runs);
    let selection_log = selection
        .log
        .iter()
        .map(|s| Decision {
            effect: s.term.effect_name().into(),
            joint: s.term.joint().map(|j| joints[j].clone()),
            cv_mse: s.cv_mse,
            accepted: s.accepted,
            reason: s.reason.clone(),
        })
        .collect();
    let report = Report {
        simgap_version: env!("CARGO_PKG_VERSION").into(),
        model: model.name().into(),
        formulation: formulation.as_str().into(),
        joints: joints.clone(),
        fit_logs: prep.fit_runs.iter().map(|r| r.source.clone()).collect(),
        holdout_logs: prep.hold_runs.iter().map(|r| r.source.clone()).collect(),
        verdict,
        selected_effects,
        candidates,
        alternatives,
        notes,
        residual: residual_tests,
        sensors: prep.sensors.clone(),
        gap: Gap {
            headline,
            headline_reason,
            kstep: kstep_report,
            fit_kstep_cv_before: scorer.nominal.clone(),
            fit_kstep_cv_after: final_cv,
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
    let Prepared { hold_runs, data, .. } = prep;
    Ok(Diagnosis {
        report,
        effects: sel_effects,
        holdout: hold_runs,
        holdout_nominal: hold_nominal.into_iter().map(|g| g.1).collect(),
        holdout_corrected: hold_after.into_iter().map(|g| g.1).collect(),
        fit_data: data,
        interval_variants,
    })
}

/// The controller sample period of the fit runs [s].
fn sample_period(runs: &[Run]) -> f64 {
    runs.iter()
        .find_map(|r| r.experiment.as_ref().map(|e| e.sample_period))
        .filter(|t| t.is_finite() && *t > 0.0)
        .unwrap_or_else(|| runs.first().map_or(0.0025, |r| kstep::median_spacing(&r.t)))
}

/// The prepare stage: align, check, repair glitches, infer sensors, smooth.
fn prepare(model: &Model, formulation: Formulation, fit: &[Run], holdout: &[Run], options: &DiagnoseOptions) -> Result<Prepared> {
    if fit.is_empty() {
        return Err(Error::Input("no fit log given; expected at least one".into()));
    }
    if holdout.is_empty() {
        return Err(Error::Input("no held-out log given; expected at least one (held-out runs measure how far the gap shrinks)".into()));
    }
    let mut notes = Vec::new();
    let mut fit_runs: Vec<Run> = fit.iter().map(|r| align_run(model, r)).collect::<Result<_>>()?;
    let mut hold_runs: Vec<Run> = holdout.iter().map(|r| align_run(model, r)).collect::<Result<_>>()?;
    // every run carries its experiment, with a sample period its stamps allow
    for r in fit_runs.iter().chain(&hold_runs) {
        let Some(exp) = &r.experiment else {
            return Err(Error::Log {
                log: r.source.clone(),
                message: "no experiment (controller, joints, kp, kv, sample_period) in its metadata, sidecar or the call; expected one to predict and re-simulate it (use controller 'replay' for open-loop runs or an unknown controller)".into(),
            });
        };
        if r.len() < 3 {
            return Err(Error::Log { log: r.source.clone(), message: format!("{} samples; expected a log of at least a few seconds", r.len()) });
        }
        let spacing = kstep::median_spacing(&r.t);
        let ratio = exp.sample_period / spacing;
        if !(exp.sample_period.is_finite() && exp.sample_period > 0.0 && (0.02..=50.0).contains(&ratio)) {
            return Err(Error::Log {
                log: r.source.clone(),
                message: format!(
                    "sample_period {} s, but the log's stamps are {:.6} s apart (median); expected a period within a factor 50 of the stamp spacing",
                    exp.sample_period, spacing
                ),
            });
        }
        if (ratio - 1.0).abs() > 0.05 {
            notes.push(format!(
                "{}: the experiment's sample period {} s differs from the median stamp spacing {:.6} s; the controller is simulated at the experiment's period",
                r.source, exp.sample_period, spacing
            ));
        }
    }
    // a held-out run must be one the fit never saw (a robot at rest logs the same samples twice:
    // that is no copy, and the answer will be that nothing can be told)
    for h in hold_runs.iter().filter(|h| h.q.chunks(h.dof().max(1)).any(|row| row != &h.q[..h.dof()])) {
        if let Some(f) = fit_runs.iter().find(|f| robust::same_content(f, h)) {
            return Err(Error::Input(format!("held-out log {} holds the same samples as fit log {}; a held-out run must be one the fit never saw", h.source, f.source)));
        }
    }
    // glitches: found, replaced, reported
    for r in fit_runs.iter_mut().chain(hold_runs.iter_mut()) {
        let found = robust::repair_glitches(r);
        for g in found.iter().take(5) {
            notes.push(g.to_string());
        }
        if found.len() > 5 {
            notes.push(format!("{}: {} more glitch samples replaced (the first five are listed)", r.source, found.len() - 5));
        }
    }
    // sensors as the logs show them
    let sensors: Vec<resim::InferredSensors> = fit_runs.iter().chain(&hold_runs).map(resim::infer_sensors).collect();
    let mut kinds: Vec<(String, Vec<&str>)> = Vec::new();
    for s in sensors.iter().filter(|s| s.velocity == "backward_difference" || s.counts_per_rev.is_some()) {
        let kind = format!("velocity {}{}", s.velocity.replace('_', " "), s.counts_per_rev.map_or(String::new(), |c| format!(", encoder {c} counts per revolution")));
        match kinds.iter_mut().find(|k| k.0 == kind) {
            Some(k) => k.1.push(&s.log),
            None => kinds.push((kind, vec![&s.log])),
        }
    }
    for (kind, logs) in kinds {
        notes.push(format!("sensors inferred from the logs ({}): {kind}; the re-simulated controller sees the same", logs.join(", ")));
    }
    // passive joints: commanded effort always zero in every run
    let n = model.dof();
    let passive: Vec<bool> = (0..n).map(|j| fit_runs.iter().chain(&hold_runs).all(|r| r.tau.iter().skip(j).step_by(n).all(|v| *v == 0.0))).collect();
    for (j, p) in passive.iter().enumerate() {
        if *p {
            notes.push(format!("joint {} is passive (commanded effort always 0): actuator effects (gain, offset, saturation) are not tried on it", model.joint_names()[j]));
        }
    }
    let data: Vec<FitData> = fit_runs.iter().map(|r| FitData::new(model, formulation, r.clone(), &options.prepare)).collect::<Result<_>>()?;
    let horizons = if options.horizons.is_empty() { kstep::DEFAULT_HORIZONS.to_vec() } else { options.horizons.clone() };
    if let Some(h) = horizons.iter().find(|h| !(h.is_finite() && **h > 0.0)) {
        return Err(Error::Input(format!("prediction horizon {h} s; expected positive numbers")));
    }
    let sensor_of = |r: &Run| sensors.iter().find(|s| s.log == r.source).map(|s| s.params()).unwrap_or_else(simgap_sim::SensorParams::exact);
    let fit_pred: Vec<PredictionRun> = fit_runs
        .iter()
        .enumerate()
        .map(|(i, r)| PredictionRun::new(r.clone(), &horizons, options.prepare.window, sensor_of(r), i * FOLDS_PER_RUN, kstep::FIT_WINDOWS_PER_RUN))
        .collect();
    let hold_pred: Vec<PredictionRun> =
        hold_runs.iter().map(|r| PredictionRun::new(r.clone(), &horizons, options.prepare.window, sensor_of(r), 0, kstep::MAX_WINDOWS_PER_RUN)).collect();
    if let Some(pr) = hold_pred.iter().find(|p| p.windows() == 0) {
        return Err(Error::Log {
            log: pr.run.source.clone(),
            message: format!("too short to predict: {:.3} s; expected at least the shortest horizon ({} s) plus the smoothing window", pr.run.duration(), horizons[0]),
        });
    }
    Ok(Prepared { fit_runs, hold_runs, data, fit_pred, hold_pred, horizons, notes, sensors, passive })
}

/// Removes torque gain, offset and saturation terms of passive joints (nothing drives them).
fn drop_passive_actuator_terms(terms: &mut Vec<Term>, passive: &[bool]) {
    terms.retain(|t| !(matches!(t, Term::Gain(_) | Term::Offset(_) | Term::Saturation { .. }) && t.joint().is_some_and(|j| passive[j])));
}

/// Whether `t` fits in `terms`: one term per slot.
fn fits_in(terms: &[Term], t: &Term) -> bool {
    let gain_vs_inertia = |a: &Term, b: &Term| matches!(a, Term::Gain(_)) && matches!(b, Term::InertialError { .. });
    !terms.iter().any(|s| s.slot() == t.slot() || gain_vs_inertia(s, t) || gain_vs_inertia(t, s))
}

/// The prune stage: two paths, the better kept. (a) The torque-residual selection pruned by
/// backward elimination and completed with whole effects, by cross-validated prediction;
/// (b) forward selection of whole effects by prediction from the nominal model, then pruned
/// (only when (a) does not reach [`SECOND_PATH_ABOVE`]).
/// A set that does not beat the nominal model's prediction by [`ADD_GAIN`] is emptied: the
/// data then support no effect.
fn prune_and_complete(
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
        let Some((set, s, out, into)) = exchange(scorer, groups, alone_score, &terms, score) else { break };
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
fn refine_by_prediction(
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

/// A set of terms whose parameters multiple shooting fitted.
struct Refined {
    /// What the set is, in words.
    name: String,
    terms: Vec<Term>,
    designs: Vec<TermDesign>,
    /// The fit on all fit runs; its `std` is the reported spread (shooting's own, the halves'
    /// disagreement and the torque-residual fit's, combined).
    shot: shooting::Shot,
    /// Shooting's own standard deviations, `σ² (JᵀJ)⁻¹` alone.
    own_std: nalgebra::DVector<f64>,
    /// Cross-validated k-step RMS per horizon on the fit runs [rad].
    cv: Vec<f64>,
    /// Its score against the nominal model ([`kstep::score`]).
    score: f64,
}

/// A set tried by the shooting stage: its two-fold cross-validation.
struct Tried {
    name: String,
    terms: Vec<Term>,
    designs: Vec<TermDesign>,
    /// The fits on each half of the fit runs.
    halves: Vec<nalgebra::DVector<f64>>,
    cv: Vec<f64>,
    score: f64,
    /// Whether its gain over the nominal model holds fold by fold.
    test: kstep::FoldTest,
}

/// The shooting stage, for open-loop fit runs: the selected set, the selected set with an
/// inertial correction in place of a payload, and the physically natural set of a system-
/// identification run (inertial error of every link, Coulomb and viscous friction and rotor
/// inertia on every joint), each fitted by multiple shooting ([`shooting`]) from the start of
/// lowest cost among its torque-residual fit, the same with the URDF's inertia, and the answers
/// of the sets tried before it (shared terms kept, the others at 0).
///
/// Feedback runs keep the torque-residual fit: their torque residual is well conditioned (the
/// controller keeps the motion near its reference, accelerations are smooth), while in a k-step
/// window the controller corrects the model's errors, so prediction constrains the parameters
/// less. (On the synthetic demo, shooting predicted the held-out run better but moved the
/// elbow's viscous friction from 2.3 % to 3.7 % off the hidden value.)
///
/// Each set is scored by two-fold cross-validated k-step prediction of the fit runs: the fit runs'
/// folds are split into even and odd ones (alternate fifths of every run); each half is fitted
/// (torque-residual start and shooting) on the other half alone and predicted with it. The set of
/// lowest score replaces the selection when it beats `current` (the selected set's score with its
/// torque-residual fit, cross-validated over every fold) by [`ADD_GAIN`]; it is then refitted on
/// all fit runs. Returns it (or none) and notes saying what was tried.
fn refine_by_shooting(
    scorer: &Scorer<'_>,
    selected: &[Term],
    current: f64,
    progress: &mut dyn FnMut(Progress),
    options: &DiagnoseOptions,
) -> Result<(Option<Refined>, Vec<String>)> {
    let (model, formulation, ctx, prep) = (scorer.model, scorer.formulation, scorer.ctx, scorer.prep);
    let n = model.dof();
    let has_inertial = ctx.inertial_basis.ncols() > 0;
    let open_loop = prep.fit_runs.iter().all(|r| r.experiment.as_ref().is_none_or(|e| e.controller == ControllerKind::Replay));
    if !open_loop {
        return Ok((None, Vec::new()));
    }
    let mut sets: Vec<(String, Vec<Term>)> = Vec::new();
    let fitted_columns = |terms: &[Term]| terms.iter().any(|t| !matches!(t, Term::Saturation { .. } | Term::Delay { .. } | Term::CoriolisStructure));
    if fitted_columns(selected) {
        sets.push(("the selected set".into(), selected.to_vec()));
    }
    if has_inertial && selected.iter().any(|t| matches!(t, Term::Payload { .. })) {
        let mut with: Vec<Term> = selected.iter().filter(|t| !matches!(t, Term::Payload { .. })).cloned().collect();
        with.push(ctx.inertial_term());
        sets.push(("the selected set with an inertial correction of every link in place of the payload".into(), with));
    }
    if has_inertial {
        let mut natural = vec![ctx.inertial_term()];
        for j in 0..n {
            natural.push(Term::Coulomb(j));
            natural.push(Term::Viscous(j));
            if !prep.passive[j] {
                natural.push(Term::Armature(j));
            }
        }
        sets.push(("an inertial correction of every link with Coulomb and viscous friction and rotor inertia on every joint".into(), natural));
    }
    if sets.is_empty() {
        return Ok((None, Vec::new()));
    }
    let sopts = shooting::Options::default();
    let shoot_runs = shooting::shooting_runs(&prep.fit_pred, options.prepare.window, &sopts);
    let stop = options.stop.as_deref();
    // starts: the torque-residual fit, and the same with the URDF's inertia
    let starts = |designs: &[TermDesign], theta: nalgebra::DVector<f64>| -> Vec<nalgebra::DVector<f64>> {
        let mut c = 0;
        let mut urdf = theta.clone();
        let mut inertial = false;
        for d in designs {
            if d.inertial.is_some() {
                urdf.rows_mut(c, d.cols.len()).fill(0.0);
                inertial = true;
            }
            c += d.cols.len();
        }
        if inertial {
            vec![theta, urdf]
        } else {
            vec![theta]
        }
    };
    // θ of `to` from the answer `theta` of the set `from`: shared terms keep their values, the
    // others start at 0 (no friction, no rotor inertia, the URDF's inertia), so that a larger set
    // starts where a smaller one ended
    let transfer = |from: &Tried, theta: &nalgebra::DVector<f64>, to: &[Term], to_designs: &[TermDesign]| -> nalgebra::DVector<f64> {
        let k: usize = to_designs.iter().map(|d| d.cols.len()).sum();
        let mut out = nalgebra::DVector::zeros(k);
        let mut c = 0;
        for (t, d) in to.iter().zip(to_designs) {
            let mut cf = 0;
            for (tf, df) in from.terms.iter().zip(&from.designs) {
                if tf == t && df.cols.len() == d.cols.len() {
                    out.rows_mut(c, d.cols.len()).copy_from(&theta.rows(cf, d.cols.len()));
                }
                cf += df.cols.len();
            }
            c += d.cols.len();
        }
        out
    };
    let mut tried: Vec<Tried> = Vec::new();
    for (si, (name, terms)) in sets.iter().enumerate() {
        progress(Progress { stage: "refining by multiple shooting", done: si, total: sets.len() + 1 });
        check_stop(options)?;
        let (designs, gr, _) = fit_terms(&ctx.problem, ctx.data, terms);
        let mut merged: Vec<kstep::Errors> =
            prep.fit_pred.iter().map(|pr| kstep::Errors { horizons: prep.horizons.len(), dof: n, sq: vec![f64::NAN; pr.windows() * prep.horizons.len() * n] }).collect();
        let mut halves = Vec::new();
        for half in 0..2 {
            let held = |f: usize| (f % FOLDS_PER_RUN) % 2 == half;
            let keep = |r: usize, w: usize| !held(shoot_runs[r].fold[w]);
            let problem = shooting::Problem { model, formulation, terms, designs: &designs, runs: &shoot_runs, keep: &keep, options: &sopts };
            let mut from = starts(&designs, fit::theta_without(&gr, &held));
            from.extend(tried.iter().map(|t| transfer(t, &t.halves[half], terms, &designs)));
            let shot = shooting::fit(&problem, &from, stop)?;
            let eff = effects::to_effects(model, &fitted_terms(terms, &designs, &shot.theta, None));
            let errs: Vec<kstep::Errors> =
                prep.fit_pred.par_iter().map(|pr| kstep::predict(model, formulation, &eff, pr, &prep.horizons, &|w| held(pr.fold[w]))).collect::<Result<_>>()?;
            for (m, e) in merged.iter_mut().zip(&errs) {
                for (a, v) in m.sq.iter_mut().zip(&e.sq) {
                    if v.is_finite() {
                        *a = *v;
                    }
                }
            }
            halves.push(shot.theta);
        }
        let mut all = kstep::Errors { horizons: prep.horizons.len(), dof: n, sq: Vec::new() };
        for m in &merged {
            all.sq.extend_from_slice(&m.sq);
        }
        let cv = all.rms();
        let score = kstep::score(&cv, &scorer.nominal);
        let test = scorer.against_nominal(&all);
        tried.push(Tried { name: name.clone(), terms: terms.clone(), designs, halves, cv, score, test });
    }
    let mut notes: Vec<String> = tried
        .iter()
        .map(|r| {
            format!(
                "multiple shooting ({} s windows restarted from the measured state, errors at {} instants per window; two-fold cross-validation over alternate fifths of every fit run): {} predicts the fit runs at {:.4} of the nominal model's k-step error (fold by fold: upper 2-standard-error bound {:.3}, worst fold {:.3}; torque-residual fit of the selected set: {current:.4})",
                sopts.window, sopts.points, r.name, r.score, r.test.bound, r.test.worst
            )
        })
        .collect();
    let Some(bi) = (0..tried.len()).min_by(|a, b| tried[*a].score.total_cmp(&tried[*b].score)) else { return Ok((None, notes)) };
    if tried[bi].score < current * (1.0 - ADD_GAIN) && !tried[bi].test.holds(PRUNE_TOLERANCE, ADD_GAIN) {
        notes.push(format!(
            "multiple shooting: {} predicts the fit runs at {:.4} of the nominal model's k-step error, but not in every part of them (fold by fold, the upper 2-standard-error bound of that ratio is {:.3} and the worst fold's {:.3}): the torque-residual answer is kept",
            tried[bi].name, tried[bi].score, tried[bi].test.bound, tried[bi].test.worst
        ));
        return Ok((None, notes));
    }
    if !(tried[bi].score < current * (1.0 - ADD_GAIN)) {
        notes.push(format!(
            "multiple shooting does not predict the fit runs better than the torque-residual fit by {:.0} %: the torque-residual parameters are kept",
            100.0 * ADD_GAIN
        ));
        return Ok((None, notes));
    }
    // the chosen set on all fit runs
    progress(Progress { stage: "refining by multiple shooting", done: sets.len(), total: sets.len() + 1 });
    let best = tried.swap_remove(bi);
    let keep = |_: usize, _: usize| true;
    let (_, _, f) = fit_terms(&ctx.problem, ctx.data, &best.terms);
    let problem = shooting::Problem { model, formulation, terms: &best.terms, designs: &best.designs, runs: &shoot_runs, keep: &keep, options: &sopts };
    // starts: the torque-residual fit (and with the URDF's inertia), the two halves' answers
    let mut from = starts(&best.designs, f.theta.clone());
    from.extend(best.halves.iter().cloned());
    let mut shot = shooting::fit(&problem, &from, stop)?;
    notes.push(format!(
        "the parameters of the selected effects are fitted by multiple shooting on all fit runs (normalised k-step cost {:.3e} → {:.3e} in {} iterations); their 95 % intervals are 1.96 σ with σ² the sum of σ² (JᵀJ)⁻¹ of the shooting residuals, a quarter of the squared difference of the two halves' answers, and the squared difference from the torque-residual fit of the same set (the disagreement of two methods bounds the error either makes)",
        shot.cost_start, shot.cost, shot.iterations
    ));
    // the reported spread: σ² (JᵀJ)⁻¹ alone treats the errors along a window as independent
    // and misses what the whole record shares (the self-check found 38 % coverage with it);
    // the two halves' disagreement (σ of a full-data answer ≈ |θ₁ − θ₂| / 2) and the other
    // method's answer add what it misses (shooting's own σ is kept as an interval variant)
    let shot_std = shot.std.clone();
    let halves = match (best.halves.first(), best.halves.get(1)) {
        (Some(a), Some(b)) if a.len() == shot.theta.len() && b.len() == shot.theta.len() => Some((a, b)),
        _ => None,
    };
    for i in 0..shot.theta.len() {
        let half = halves.map_or(0.0, |(a, b)| 0.5 * (a[i] - b[i]));
        let method = f.theta.get(i).map_or(0.0, |t| shot.theta[i] - t);
        let total = (shot.std[i].powi(2) + half.powi(2) + method.powi(2)).sqrt();
        shot.std[i] = if total.is_finite() { total } else { shot.std[i] };
    }
    // a friction, rotor inertia or payload at its lower bound 0 is no effect: left out
    let (mut terms, mut designs, mut theta, mut std, mut own_std) = (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut none: Vec<String> = Vec::new();
    let mut c = 0;
    for (t, d) in best.terms.iter().zip(&best.designs) {
        let k = d.cols.len();
        let zero = d.inertial.is_none() && k > 0 && (0..k).all(|a| shot.theta[c + a] == 0.0 && d.lo.get(a) == Some(&0.0));
        if zero {
            none.push(describe_term(t, &scorer.model.joint_names().iter().map(|s| s.to_string()).collect::<Vec<_>>()));
        } else {
            terms.push(t.clone());
            designs.push(d.clone());
            theta.extend_from_slice(&shot.theta.as_slice()[c..c + k]);
            std.extend_from_slice(&shot.std.as_slice()[c..c + k]);
            own_std.extend_from_slice(&shot_std.as_slice()[c..c + k]);
        }
        c += k;
    }
    if !none.is_empty() {
        notes.push(format!("fitted by multiple shooting at their bound 0, so left out: {}", none.join(", ")));
    }
    let shot = shooting::Shot { theta: nalgebra::DVector::from_vec(theta), std: nalgebra::DVector::from_vec(std), ..shot };
    Ok((Some(Refined { name: best.name, terms, designs, shot, own_std: nalgebra::DVector::from_vec(own_std), cv: best.cv, score: best.score }), notes))
}

/// The null test of an effect added by prediction: how much the set `with` improves on the set
/// `base` (the ratio of their cross-validated k-step scores) on the fit runs re-simulated with
/// `base`'s effects fitted on the fit runs (the same torques, references and sensors, and
/// nothing else hidden). An effect that improves those runs as much compensates a bias of the
/// pipeline, not of the robot. `None` when a run cannot be re-simulated.
fn null_ratio(scorer: &Scorer<'_>, base: &[Term], with: &[Term], options: &DiagnoseOptions) -> Option<f64> {
    let effects = if base.is_empty() {
        Vec::new()
    } else {
        let (designs, _, f) = fit_terms(&scorer.ctx.problem, scorer.ctx.data, base);
        effects::to_effects(scorer.model, &fitted_terms(base, &designs, &f.theta, None))
    };
    let synthetic = uncertainty::synthetic_runs(scorer.model, scorer.formulation, &effects, &scorer.prep.fit_runs);
    if synthetic.len() != scorer.prep.fit_runs.len() {
        return None;
    }
    let prep = prepare(scorer.model, scorer.formulation, &synthetic, &scorer.prep.hold_runs, options).ok()?;
    let scales = select::parameter_scales(scorer.model);
    let ctx = Context::new(&prep.data, sample_period(&prep.fit_runs), &scales);
    let null = Scorer::new(scorer.model, scorer.formulation, &ctx, &prep);
    let r = null.score(with) / null.score(base);
    r.is_finite().then_some(r)
}

/// Orders the selected effects by how much prediction worsens without each (most needed first).
fn rank_selected(scorer: &Scorer<'_>, terms: &[Term], reports: &mut [EffectReport]) {
    if reports.len() < 2 {
        return;
    }
    let loss: Vec<(String, f64)> = reports
        .par_iter()
        .map(|r| {
            let rest: Vec<Term> = terms.iter().filter(|t| t.effect_name() != r.effect).cloned().collect();
            (r.effect.clone(), scorer.score(&rest))
        })
        .collect();
    let of = |name: &str| loss.iter().find(|l| l.0 == name).map_or(0.0, |l| l.1);
    reports.sort_by(|a, b| of(&b.effect).total_cmp(&of(&a.effect)));
}

/// Which figure answers "how far", and why.
fn headline(prep: &Prepared, before_runs: &[resim::RunGap], after_runs: &[resim::RunGap], before: f64) -> (String, String) {
    let open_loop: Vec<&str> = prep.hold_runs.iter().filter(|r| r.experiment.as_ref().is_none_or(|e| e.controller == ControllerKind::Replay)).map(|r| r.source.as_str()).collect();
    if !open_loop.is_empty() {
        return (
            "k_step".into(),
            format!("held-out run(s) {} are open-loop replays: a whole-run simulation of an open loop measures how fast trajectories diverge, not the model", open_loop.join(", ")),
        );
    }
    if let Some(g) = before_runs.iter().chain(after_runs).find(|g| g.status != "completed") {
        return ("k_step".into(), format!("the closed-loop simulation of {} did not complete ({}): its whole-run figure measures divergence", g.log, g.status));
    }
    // the closed loop must stay near the measured run: within a fifth of the motion's spread
    let spread = {
        let (mut s, mut c) = (0.0, 0usize);
        for r in &prep.hold_runs {
            let n = r.dof();
            for j in 0..n {
                let col: Vec<f64> = r.q.iter().skip(j).step_by(n).copied().collect();
                let m = col.iter().sum::<f64>() / col.len().max(1) as f64;
                s += col.iter().map(|v| (v - m).powi(2)).sum::<f64>();
                c += col.len();
            }
        }
        (s / c.max(1) as f64 * prep.hold_runs.first().map_or(1, Run::dof) as f64).sqrt()
    };
    if before > 0.2 * spread {
        return ("k_step".into(), format!("the nominal closed-loop simulation strays {before:.3e} rad (L²) from the measured runs, more than a fifth of the motion's spread ({spread:.3e} rad): the whole-run figure would measure divergence"));
    }
    ("closed_loop".into(), "every held-out run is a feedback loop and its closed-loop simulation stays near the measured run: the whole-run L² (eq. 127) is meaningful; k-step figures are given beside it".into())
}

/// The candidates (indices into `groups`) tried in place of the selected effect `name`: the two
/// best alone among those scoring alone at most `within` times `name`'s own score, and, for an
/// inertial correction, its exact equivalents (a payload: a point mass on the last link; a
/// torque gain: all links scaled) whatever they score alone.
fn swap_candidates(groups: &[(&'static str, Vec<Term>)], alone_score: &[f64], names: &[String], name: &str, within: f64) -> Vec<usize> {
    let Some(si) = groups.iter().position(|g| g.0 == name) else { return Vec::new() };
    let mut others: Vec<usize> = (0..groups.len()).filter(|&i| i != si && !names.iter().any(|n| n == groups[i].0) && alone_score[i] <= alone_score[si] * within).collect();
    others.sort_by(|a, b| alone_score[*a].total_cmp(&alone_score[*b]));
    others.truncate(2);
    if name == "inertial_error" {
        for partner in ["payload", "torque_gain"] {
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
fn swapped(terms: &[Term], name: &str, with: &[Term]) -> Vec<Term> {
    let mut set: Vec<Term> = terms.iter().filter(|t| t.effect_name() != name).cloned().collect();
    set.extend(with.iter().filter(|t| fits_in(&set, t)).cloned().collect::<Vec<_>>());
    set
}

/// The exchange step of the selection: one selected effect replaced by another candidate
/// ([`swap_candidates`]) when that predicts the fit runs better by [`ADD_GAIN`] and the gain
/// holds fold by fold. A stepwise selection that took an effect first (e.g. an inertial
/// correction, which absorbs most of what per-joint torque gains do to the torque residual)
/// cannot otherwise undo it. Returns the new set, its score and what was swapped for what.
fn exchange(scorer: &Scorer<'_>, groups: &[(&'static str, Vec<Term>)], alone_score: &[f64], terms: &[Term], current: f64) -> Option<(Vec<Term>, f64, String, &'static str)> {
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

/// Effect sets the data cannot tell apart from the selected one: exact equivalences, and swaps
/// of one selected effect for another whose prediction score ties within the tolerance.
fn alternatives(scorer: &Scorer<'_>, groups: &[(&'static str, Vec<Term>)], alone_score: &[f64], terms: &[Term], current: f64, selected: &[EffectReport]) -> Vec<Alternative> {
    let names: Vec<String> = selected.iter().map(|e| e.effect.clone()).collect();
    let with = |drop: &str, add: &str| -> Vec<String> {
        let mut v: Vec<String> = names.iter().filter(|n| n.as_str() != drop).cloned().collect();
        if !v.iter().any(|n| n == add) {
            v.push(add.to_string());
        }
        v
    };
    let mut out = Vec::new();
    // exact equivalences
    for e in selected {
        match e.effect.as_str() {
            "payload" => out.push(Alternative {
                effects: with("payload", "inertial_error"),
                why: "a point mass on the last link is an inertial error of the last link: the same dynamics".into(),
            }),
            "torque_gain" => {
                if let Some(Param::PerJoint(k)) = e.parameters.get("k") {
                    let mean = k.iter().sum::<f64>() / k.len().max(1) as f64;
                    if e.joints.len() == scorer.model.dof() && k.iter().all(|x| (x - mean).abs() <= 0.02 * mean.abs()) {
                        out.push(Alternative {
                            effects: with("torque_gain", "inertial_error"),
                            why: format!(
                                "a torque gain equal on every joint (k ≈ {mean:.3}) and every link's inertial parameters scaled by 1/k are the same dynamics up to friction"
                            ),
                        });
                    }
                }
            }
            "stribeck_friction" => {
                if let Some(Param::PerJoint(vs)) = e.parameters.get("vs") {
                    if vs.iter().all(|v| *v <= 0.02) {
                        out.push(Alternative {
                            effects: with("stribeck_friction", "coulomb_friction"),
                            why: "the Stribeck velocity is below what these runs resolve: Coulomb friction is the same effect here".into(),
                        });
                    }
                }
            }
            _ => {}
        }
    }
    // ties: swap one selected effect for a candidate of similar prediction on its own
    if current.is_finite() && !terms.is_empty() {
        let mut swaps: Vec<(String, usize)> = Vec::new();
        for name in &names {
            for i in swap_candidates(groups, alone_score, &names, name, 1.0 + 5.0 * TIE_TOLERANCE) {
                swaps.push((name.clone(), i));
            }
        }
        let scored: Vec<(String, usize, f64, bool)> = swaps
            .par_iter()
            .map(|(name, i)| {
                let set = swapped(terms, name, &groups[*i].1);
                let s = scorer.score(&set);
                // a swap better on the whole but not fold by fold is named with that said
                let holds = s < current * (1.0 - TIE_TOLERANCE) && scorer.gain_test(&set, terms).holds(PRUNE_TOLERANCE, ADD_GAIN);
                (name.clone(), *i, s, holds)
            })
            .collect();
        for (name, i, s, holds) in scored {
            if s <= current * (1.0 + TIE_TOLERANCE) {
                let effects = with(&name, groups[i].0);
                if !out.iter().any(|a: &Alternative| a.effects == effects) {
                    let why = if s < current * (1.0 - TIE_TOLERANCE) {
                        format!(
                            "replacing {name} by {} predicts the fit runs better on the whole (cross-validated k-step score {s:.4} against {current:.4}){}",
                            groups[i].0,
                            if holds { "" } else { " but not in every part of them" }
                        )
                    } else {
                        format!(
                            "replacing {name} by {} predicts the fit runs as well (cross-validated k-step score {s:.4} against {current:.4}, within {:.0} %)",
                            groups[i].0,
                            100.0 * TIE_TOLERANCE
                        )
                    };
                    out.push(Alternative { effects, why });
                }
            }
        }
    }
    out
}

/// What is left after the selected effects, in words.
fn residual_notes(k: &KStep, fit_cv: &[f64], fit_nominal: &[f64], horizons: &[f64]) -> Vec<String> {
    let mut notes = Vec::new();
    for (i, h) in horizons.iter().enumerate() {
        let (a, f) = (k.after.get(i).copied().unwrap_or(f64::NAN), k.floor.get(i).copied().unwrap_or(f64::NAN));
        if a.is_finite() && f.is_finite() && a >= f {
            notes.push(format!("at {h} s the corrected model predicts the held-out runs no better than constant-velocity extrapolation ({a:.3e} vs {f:.3e} rad): at this horizon the figures say nothing about physics"));
        }
    }
    if let (Some(a), Some(b)) = (fit_cv.first(), fit_nominal.first()) {
        if a.is_finite() && b.is_finite() && *b > 0.0 && a / b > 0.5 {
            notes.push(format!("after the selected effects the fit runs' cross-validated k-step error at {} s is still {:.0} % of the nominal model's: much of the gap is left (the residual test of each joint, in these notes, says whether it is noise or structure)", horizons[0], 100.0 * a / b));
        }
    }
    notes
}

/// The one-sentence conclusion; never says "explained" when the held-out figure got worse or
/// the nominal simulation diverged.
fn verdict(moving: bool, selected: &[EffectReport], headline: &str, k: &KStep, before: f64, after: f64, before_runs: &[resim::RunGap]) -> String {
    if !moving {
        return "cannot tell: the fit logs show no motion (all velocities below 1e-3 rad/s), so no effect can be told apart".to_string();
    }
    let names: Vec<String> = selected.iter().map(|e| if e.joints.is_empty() { e.effect.clone() } else { format!("{} on {}", e.effect, e.joints.join(", ")) }).collect();
    let (figure, b, a) = if headline == "closed_loop" {
        ("closed-loop L²".to_string(), before, after)
    } else {
        let i = k.horizons_s.len().saturating_sub(1).min(k.horizons_s.iter().position(|h| *h >= 0.5).unwrap_or(usize::MAX));
        (
            format!("k-step error at {} s", k.horizons_s.get(i).copied().unwrap_or(f64::NAN)),
            k.before.get(i).copied().unwrap_or(f64::NAN),
            k.after.get(i).copied().unwrap_or(f64::NAN),
        )
    };
    let diverged = before_runs.iter().any(|g| g.status != "completed");
    let diverged_note = if diverged && headline != "closed_loop" { " (the nominal closed-loop simulation diverged, so the closed-loop figure is not used)" } else { "" };
    if selected.is_empty() {
        return format!("nothing significant: no effect improves the cross-validated prediction of the fit runs; held-out {figure} {b:.3e} rad{diverged_note}");
    }
    if !(a < b) {
        return format!(
            "not explained: the effects the fit runs support ({}) do not improve the held-out {figure}: {b:.3e} → {a:.3e} rad (worse or equal){diverged_note}",
            names.join("; ")
        );
    }
    // every horizon must improve for the gap to be called explained
    let worse: Vec<String> =
        k.horizons_s.iter().zip(k.before.iter().zip(&k.after)).filter(|(_, (b, a))| !(a < b)).map(|(h, (b, a))| format!("{h} s ({b:.3e} → {a:.3e} rad)")).collect();
    if !worse.is_empty() {
        return format!(
            "partly explained: with {} the held-out {figure} goes {b:.3e} → {a:.3e} rad, but the k-step error is worse or equal at {}{diverged_note}",
            names.join("; "),
            worse.join(", ")
        );
    }
    // how much of the gap is gone decides the word: a small improvement is no explanation
    let ratio = a / b;
    if ratio > BARELY_ABOVE {
        return format!(
            "barely explained: with {} the held-out {figure} goes {b:.3e} → {a:.3e} rad ({:.1} % of before), a change of the size noise and small unmodelled effects make{diverged_note}",
            names.join("; "),
            100.0 * ratio
        );
    }
    if ratio > EXPLAINED_BELOW {
        return format!(
            "partly explained: {} shrink the held-out {figure} {b:.3e} → {a:.3e} rad ({:.1} % of before); more than half of the gap remains{diverged_note}",
            names.join("; "),
            100.0 * ratio
        );
    }
    format!("the gap is explained by {}; held-out {figure} {b:.3e} → {a:.3e} rad ({:.1} % of before){diverged_note}", names.join("; "), 100.0 * ratio)
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
