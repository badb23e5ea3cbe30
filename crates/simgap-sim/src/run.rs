//! A run: what a robot or a simulation did, as columnar arrays, and the experiment behind it.

use std::collections::BTreeMap;

/// The controller of an experiment.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ControllerKind {
    /// τ = Kp (q_ref − q) + Kv (q̇_ref − q̇).
    Pd,
    /// The same plus the model's g(q).
    PdGravity,
    /// The logged effort applied open-loop.
    Replay,
}

impl ControllerKind {
    /// The metadata spelling: `pd`, `pd_gravity` or `replay`.
    pub fn as_str(self) -> &'static str {
        match self {
            ControllerKind::Pd => "pd",
            ControllerKind::PdGravity => "pd_gravity",
            ControllerKind::Replay => "replay",
        }
    }
}

impl std::str::FromStr for ControllerKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "pd" => Ok(ControllerKind::Pd),
            "pd_gravity" => Ok(ControllerKind::PdGravity),
            "replay" => Ok(ControllerKind::Replay),
            other => Err(format!("unknown controller '{other}'; expected pd, pd_gravity or replay")),
        }
    }
}

/// The `simgap.experiment` metadata of a log.
#[derive(Clone, Debug, PartialEq)]
pub struct Experiment {
    /// Controller kind.
    pub controller: ControllerKind,
    /// Joint names giving the order of `kp` and `kv`.
    pub joints: Vec<String>,
    /// Proportional gains [N·m/rad], aligned with `joints`.
    pub kp: Vec<f64>,
    /// Derivative gains [N·m·s/rad], aligned with `joints`.
    pub kv: Vec<f64>,
    /// Controller sample period [s].
    pub sample_period: f64,
    /// Any other metadata entries, kept as read.
    pub extra: BTreeMap<String, String>,
}

/// A run as columnar arrays. Matrices are row-major `len() × dof()` in `joints` order.
#[derive(Clone, Debug, PartialEq)]
pub struct Run {
    /// Joint names (the column order of every matrix here).
    pub joints: Vec<String>,
    /// Sample times [s], strictly increasing (absolute times allowed).
    pub t: Vec<f64>,
    /// Measured positions q [rad or m].
    pub q: Vec<f64>,
    /// Measured velocities q̇ as the controller saw them.
    pub qd: Vec<f64>,
    /// Commanded effort τ_cmd [N·m or N] (empty when a log has none: check before replaying
    /// or fitting).
    pub tau: Vec<f64>,
    /// Reference positions q_ref (empty when the log has none).
    pub q_ref: Vec<f64>,
    /// Reference velocities q̇_ref (empty when the log has none, meaning zero).
    pub qd_ref: Vec<f64>,
    /// Feed-forward torque τ_ff [N·m or N] the controller adds to its feedback (the `effort` of
    /// `/joint_reference`; empty means zero).
    pub tau_ff: Vec<f64>,
    /// Torque the drives report delivering [N·m or N] (`/joint_effort_measured`; empty when
    /// the log has none).
    pub tau_measured: Vec<f64>,
    /// Absolute time of the log's first sample [ns since the Unix epoch] when the log had
    /// absolute stamps; `t` is then time since that start (`t[0]` = 0).
    pub start_ns: Option<i64>,
    /// The experiment, when known.
    pub experiment: Option<Experiment>,
    /// Where the run came from (file name, or `simulation`).
    pub source: String,
}

impl Run {
    /// An empty run for these joints.
    pub fn new(joints: Vec<String>) -> Self {
        Run {
            joints,
            t: Vec::new(),
            q: Vec::new(),
            qd: Vec::new(),
            tau: Vec::new(),
            q_ref: Vec::new(),
            qd_ref: Vec::new(),
            tau_ff: Vec::new(),
            tau_measured: Vec::new(),
            start_ns: None,
            experiment: None,
            source: String::new(),
        }
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True when there is no sample.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Row `k` of a row-major matrix of this run.
    ///
    /// # Panics
    /// If `k` is out of range.
    pub fn row<'a>(&self, m: &'a [f64], k: usize) -> &'a [f64] {
        let n = self.dof();
        &m[k * n..(k + 1) * n]
    }

    /// Column of joint `j` of a row-major matrix of this run.
    pub fn column(&self, m: &[f64], j: usize) -> Vec<f64> {
        let n = self.dof();
        m.iter().skip(j).step_by(n).copied().collect()
    }

    /// Duration [s] (zero for fewer than two samples).
    pub fn duration(&self) -> f64 {
        match (self.t.first(), self.t.last()) {
            (Some(a), Some(b)) => b - a,
            _ => 0.0,
        }
    }
}

/// One sample handed to a [`Sink`](crate::sink::Sink).
#[derive(Clone, Copy, Debug)]
pub struct Sample<'a> {
    /// Time [s].
    pub t: f64,
    /// Measured positions.
    pub q: &'a [f64],
    /// Measured velocities.
    pub qd: &'a [f64],
    /// Commanded effort.
    pub tau: &'a [f64],
    /// Reference positions.
    pub q_ref: &'a [f64],
    /// Reference velocities.
    pub qd_ref: &'a [f64],
}
