//! `simgap.Run`, logs, the L² index and closed-loop simulation (`simgap-sim`).
//!
//! A `Run` holds columnar arrays (`t` of shape `(N,)`, `q`, `qd`, `tau`, `q_ref`, `qd_ref`,
//! `tau_ff`, `tau_measured` of shape `(N, dof)` in `joints` order, C-ordered float64). Logs are matched to models by joint
//! name. Reading, writing and simulating release the GIL; a simulation stops at the next sample
//! on Ctrl-C and raises `KeyboardInterrupt`.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use numpy::PyUntypedArrayMethods;
use pyo3::prelude::*;
use simgap_core::Model;
use simgap_log::{LogOptions, TopicMap};
use simgap_sim::reference::{Reference, Step};
use simgap_sim::{experiment_from_map, experiment_to_map, reorder_joints};
use simgap_sim::{ControllerKind, Effect, Experiment, Integrator, L2Report, MemorySink, Plant, Run, RunEnd, SensorParams, SimParams, VelocityEstimate};

use crate::conv::{row_major, to_array, ArrayArg};
use crate::errors::{from_log, from_sim, Kind};
use crate::model::{formulation, PyModel};
use crate::worker::WorkerError;

/// A run of a robot or a simulation: time, measured and reference signals, and the experiment
/// (controller, gains, sample period) that produced it.
///
/// Matrices have shape (N, dof) with columns in `joints` order, as C-ordered float64 arrays.
#[pyclass(module = "simgap._simgap", name = "Run", frozen)]
pub(crate) struct PyRun {
    run: Arc<Run>,
}

impl PyRun {
    pub(crate) fn from_run(run: Run) -> Self {
        PyRun { run: Arc::new(run) }
    }

    /// The run, shared.
    pub(crate) fn shared(&self) -> Arc<Run> {
        self.run.clone()
    }

    fn matrix<'py>(&self, py: Python<'py>, m: &[f64]) -> Option<Bound<'py, PyAny>> {
        (!m.is_empty() || self.run.is_empty()).then(|| to_array(py, m.to_vec(), &[self.run.len(), self.run.dof()]).into_any())
    }
}

/// A `(rows, cols)` matrix argument, or `(rows,)` when `cols` is `None`, flattened row-major.
fn sized(name: &str, arr: &ArrayArg<'_>, rows: usize, cols: Option<usize>) -> PyResult<Vec<f64>> {
    let shape = arr.shape();
    let ok = match cols {
        None => shape == [rows],
        Some(c) => shape == [rows, c],
    };
    if !ok {
        let expected = match cols {
            None => format!("({rows},)"),
            Some(c) => format!("({rows}, {c})"),
        };
        return Err(Kind::Dimension.err(format!("{name}: expected shape {expected}, got {shape:?}")));
    }
    Ok(row_major(arr).into_owned())
}

/// An experiment from its `simgap.experiment` metadata map.
fn experiment(map: BTreeMap<String, String>) -> PyResult<Experiment> {
    experiment_from_map(&map).map_err(|m| Kind::Log.err(format!("experiment: {m}")))
}

#[pymethods]
impl PyRun {
    /// Builds a run from arrays; `joints` names the columns. `tau`, `q_ref`, `qd_ref`,
    /// `tau_ff`, `tau_measured` may be omitted; `experiment` is the `simgap.experiment` metadata
    /// map (`controller`, `joints`, `kp`, `kv`, `sample_period`, as strings); `start_ns` the
    /// absolute time of `t = 0` [ns since the Unix epoch]. A position-controlled servo's
    /// signals: `duty` (PWM duty in [−1, 1]), `torque_enable` (0/1) and `temperature` [°C], shape
    /// (N, dof), and `voltage` [V], shape (N,).
    ///
    /// Raises DimensionError for arrays of the wrong shape, LogError for an invalid run (time
    /// not strictly increasing, non-finite values, duplicate joints, a bad experiment).
    #[new]
    #[pyo3(signature = (joints, t, q, qd, tau = None, q_ref = None, qd_ref = None, experiment = None, source = "python", tau_ff = None, tau_measured = None, start_ns = None, duty = None, torque_enable = None, voltage = None, temperature = None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        joints: Vec<String>,
        t: ArrayArg<'_>,
        q: ArrayArg<'_>,
        qd: ArrayArg<'_>,
        tau: Option<ArrayArg<'_>>,
        q_ref: Option<ArrayArg<'_>>,
        qd_ref: Option<ArrayArg<'_>>,
        experiment: Option<BTreeMap<String, String>>,
        source: &str,
        tau_ff: Option<ArrayArg<'_>>,
        tau_measured: Option<ArrayArg<'_>>,
        start_ns: Option<i64>,
        duty: Option<ArrayArg<'_>>,
        torque_enable: Option<ArrayArg<'_>>,
        voltage: Option<ArrayArg<'_>>,
        temperature: Option<ArrayArg<'_>>,
    ) -> PyResult<Self> {
        let n = joints.len();
        let t = match t.shape() {
            [_] => row_major(&t).into_owned(),
            s => return Err(Kind::Dimension.err(format!("t: expected shape (N,), got {s:?}"))),
        };
        let rows = t.len();
        let opt = |name: &str, a: &Option<ArrayArg<'_>>| a.as_ref().map_or(Ok(Vec::new()), |a| sized(name, a, rows, Some(n)));
        let run = Run {
            q: sized("q", &q, rows, Some(n))?,
            qd: sized("qd", &qd, rows, Some(n))?,
            tau: opt("tau", &tau)?,
            q_ref: opt("q_ref", &q_ref)?,
            qd_ref: opt("qd_ref", &qd_ref)?,
            tau_ff: opt("tau_ff", &tau_ff)?,
            tau_measured: opt("tau_measured", &tau_measured)?,
            drive: simgap_sim::DriveSignals {
                duty: opt("duty", &duty)?,
                torque_enable: opt("torque_enable", &torque_enable)?,
                voltage: voltage.as_ref().map_or(Ok(Vec::new()), |a| sized("voltage", a, rows, None))?,
                temperature: opt("temperature", &temperature)?,
            },
            start_ns,
            experiment: experiment.map(self::experiment).transpose()?,
            source: source.to_owned(),
            notes: Vec::new(),
            left_out: Vec::new(),
            t,
            joints,
        };
        simgap_sim::validate_run(&run).map_err(from_sim)?;
        Ok(PyRun::from_run(run))
    }

    /// Joint names: the column order of every matrix.
    #[getter]
    fn joints(&self) -> Vec<String> {
        self.run.joints.clone()
    }

    /// Number of joints.
    #[getter]
    fn dof(&self) -> usize {
        self.run.dof()
    }

    /// Sample times [s], shape (N,): time since the log's start (see `start_ns`).
    #[getter]
    fn t<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        to_array(py, self.run.t.clone(), &[self.run.len()]).into_any()
    }

    /// Measured positions [rad or m], shape (N, dof).
    #[getter]
    fn q<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        to_array(py, self.run.q.clone(), &[self.run.len(), self.run.dof()]).into_any()
    }

    /// Measured velocities (as the controller saw them) [rad/s or m/s], shape (N, dof).
    #[getter]
    fn qd<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        to_array(py, self.run.qd.clone(), &[self.run.len(), self.run.dof()]).into_any()
    }

    /// Commanded torques [N·m or N], shape (N, dof); None when the log has no effort.
    #[getter]
    fn tau<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyAny>> {
        self.matrix(py, &self.run.tau)
    }

    /// Reference positions, shape (N, dof); None when the run has no reference.
    #[getter]
    fn q_ref<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyAny>> {
        self.matrix(py, &self.run.q_ref)
    }

    /// Reference velocities, shape (N, dof); None when absent (zero).
    #[getter]
    fn qd_ref<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyAny>> {
        self.matrix(py, &self.run.qd_ref)
    }

    /// Feed-forward torques the controller adds to its feedback [N·m or N] (the effort of the
    /// reference topic), shape (N, dof); None when absent (zero).
    #[getter]
    fn tau_ff<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyAny>> {
        self.matrix(py, &self.run.tau_ff)
    }

    /// Torques the drives report delivering [N·m or N] (`/joint_effort_measured`), shape
    /// (N, dof); None when the log has none.
    #[getter]
    fn tau_measured<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyAny>> {
        self.matrix(py, &self.run.tau_measured)
    }

    /// A servo's measured PWM duty in [−1, 1], shape (N, dof); None when the log has none.
    #[getter]
    fn duty<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyAny>> {
        self.matrix(py, &self.run.drive.duty)
    }

    /// A servo's torque enable (0 or 1), shape (N, dof); None when the log has none (enabled).
    #[getter]
    fn torque_enable<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyAny>> {
        self.matrix(py, &self.run.drive.torque_enable)
    }

    /// A servo's supply voltage [V], shape (N,); None when the log has none.
    #[getter]
    fn voltage<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyAny>> {
        (!self.run.drive.voltage.is_empty()).then(|| to_array(py, self.run.drive.voltage.clone(), &[self.run.len()]).into_any())
    }

    /// A servo's temperature [°C], shape (N, dof); None when the log has none.
    #[getter]
    fn temperature<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyAny>> {
        self.matrix(py, &self.run.drive.temperature)
    }

    /// Absolute time of `t = 0` [ns since the Unix epoch] for logs with absolute stamps, else
    /// None.
    #[getter]
    fn start_ns(&self) -> Option<i64> {
        self.run.start_ns
    }

    /// The `simgap.experiment` metadata as a dict of strings, or None.
    #[getter]
    fn experiment(&self) -> Option<BTreeMap<String, String>> {
        self.run.experiment.as_ref().map(experiment_to_map)
    }

    /// Where the run came from (file name, or "simulation").
    #[getter]
    fn source(&self) -> String {
        self.run.source.clone()
    }

    /// What the log's reader noted for a report (e.g. that a LeRobot dataset's timestamps are
    /// nominal), one sentence each; a diagnosis puts them in its notes.
    #[getter]
    fn notes(&self) -> Vec<String> {
        self.run.notes.clone()
    }

    /// Joints the log records but not as positions a model can use (a LeRobot joint
    /// range-normalised without its calibration file): not in `joints`; a diagnosis locks a
    /// model joint of that name at its zero position.
    #[getter]
    fn left_out(&self) -> Vec<String> {
        self.run.left_out.clone()
    }

    /// Duration [s]: last sample time minus first (0 for fewer than two samples).
    #[getter]
    fn duration(&self) -> f64 {
        self.run.duration()
    }

    fn __len__(&self) -> usize {
        self.run.len()
    }

    fn __repr__(&self) -> String {
        format!("Run(source={:?}, joints={:?}, samples={}, duration={})", self.run.source, self.run.joints, self.run.len(), self.run.duration())
    }
}

/// L² indices of a difference signal (the seed paper's eq. 127).
#[pyclass(module = "simgap._simgap", name = "L2Report", frozen)]
pub(crate) struct PyL2Report {
    report: L2Report,
}

#[pymethods]
impl PyL2Report {
    /// Joint names (the order of the per-joint arrays).
    #[getter]
    fn joints(&self) -> Vec<String> {
        self.report.joints.clone()
    }

    /// L² of the whole difference vector [rad or m].
    #[getter]
    fn overall(&self) -> f64 {
        self.report.overall
    }

    /// L² of each joint, shape (dof,).
    #[getter]
    fn per_joint<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        to_array(py, self.report.per_joint.clone(), &[self.report.per_joint.len()]).into_any()
    }

    /// Maximum absolute difference of each joint, shape (dof,).
    #[getter]
    fn max_abs_per_joint<'py>(&self, py: Python<'py>) -> Bound<'py, PyAny> {
        to_array(py, self.report.max_abs_per_joint.clone(), &[self.report.max_abs_per_joint.len()]).into_any()
    }

    /// Time span used, (start, end) [s].
    #[getter]
    fn span(&self) -> (f64, f64) {
        self.report.span
    }

    /// Number of samples used.
    #[getter]
    fn samples(&self) -> usize {
        self.report.samples
    }

    fn __repr__(&self) -> String {
        format!("L2Report(overall={}, per_joint={:?}, joints={:?}, samples={})", self.report.overall, self.report.per_joint, self.report.joints, self.report.samples)
    }
}

/// The options of a read: topic map, experiment, LeRobot calibration file.
fn log_options(topics: Option<BTreeMap<String, String>>, experiment: Option<BTreeMap<String, String>>, calibration: Option<PathBuf>) -> PyResult<LogOptions> {
    let mut options = LogOptions {
        experiment: experiment.map(self::experiment).transpose()?,
        calibration: calibration.map(|c| simgap_log::lerobot::Calibration::read(&c)).transpose().map_err(from_log)?,
        ..LogOptions::default()
    };
    if let Some(map) = topics {
        let mut t = TopicMap::default();
        for (role, spec) in map {
            let spec = simgap_log::TopicSpec::parse(&spec).map_err(|m| Kind::Log.err(format!("topics: {m}")))?;
            t.set(&role, spec).map_err(|m| Kind::Log.err(format!("topics: {m}")))?;
        }
        options.topics = t;
    }
    Ok(options)
}

/// A read's warnings as UserWarnings naming the log.
fn warn(py: Python<'_>, path: &std::path::Path, warnings: &[String]) -> PyResult<()> {
    for w in warnings {
        let message = std::ffi::CString::new(format!("{}: {w}", path.display())).unwrap_or_default();
        PyErr::warn(py, &py.get_type::<pyo3::exceptions::PyUserWarning>(), &message, 1)?;
    }
    Ok(())
}

/// The run with its columns in `joints` order (by name); joints the log left out
/// (`Run.left_out`) are skipped, not an error.
fn in_order(run: Run, joints: Option<&[String]>) -> PyResult<Run> {
    match joints {
        None => Ok(run),
        Some(j) => {
            let wanted: Vec<String> = j.iter().filter(|j| !run.left_out.contains(j)).cloned().collect();
            reorder_joints(&run, &wanted, false).map_err(from_sim)
        }
    }
}

/// Reads a log: a ROS 2 MCAP file (`.mcap`), a rosbag2 bag folder (`metadata.yaml` and
/// `.mcap` files), CSV (`.csv` / `.csv.gz`), or one episode of a LeRobot dataset
/// (`FOLDER#N`; a folder or selection of several episodes is read with `read_logs`).
///
/// With `joints` (e.g. `model.joint_names`), the columns are put in that order, matched by
/// name (joints the log leaves out, `Run.left_out`, are skipped). `topics` maps roles to
/// topics, e.g. `{"states": "/arm/joint_states", "effort":
/// "/effort_controller/commands[j1;j2]"}` (roles `states`, `reference`, `effort`,
/// `measured_effort`; joint names in brackets for messages without names). `experiment` (the
/// `simgap.experiment` map) applies only if the log carries none (no metadata record, no
/// sidecar `NAME.experiment.json`, for a dataset `meta/simgap.experiment.json`).
/// `calibration`: LeRobot's calibration file, which makes a dataset's range-normalised joint
/// (a gripper's 0–100) an angle; without it that joint is left out. A file its recorder did
/// not finish is read up to its last complete record, with a UserWarning saying how much was
/// recovered. Raises LogError naming the file and the problem, for any content of the file.
#[pyfunction]
#[pyo3(signature = (path, joints = None, topics = None, experiment = None, calibration = None))]
pub(crate) fn read_log(
    py: Python<'_>,
    path: PathBuf,
    joints: Option<Vec<String>>,
    topics: Option<BTreeMap<String, String>>,
    experiment: Option<BTreeMap<String, String>>,
    calibration: Option<PathBuf>,
) -> PyResult<PyRun> {
    let options = log_options(topics, experiment, calibration)?;
    let read = py.detach(|| simgap_log::read_log_with_warnings(&path, &options)).map_err(from_log)?;
    warn(py, &path, &read.warnings)?;
    Ok(PyRun::from_run(in_order(read.run, joints.as_deref())?))
}

/// Reads every run a log holds, as a list: one per episode of a LeRobot dataset (a folder
/// means every episode, `FOLDER#0,3-5` those episodes, in that order; each run is named
/// `FOLDER#N`), else the one run of an MCAP file, bag folder or CSV file. The arguments are
/// `read_log`'s; a dataset's warnings are given once. Raises LogError naming the folder, the
/// file and the episode.
#[pyfunction]
#[pyo3(signature = (path, joints = None, topics = None, experiment = None, calibration = None))]
pub(crate) fn read_logs(
    py: Python<'_>,
    path: PathBuf,
    joints: Option<Vec<String>>,
    topics: Option<BTreeMap<String, String>>,
    experiment: Option<BTreeMap<String, String>>,
    calibration: Option<PathBuf>,
) -> PyResult<Vec<PyRun>> {
    let options = log_options(topics, experiment, calibration)?;
    let reads = py.detach(|| simgap_log::read_logs_with_warnings(&path, &options)).map_err(from_log)?;
    warn(py, &path, reads.first().map(|r| r.warnings.as_slice()).unwrap_or_default())?;
    reads.into_iter().map(|r| in_order(r.run, joints.as_deref()).map(PyRun::from_run)).collect()
}

/// The episode indices of a LeRobot dataset folder, in order (`FOLDER#N` reads episode `N`).
/// Raises LogError naming the folder and the metadata file at fault.
#[pyfunction]
#[pyo3(signature = (path))]
pub(crate) fn lerobot_episodes(py: Python<'_>, path: PathBuf) -> PyResult<Vec<i64>> {
    py.detach(|| simgap_log::lerobot::episode_indices(&path)).map_err(from_log)
}

/// Writes a run as a log, the format chosen by extension (`.mcap`, `.csv`, `.csv.gz`; CSV logs
/// get their experiment in a sidecar JSON file). Raises LogError.
#[pyfunction]
#[pyo3(signature = (run, path))]
pub(crate) fn write_log(py: Python<'_>, run: &PyRun, path: PathBuf) -> PyResult<()> {
    let run = run.run.clone();
    py.detach(|| simgap_log::write_log(&run, &path)).map_err(from_log)
}

/// The L² index (eq. 127): sqrt(1/(t_end − t_0) ∫ ‖x‖² dt), trapezoid rule.
///
/// `t`: sample times, shape (N,); `x`: the signal, shape (N,) or (N, k). Zero for fewer than
/// two samples.
#[pyfunction]
#[pyo3(signature = (t, x))]
pub(crate) fn l2(t: ArrayArg<'_>, x: ArrayArg<'_>) -> PyResult<f64> {
    let ts = match t.shape() {
        [_] => row_major(&t),
        s => return Err(Kind::Dimension.err(format!("t: expected shape (N,), got {s:?}"))),
    };
    let cols = match x.shape() {
        [n] if *n == ts.len() => 1,
        [n, k] if *n == ts.len() => *k,
        s => return Err(Kind::Dimension.err(format!("x: expected shape ({0},) or ({0}, k) like t, got {s:?}", ts.len()))),
    };
    Ok(simgap_sim::l2_index(&ts, &row_major(&x), cols))
}

/// L² of the position difference a.q − b.q (eq. 127), with `b` linearly resampled onto `a`'s
/// times and joints matched by name; only samples inside both runs and inside
/// `window = (start, end)` [s] count. Raises LogError when a joint of `a` is not in `b`,
/// SimulationError when fewer than two samples remain.
#[pyfunction]
#[pyo3(signature = (a, b, window = None))]
pub(crate) fn compare(a: &PyRun, b: &PyRun, window: Option<(f64, f64)>) -> PyResult<PyL2Report> {
    simgap_sim::l2_between(&a.run, &b.run, window).map(|report| PyL2Report { report }).map_err(from_sim)
}

/// L² of a run's tracking error q_ref − q (eq. 127 as the paper uses it), optionally within
/// `window = (start, end)` [s]. Raises SimulationError when the run has no reference.
#[pyfunction]
#[pyo3(signature = (run, window = None))]
pub(crate) fn l2_tracking(run: &PyRun, window: Option<(f64, f64)>) -> PyResult<PyL2Report> {
    simgap_sim::l2_tracking(&run.run, window).map(|report| PyL2Report { report }).map_err(from_sim)
}

/// Everything a simulation needs, owned, so that it can run on another thread.
struct Job {
    model: Arc<Model>,
    formulation: simgap_core::Formulation,
    effects: Vec<Effect>,
    experiment: Experiment,
    reference: Option<Arc<Run>>,
    target: Vec<f64>,
    replay: Option<Arc<Run>>,
    params: SimParams,
}

impl Job {
    /// Runs the closed loop; `stop` ends it at the next sample.
    fn run(&self, stop: &AtomicBool) -> simgap_sim::Result<(Run, RunEnd)> {
        let plant = Plant::new(&self.model, self.formulation, &self.effects)?;
        let mut controller = simgap_sim::controller_from_experiment(&self.experiment, &self.model, self.replay.as_deref())?;
        let reference: Box<dyn Reference> = match &self.reference {
            Some(run) => simgap_sim::reference_from_run_for(run, &self.model)?,
            None => Box::new(Step { target: self.target.clone() }),
        };
        let mut sink = MemorySink::new();
        let end = simgap_sim::simulate::simulate(&plant, controller.as_mut(), reference.as_ref(), &self.params, &mut sink, Some(stop))?;
        let mut run = sink.into_run();
        run.source = "simulation".to_owned();
        Ok((run, end))
    }
}

/// Runs `job` on its own thread (see [`crate::worker`]); on Ctrl-C the simulation stops at its
/// next sample.
fn run_interruptible(py: Python<'_>, job: Job) -> PyResult<Run> {
    let result = match crate::worker::run_interruptible(py, "simgap-simulate", move |stop| job.run(stop)) {
        Ok(result) => result,
        Err(WorkerError::Signal(e)) => return Err(e),
        Err(WorkerError::Spawn(e)) => return Err(Kind::Simulation.err(format!("cannot start the simulation thread: {e}"))),
        Err(WorkerError::Lost) => return Err(Kind::Simulation.err("the simulation thread ended without a result")),
    };
    let (run, end) = result.map_err(from_sim)?;
    end.into_result().map_err(from_sim)?;
    Ok(run)
}

/// A joint vector argument of length `dof`.
fn joint_vector(name: &str, arr: &ArrayArg<'_>, dof: usize) -> PyResult<Vec<f64>> {
    match arr.shape() {
        [n] if *n == dof => Ok(row_major(arr).into_owned()),
        [n] => Err(Kind::Dimension.err(format!("{name}: expected {dof}, got {n}"))),
        s => Err(Kind::Dimension.err(format!("{name}: expected shape ({dof},), got {s:?}"))),
    }
}

/// Simulates the sampled closed loop: the plant `model` (plus `effects`) under a controller
/// following `reference`, sampled like a real controller (zero-order hold, encoder
/// quantisation, backward-difference velocity), integrated by RK4. Returns the run as a log
/// would record it (measured q, q̇ as the controller saw them, commanded τ, reference).
///
/// `reference`: a target position, shape (dof,) (a step at t0; q̇_ref = 0), or a Run whose
/// reference (else measured q) is followed, joints matched by name. With a Run, `t0`,
/// `duration`, `q0`, `qd0`, the controller, its gains and the sample period default to the
/// run's (its first sample, its experiment).
///
/// `experiment`: a dict of the `simgap.experiment` keys (a sidecar's) or the path of an
/// experiment file, in place of the reference run's: the controller, its gains or a servo's
/// constants, the sample period.
///
/// `controller`: "pd" (τ = Kp(q_ref − q) + Kv(q̇_ref − q̇)), "pd_gravity" (plus the model's
/// g(q)), "replay" (the logged effort of `replay`, default the reference run, open loop) or
/// "servo" (a position-controlled servo with the constants of the experiment, `duty_gain`,
/// `max_duty`, `supply_voltage`, `kt`, `R`, reading the reference run's logged torque enable
/// and voltage, if any; the returned run holds its duty, torque enable and voltage besides
/// the command τ = (kt/R) V duty). `kp`, `kv`: gains, shape (dof,), in model order.
/// `effects`: unmodelled effects in the CLI spelling, e.g. "viscous_friction:b=2.288,0.175",
/// "coulomb_friction:fc=7.17,1.734;w=0.01".
/// `coulomb_width` [rad/s or m/s]: the width `w` of sign(q̇) ≈ tanh(q̇/w) for every dry
/// friction spelled without its own `w` (0: the exact sign); a `w` in the spelling wins.
/// `integrator`: "rk4" (`substeps` steps per sample, raised automatically for stiff friction)
/// or "adaptive" (Dormand–Prince with `rtol`, `atol`). `counts_per_rev`: encoder resolution
/// (default 1,024,000 counts per revolution; None = exact positions); `velocity`:
/// "backward_difference" or "exact".
///
/// Raises SimulationError when the run diverges or a parameter is invalid, LogError when the
/// reference or replay run does not match the model's joints, DimensionError for vectors of
/// the wrong length, KeyboardInterrupt on Ctrl-C. Ranges are checked at once, with the words of
/// `simgap simulate`: 1e-6 ≤ sample_period ≤ 1 s, 0 < duration ≤ 86400 s, 1 ≤ substeps ≤
/// 10000, at most 1e9 integration steps, and at most 1e7 samples (the returned Run is held in
/// memory; `simgap simulate --out RUN.mcap` writes longer runs as they go).
#[pyfunction]
#[pyo3(signature = (
    model, reference, *, controller = None, kp = None, kv = None, replay = None,
    formulation = "euler_lagrange", effects = Vec::new(), duration = None, sample_period = None, t0 = None,
    q0 = None, qd0 = None, substeps = 1, integrator = "rk4", rtol = 1e-10, atol = 1e-10,
    counts_per_rev = Some(1_024_000.0), velocity = "backward_difference", noise_std = 0.0, seed = 0,
    coulomb_width = 0.01, torque_limits_from_model = false, divergence_bound = 1e4, experiment = None
))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn simulate(
    py: Python<'_>,
    model: &PyModel,
    reference: &Bound<'_, PyAny>,
    controller: Option<&str>,
    kp: Option<ArrayArg<'_>>,
    kv: Option<ArrayArg<'_>>,
    replay: Option<&PyRun>,
    formulation: &str,
    effects: Vec<String>,
    duration: Option<f64>,
    sample_period: Option<f64>,
    t0: Option<f64>,
    q0: Option<ArrayArg<'_>>,
    qd0: Option<ArrayArg<'_>>,
    substeps: usize,
    integrator: &str,
    rtol: f64,
    atol: f64,
    counts_per_rev: Option<f64>,
    velocity: &str,
    noise_std: f64,
    seed: u64,
    coulomb_width: f64,
    torque_limits_from_model: bool,
    divergence_bound: f64,
    experiment: Option<&Bound<'_, PyAny>>,
) -> PyResult<PyRun> {
    let model_arc = model.model();
    let dof = model_arc.dof();
    let joints: Vec<String> = model_arc.joint_names().into_iter().map(str::to_owned).collect();
    let formulation = self::formulation(formulation)?;
    let bad = |what: &str, message: String| from_sim(simgap_sim::Error::Invalid { what: what.into(), message });
    // the width of dry frictions spelled without `w`: checked whether or not one needs it
    if !(coulomb_width.is_finite() && coulomb_width >= 0.0) {
        return Err(bad("coulomb_width", format!("{} rad/s; expected a finite width >= 0 (0: the exact sign)", simgap_sim::simulate::number(coulomb_width))));
    }
    let effects = effects.iter().map(|s| Effect::parse_with_width(s, dof, coulomb_width)).collect::<Result<Vec<_>, _>>().map_err(from_sim)?;

    // the reference: a target or a run (then also the defaults of the run)
    let (reference_run, target) = match reference.cast::<PyRun>() {
        Ok(r) => (Some(r.get().run.clone()), Vec::new()),
        Err(_) => {
            let target: ArrayArg<'_> = reference.extract().map_err(|e| Kind::Dimension.err(format!("reference: expected a Run or a target of shape ({dof},): {e}")))?;
            (None, joint_vector("reference", &target, dof)?)
        }
    };
    let first_state = match &reference_run {
        Some(run) if !run.is_empty() => {
            let ordered = reorder_joints(run, &joints, true).map_err(from_sim)?;
            let qd0 = if ordered.qd.is_empty() { vec![0.0; dof] } else { ordered.qd[..dof].to_vec() };
            Some((ordered.q[..dof].to_vec(), qd0))
        }
        Some(run) => return Err(bad("reference", format!("{}: the run has no sample", run.source))),
        None => None,
    };
    // the experiment given, else the reference run's
    let given = experiment.filter(|e| !e.is_none()).map(crate::conv::experiment_arg).transpose()?;
    let logged = given.or_else(|| reference_run.as_ref().and_then(|r| r.experiment.clone()));

    // the controller and its experiment
    let kind = match (controller, &logged) {
        (Some(c), _) => c.parse::<ControllerKind>().map_err(|m| bad("controller", m))?,
        (None, Some(e)) => e.controller,
        (None, None) => return Err(bad("controller", "none given, no experiment given and the reference has none; expected 'pd', 'pd_gravity', 'replay' or 'servo'".into())),
    };
    let period = sample_period.or(logged.as_ref().map(|e| e.sample_period).filter(|p| p.is_finite() && *p > 0.0)).unwrap_or(0.0025);
    let experiment = match (kind, kp, kv, &logged) {
        (ControllerKind::Replay, _, _, _) => Experiment { controller: kind, joints: joints.clone(), kp: Vec::new(), kv: Vec::new(), sample_period: period, extra: BTreeMap::new() },
        (_, Some(kp), Some(kv), _) => Experiment {
            controller: kind,
            joints: joints.clone(),
            kp: joint_vector("kp", &kp, dof)?,
            kv: joint_vector("kv", &kv, dof)?,
            sample_period: period,
            extra: BTreeMap::new(),
        },
        (_, None, None, Some(e)) => Experiment { controller: kind, sample_period: period, ..e.clone() },
        _ => return Err(bad("gains", "expected both kp and kv (or an experiment, given or the reference run's, that has them)".into())),
    };
    // the run the controller reads: a replay's efforts, a servo's torque enable and voltage
    let replay = match (kind, replay) {
        (ControllerKind::Replay, Some(r)) => Some(r.run.clone()),
        (ControllerKind::Replay | ControllerKind::Servo, None) => reference_run.clone(),
        _ => None,
    };

    // the parameters
    let integrator = match integrator {
        "rk4" => Integrator::Rk4,
        "adaptive" => Integrator::Adaptive { rtol, atol },
        other => return Err(bad("integrator", format!("'{other}'; expected 'rk4' or 'adaptive'"))),
    };
    let velocity = match velocity {
        "backward_difference" => VelocityEstimate::BackwardDifference,
        "exact" => VelocityEstimate::Exact,
        other => return Err(bad("velocity", format!("'{other}'; expected 'backward_difference' or 'exact'"))),
    };
    let span = reference_run.as_ref().map(|r| (r.t[0], r.duration()));
    let state = |name: &str, given: Option<ArrayArg<'_>>, from_run: Option<Vec<f64>>| -> PyResult<Vec<f64>> {
        match given {
            Some(a) => joint_vector(name, &a, dof),
            None => Ok(from_run.unwrap_or_default()),
        }
    };
    let params = SimParams {
        t0: t0.or(span.map(|s| s.0)).unwrap_or(0.0),
        sample_period: period,
        duration: duration.or(span.map(|s| s.1)).unwrap_or(3.0),
        substeps,
        integrator,
        sensor: SensorParams { counts_per_rev, velocity, noise_std, seed },
        torque_limits_from_model,
        divergence_bound,
        q0: state("q0", q0, first_state.as_ref().map(|s| s.0.clone()))?,
        qd0: state("qd0", qd0, first_state.map(|s| s.1))?,
        experiment: Some(experiment.clone()),
    };
    // every range at once, with the CLI's words, before a thread is started or memory reserved
    params.validate(dof).map_err(from_sim)?;
    params.check_in_memory().map_err(from_sim)?;
    let job = Job { model: model_arc, formulation, effects, experiment, reference: reference_run, target, replay, params };
    run_interruptible(py, job).map(PyRun::from_run)
}
