//! The simulation's parameters ([`SimParams`]), each with its unit and default, and the ranges
//! they are checked against.

use crate::error::{Error, Result};
use crate::experiment::Experiment;
use crate::integrate::Integrator;
use crate::sensor::SensorParams;

/// Default RK4 steps per sample period.
///
/// Measured on the paper's experiment (PD, 2.5 ms, 3 s, exact sensors) against a
/// Dormand–Prince reference (rtol = atol = 1e-12): the maximum position error is 3.2e-10 rad
/// with 1 substep and 2.0e-11 rad with 2 (both formulations alike), so one RK4 step per sample
/// meets the 1e-6 rad target with a margin of 3000 (test
/// `paper_defaults_converge_to_a_micro_radian`). Raise it for faster closed loops; friction
/// stiffness raises it automatically ([`effective_substeps`](crate::substeps::effective_substeps)).
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
    /// dynamics stiff (see [`effective_substeps`](crate::substeps::effective_substeps)); ignored by the adaptive integrator. Default
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
    /// ends as [`RunEnd::Diverged`](crate::sink::RunEnd::Diverged). Default 1e4.
    pub divergence_bound: f64,
    /// Initial positions [rad or m], model order; empty = zeros. Default empty.
    pub q0: Vec<f64>,
    /// Initial velocities [rad/s or m/s], model order; empty = zeros. Default empty.
    pub qd0: Vec<f64>,
    /// Metadata handed to the sink; `None` = described by the controller
    /// ([`Controller::experiment`](crate::controller::Controller::experiment)). Default `None`.
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
    /// Most samples a run held in memory may have ([`SimParams::check_in_memory`](super::SimParams::check_in_memory)).
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
    /// [`simulate`](crate::simulate::simulate), the CLI and the Python bindings all refuse through it, with the same words.
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
