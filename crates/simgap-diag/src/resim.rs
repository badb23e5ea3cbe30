//! How far: closed-loop re-simulation of logged runs with and without effects.

use simgap_core::{Formulation, Model};
use simgap_sim::{l2_between, reference_from_run_for, simulate_experiment_with_end, Effect, Run, RunEnd, SensorParams, SimParams, VelocityEstimate};

use crate::error::{Error, Result};

/// The sensors the re-simulation gives the controller: from the experiment's extra metadata
/// (`counts_per_rev`, `velocity` = `backward_difference` | `exact`), exact otherwise.
pub fn sensor_for(run: &Run) -> SensorParams {
    let mut s = SensorParams::exact();
    if let Some(exp) = &run.experiment {
        if let Some(c) = exp.extra.get("counts_per_rev").and_then(|v| v.parse::<f64>().ok()) {
            s.counts_per_rev = Some(c);
        }
        if exp.extra.get("velocity").map(String::as_str) == Some("backward_difference") {
            s.velocity = VelocityEstimate::BackwardDifference;
        }
    }
    s
}

/// Re-simulates a logged (model-aligned) run in closed loop: same experiment, reference,
/// initial state and sample times. Returns the simulated run and how it ended.
///
/// # Errors
/// [`Error::Log`] when the run has no experiment; simulator errors.
pub fn resimulate(model: &Model, formulation: Formulation, effects: &[Effect], run: &Run) -> Result<(Run, RunEnd)> {
    let exp = run.experiment.as_ref().ok_or_else(|| Error::Log {
        log: run.source.clone(),
        message: "no simgap.experiment metadata (controller, gains, sample period); cannot re-simulate the closed loop".into(),
    })?;
    let reference = reference_from_run_for(run, model)?;
    let n = run.dof();
    let params = SimParams {
        t0: run.t[0],
        duration: run.duration(),
        sample_period: exp.sample_period,
        sensor: sensor_for(run),
        q0: run.q[..n].to_vec(),
        qd0: if run.qd.len() >= n { run.qd[..n].to_vec() } else { vec![0.0; n] },
        ..SimParams::default()
    };
    let replay = if exp.controller == simgap_sim::ControllerKind::Replay { Some(run) } else { None };
    Ok(simulate_experiment_with_end(model, formulation, effects, exp, reference.as_ref(), &params, replay)?)
}

/// Closed-loop L² of (simulation − measured) for one run.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RunGap {
    /// Log name.
    pub log: String,
    /// Overall L² [rad].
    pub l2: f64,
    /// Per-joint L².
    pub per_joint: Vec<f64>,
    /// `completed` or `diverged at t = … on …`.
    pub status: String,
}

/// Re-simulates and scores one run; a diverged simulation scores over its partial span
/// (status says so), and a failed one scores infinity.
pub fn gap(model: &Model, formulation: Formulation, effects: &[Effect], run: &Run) -> (RunGap, Option<Run>) {
    let n = run.dof();
    match resimulate(model, formulation, effects, run) {
        Ok((sim, end)) => {
            let status = match &end {
                RunEnd::Completed => "completed".to_string(),
                RunEnd::Diverged { t, joint } => format!("diverged at t = {t:.3} s on {joint}"),
                RunEnd::Interrupted { t } => format!("interrupted at t = {t:.3} s"),
            };
            match l2_between(run, &sim, None) {
                Ok(r) if end == RunEnd::Completed => (RunGap { log: run.source.clone(), l2: r.overall, per_joint: r.per_joint, status }, Some(sim)),
                _ => (RunGap { log: run.source.clone(), l2: f64::INFINITY, per_joint: vec![f64::INFINITY; n], status }, Some(sim)),
            }
        }
        Err(e) => (RunGap { log: run.source.clone(), l2: f64::INFINITY, per_joint: vec![f64::INFINITY; n], status: format!("failed: {e}") }, None),
    }
}

/// Combines per-run L² into one index over all runs (time-weighted root mean square).
pub fn combine(gaps: &[RunGap], runs: &[Run]) -> (f64, Vec<f64>) {
    let n = runs.first().map_or(0, Run::dof);
    let mut total = 0.0;
    let mut per = vec![0.0; n];
    let mut span = 0.0;
    for (g, r) in gaps.iter().zip(runs) {
        let d = r.duration();
        total += g.l2 * g.l2 * d;
        for (p, v) in per.iter_mut().zip(&g.per_joint) {
            *p += v * v * d;
        }
        span += d;
    }
    let span = if span > 0.0 { span } else { 1.0 };
    ((total / span).sqrt(), per.iter().map(|v| (v / span).sqrt()).collect())
}
