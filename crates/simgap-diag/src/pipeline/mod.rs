//! The pipeline: [`diagnose`] runs the stages in order, one call per stage, each in its own
//! module taking what the stage before produced; [`runner::Stages`] reports progress and honours
//! the stop flag.

mod candidates;
mod chosen;
mod drive_swap;
mod how_far;
mod intervals;
mod locate;
mod notes;
mod parsimony;
mod play;
mod prune;
mod refine;
mod report;
mod runner;
mod screen;
mod select;
mod what_is_left;

use simgap_core::{Formulation, Model};
use simgap_sim::{Effect, Run};

use crate::error::Result;
use crate::options::{DiagnoseOptions, Progress};
use crate::prediction::kstep;
use crate::prepare::{prepare, sample_period};
use crate::report::{Diagnosis, KStep, WindowStart};
use crate::select::scorer::Scorer;
use crate::select::{parameter_scales, Context};
use runner::{shown, Stages};

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
    let mut stages = Stages::new(options, progress);
    // prepare: every log aligned, checked, repaired, smoothed once
    let prep = stages.run(shown("preparing logs", 0, fit.len() + holdout.len()), |_| prepare(model, formulation, fit, holdout, &options.prepare, &options.horizons))?;
    // the fit context every later stage fits in: the torque-residual problem and its caches
    let ctx = Context::new(&prep.data, sample_period(&prep.fit_runs), &parameter_scales(model));
    // locate: where the gap lies, from the nominal closed loop on the fit runs
    let located = stages.run(shown("locating the gap", 0, prep.fit_runs.len()), |_| Ok(locate::locate_gap(model, formulation, &prep)))?;
    // select: forward stepwise on the torque residual
    let selection = stages.run(shown("selecting on the torque residual", 0, 1), |_| Ok(select::select_on_residual(&ctx, &prep, &options.select)))?;
    // the k-step scorer every stage by prediction scores sets with
    let scorer = Scorer::new(model, formulation, &ctx, &prep);
    // candidates: every effect alone, scored by prediction
    let candidates = stages.run(None, |s| Ok(candidates::candidates(&ctx, &scorer, &prep, selection.terms.len(), s)))?;
    // prune: the selection pruned, completed and exchanged by prediction
    let selection = stages.run(None, |s| prune::prune(&scorer, &candidates, selection, &prep, s))?;
    // parsimony: a richer effect the simpler nested in it matches becomes the simpler
    let chosen = stages.run(None, |_| Ok(parsimony::parsimony(&scorer, &prep, selection)))?;
    // play: the backlash of each drive whose rotor inertia the set holds, searched by prediction
    let chosen = stages.run(None, |s| play::play(&scorer, &prep, chosen, s))?;
    // refine: the set fitted by multiple shooting where prediction says so
    let chosen = stages.run(None, |s| refine::refine(&scorer, &prep, chosen, s))?;
    // drive swap: on a one-joint servo arm, the drive's constants in place of an inertia
    let chosen = stages.run(None, |s| drive_swap::drive_swap(&scorer, chosen, s))?;
    // intervals: 95 % intervals, and the plausibility rounds
    let intervals = stages.run(shown("intervals and plausibility", 0, 1), |s| intervals::intervals(&scorer, &prep, chosen, s))?;
    // how far: held-out runs predicted and re-simulated, before and after
    let how_far = stages.run(shown("predicting held-out runs", 0, 3), |s| how_far::how_far(model, formulation, &prep, &located, &intervals.effects, s))?;
    // screen: every candidate alone on the held-out runs
    let screened = stages.run(None, |s| screen::screen(&scorer, &prep, &candidates, &intervals.chosen, &how_far, s))?;
    // notes: alternatives and notes
    let notes = stages.run(shown("naming alternatives and notes", 0, 1), |_| Ok(notes::notes(&scorer, &prep, &located, &candidates, &intervals, &how_far, options)))?;
    // what is left: the torque residual after the selected effects, joint by joint
    let notes = stages.run(shown("testing what is left", 0, 1), |_| Ok(what_is_left::what_is_left(&scorer, &prep, &intervals, notes)))?;
    // report: headline, verdict, the report
    let report = report::report(&scorer, &prep, located, screened, &intervals, &how_far, notes);
    Ok(report::diagnosis(model, report, prep, intervals, how_far))
}

/// k-step prediction of logged runs by `model` alone (`before`) and with `effects` (`after`),
/// with the constant-velocity floor: how well a model predicts logs, without a diagnosis
/// (e.g. to compare a published identified model with a corrected one on the same runs).
///
/// Runs are prepared as [`diagnose`] prepares its held-out runs (aligned to the model by joint
/// name, glitches repaired, sensors inferred); `horizons` [s] (empty: 0.1, 0.25 and 0.5 s);
/// `window` is the smoothing window [s] of the restart states.
///
/// # Errors
/// [`Error::Log`] for runs that do not match the model, have no experiment or are too short
/// for a window; [`Error::Input`] for a horizon that is not a positive number;
/// [`Error::Sim`] for an effect that does not fit the model (a vector of the wrong length, a
/// negative friction).
pub fn predict(model: &Model, formulation: Formulation, effects: &[Effect], runs: &[Run], horizons: &[f64], window: f64) -> Result<KStep> {
    let horizons = crate::prepare::horizons(horizons)?;
    simgap_sim::effects::validate_effects(effects, model.dof())?;
    let prepared = crate::prepare::prediction_runs(model, runs, &horizons, window)?;
    let (floor_all, floor_runs) = kstep::floor_all(&prepared, &horizons, model.dof());
    let (before, before_runs) = kstep::predict_all(model, formulation, &[], &prepared, &horizons)?;
    let (after, after_runs) = if effects.is_empty() { (before.clone(), before_runs.clone()) } else { kstep::predict_all(model, formulation, effects, &prepared, &horizons)? };
    let mut k = how_far::kstep_figures(&horizons, &prepared, (&floor_all, &floor_runs), (&before, &before_runs), (&after, &after_runs));
    let n = model.dof();
    for (r, pr) in k.runs.iter_mut().zip(&prepared) {
        r.window_starts =
            pr.starts.iter().map(|&k0| WindowStart { t0: pr.run.t[k0], q0: pr.q_hat[k0 * n..(k0 + 1) * n].to_vec(), qd0: pr.qd_hat[k0 * n..(k0 + 1) * n].to_vec() }).collect();
        let feedback = pr.run.experiment.as_ref().is_some_and(|e| e.controller != simgap_sim::ControllerKind::Replay);
        if feedback {
            let mae = |effects: &[Effect]| whole_run_mae(model, formulation, effects, &pr.run);
            r.whole_run_mae = Some((mae(&[]), mae(effects)));
        }
    }
    Ok(k)
}

/// Mean absolute position error [rad or m] of a closed-loop re-simulation of `run` from its
/// first sample, over every sample and joint (infinity when the simulation fails or diverges).
fn whole_run_mae(model: &Model, formulation: Formulation, effects: &[Effect], run: &Run) -> f64 {
    let n = run.dof();
    match crate::prediction::resim::resimulate(model, formulation, effects, run) {
        Ok((sim, simgap_sim::RunEnd::Completed)) if !sim.is_empty() => {
            let q = simgap_sim::interpolate_rows(&sim.t, &sim.q, n, &run.t);
            q.iter().zip(&run.q).map(|(a, b)| (a - b).abs()).sum::<f64>() / run.q.len().max(1) as f64
        }
        _ => f64::INFINITY,
    }
}
