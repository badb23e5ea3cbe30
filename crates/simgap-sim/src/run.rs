//! A run: what a robot or a simulation did, as columnar arrays, and the experiment behind it.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::experiment::check_experiment;
pub use crate::experiment::{experiment_from_map, experiment_to_map, ControllerKind, Experiment, KEY_CONTROLLER, KEY_JOINTS, KEY_KP, KEY_KV, KEY_SAMPLE_PERIOD};

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
    /// What a position-controlled servo logs beside its states (duty, torque enable, voltage,
    /// temperature); empty for other drives.
    pub drive: DriveSignals,
    /// Absolute time of the log's first sample [ns since the Unix epoch] when the log had
    /// absolute stamps; `t` is then time since that start (`t[0]` = 0).
    pub start_ns: Option<i64>,
    /// The experiment, when known.
    pub experiment: Option<Experiment>,
    /// Where the run came from (file name, or `simulation`).
    pub source: String,
    /// What the reader noted about the log for a report (e.g. that its timestamps are
    /// nominal), one sentence each, without the log's name.
    pub notes: Vec<String>,
    /// Joints of the robot the log records, but not as positions a model can use (a LeRobot
    /// joint range-normalised without its calibration): they are not in `joints`, and a
    /// diagnosis locks a model joint of that name at its zero position instead of refusing
    /// the log.
    pub left_out: Vec<String>,
}

/// What a position-controlled servo logs beside its states. Every vector may be empty (the
/// signal is absent); per-joint signals are row-major `len() × dof()` like the run's matrices.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DriveSignals {
    /// Measured PWM duty in [−1, 1] (the servo's *present PWM*; empty: not logged).
    pub duty: Vec<f64>,
    /// Torque enable, 0 (bridge open: no torque, no back-EMF) or 1 (empty: enabled throughout).
    pub torque_enable: Vec<f64>,
    /// Supply voltage [V], one value per sample (empty: the experiment's `supply_voltage`).
    pub voltage: Vec<f64>,
    /// Winding or case temperature [°C] (reported, not modelled; empty: not logged).
    pub temperature: Vec<f64>,
}

impl DriveSignals {
    /// True when no drive signal is logged.
    pub fn is_empty(&self) -> bool {
        self.duty.is_empty() && self.torque_enable.is_empty() && self.voltage.is_empty() && self.temperature.is_empty()
    }

    /// The signals with each per-joint matrix passed through `per_joint` and the voltage through
    /// `per_sample` (for a slice of the run, or its joints reordered).
    pub fn map(&self, per_joint: impl Fn(&[f64]) -> Vec<f64>, per_sample: impl Fn(&[f64]) -> Vec<f64>) -> DriveSignals {
        DriveSignals { duty: per_joint(&self.duty), torque_enable: per_joint(&self.torque_enable), voltage: per_sample(&self.voltage), temperature: per_joint(&self.temperature) }
    }

    /// Whether the drive of joint `j` is enabled at sample `k` (`dof` joints; enabled when the
    /// log has no torque-enable signal).
    pub fn enabled(&self, k: usize, j: usize, dof: usize) -> bool {
        self.torque_enable.get(k * dof + j).is_none_or(|e| *e > 0.5)
    }
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
            drive: DriveSignals::default(),
            start_ns: None,
            experiment: None,
            source: String::new(),
            notes: Vec::new(),
            left_out: Vec::new(),
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

    /// Samples `range` of the run (every signal it has, experiment and source kept; `range`
    /// clamped to the run's samples).
    pub fn slice(&self, range: std::ops::Range<usize>) -> Run {
        let (a, b) = (range.start.min(self.len()), range.end.min(self.len()));
        let (a, b) = (a.min(b), b);
        let n = self.dof();
        let rows = |m: &[f64]| if m.len() >= b * n { m[a * n..b * n].to_vec() } else { Vec::new() };
        Run {
            joints: self.joints.clone(),
            t: self.t[a..b].to_vec(),
            q: rows(&self.q),
            qd: rows(&self.qd),
            tau: rows(&self.tau),
            q_ref: rows(&self.q_ref),
            qd_ref: rows(&self.qd_ref),
            tau_ff: rows(&self.tau_ff),
            tau_measured: rows(&self.tau_measured),
            drive: self.drive.map(rows, |v| if v.len() >= b { v[a..b].to_vec() } else { Vec::new() }),
            start_ns: self.start_ns,
            experiment: self.experiment.clone(),
            source: self.source.clone(),
            notes: self.notes.clone(),
            left_out: self.left_out.clone(),
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
    /// What a position-controlled servo logs of its drive at this sample (`None` for a
    /// torque-controlled drive).
    pub drive: Option<DriveSample<'a>>,
}

/// The drive signals of a position-controlled servo at one sample, as it logs them (model
/// order): the duty its bridge applies (0 while disabled), its torque enable (1 or 0) and the
/// supply voltage [V].
#[derive(Clone, Copy, Debug)]
pub struct DriveSample<'a> {
    /// Duty in [−1, 1] applied over the sample (0 while the drive is disabled).
    pub duty: &'a [f64],
    /// Torque enable, 1 or 0.
    pub torque_enable: &'a [f64],
    /// Supply voltage [V].
    pub voltage: f64,
}

// ---------------------------------------------------------------------------------------------
// checks, joint mapping and resampling shared by every reader of runs

/// Checks a run: unique non-empty joint names, finite values, strictly increasing time,
/// matrices of `len() × dof()` values (`tau`, `q_ref`, `qd_ref`, `tau_ff`, `tau_measured` may
/// also be empty, `qd_ref` only with a `q_ref`), and an experiment whose gains match its joints, which must be joints
/// of the run.
///
/// # Errors
/// [`Error::Log`] with `run.source` as the path, saying what is wrong and where.
pub fn validate_run(run: &Run) -> Result<()> {
    let err = |m: String| log_error(Path::new(&run.source), m);
    let n = run.len();
    let dof = run.dof();
    // joint names
    let mut seen = HashSet::new();
    for j in &run.joints {
        if j.is_empty() {
            return Err(err("a joint has an empty name".into()));
        }
        if !seen.insert(j.as_str()) {
            return Err(err(format!("joint '{j}' appears twice")));
        }
    }
    // time: finite and strictly increasing
    for (k, &t) in run.t.iter().enumerate() {
        if !t.is_finite() {
            return Err(err(format!("time of sample {k} is {t}")));
        }
        if k > 0 && t <= run.t[k - 1] {
            return Err(err(format!("time is not strictly increasing: sample {k} at t = {t} s follows t = {} s", run.t[k - 1])));
        }
    }
    // matrix sizes and finite values
    let matrices: [(&str, &[f64], bool); 10] = [
        ("q", &run.q, false),
        ("qd", &run.qd, false),
        ("tau", &run.tau, true),
        ("q_ref", &run.q_ref, true),
        ("qd_ref", &run.qd_ref, true),
        ("tau_ff", &run.tau_ff, true),
        ("tau_measured", &run.tau_measured, true),
        ("duty", &run.drive.duty, true),
        ("torque_enable", &run.drive.torque_enable, true),
        ("temperature", &run.drive.temperature, true),
    ];
    for (name, m, may_be_empty) in matrices {
        if m.is_empty() && (may_be_empty || n == 0) {
            continue;
        }
        if m.len() != n * dof {
            return Err(err(format!("{name} has {} values, expected {n} samples × {dof} joints = {}", m.len(), n * dof)));
        }
        if let Some(i) = m.iter().position(|x| !x.is_finite()) {
            return Err(err(format!("{name} of joint '{}' is {} at t = {} s (sample {})", run.joints[i % dof], m[i], run.t[i / dof], i / dof)));
        }
    }
    if !run.qd_ref.is_empty() && run.q_ref.is_empty() {
        return Err(err("qd_ref is given without q_ref".into()));
    }
    // servo signals: a duty is a fraction of the supply, an enable is 0 or 1, a voltage one
    // positive number per sample
    if let Some(i) = run.drive.duty.iter().position(|d| d.abs() > 1.0 + 1e-9) {
        return Err(err(format!(
            "duty of joint '{}' is {} at t = {} s (sample {}); expected a PWM duty in [-1, 1]",
            run.joints[i % dof],
            run.drive.duty[i],
            run.t[i / dof],
            i / dof
        )));
    }
    if let Some(i) = run.drive.torque_enable.iter().position(|e| *e != 0.0 && *e != 1.0) {
        return Err(err(format!("torque_enable of joint '{}' is {} at sample {}; expected 0 or 1", run.joints[i % dof], run.drive.torque_enable[i], i / dof)));
    }
    if !run.drive.voltage.is_empty() {
        if run.drive.voltage.len() != n {
            return Err(err(format!("voltage has {} values, expected one per sample ({n})", run.drive.voltage.len())));
        }
        if let Some(k) = run.drive.voltage.iter().position(|v| !(v.is_finite() && *v >= 0.0)) {
            return Err(err(format!("voltage is {} V at t = {} s (sample {k}); expected a finite number >= 0", run.drive.voltage[k], run.t[k])));
        }
    }
    // experiment
    if let Some(e) = &run.experiment {
        check_experiment(e).map_err(err)?;
        if let Some(j) = e.joints.iter().find(|j| !run.joints.contains(j)) {
            return Err(err(format!("the experiment names joint '{j}', which is not in the run (joints: {})", run.joints.join(", "))));
        }
    }
    Ok(())
}

/// Returns the run with its joints in `joints` order (a model's order).
///
/// With `drop_extra`, joints of the run that are not in `joints` are dropped (e.g. a gripper
/// finger in a bag of an arm); without, they are an error.
///
/// # Errors
/// [`Error::JointMismatch`] naming the first joint of `joints` missing from the run, or (without
/// `drop_extra`) the first joint of the run not in `joints`.
pub fn reorder_joints(run: &Run, joints: &[String], drop_extra: bool) -> Result<Run> {
    let mismatch = |joint: &str, problem: &str| Error::JointMismatch { source_name: run.source.clone(), joint: joint.to_string(), problem: problem.to_string() };
    let mut index = Vec::with_capacity(joints.len());
    for j in joints {
        match run.joints.iter().position(|r| r == j) {
            Some(i) => index.push(i),
            None => return Err(mismatch(j, &format!("is in the model but not in the log (log joints: {})", run.joints.join(", ")))),
        }
    }
    if !drop_extra {
        if let Some(extra) = run.joints.iter().find(|r| !joints.contains(r)) {
            return Err(mismatch(extra, &format!("is in the log but not in the model (model joints: {})", joints.join(", "))));
        }
    }
    let pick = |m: &[f64]| -> Vec<f64> {
        if m.is_empty() {
            return Vec::new();
        }
        let dof = run.dof();
        let mut out = Vec::with_capacity(run.len() * index.len());
        for row in m.chunks_exact(dof) {
            out.extend(index.iter().map(|&i| row[i]));
        }
        out
    };
    Ok(Run {
        joints: joints.to_vec(),
        t: run.t.clone(),
        q: pick(&run.q),
        qd: pick(&run.qd),
        tau: pick(&run.tau),
        q_ref: pick(&run.q_ref),
        qd_ref: pick(&run.qd_ref),
        tau_ff: pick(&run.tau_ff),
        tau_measured: pick(&run.tau_measured),
        drive: run.drive.map(pick, <[f64]>::to_vec),
        start_ns: run.start_ns,
        experiment: run.experiment.clone(),
        source: run.source.clone(),
        notes: run.notes.clone(),
        left_out: run.left_out.clone(),
    })
}

/// Gives an experiment without a sample period (read as NaN) the median spacing of the run's
/// stamps, as the metadata convention says.
pub fn fill_sample_period(run: &mut Run) {
    let Some(e) = run.experiment.as_mut() else { return };
    if !e.sample_period.is_nan() || run.t.len() < 2 {
        return;
    }
    let mut d: Vec<f64> = run.t.windows(2).map(|w| w[1] - w[0]).collect();
    d.sort_by(f64::total_cmp);
    e.sample_period = d[d.len() / 2];
}

/// Velocities by central differences of positions (one-sided at the ends), for logs without
/// measured velocities. `q` is row-major `t.len() × dof`; fewer than two samples give zeros.
pub fn central_difference(t: &[f64], q: &[f64], dof: usize) -> Vec<f64> {
    let n = t.len();
    let mut qd = vec![0.0; n * dof];
    if n < 2 {
        return qd;
    }
    for k in 0..n {
        let (a, b) = if k == 0 {
            (0, 1)
        } else if k == n - 1 {
            (n - 2, n - 1)
        } else {
            (k - 1, k + 1)
        };
        let dt = t[b] - t[a];
        for j in 0..dof {
            qd[k * dof + j] = (q[b * dof + j] - q[a * dof + j]) / dt;
        }
    }
    qd
}

/// Linear interpolation of the row-major matrix `m` (samples at `ts`, increasing) at the times
/// `t` (increasing), held constant outside `ts`. For references and measured torques logged at
/// other times than the states.
pub fn interpolate_rows(ts: &[f64], m: &[f64], dof: usize, t: &[f64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(t.len() * dof);
    let mut i = 0;
    for &x in t {
        if ts.is_empty() {
            out.extend(std::iter::repeat_n(0.0, dof));
            continue;
        }
        while i + 1 < ts.len() && ts[i + 1] <= x {
            i += 1;
        }
        if x <= ts[0] {
            out.extend_from_slice(&m[..dof]);
        } else if i + 1 >= ts.len() {
            out.extend_from_slice(&m[(ts.len() - 1) * dof..ts.len() * dof]);
        } else {
            let s = (x - ts[i]) / (ts[i + 1] - ts[i]);
            for j in 0..dof {
                let a = m[i * dof + j];
                let b = m[(i + 1) * dof + j];
                out.push(a + s * (b - a));
            }
        }
    }
    out
}

/// An [`Error::Log`] for `path`.
fn log_error(path: &Path, message: impl Into<String>) -> Error {
    Error::Log { path: PathBuf::from(path), message: message.into() }
}

/// Zero-order hold of the row-major matrix `m` (samples at `ts`, increasing) at the times `t`
/// (increasing): the row of the last `ts` at or before each time, the first row before `ts`
/// starts. For commands, which stay in force until the next one.
pub fn hold_rows(ts: &[f64], m: &[f64], dof: usize, t: &[f64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(t.len() * dof);
    let mut i = 0;
    for &x in t {
        if ts.is_empty() {
            out.extend(std::iter::repeat_n(0.0, dof));
            continue;
        }
        while i + 1 < ts.len() && ts[i + 1] <= x {
            i += 1;
        }
        out.extend_from_slice(&m[i * dof..(i + 1) * dof]);
    }
    out
}
