//! Sensors: encoder quantisation, noise and velocity estimation, as the controller sees them.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use simgap_core::Model;

use crate::error::{Error, Result};

/// How the controller obtains q̇.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VelocityEstimate {
    /// `q̇_k = (q_meas,k − q_meas,k−1) / T`, as the paper's controller; at the first sample
    /// (no previous measurement) the true initial velocity.
    BackwardDifference,
    /// The true velocity (plus noise, if any).
    Exact,
}

/// Sensor model. The defaults reproduce the paper: 1,024,000 counts per revolution, velocity by
/// backward difference, no noise.
#[derive(Clone, Debug, PartialEq)]
pub struct SensorParams {
    /// Encoder counts per revolution of rotational joints; positions are rounded to multiples
    /// of `2π / counts_per_rev` rad. `None` = exact positions. Prismatic joints are never
    /// quantised. Default `Some(1_024_000.0)`.
    pub counts_per_rev: Option<f64>,
    /// Velocity estimate. Default [`VelocityEstimate::BackwardDifference`].
    pub velocity: VelocityEstimate,
    /// Standard deviation of Gaussian noise added to positions before quantisation [rad or m].
    /// Default 0. With [`VelocityEstimate::Exact`] the same σ (in rad/s or m/s) is added to
    /// the velocity.
    pub noise_std: f64,
    /// Seed of the noise generator (ChaCha8). Default 0.
    pub seed: u64,
}

impl Default for SensorParams {
    fn default() -> Self {
        SensorParams { counts_per_rev: Some(1_024_000.0), velocity: VelocityEstimate::BackwardDifference, noise_std: 0.0, seed: 0 }
    }
}

impl SensorParams {
    /// Exact sensors: no quantisation, no noise, exact velocity.
    pub fn exact() -> Self {
        SensorParams { counts_per_rev: None, velocity: VelocityEstimate::Exact, noise_std: 0.0, seed: 0 }
    }
}

/// The state of the sensors during one run.
#[derive(Clone, Debug)]
pub struct Sensor {
    params: SensorParams,
    rotational: Vec<bool>,
    prev: Vec<f64>,
    has_prev: bool,
    period: f64,
    rng: ChaCha8Rng,
}

impl Sensor {
    /// Sensors for `model` sampled every `sample_period` seconds.
    ///
    /// # Errors
    /// [`Error::Invalid`] for a non-positive count or negative noise.
    pub fn new(params: &SensorParams, model: &Model, sample_period: f64) -> Result<Self> {
        if let Some(c) = params.counts_per_rev {
            if !(c.is_finite() && c > 0.0) {
                return Err(Error::Invalid { what: "counts_per_rev".into(), message: format!("{c}; expected a positive number") });
            }
        }
        if !(params.noise_std.is_finite() && params.noise_std >= 0.0) {
            return Err(Error::Invalid { what: "noise_std".into(), message: format!("{}; expected a finite number >= 0", params.noise_std) });
        }
        let n = model.dof();
        Ok(Sensor {
            params: params.clone(),
            rotational: model.joints().iter().map(|j| j.kind.is_rotational()).collect(),
            prev: vec![0.0; n],
            has_prev: false,
            period: sample_period,
            rng: ChaCha8Rng::seed_from_u64(params.seed),
        })
    }

    /// A standard normal number (Box–Muller).
    fn normal(&mut self) -> f64 {
        let u1: f64 = 1.0 - self.rng.random::<f64>();
        let u2: f64 = self.rng.random::<f64>();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }

    /// Restarts the sensors as if `q_meas_prev` had been measured one sample before (the
    /// backward-difference velocity then continues from it), e.g. to restart a prediction from
    /// a logged state.
    pub fn restart(&mut self, q_meas_prev: &[f64]) {
        self.prev.copy_from_slice(q_meas_prev);
        self.has_prev = true;
    }

    /// Measures the true state `(q, qd)` into `(q_meas, qd_meas)`. Call once per sample, in
    /// order.
    pub fn measure(&mut self, q: &[f64], qd: &[f64], q_meas: &mut [f64], qd_meas: &mut [f64]) {
        let sigma = self.params.noise_std;
        let resolution = self.params.counts_per_rev.map(|c| std::f64::consts::TAU / c);
        // positions: noise, then encoder quantisation
        for i in 0..q.len() {
            let mut x = q[i];
            if sigma > 0.0 {
                x += sigma * self.normal();
            }
            if let (Some(r), true) = (resolution, self.rotational[i]) {
                x = (x / r).round() * r;
            }
            q_meas[i] = x;
        }
        // velocities
        match self.params.velocity {
            VelocityEstimate::BackwardDifference if self.has_prev => {
                for i in 0..q.len() {
                    qd_meas[i] = (q_meas[i] - self.prev[i]) / self.period;
                }
            }
            VelocityEstimate::BackwardDifference => qd_meas.copy_from_slice(qd),
            VelocityEstimate::Exact => {
                for i in 0..q.len() {
                    qd_meas[i] = qd[i] + if sigma > 0.0 { sigma * self.normal() } else { 0.0 };
                }
            }
        }
        self.prev.copy_from_slice(q_meas);
        self.has_prev = true;
    }
}
