//! How far: closed-loop re-simulation of logged runs with and without effects.

use simgap_core::{Formulation, Model};
use simgap_sim::{l2_between, reference_from_run_for, resolvable_effects, simulate_experiment_with_end, Effect, Run, RunEnd, SensorParams, SimParams};

use crate::error::{Error, Result};
use crate::prediction::MAX_BAND_SUBSTEPS;
use crate::prepare::sensors::infer_sensors;

/// The sensors the re-simulation gives the controller ([`infer_sensors`]).
pub(crate) fn sensor_for(run: &Run) -> SensorParams {
    infer_sensors(run).params()
}

/// The simulation parameters that re-simulate `run`: its start, span, sample
/// period, inferred sensors and initial state.
fn sim_params(run: &Run, sample_period: f64) -> SimParams {
    let n = run.dof();
    SimParams {
        t0: run.t[0],
        duration: run.duration(),
        sample_period,
        sensor: sensor_for(run),
        q0: run.q[..n].to_vec(),
        qd0: if run.qd.len() >= n { run.qd[..n].to_vec() } else { vec![0.0; n] },
        ..SimParams::default()
    }
}

/// Re-simulates a logged (model-aligned) run in closed loop: same experiment, reference,
/// initial state and sample times. Returns the simulated run and how it ended.
///
/// # Errors
/// [`Error::Log`] when the run has no experiment; simulator errors.
pub(crate) fn resimulate(model: &Model, formulation: Formulation, effects: &[Effect], run: &Run) -> Result<(Run, RunEnd)> {
    let exp = run.experiment.as_ref().ok_or_else(|| Error::Log {
        log: run.source.clone(),
        message: "no simgap.experiment metadata (controller, gains, sample period); cannot re-simulate the closed loop".into(),
    })?;
    let reference = reference_from_run_for(run, model)?;
    let params = sim_params(run, exp.sample_period);
    // a replay applies the run's efforts; a servo reads its logged voltage and torque enable
    let replay = if matches!(exp.controller, simgap_sim::ControllerKind::Replay | simgap_sim::ControllerKind::Servo) { Some(run) } else { None };
    // a dry friction's band too narrow for the sample period as the exact sign, as k-step
    // predictions integrate it (a load friction's too, where the drive's torque is held over
    // each sample: not a servo)
    let effects = resolvable_effects(model, formulation, effects, &params, MAX_BAND_SUBSTEPS, exp.controller.holds_torque_over_sample());
    Ok(simulate_experiment_with_end(model, formulation, &effects, exp, reference.as_ref(), &params, replay)?)
}

/// PD gains [N·m/rad, N·m·s/rad] giving each joint a natural frequency `hz` and damping 0.7 on
/// the diagonal of H(q): `kp = ω² H_jj`, `kv = 1.4 ω H_jj`, `ω = 2π hz`.
pub(crate) fn pd_gains_at(model: &Model, q: &[f64], hz: f64) -> (Vec<f64>, Vec<f64>) {
    let h = simgap_core::mass_matrix(model, &mut simgap_core::Workspace::new(model), q);
    let w = std::f64::consts::TAU * hz;
    let kp = (0..model.dof()).map(|j| w * w * h[(j, j)]).collect();
    let kv = (0..model.dof()).map(|j| 2.0 * 0.7 * w * h[(j, j)]).collect();
    (kp, kv)
}

/// Natural frequency [Hz] of the weak tracking loop [`resimulate_tracked`] adds to an open-loop
/// replay (damping 0.7, on the diagonal of H at the run's first position).
pub(crate) const TRACKING_HZ: f64 = 2.0;

/// A logged (model-aligned) run re-simulated with `effects` as [`resimulate`] does, except that
/// an open-loop replay also tracks its own logged positions and velocities by a weak PD
/// ([`TRACKING_HZ`]; none on a joint whose logged torque is zero throughout, a passive one), and
/// the simulated log records the torque applied (the logged effort plus that correction) under the
/// run's own experiment. Replayed open loop, a long arm's re-simulation drifts away from its log
/// within seconds, into motions the real run never made; tracked, it stays near them, while the
/// applied torque and the motion still obey the model with `effects` exactly. Other controllers
/// are re-simulated as they are.
///
/// # Errors
/// As [`resimulate`].
pub(crate) fn resimulate_tracked(model: &Model, formulation: Formulation, effects: &[Effect], run: &Run) -> Result<(Run, RunEnd)> {
    let exp = match run.experiment.as_ref() {
        Some(e) if e.controller == simgap_sim::ControllerKind::Replay => e,
        _ => return resimulate(model, formulation, effects, run),
    };
    let n = run.dof();
    let rows = run.len();
    if n == 0 || rows < 2 || run.q.len() != rows * n || run.tau.len() != rows * n {
        return resimulate(model, formulation, effects, run);
    }
    let (mut kp, mut kv) = pd_gains_at(model, &run.q[..n], TRACKING_HZ);
    for j in (0..n).filter(|&j| (0..rows).all(|k| run.tau[k * n + j] == 0.0)) {
        (kp[j], kv[j]) = (0.0, 0.0);
    }
    let tracking = simgap_sim::Experiment { controller: simgap_sim::ControllerKind::Pd, kp, kv, ..exp.clone() };
    let reference = simgap_sim::Sampled { t: run.t.clone(), q: run.q.clone(), qd: if run.qd.len() == rows * n { run.qd.clone() } else { Vec::new() }, tau_ff: run.tau.clone() };
    let params = sim_params(run, exp.sample_period);
    let effects = resolvable_effects(model, formulation, effects, &params, MAX_BAND_SUBSTEPS, tracking.controller.holds_torque_over_sample());
    let (mut sim, end) = simulate_experiment_with_end(model, formulation, &effects, &tracking, &reference, &params, None)?;
    sim.experiment = Some(exp.clone());
    Ok((sim, end))
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
pub(crate) fn gap(model: &Model, formulation: Formulation, effects: &[Effect], run: &Run) -> (RunGap, Option<Run>) {
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
pub(crate) fn combine(gaps: &[RunGap], runs: &[Run]) -> (f64, Vec<f64>) {
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
