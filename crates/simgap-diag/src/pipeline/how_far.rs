//! The how-far stage: the held-out runs, never used to fit or to select, predicted k steps ahead
//! ([`crate::prediction::kstep`]) and re-simulated in closed loop
//! ([`crate::prediction::resim`]), by the nominal model and with the selected effects.

use rayon::prelude::*;
use simgap_core::{Formulation, Model};
use simgap_sim::{Effect, Run};

use crate::error::Result;
use crate::options::Progress;
use crate::pipeline::locate::Located;
use crate::pipeline::runner::Stages;
use crate::prediction::kstep::{self, Errors, PredictionRun};
use crate::prediction::resim::{self, RunGap};
use crate::prepare::Prepared;
use crate::report::{KStep, RunKStep};

/// How far the gap shrinks with the selected effects.
pub(crate) struct HowFar {
    /// The k-step figures of the held-out runs: floor, nominal and corrected, pooled and per run.
    pub(crate) kstep: KStep,
    /// Per held-out run, the constant-velocity floor's k-step errors.
    pub(crate) floor_runs: Vec<Errors>,
    /// Per held-out run, the nominal model's k-step errors.
    pub(crate) before_runs_k: Vec<Errors>,
    /// Per held-out run, the corrected model's k-step errors.
    pub(crate) after_runs_k: Vec<Errors>,
    /// Per held-out run, the nominal model's closed-loop gap.
    pub(crate) before_runs: Vec<RunGap>,
    /// Per held-out run, the corrected model's closed-loop gap.
    pub(crate) after_runs: Vec<RunGap>,
    /// The nominal model's closed-loop L² gap over the held-out runs [rad or m].
    pub(crate) before: f64,
    /// The same per joint.
    pub(crate) before_joint: Vec<f64>,
    /// The corrected model's closed-loop L² gap over the held-out runs [rad or m].
    pub(crate) after: f64,
    /// The same per joint.
    pub(crate) after_joint: Vec<f64>,
    /// The nominal model's closed-loop L² gap over the fit runs [rad or m].
    pub(crate) fit_before: f64,
    /// The corrected model's closed-loop L² gap over the fit runs [rad or m].
    pub(crate) fit_after: f64,
    /// The held-out runs' nominal closed-loop simulations.
    pub(crate) holdout_nominal: Vec<Option<Run>>,
    /// The held-out runs' closed-loop simulations with the selected effects.
    pub(crate) holdout_corrected: Vec<Option<Run>>,
}

/// The how-far stage: held-out runs predicted k steps ahead and re-simulated in closed loop,
/// before and after `effects`; the fit runs re-simulated with them (their nominal gap is the
/// locate stage's).
///
/// # Errors
/// [`crate::Error::Interrupted`] when the diagnosis is stopped.
pub(crate) fn how_far(model: &Model, formulation: Formulation, prep: &Prepared, located: &Located, effects: &[Effect], stages: &mut Stages<'_>) -> Result<HowFar> {
    let horizons = &prep.horizons;
    // held-out runs predicted k steps ahead: the floor, the nominal model, the corrected one
    let (floor_all, floor_runs) = kstep::floor_all(&prep.hold_pred, horizons, model.dof());
    let (before_k, before_runs_k) = kstep::predict_all(model, formulation, &[], &prep.hold_pred, horizons)?;
    let (after_k, after_runs_k) =
        if effects.is_empty() { (before_k.clone(), before_runs_k.clone()) } else { kstep::predict_all(model, formulation, effects, &prep.hold_pred, horizons)? };
    stages.check()?;
    // held-out runs re-simulated in closed loop, nominal and corrected
    stages.announce(Progress { stage: "re-simulating held-out runs", done: 1, total: 3 });
    let hold_nominal: Vec<(RunGap, Option<Run>)> = prep.hold_runs.par_iter().map(|r| resim::gap(model, formulation, &[], r)).collect();
    let hold_after: Vec<(RunGap, Option<Run>)> =
        if effects.is_empty() { hold_nominal.clone() } else { prep.hold_runs.par_iter().map(|r| resim::gap(model, formulation, effects, r)).collect() };
    let before_runs: Vec<RunGap> = hold_nominal.iter().map(|g| g.0.clone()).collect();
    let after_runs: Vec<RunGap> = hold_after.iter().map(|g| g.0.clone()).collect();
    let (before, before_joint) = resim::combine(&before_runs, &prep.hold_runs);
    let (after, after_joint) = resim::combine(&after_runs, &prep.hold_runs);
    // fit runs re-simulated in closed loop, nominal and corrected
    let fit_before = resim::combine(&located.fit_nominal, &prep.fit_runs).0;
    let fit_after = if effects.is_empty() {
        fit_before
    } else {
        let g: Vec<RunGap> = prep.fit_runs.par_iter().map(|r| resim::gap(model, formulation, effects, r).0).collect();
        resim::combine(&g, &prep.fit_runs).0
    };
    // the k-step figures, pooled and per run
    let kstep = kstep_figures(horizons, &prep.hold_pred, (&floor_all, &floor_runs), (&before_k, &before_runs_k), (&after_k, &after_runs_k));
    Ok(HowFar {
        kstep,
        floor_runs,
        before_runs_k,
        after_runs_k,
        before_runs,
        after_runs,
        before,
        before_joint,
        after,
        after_joint,
        fit_before,
        fit_after,
        holdout_nominal: hold_nominal.into_iter().map(|g| g.1).collect(),
        holdout_corrected: hold_after.into_iter().map(|g| g.1).collect(),
    })
}

/// The k-step figures of held-out runs `runs`: the floor (constant velocity), the nominal model
/// (`before`) and the corrected one (`after`), pooled and per run.
pub(crate) fn kstep_figures(horizons: &[f64], runs: &[PredictionRun], floor: (&Errors, &[Errors]), before: (&Errors, &[Errors]), after: (&Errors, &[Errors])) -> KStep {
    KStep {
        horizons_s: horizons.to_vec(),
        before: before.0.rms(),
        after: after.0.rms(),
        floor: floor.0.rms(),
        per_joint_before: before.0.rms_per_joint(),
        per_joint_after: after.0.rms_per_joint(),
        runs: runs
            .iter()
            .enumerate()
            .map(|(i, pr)| RunKStep {
                log: pr.run.source.clone(),
                windows: pr.windows(),
                before: before.1[i].rms(),
                after: after.1[i].rms(),
                floor: floor.1[i].rms(),
                window_starts: Vec::new(),
                whole_run_mae: None,
            })
            .collect(),
    }
}
