//! Controllers: the callback the simulator calls once per sample.

use std::collections::BTreeMap;

use simgap_core::{gravity_torques_into, Model, Workspace};

use crate::error::{Error, Result};
use crate::run::{ControllerKind, Experiment, Run};

/// A sampled controller: the commanded torque from the measurements and the reference.
///
/// Every slice has length `dof` in model joint order. Called once per sample period; the
/// simulator holds the torque until the next sample (zero-order hold).
pub trait Controller {
    /// Writes the commanded torque τ_cmd [N·m or N] into `out`.
    fn torque(&mut self, t: f64, q_meas: &[f64], qd_meas: &[f64], q_ref: &[f64], qd_ref: &[f64], out: &mut [f64]);

    /// Whether the reference's feed-forward torque is added to this controller's command:
    /// true for feedback controllers, false for a replay (its logged effort already holds
    /// everything that was commanded).
    fn adds_feed_forward(&self) -> bool {
        true
    }

    /// The `simgap.experiment` metadata describing this controller, for the sink.
    ///
    /// The default describes a replay (no gains).
    fn experiment(&self, joints: &[String], sample_period: f64) -> Experiment {
        Experiment { controller: ControllerKind::Replay, joints: joints.to_vec(), kp: Vec::new(), kv: Vec::new(), sample_period, extra: BTreeMap::new() }
    }
}

/// Zero torque: free motion.
#[derive(Clone, Copy, Debug, Default)]
pub struct ZeroTorque;

impl Controller for ZeroTorque {
    fn torque(&mut self, _t: f64, _q: &[f64], _qd: &[f64], _q_ref: &[f64], _qd_ref: &[f64], out: &mut [f64]) {
        out.fill(0.0);
    }
}

/// PD control: `τ = Kp (q_ref − q) + Kv (q̇_ref − q̇)`, diagonal gains in model order (the
/// simulator adds the reference's feed-forward torque).
#[derive(Clone, Debug, PartialEq)]
pub struct Pd {
    /// Proportional gains [N·m/rad].
    pub kp: Vec<f64>,
    /// Derivative gains [N·m·s/rad].
    pub kv: Vec<f64>,
}

impl Controller for Pd {
    fn torque(&mut self, _t: f64, q: &[f64], qd: &[f64], q_ref: &[f64], qd_ref: &[f64], out: &mut [f64]) {
        for i in 0..out.len() {
            out[i] = self.kp[i] * (q_ref[i] - q[i]) + self.kv[i] * (qd_ref[i] - qd[i]);
        }
    }

    fn experiment(&self, joints: &[String], sample_period: f64) -> Experiment {
        gains_experiment(ControllerKind::Pd, joints, &self.kp, &self.kv, sample_period)
    }
}

/// PD control with gravity compensation from the controller's own model:
/// `τ = Kp (q_ref − q) + Kv (q̇_ref − q̇) + g_model(q_meas)`.
#[derive(Clone, Debug)]
pub struct PdGravity {
    /// Proportional gains [N·m/rad].
    pub kp: Vec<f64>,
    /// Derivative gains [N·m·s/rad].
    pub kv: Vec<f64>,
    /// The model whose g(q) is compensated (the controller's belief, not the plant).
    pub model: Model,
    ws: Workspace,
    g: Vec<f64>,
}

impl PdGravity {
    /// A PD + gravity controller.
    pub fn new(kp: Vec<f64>, kv: Vec<f64>, model: Model) -> Self {
        let ws = Workspace::new(&model);
        let g = vec![0.0; model.dof()];
        PdGravity { kp, kv, model, ws, g }
    }
}

impl Controller for PdGravity {
    fn torque(&mut self, _t: f64, q: &[f64], qd: &[f64], q_ref: &[f64], qd_ref: &[f64], out: &mut [f64]) {
        gravity_torques_into(&self.model, &mut self.ws, q, &mut self.g);
        for i in 0..out.len() {
            out[i] = self.kp[i] * (q_ref[i] - q[i]) + self.kv[i] * (qd_ref[i] - qd[i]) + self.g[i];
        }
    }

    fn experiment(&self, joints: &[String], sample_period: f64) -> Experiment {
        gains_experiment(ControllerKind::PdGravity, joints, &self.kp, &self.kv, sample_period)
    }
}

fn gains_experiment(kind: ControllerKind, joints: &[String], kp: &[f64], kv: &[f64], sample_period: f64) -> Experiment {
    Experiment { controller: kind, joints: joints.to_vec(), kp: kp.to_vec(), kv: kv.to_vec(), sample_period, extra: BTreeMap::new() }
}

/// Open-loop replay of a logged effort, zero-order hold: at time `t` the torque of the last
/// logged sample with `t_k <= t + tol` (`tol` = half the mean sample spacing, so timestamp
/// jitter does not shift the replay by a sample), the first sample before the log starts.
#[derive(Clone, Debug, PartialEq)]
pub struct Replay {
    /// Sample times [s], increasing.
    pub t: Vec<f64>,
    /// Torques, row-major `t.len() × dof`, model order.
    pub tau: Vec<f64>,
    cursor: usize,
    tol: f64,
}

impl Replay {
    /// A replay of `tau` (row-major, `t.len()` rows).
    ///
    /// # Errors
    /// [`Error::Invalid`] for an empty log or a length mismatch.
    pub fn new(t: Vec<f64>, tau: Vec<f64>) -> Result<Self> {
        if t.is_empty() || tau.len() % t.len() != 0 || tau.is_empty() {
            return Err(Error::Invalid {
                what: "replay".into(),
                message: format!("{} times and {} torque values; expected a non-empty log with one row per time", t.len(), tau.len()),
            });
        }
        let tol = if t.len() > 1 { 0.5 * (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64 } else { 0.0 };
        Ok(Replay { t, tau, cursor: 0, tol: tol.max(1e-9) })
    }
}

impl Controller for Replay {
    fn adds_feed_forward(&self) -> bool {
        false
    }

    fn torque(&mut self, t: f64, _q: &[f64], _qd: &[f64], _q_ref: &[f64], _qd_ref: &[f64], out: &mut [f64]) {
        let n = out.len();
        let tol = self.tol;
        // move the cursor to the last sample at or before t (times are mostly increasing)
        if self.cursor >= self.t.len() || self.t[self.cursor] > t + tol {
            self.cursor = self.t.partition_point(|&tk| tk <= t + tol).saturating_sub(1);
        }
        while self.cursor + 1 < self.t.len() && self.t[self.cursor + 1] <= t + tol {
            self.cursor += 1;
        }
        out.copy_from_slice(&self.tau[self.cursor * n..(self.cursor + 1) * n]);
    }
}

/// Positions of the model's joints among `names`.
///
/// # Errors
/// [`Error::JointMismatch`] naming the first model joint missing from `names`.
pub fn joint_map(model: &Model, names: &[String], source_name: &str) -> Result<Vec<usize>> {
    model
        .joint_names()
        .iter()
        .map(|j| {
            names.iter().position(|n| n == j).ok_or_else(|| Error::JointMismatch {
                source_name: source_name.into(),
                joint: (*j).to_string(),
                problem: "is in the model but not in the log".into(),
            })
        })
        .collect()
}

/// The controller of an experiment, with gains (and replayed efforts) mapped to the model's
/// joints by name. `PdGravity` compensates gravity with `model`.
///
/// # Errors
/// [`Error::JointMismatch`] when a model joint has no gain (or no replayed effort);
/// [`Error::Invalid`] for gains of the wrong length or a replay without a run.
pub fn controller_from_experiment(exp: &Experiment, model: &Model, replay: Option<&Run>) -> Result<Box<dyn Controller>> {
    match exp.controller {
        ControllerKind::Pd | ControllerKind::PdGravity => {
            if exp.kp.len() != exp.joints.len() || exp.kv.len() != exp.joints.len() {
                return Err(Error::Invalid {
                    what: "experiment gains".into(),
                    message: format!("{} joints, {} kp, {} kv; expected one gain of each per joint", exp.joints.len(), exp.kp.len(), exp.kv.len()),
                });
            }
            let map = joint_map(model, &exp.joints, "experiment")?;
            let kp = map.iter().map(|&i| exp.kp[i]).collect();
            let kv = map.iter().map(|&i| exp.kv[i]).collect();
            Ok(if exp.controller == ControllerKind::Pd { Box::new(Pd { kp, kv }) } else { Box::new(PdGravity::new(kp, kv, model.clone())) })
        }
        ControllerKind::Replay => {
            let run = replay.ok_or_else(|| Error::Invalid { what: "replay".into(), message: "a replay experiment needs the logged run".into() })?;
            let map = joint_map(model, &run.joints, &run.source)?;
            let (n, m) = (run.dof(), model.dof());
            let mut tau = vec![0.0; run.len() * m];
            for k in 0..run.len() {
                for (i, &j) in map.iter().enumerate() {
                    tau[k * m + i] = run.tau[k * n + j];
                }
            }
            Ok(Box::new(Replay::new(run.t.clone(), tau)?))
        }
    }
}
