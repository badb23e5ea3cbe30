//! The sampled closed-loop simulation: a loop with a controller callback and a sink.
//!
//! At each sample `k` (time `t_k = t0 + k·T`):
//! 1. the state is checked (non-finite or `|q̇| > divergence_bound` ends the run as
//!    [`RunEnd::Diverged`] before anything non-finite is recorded);
//! 2. the sensors measure `(q, q̇)` ([`SensorParams`]);
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

use simgap_core::{mass_matrix, Formulation, Model, Workspace};

use crate::controller::{controller_from_experiment, Controller};
use crate::effects::{armature, friction_slope_bound, moving_friction_slope_bound, Effect};
use crate::error::{Error, Result};
use crate::integrate::Integrator;
use crate::plant::Plant;
use crate::reference::Reference;
use crate::run::{Experiment, Run, Sample};
use crate::sensor::SensorParams;
use crate::sink::{MemorySink, RunEnd, Sink};
use crate::step::Stepper;

/// Default RK4 steps per sample period.
///
/// Measured on the paper's experiment (PD, 2.5 ms, 3 s, exact sensors) against a
/// Dormand–Prince reference (rtol = atol = 1e-12): the maximum position error is 3.2e-10 rad
/// with 1 substep and 2.0e-11 rad with 2 (both formulations alike), so one RK4 step per sample
/// meets the 1e-6 rad target with a margin of 3000 (test
/// `paper_defaults_converge_to_a_micro_radian`). Raise it for faster closed loops; friction
/// stiffness raises it automatically ([`effective_substeps`]).
pub const DEFAULT_SUBSTEPS: usize = 1;

/// Simulation parameters. Every field states its unit and default ([`SimParams::default`]).
#[derive(Clone, Debug, PartialEq)]
pub struct SimParams {
    /// Start time t0 [s]; sample `k` is at `t0 + k·sample_period`. Default 0.
    pub t0: f64,
    /// Controller sample period T [s]. Default 0.0025 (the paper's 2.5 ms).
    pub sample_period: f64,
    /// Duration [s]; the run has `round(duration / T) + 1` samples, from `t0` to
    /// `t0 + duration`. Default 3 (long enough for the paper's experiment to settle).
    pub duration: f64,
    /// RK4 steps per sample period, a minimum: raised automatically when friction makes the
    /// dynamics stiff (see [`effective_substeps`]); ignored by the adaptive integrator. Default
    /// [`DEFAULT_SUBSTEPS`].
    pub substeps: usize,
    /// Integrator within each sample. Default [`Integrator::Rk4`].
    pub integrator: Integrator,
    /// Sensor model. Default: the paper's encoders (1,024,000 counts/rev) and backward
    /// difference velocity.
    pub sensor: SensorParams,
    /// Also saturate applied torques at the model's (URDF) effort limits. Default false (the
    /// paper's simulation does not saturate).
    pub torque_limits_from_model: bool,
    /// Divergence bound on `|q̇|` [rad/s or m/s]: beyond it, or on a non-finite state, the run
    /// ends as [`RunEnd::Diverged`]. Default 1e4.
    pub divergence_bound: f64,
    /// Initial positions [rad or m], model order; empty = zeros. Default empty.
    pub q0: Vec<f64>,
    /// Initial velocities [rad/s or m/s], model order; empty = zeros. Default empty.
    pub qd0: Vec<f64>,
    /// Metadata handed to the sink; `None` = described by the controller
    /// ([`Controller::experiment`]). Default `None`.
    pub experiment: Option<Experiment>,
}

impl Default for SimParams {
    fn default() -> Self {
        SimParams {
            t0: 0.0,
            sample_period: 0.0025,
            duration: 3.0,
            substeps: DEFAULT_SUBSTEPS,
            integrator: Integrator::Rk4,
            sensor: SensorParams::default(),
            torque_limits_from_model: false,
            divergence_bound: 1e4,
            q0: Vec::new(),
            qd0: Vec::new(),
            experiment: None,
        }
    }
}

/// Ranges of [`SimParams`] checked by [`SimParams::validate`]: the most a run may ask for.
pub mod limits {
    /// Shortest sample period [s].
    pub const MIN_SAMPLE_PERIOD: f64 = 1e-6;
    /// Longest sample period [s].
    pub const MAX_SAMPLE_PERIOD: f64 = 1.0;
    /// Longest duration [s]: a day.
    pub const MAX_DURATION: f64 = 86_400.0;
    /// Most RK4 steps per sample asked for (`substeps`).
    pub const MAX_SUBSTEPS: usize = 10_000;
    /// Most integration steps a run may take: samples × `substeps`.
    pub const MAX_STEPS: f64 = 1e9;
    /// Most samples a run held in memory may have ([`SimParams::check_in_memory`]).
    pub const MAX_MEMORY_SAMPLES: f64 = 1e7;
    /// Largest position noise [rad or m].
    pub const MAX_NOISE_STD: f64 = 1.0;
}

/// A number as people write it: plain between 0.001 and 10⁶, else in exponent form (`1e-12`,
/// `3.2e7`).
pub fn number(x: f64) -> String {
    if x == 0.0 || (x.abs() >= 1e-3 && x.abs() < 1e6) || !x.is_finite() {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

impl SimParams {
    /// Checks every parameter against its range, before anything is simulated: `sample_period`
    /// in [1e-6, 1] s, `duration` in (0, 86400] s, `t0` finite, `substeps` in [1, 10000],
    /// at most 1e9 integration steps (samples × substeps), adaptive tolerances positive,
    /// `divergence_bound` positive, `q0`/`qd0` empty or one
    /// finite value per joint, encoder counts positive, noise in [0, 1] rad (see [`limits`]).
    /// [`simulate`], the CLI and the Python bindings all refuse through it, with the same words.
    ///
    /// # Errors
    /// [`Error::Invalid`] naming the parameter, the value and the range expected.
    pub fn validate(&self, dof: usize) -> Result<()> {
        use limits::*;
        let bad = |what: &str, message: String| Err(Error::Invalid { what: what.into(), message });
        let range = |what: &str, value: f64, lo: f64, hi: f64, unit: &str, lo_open: bool| -> Result<()> {
            let inside = value.is_finite() && value <= hi && if lo_open { value > lo } else { value >= lo };
            if inside {
                return Ok(());
            }
            let unit = if unit.is_empty() { String::new() } else { format!(" {unit}") };
            let lo_rel = if lo_open { "<" } else { "≤" };
            bad(what, format!("{}{unit} is out of range; expected {} {lo_rel} {what} ≤ {}{unit}", number(value), number(lo), number(hi)))
        };
        range("sample_period", self.sample_period, MIN_SAMPLE_PERIOD, MAX_SAMPLE_PERIOD, "s", false)?;
        range("duration", self.duration, 0.0, MAX_DURATION, "s", true)?;
        if !self.t0.is_finite() {
            return bad("t0", format!("{}; expected a finite time", self.t0));
        }
        range("substeps", self.substeps as f64, 1.0, MAX_SUBSTEPS as f64, "", false)?;
        let samples = (self.duration / self.sample_period).round() + 1.0;
        let steps = samples * self.substeps as f64;
        if steps > MAX_STEPS {
            return bad(
                "duration",
                format!(
                    "{} s at sample_period {} s × substeps {} gives {} integration steps; expected at most {}",
                    number(self.duration),
                    number(self.sample_period),
                    self.substeps,
                    number(steps),
                    number(MAX_STEPS)
                ),
            );
        }
        if let Integrator::Adaptive { rtol, atol } = self.integrator {
            if !(rtol > 0.0 && atol > 0.0 && rtol.is_finite() && atol.is_finite()) {
                return bad("integrator", format!("rtol = {rtol}, atol = {atol}; expected positive tolerances"));
            }
        }
        if !(self.divergence_bound > 0.0) {
            return bad("divergence_bound", format!("{}; expected a positive number", self.divergence_bound));
        }
        for (name, v) in [("q0", &self.q0), ("qd0", &self.qd0)] {
            if !(v.is_empty() || v.len() == dof) {
                return bad(name, format!("{} values; expected {dof} (one per joint) or none", v.len()));
            }
            if v.iter().any(|x| !x.is_finite()) {
                return bad(name, "non-finite value".into());
            }
        }
        if let Some(c) = self.sensor.counts_per_rev {
            if !(c.is_finite() && c > 0.0) {
                return bad("counts_per_rev", format!("{}; expected a positive number of counts per revolution, or none (exact positions)", number(c)));
            }
        }
        range("noise_std", self.sensor.noise_std, 0.0, MAX_NOISE_STD, "rad", false)?;
        Ok(())
    }

    /// Checks that the run fits in memory: at most 1e7 samples ([`limits::MAX_MEMORY_SAMPLES`];
    /// a run of a day at 400 Hz has 3.5e7). A sink that writes as the run goes (an MCAP log)
    /// needs no such bound.
    ///
    /// # Errors
    /// [`Error::Invalid`] naming the number of samples and the bound.
    pub fn check_in_memory(&self) -> Result<()> {
        let samples = (self.duration / self.sample_period).round() + 1.0;
        if samples > limits::MAX_MEMORY_SAMPLES {
            return Err(Error::Invalid {
                what: "duration".into(),
                message: format!(
                    "{} s at sample_period {} s gives {} samples; a run held in memory has at most {} (write longer runs to a log as they go: simgap simulate --out RUN.mcap)",
                    number(self.duration),
                    number(self.sample_period),
                    number(samples),
                    number(limits::MAX_MEMORY_SAMPLES)
                ),
            });
        }
        Ok(())
    }

    /// Number of sample intervals, `round(duration / T)`.
    pub fn intervals(&self) -> usize {
        (self.duration / self.sample_period).round() as usize
    }
}

/// Simulates the closed loop `plant` + `controller` following `reference` (see the module
/// documentation for the order of events), writing every sample to `sink`.
///
/// `stop`, when given and set (e.g. by Ctrl-C), ends the run at the next sample as
/// [`RunEnd::Interrupted`]. The sink is always finished once `begin` was called, with how the
/// run ended. Never allocates inside the step loop (the sink may).
///
/// # Errors
/// [`Error::Invalid`] for bad parameters (before the sink is begun); the sink's errors.
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

/// The RK4 steps per sample the simulator uses: `params.substeps`, raised so that
/// `h · λ <= 2` where `λ = λ_max(H⁻¹ diag(s))` is the largest rate of the friction stiffness
/// (`s` from [`friction_slope_bound`], `H` the plant's mass matrix plus armature at `q0`;
/// computed as the largest eigenvalue of the symmetric `S^½ H⁻¹ S^½`). RK4's stability interval
/// on the negative real axis is `h·λ < 2.785`, so the rule keeps a margin of 28 % for the change
/// of H along the run. At most 10,000.
/// Each dry friction counts with its own width `w`; one with `w = 0` (the exact sign) counts
/// not at all (see [`friction_slope_bound`]).
pub fn effective_substeps(plant: &Plant, params: &SimParams) -> usize {
    substeps_and_moving_rate(plant, params).0
}

/// [`effective_substeps`], and the largest rate of the friction stiffness while every joint
/// moves faster than its [`stiff_band`](crate::effects::stiff_band) [1/s]: the same `λ` with the
/// slopes of [`moving_friction_slope_bound`](crate::effects::moving_friction_slope_bound). A
/// sample interval clear of every band needs only the steps that rate asks for
/// ([`crate::Stepper::advance`]). The rate is `None` where [`effective_substeps`] does not raise
/// the substeps (no friction, the adaptive integrator, a singular H, or a stiffness the
/// requested substeps already resolve).
pub(crate) fn substeps_and_moving_rate(plant: &Plant, params: &SimParams) -> (usize, Option<f64>) {
    let n = plant.dof();
    let mut full = vec![0.0; n];
    friction_slope_bound(plant.effects(), &mut full);
    add_load_friction_slope(plant, &mut full);
    let Some(inv) = stiffness_inverse(plant, params, &full) else { return (params.substeps, None) };
    let substeps = substeps_for_rate(params.sample_period, largest_rate(&inv, &full), params.substeps);
    if substeps == params.substeps {
        return (substeps, None);
    }
    let mut moving = vec![0.0; n];
    moving_friction_slope_bound(plant.effects(), &mut moving);
    add_load_friction_slope(plant, &mut moving);
    (substeps, Some(largest_rate(&inv, &moving)))
}

/// The substeps of a sample interval of `period` seconds for friction rates `lambda` [1/s]
/// (`h · λ ≤ 2`, see [`effective_substeps`]): at least `base`, at most 10,000.
pub(crate) fn substeps_for_rate(period: f64, lambda: f64, base: usize) -> usize {
    let needed = (period * lambda / 2.0).ceil();
    if needed.is_finite() {
        base.max(needed.min(10_000.0) as usize)
    } else {
        base
    }
}

/// A load friction's slope grows with the drive's torque: bounded from the effort limits.
fn add_load_friction_slope(plant: &Plant, slope: &mut [f64]) {
    for e in plant.effects() {
        use crate::effects::Effect;
        // the load part's step over w (its largest per unit torque) and, in Stribeck form, its
        // rise over vs (slope at most 2 |mus − mu| |τ| / vs)
        let (mu, rise, w) = match e {
            Effect::LoadFriction { mu, w, .. } => (mu, None, w),
            Effect::LoadStribeckFriction { mu, mus, vs, w, .. } => (mu, Some((mus, vs)), w),
            _ => continue,
        };
        for (i, s) in slope.iter_mut().enumerate() {
            let limit = plant.effort_limits()[i];
            if w[i] > 0.0 && limit.is_finite() {
                let (most, hump) = match rise {
                    Some((mus, vs)) if vs[i] > 0.0 => (mu[i].max(mus[i]), 2.0 * (mus[i] - mu[i]).abs() / vs[i]),
                    Some((mus, _)) => (mu[i].max(mus[i]), 0.0),
                    None => (mu[i], 0.0),
                };
                *s += most * limit / w[i] + hump * limit;
            }
        }
    }
}

/// `(H + diag(ia))⁻¹` at `params.q0` when friction slopes `slope` make RK4's step matter
/// (`None` without friction, with the adaptive integrator, or for a singular H).
fn stiffness_inverse(plant: &Plant, params: &SimParams, slope: &[f64]) -> Option<nalgebra::DMatrix<f64>> {
    let n = plant.dof();
    if slope.iter().all(|s| *s == 0.0) || !matches!(params.integrator, Integrator::Rk4) {
        return None;
    }
    let q0 = if params.q0.len() == n { params.q0.clone() } else { vec![0.0; n] };
    let mut h = mass_matrix(plant.model(), &mut Workspace::new(plant.model()), &q0);
    let mut ia = vec![0.0; n];
    armature(plant.effects(), &mut ia);
    for i in 0..n {
        h[(i, i)] += ia[i];
    }
    h.try_inverse()
}

/// `λ_max(H⁻¹ diag(s)) = λ_max(S^½ H⁻¹ S^½)`, a symmetric positive semi-definite matrix, from
/// `inv = H⁻¹`.
fn largest_rate(inv: &nalgebra::DMatrix<f64>, slope: &[f64]) -> f64 {
    let n = slope.len();
    let root: Vec<f64> = slope.iter().map(|s| s.max(0.0).sqrt()).collect();
    let m = nalgebra::DMatrix::from_fn(n, n, |i, j| root[i] * inv[(i, j)] * root[j]);
    m.symmetric_eigenvalues().iter().copied().fold(0.0f64, f64::max)
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
/// [`Error::Diverged`] when the run diverged (use [`simulate_experiment_with_end`] to keep
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
