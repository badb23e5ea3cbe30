//! Reference trajectories q_ref(t), q̇_ref(t).

use simgap_core::Model;

use crate::controller::joint_map;
use crate::error::{Error, Result};
use crate::run::Run;

/// A reference trajectory. Every slice has length `dof` in model joint order.
pub trait Reference {
    /// Writes q_ref(t) and q̇_ref(t).
    fn eval(&self, t: f64, q_ref: &mut [f64], qd_ref: &mut [f64]);

    /// Writes the feed-forward torque τ_ff(t) [N·m or N] a feedback controller adds to its
    /// command (computed torque, a trajectory optimiser's torque). Default: zero.
    fn feed_forward(&self, _t: f64, tau_ff: &mut [f64]) {
        tau_ff.fill(0.0);
    }
}

/// A constant set point (a step at the start of the run); q̇_ref = 0.
#[derive(Clone, Debug, PartialEq)]
pub struct Step {
    /// Target positions [rad or m].
    pub target: Vec<f64>,
}

impl Reference for Step {
    fn eval(&self, _t: f64, q_ref: &mut [f64], qd_ref: &mut [f64]) {
        q_ref.copy_from_slice(&self.target);
        qd_ref.fill(0.0);
    }
}

/// Set points switched at given times: `targets` row `k` from `times[k]` on (row 0 also
/// before `times[0]`); q̇_ref = 0.
#[derive(Clone, Debug, PartialEq)]
pub struct PiecewiseSetpoints {
    /// Switching times [s], increasing.
    pub times: Vec<f64>,
    /// Targets, row-major `times.len() × dof`.
    pub targets: Vec<f64>,
}

impl Reference for PiecewiseSetpoints {
    fn eval(&self, t: f64, q_ref: &mut [f64], qd_ref: &mut [f64]) {
        let n = q_ref.len();
        let k = self.times.partition_point(|&tk| tk <= t).saturating_sub(1);
        q_ref.copy_from_slice(&self.targets[k * n..(k + 1) * n]);
        qd_ref.fill(0.0);
    }
}

/// A sum of sinusoids per joint with analytic velocity:
/// `q_i(t) = offset_i + Σ_k a_ik sin(2π f_ik t + φ_ik)`.
#[derive(Clone, Debug, PartialEq)]
pub struct Fourier {
    /// Offsets [rad or m], one per joint.
    pub offset: Vec<f64>,
    /// Amplitudes `a_ik` [rad or m], one list per joint.
    pub amplitudes: Vec<Vec<f64>>,
    /// Frequencies `f_ik` [Hz], aligned with `amplitudes`.
    pub frequencies: Vec<Vec<f64>>,
    /// Phases `φ_ik` [rad], aligned with `amplitudes`; a missing list or entry is 0.
    pub phases: Vec<Vec<f64>>,
}

impl Reference for Fourier {
    fn eval(&self, t: f64, q_ref: &mut [f64], qd_ref: &mut [f64]) {
        use std::f64::consts::TAU;
        for i in 0..q_ref.len() {
            let (mut q, mut qd) = (self.offset[i], 0.0);
            for (k, (&a, &f)) in self.amplitudes[i].iter().zip(&self.frequencies[i]).enumerate() {
                let phase = self.phases.get(i).and_then(|p| p.get(k)).copied().unwrap_or(0.0);
                let w = TAU * f;
                let (s, c) = (w * t + phase).sin_cos();
                q += a * s;
                qd += a * w * c;
            }
            q_ref[i] = q;
            qd_ref[i] = qd;
        }
    }
}

/// A sampled reference: q_ref linearly interpolated between samples (held constant outside
/// the sampled span), q̇_ref interpolated likewise, or zero when `qd` is empty; the
/// feed-forward torque held from its last sample at or before `t` (a controller's sampled
/// command), or zero when `tau_ff` is empty.
#[derive(Clone, Debug, PartialEq)]
pub struct Sampled {
    /// Sample times [s], increasing.
    pub t: Vec<f64>,
    /// Positions, row-major `t.len() × dof`.
    pub q: Vec<f64>,
    /// Velocities, row-major, or empty for zero.
    pub qd: Vec<f64>,
    /// Feed-forward torques, row-major, or empty for zero.
    pub tau_ff: Vec<f64>,
}

impl Sampled {
    fn interpolate(&self, m: &[f64], t: f64, out: &mut [f64]) {
        let n = out.len();
        let len = self.t.len();
        if len == 1 || t <= self.t[0] {
            out.copy_from_slice(&m[..n]);
            return;
        }
        if t >= self.t[len - 1] {
            out.copy_from_slice(&m[(len - 1) * n..len * n]);
            return;
        }
        let k = self.t.partition_point(|&tk| tk <= t) - 1;
        let s = (t - self.t[k]) / (self.t[k + 1] - self.t[k]);
        for i in 0..n {
            out[i] = (1.0 - s) * m[k * n + i] + s * m[(k + 1) * n + i];
        }
    }
}

impl Reference for Sampled {
    fn eval(&self, t: f64, q_ref: &mut [f64], qd_ref: &mut [f64]) {
        self.interpolate(&self.q, t, q_ref);
        if self.qd.is_empty() {
            qd_ref.fill(0.0);
        } else {
            self.interpolate(&self.qd, t, qd_ref);
        }
    }

    fn feed_forward(&self, t: f64, tau_ff: &mut [f64]) {
        let n = tau_ff.len();
        if self.tau_ff.is_empty() {
            tau_ff.fill(0.0);
            return;
        }
        // the last sample at or before t, within half a spacing of timestamp jitter
        let len = self.t.len();
        let tol = if len > 1 { 0.5 * (self.t[len - 1] - self.t[0]) / (len - 1) as f64 } else { 0.0 };
        let k = self.t.partition_point(|&tk| tk <= t + tol).saturating_sub(1);
        tau_ff.copy_from_slice(&self.tau_ff[k * n..(k + 1) * n]);
    }
}

/// The reference of a logged run, assuming the run's joint order is the model's (use
/// [`reference_from_run_for`] to map by name). Uses `q_ref`/`qd_ref`; a run without a
/// reference uses its measured `q` (as for replay runs, whose controller ignores it).
///
/// # Panics
/// If the run has no sample.
pub fn reference_from_run(run: &Run) -> Box<dyn Reference> {
    assert!(!run.is_empty(), "reference_from_run: the run has no sample");
    let q = if run.q_ref.is_empty() { run.q.clone() } else { run.q_ref.clone() };
    let qd = if run.q_ref.is_empty() { Vec::new() } else { run.qd_ref.clone() };
    Box::new(Sampled { t: run.t.clone(), q, qd, tau_ff: run.tau_ff.clone() })
}

/// The reference of a logged run in the model's joint order (joints matched by name).
///
/// # Errors
/// [`Error::JointMismatch`] when a model joint is not in the run; [`Error::Invalid`] for an
/// empty run.
pub fn reference_from_run_for(run: &Run, model: &Model) -> Result<Box<dyn Reference>> {
    if run.is_empty() {
        return Err(Error::Invalid { what: "reference".into(), message: format!("{}: the run has no sample", run.source) });
    }
    let map = joint_map(model, &run.joints, &run.source)?;
    let (n, m) = (run.dof(), model.dof());
    let reorder = |src: &[f64]| -> Vec<f64> {
        if src.is_empty() {
            return Vec::new();
        }
        let mut out = vec![0.0; run.len() * m];
        for k in 0..run.len() {
            for (i, &j) in map.iter().enumerate() {
                out[k * m + i] = src[k * n + j];
            }
        }
        out
    };
    let (q, qd) = if run.q_ref.is_empty() { (reorder(&run.q), Vec::new()) } else { (reorder(&run.q_ref), reorder(&run.qd_ref)) };
    Ok(Box::new(Sampled { t: run.t.clone(), q, qd, tau_ff: reorder(&run.tau_ff) }))
}
