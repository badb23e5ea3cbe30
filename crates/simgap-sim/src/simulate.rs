//! The sampled closed-loop simulation: a loop with a controller callback and a sink.
//!
//! At each sample `k` (time `t_k = t0 + k·T`):
//! 1. the state is checked (non-finite or `|q̇| > divergence_bound` ends the run as
//!    [`RunEnd::Diverged`] before anything non-finite is recorded);
//! 2. the sensors measure `(q, q̇)` ([`SensorParams`](crate::sensor::SensorParams));
//! 3. the reference gives `(q_ref, q̇_ref)` and the controller the command `τ_cmd` (plus the
//!    reference's feed-forward torque for a feedback controller);
//! 4. the sample `(t_k, q_meas, q̇_meas, τ_cmd, q_ref, q̇_ref)` goes to the sink (the logged
//!    effort is the commanded torque);
//! 5. the actuators turn the (delayed) command into `τ_applied`
//!    ([`applied_torque`](crate::effects::applied_torque)), held constant (zero-order hold)
//!    while the plant is integrated to `t_{k+1}`.
//!
//! **Time delay.** With `delay = m·T + r`, `0 <= r < T`, the torque held over sample `k` is
//! `(1 − r/T)·τ_cmd,k−m + (r/T)·τ_cmd,k−m−1`: the exact delayed zero-order-hold signal averaged
//! over the sample (exact when the delay is a multiple of T, continuous in the delay so it
//! can be fitted). Commands before the first sample are taken equal to the first one.

use std::sync::atomic::{AtomicBool, Ordering};

use simgap_core::{Formulation, Model};

use crate::controller::{controller_from_experiment, Controller};
use crate::effects::Effect;
use crate::error::Result;
pub use crate::params::{limits, number, SimParams, DEFAULT_SUBSTEPS};
use crate::plant::Plant;
use crate::reference::Reference;
use crate::run::{Experiment, Run, Sample};
use crate::sink::{MemorySink, RunEnd, Sink};
use crate::step::Stepper;
pub use crate::substeps::effective_substeps;

/// Simulates the closed loop `plant` + `controller` following `reference` (see the module
/// documentation for the order of events), writing every sample to `sink`.
///
/// `stop`, when given and set (e.g. by Ctrl-C), ends the run at the next sample as
/// [`RunEnd::Interrupted`]. The sink is always finished once `begin` was called, with how the
/// run ended. Never allocates inside the step loop (the sink may).
///
/// # Errors
/// [`Error::Invalid`](crate::Error::Invalid) for bad parameters (before the sink is begun); the sink's errors.
/// Divergence and interruption are not errors: they are the returned [`RunEnd`].
pub fn simulate(plant: &Plant, controller: &mut dyn Controller, reference: &dyn Reference, params: &SimParams, sink: &mut dyn Sink, stop: Option<&AtomicBool>) -> Result<RunEnd> {
    let n = plant.dof();
    params.validate(n)?;
    let names: Vec<String> = plant.model().joint_names().iter().map(|s| s.to_string()).collect();
    // parameters and sensors are checked before the sink is begun
    let mut stepper = Stepper::new(plant, params, params.intervals() + 1)?;
    let experiment = params.experiment.clone().unwrap_or_else(|| controller.experiment(&names, params.sample_period));
    sink.begin(&names, &experiment)?;
    let mut last_t = params.t0;
    match step_loop(&mut stepper, controller, reference, params, sink, stop, &names, &mut last_t) {
        Ok(end) => {
            sink.finish(&end)?;
            Ok(end)
        }
        Err(e) => {
            let _ = sink.finish(&RunEnd::Interrupted { t: last_t });
            Err(e)
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn step_loop(
    stepper: &mut Stepper<'_>,
    controller: &mut dyn Controller,
    reference: &dyn Reference,
    params: &SimParams,
    sink: &mut dyn Sink,
    stop: Option<&AtomicBool>,
    names: &[String],
    last_t: &mut f64,
) -> Result<RunEnd> {
    let n = stepper.dof();
    let period = params.sample_period;
    let intervals = params.intervals();
    // buffers, allocated once
    let mut y = vec![0.0; 2 * n];
    if !params.q0.is_empty() {
        y[..n].copy_from_slice(&params.q0);
    }
    if !params.qd0.is_empty() {
        y[n..].copy_from_slice(&params.qd0);
    }
    let (mut q_ref, mut qd_ref, mut tau_ff) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let adds_ff = controller.adds_feed_forward();

    for k in 0..=intervals {
        let t = params.t0 + k as f64 * period;
        // interruption
        if stop.is_some_and(|s| s.load(Ordering::Relaxed)) {
            return Ok(RunEnd::Interrupted { t: *last_t });
        }
        // divergence: non-finite or too fast
        if let Some(j) = stepper.diverged(&y) {
            return Ok(RunEnd::Diverged { t, joint: names[j].clone() });
        }
        // sensors, reference, controller and feed-forward
        reference.eval(t, &mut q_ref, &mut qd_ref);
        if adds_ff {
            reference.feed_forward(t, &mut tau_ff);
        }
        if let Some(j) = stepper.command(controller, t, &y, &q_ref, &qd_ref, if adds_ff { &tau_ff } else { &[] }) {
            return Ok(RunEnd::Diverged { t, joint: names[j].clone() });
        }
        let (q_meas, qd_meas) = stepper.measured();
        let drive = controller.drive_sample();
        sink.record(&Sample { t, q: q_meas, qd: qd_meas, tau: stepper.command_torque(), q_ref: &q_ref, qd_ref: &qd_ref, drive })?;
        *last_t = t;
        if k == intervals {
            break;
        }
        // delay line, held torque, integration over the sample
        stepper.advance(k, t, period, &mut y);
    }
    Ok(RunEnd::Completed)
}

/// Simulates an experiment (`simgap.experiment`) into memory: the controller from
/// [`controller_from_experiment`] (gains mapped by joint name; `replay` is the logged run of
/// a replay experiment), the plant `model` + `effects` under `formulation`, and the sample
/// period of the experiment (overriding `params.sample_period`). The run's metadata is the
/// experiment.
///
/// To re-simulate a logged run: `reference_from_run(run)`, `params.t0 = run.t[0]`,
/// `params.duration = run.duration()`, `q0`/`qd0` from its first sample.
///
/// # Errors
/// As [`Plant::new`], [`controller_from_experiment`] and [`simulate`];
/// [`Error::Diverged`](crate::Error::Diverged) when the run diverged (use [`simulate_experiment_with_end`] to keep
/// the partial run).
pub fn simulate_experiment(
    model: &Model,
    formulation: Formulation,
    effects: &[Effect],
    experiment: &Experiment,
    reference: &dyn Reference,
    params: &SimParams,
    replay: Option<&Run>,
) -> Result<Run> {
    let (run, end) = simulate_experiment_with_end(model, formulation, effects, experiment, reference, params, replay)?;
    end.into_result()?;
    Ok(run)
}

/// [`simulate_experiment`] returning the (possibly partial) run and how it ended.
///
/// # Errors
/// As [`simulate_experiment`], except divergence, which is returned as the [`RunEnd`].
pub fn simulate_experiment_with_end(
    model: &Model,
    formulation: Formulation,
    effects: &[Effect],
    experiment: &Experiment,
    reference: &dyn Reference,
    params: &SimParams,
    replay: Option<&Run>,
) -> Result<(Run, RunEnd)> {
    let plant = Plant::new(model, formulation, effects)?;
    let mut controller = controller_from_experiment(experiment, model, replay)?;
    let mut p = params.clone();
    if experiment.sample_period.is_finite() && experiment.sample_period > 0.0 {
        p.sample_period = experiment.sample_period;
    }
    p.experiment = Some(experiment.clone());
    let mut sink = MemorySink::new();
    let end = simulate(&plant, controller.as_mut(), reference, &p, &mut sink, None)?;
    Ok((sink.into_run(), end))
}
