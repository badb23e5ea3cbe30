//! `simgap.diagnose` and `simgap.Report`: the Python face of `simgap diagnose`.
//!
//! `diagnose` reads the logs given as paths and runs `simgap_diag::diagnose` on its own thread
//! while this one, with the GIL released in between, checks for Ctrl-C every 50 ms (as
//! `sim::simulate` does). On Ctrl-C the diagnosis's stop flag is set, it stops at its next step
//! with `Error::Interrupted`, and `KeyboardInterrupt` is raised once the worker has ended.
//!
//! A `Report` holds the whole `Diagnosis` (for `to_html`) and its JSON text; every attribute is
//! the JSON parsed by Python's `json` module, so `to_dict()` has exactly the keys of the CLI's
//! `--json` output, `where` included.

use std::any::Any;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};

use pyo3::exceptions::{PyKeyError, PyTypeError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyString};
use simgap_core::{Formulation, Model};
use simgap_diag::{DiagnoseOptions, Diagnosis, Progress};
use simgap_sim::{Experiment, Run};

use crate::conv::{experiment_arg, type_name};
use crate::errors::{from_diag, Kind};
use crate::model::{formulation, PyModel};
use crate::sim::PyRun;
use crate::worker::WorkerError;

/// One log argument: a run already in memory, or a file to read.
enum Source {
    Run(Arc<Run>),
    Path(PathBuf),
}

impl Source {
    /// One item: a `Run`, or anything `os.fspath` accepts.
    fn from_item(name: &str, item: &Bound<'_, PyAny>) -> PyResult<Source> {
        if let Ok(run) = item.cast::<PyRun>() {
            return Ok(Source::Run(run.get().shared()));
        }
        item.extract::<PathBuf>()
            .map(Source::Path)
            .map_err(|_| PyTypeError::new_err(format!("{name}: expected a simgap.Run or a path (str or os.PathLike), got {}", type_name(item))))
    }

    /// A sequence of runs or paths, or a single one.
    fn from_arg(name: &str, arg: &Bound<'_, PyAny>) -> PyResult<Vec<Source>> {
        if arg.is_instance_of::<PyString>() || arg.cast::<PyRun>().is_ok() || arg.hasattr("__fspath__")? {
            return Ok(vec![Source::from_item(name, arg)?]);
        }
        let items = arg.try_iter().map_err(|_| PyTypeError::new_err(format!("{name}: expected a sequence of simgap.Run or paths, got {}", type_name(arg))))?;
        items.enumerate().map(|(i, item)| Source::from_item(&format!("{name}[{i}]"), &item?)).collect()
    }

    /// The runs (read from the log when a path: one per episode of a LeRobot dataset); errors
    /// name the file. `options` gives the experiment of logs that carry none and LeRobot's
    /// calibration file.
    fn load(&self, options: &simgap_log::LogOptions) -> simgap_diag::Result<Vec<Run>> {
        match self {
            Source::Run(run) => Ok(vec![Run::clone(run)]),
            Source::Path(path) => Ok(simgap_log::read_logs(path, options).map_err(simgap_sim::Error::from)?),
        }
    }
}

/// The latest progress report of a diagnosis: stage, steps done, steps in all.
type Latest = Arc<Mutex<Option<(String, usize, usize)>>>;

/// Everything a diagnosis needs, owned, so that it can run on another thread.
struct Job {
    model: Arc<Model>,
    formulation: Formulation,
    fit: Vec<Source>,
    holdout: Vec<Source>,
    /// Given to runs that carry none.
    experiment: Option<Experiment>,
    /// LeRobot's calibration file, for range-normalised joints of LeRobot datasets.
    calibration: Option<simgap_log::lerobot::Calibration>,
    /// The diagnosis' options, its switches set from the keywords given
    /// ([`simgap_diag::SWITCHES`]); the stop flag is added by the worker.
    options: DiagnoseOptions,
    /// Where the worker leaves its latest progress for the Python thread.
    latest: Latest,
}

/// How the worker ended.
enum Outcome {
    Done(Box<simgap_diag::Result<(Diagnosis, Arc<Model>)>>),
    Cancelled,
    Panicked(String),
}

impl Job {
    /// Reads the logs and diagnoses; the diagnosis stops at its next step once `stop` is set
    /// (by Ctrl-C or an exception from the progress callback) with `Error::Interrupted`. Whether
    /// a held-out log repeats a fit log is the library's one rule (same samples).
    fn run(&self, stop: &Arc<AtomicBool>) -> simgap_diag::Result<(Diagnosis, Arc<Model>)> {
        let options = simgap_log::LogOptions { experiment: self.experiment.clone(), calibration: self.calibration.clone(), ..simgap_log::LogOptions::default() };
        let load = |sources: &[Source]| -> simgap_diag::Result<Vec<Run>> {
            let mut runs = Vec::new();
            for s in sources {
                for mut run in s.load(&options)? {
                    if run.experiment.is_none() {
                        run.experiment = self.experiment.as_ref().map(|e| simgap_log::lerobot::without_joints(e, &run.left_out));
                    }
                    runs.push(run);
                }
            }
            Ok(runs)
        };
        let fit = load(&self.fit)?;
        let holdout = load(&self.holdout)?;
        // joints the logs record but not as positions (a LeRobot gripper without calibration)
        // are locked at their zero
        let model = match simgap_diag::model_for_runs(&self.model, fit.iter().chain(&holdout))? {
            Some(m) => Arc::new(m),
            None => self.model.clone(),
        };
        let mut progress = |p: Progress| {
            if let Ok(mut latest) = self.latest.lock() {
                *latest = Some((p.stage.to_string(), p.done, p.total));
            }
        };
        let options = DiagnoseOptions { stop: Some(stop.clone()), ..self.options.clone() };
        simgap_diag::diagnose(&model, self.formulation, &fit, &holdout, &options, &mut progress).map(|d| (d, model))
    }

    /// `run`, with a panic caught: never a panic out of the worker thread.
    fn run_caught(&self, stop: &Arc<AtomicBool>) -> Outcome {
        match catch_unwind(AssertUnwindSafe(|| self.run(stop))) {
            Ok(Err(simgap_diag::Error::Interrupted)) => Outcome::Cancelled,
            Ok(result) => Outcome::Done(Box::new(result)),
            Err(payload) => Outcome::Panicked(panic_message(payload.as_ref())),
        }
    }
}

fn panic_message(payload: &(dyn Any + Send)) -> String {
    payload.downcast_ref::<&str>().map(|s| s.to_string()).or_else(|| payload.downcast_ref::<String>().cloned()).unwrap_or_else(|| "unknown panic".into())
}

/// Runs `job` on its own thread (see [`crate::worker`]); on Ctrl-C the diagnosis stops at its
/// next progress report. `progress` is called on this thread, with the GIL, with each new
/// progress report as `(stage, done, total)`; an exception from it stops the diagnosis and is
/// raised.
fn run_interruptible(py: Python<'_>, job: Job, progress: Option<Bound<'_, PyAny>>) -> PyResult<(Diagnosis, Arc<Model>)> {
    let latest = job.latest.clone();
    let mut last: Option<(String, usize, usize)> = None;
    let mut report = move |_py: Python<'_>| -> PyResult<()> {
        let Some(callback) = &progress else { return Ok(()) };
        let now = latest.lock().ok().and_then(|l| l.clone());
        if now.is_some() && now != last {
            if let Some((stage, done, total)) = &now {
                callback.call1((stage.as_str(), *done, *total))?;
            }
            last = now;
        }
        Ok(())
    };
    let result = crate::worker::run_interruptible_ticking(py, "simgap-diagnose", move |stop| job.run_caught(stop), &mut report);
    // the last report, so a bar ends where the diagnosis did
    if result.is_ok() {
        report(py)?;
    }
    let outcome = match result {
        Ok(outcome) => outcome,
        Err(WorkerError::Signal(e)) => return Err(e),
        Err(WorkerError::Spawn(e)) => return Err(Kind::Fit.err(format!("cannot start the diagnosis thread: {e}"))),
        Err(WorkerError::Lost) => return Err(Kind::Simgap.err("the diagnosis thread ended without a result (a bug in simgap)")),
    };
    match outcome {
        Outcome::Done(result) => (*result).map_err(from_diag),
        Outcome::Cancelled => Err(Kind::Fit.err("the diagnosis was interrupted")),
        Outcome::Panicked(message) => Err(Kind::Simgap.err(format!("the diagnosis failed unexpectedly (a bug in simgap): {message}"))),
    }
}

/// Diagnoses the gap between `model` and logged runs (the `simgap diagnose`
/// pipeline): **where** the gap lies, **which** unmodelled effect causes it, and **how far** it
/// shrinks on held-out runs once that effect is added.
///
/// `fit`: runs used to fit and select effects; `holdout`: runs used only to measure the gap
/// before and after (never for fitting). Each is a sequence of `Run` (from `read_log`,
/// `read_logs` or `simulate`) or paths to logs (read like `read_logs`: a LeRobot dataset path,
/// `FOLDER` or `FOLDER#0,3-5`, gives one run per episode), or a single one. Every run must carry
/// its experiment (controller, gains, sample period) to be re-simulated in closed loop.
/// `formulation`: the C of the model under test, "euler_lagrange" or "simplified". `urdf`: the
/// URDF file `model` was loaded from, kept for `Report.export_urdf`. `calibration`: LeRobot's
/// calibration file, which makes a dataset's range-normalised joint (a gripper's 0–100) an
/// angle; a model joint the logs leave out without one (`Run.left_out`) is locked at its zero
/// position, and the report's notes say so. `**switches`: the
/// diagnosis' yes/no options by keyword (`directional_friction=True`, …), one per entry of
/// `DIAGNOSE_SWITCHES` (name, default, help), the same as the CLI's flags.
///
/// Runs on its own thread with the GIL released; Ctrl-C raises KeyboardInterrupt. Raises
/// FitError when there is no fit or held-out run, a log is given as both, or the fit fails;
/// LogError when a log cannot be read, lacks a model joint or its experiment, or is too short;
/// TypeError for arguments that are neither runs nor paths, and for a keyword that is no switch
/// or a switch that is not a bool.
#[pyfunction]
#[pyo3(signature = (model, fit, holdout, *, formulation = "euler_lagrange", experiment = None, progress = None, urdf = None, calibration = None, **switches))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn diagnose(
    py: Python<'_>,
    model: &PyModel,
    fit: &Bound<'_, PyAny>,
    holdout: &Bound<'_, PyAny>,
    formulation: &str,
    experiment: Option<&Bound<'_, PyAny>>,
    progress: Option<Bound<'_, PyAny>>,
    urdf: Option<PathBuf>,
    calibration: Option<PathBuf>,
    switches: Option<&Bound<'_, PyDict>>,
) -> PyResult<PyReport> {
    let options = switch_options(switches)?;
    let progress = progress.filter(|p| !p.is_none());
    if let Some(p) = &progress {
        if !p.is_callable() {
            return Err(PyTypeError::new_err(format!("progress: expected a callable (stage, done, total) or None, got {}", type_name(p))));
        }
    }
    let experiment = experiment.filter(|e| !e.is_none()).map(experiment_arg).transpose()?;
    let calibration = calibration.map(|c| simgap_log::lerobot::Calibration::read(&c)).transpose().map_err(crate::errors::from_log)?;
    let job = Job {
        model: model.model(),
        formulation: self::formulation(formulation)?,
        fit: Source::from_arg("fit", fit)?,
        holdout: Source::from_arg("holdout", holdout)?,
        experiment,
        calibration,
        options,
        latest: Latest::default(),
    };
    let (diagnosis, model) = run_interruptible(py, job, progress)?;
    let json = diagnosis.report.to_json();
    Ok(PyReport { diagnosis: Arc::new(diagnosis), model, json, urdf })
}

/// The options of a diagnosis with the switches given as keywords (`**switches` of
/// [`diagnose`]): TypeError, as Python raises for an unexpected keyword, for a name that is no
/// switch or a value that is not a bool.
fn switch_options(switches: Option<&Bound<'_, PyDict>>) -> PyResult<DiagnoseOptions> {
    let mut given = Vec::new();
    for (key, value) in switches.into_iter().flat_map(|d| d.iter()) {
        let name: String = key.extract()?;
        let Some(switch) = simgap_diag::switch(&name) else {
            let names: Vec<&str> = simgap_diag::SWITCHES.iter().map(|s| s.name).collect();
            return Err(PyTypeError::new_err(format!("diagnose() got an unexpected keyword argument '{name}'; expected one of {names:?}")));
        };
        let Ok(on) = value.cast::<pyo3::types::PyBool>().map(|b| b.is_true()) else {
            return Err(PyTypeError::new_err(format!("diagnose(): {name} must be True or False, got {}", type_name(&value))));
        };
        given.push((switch.name, on));
    }
    simgap_diag::options_with(&given).map_err(PyTypeError::new_err)
}

/// `DIAGNOSE_SWITCHES`: every switch of a diagnosis as `(name, default, help)`, the table the
/// CLI's flags and `diagnose`'s keywords are built from.
pub(crate) fn switch_table() -> Vec<(&'static str, bool, &'static str)> {
    simgap_diag::SWITCHES.iter().map(|s| (s.name, s.default, s.help)).collect()
}

/// Maps an export error: the URDF (or the model) to UrdfError, an effect that cannot be
/// written to FitError, anything else to SimgapError.
fn from_export(e: simgap_diag::export::ExportError) -> PyErr {
    use simgap_diag::export::ExportError as E;
    let kind = match &e {
        E::Urdf { .. } | E::Model(_) => Kind::Urdf,
        E::Effect { .. } | E::Sim(_) => Kind::Fit,
        _ => Kind::Simgap,
    };
    kind.err(e.to_string())
}

/// Writes an exported file and its sidecar; returns the sidecar's path.
fn write_export(path: &Path, file: &simgap_diag::export::ExportedFile) -> PyResult<String> {
    let side = simgap_diag::export::sidecar_path(path);
    std::fs::write(path, &file.text).map_err(|e| Kind::Simgap.err(format!("{}: cannot write: {e}", path.display())))?;
    std::fs::write(&side, file.sidecar.to_json() + "\n").map_err(|e| Kind::Simgap.err(format!("{}: cannot write: {e}", side.display())))?;
    Ok(side.display().to_string())
}

/// The result of `diagnose`: the diagnosis report, with the runs behind its figures.
#[pyclass(module = "simgap._simgap", name = "Report", frozen)]
pub(crate) struct PyReport {
    diagnosis: Arc<Diagnosis>,
    /// The model diagnosed (for inertial corrections as percentages in the HTML).
    model: Arc<Model>,
    json: String,
    /// The URDF the model was loaded from, when `diagnose` was told (for `export_urdf`).
    urdf: Option<PathBuf>,
}

impl PyReport {
    /// The whole report as Python objects (a fresh dict: callers may change it).
    fn dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        py.import("json")?.call_method1("loads", (self.json.as_str(),))
    }

    fn field<'py>(&self, py: Python<'py>, key: &str) -> PyResult<Bound<'py, PyAny>> {
        self.dict(py)?.get_item(key)
    }

    fn runs<'py>(py: Python<'py>, runs: impl IntoIterator<Item = Option<Run>>) -> PyResult<Bound<'py, PyList>> {
        let items = runs.into_iter().map(|r| r.map(PyRun::from_run)).collect::<Vec<_>>();
        let list = PyList::empty(py);
        for item in items {
            match item {
                Some(run) => list.append(Bound::new(py, run)?)?,
                None => list.append(py.None())?,
            }
        }
        Ok(list)
    }
}

#[pymethods]
impl PyReport {
    /// The report's keys (`report[key]` works for each, `where` included).
    fn keys<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        Ok(self.dict(py)?.cast_into::<PyDict>()?.keys())
    }

    /// The report as a dict with the keys of the CLI's `--json` output (`selected_effects`,
    /// `candidates`, `gap`, `where`, `verdict`, ...); non-finite numbers are None.
    fn to_dict<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.dict(py)
    }

    /// The report as JSON text, the same as the CLI's `--json` output.
    fn to_json(&self) -> String {
        self.json.clone()
    }

    /// Writes the self-contained HTML report (verdict, tables, inline SVG plots of every
    /// held-out run) to `path`, like the CLI's `--html`. Raises LogError when it cannot.
    fn to_html(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let (diagnosis, model) = (self.diagnosis.clone(), self.model.clone());
        py.detach(move || simgap_diag::html::write_html_for(&diagnosis, Some(&model), &path)).map_err(from_diag)
    }

    /// Writes the URDF the model was loaded from with the selected effects written in (the
    /// corrected `<inertial>` of every changed link, `<dynamics damping friction>` for viscous
    /// and Coulomb friction; every other byte kept) to `path`, and the selected effects a URDF
    /// cannot hold (rotor inertia, torque gain, delay, ...) to `path + ".effects.json"`, in the
    /// `selected_effects` form with a sentence on how to apply each (the CLI's
    /// `--export-urdf`). `urdf`: the URDF file the model was loaded from; default the one
    /// given to `diagnose(..., urdf=...)`. Returns the sidecar's path.
    ///
    /// Raises UrdfError when the URDF cannot be read or is not the model's, FitError when an
    /// effect cannot be written into it, SimgapError when a file cannot be written.
    #[pyo3(signature = (path, urdf = None))]
    fn export_urdf(&self, py: Python<'_>, path: PathBuf, urdf: Option<PathBuf>) -> PyResult<String> {
        let Some(urdf) = urdf.or_else(|| self.urdf.clone()) else {
            return Err(Kind::Urdf.err("export_urdf: which URDF was the model loaded from? Pass export_urdf(path, urdf=...) or diagnose(..., urdf=...)"));
        };
        let (diagnosis, model) = (self.diagnosis.clone(), self.model.clone());
        py.detach(move || {
            let text = std::fs::read_to_string(&urdf).map_err(|e| Kind::Urdf.err(format!("{}: cannot read: {e}", urdf.display())))?;
            let file = simgap_diag::export::corrected_urdf(&text, &urdf.display().to_string(), &model, &diagnosis).map_err(from_export)?;
            write_export(&path, &file)
        })
    }

    /// Writes an MJCF of the corrected robot to `path` (body inertials; joint armature,
    /// damping, frictionloss, stiffness/springref; a motor per driven joint with gear and
    /// forcerange; `<option timestep>` = the logs' sample period, gravity, RK4), and
    /// the selected effects MJCF cannot hold (delay, Stribeck shape, offsets, ...) to
    /// `path + ".effects.json"` (the CLI's `--export-mjcf`). `mujoco.MjModel.from_xml_path`
    /// loads it as it is. Returns the sidecar's path.
    ///
    /// Raises FitError when an effect cannot be written, SimgapError when a file cannot be
    /// written or the logs have no sample period.
    fn export_mjcf(&self, py: Python<'_>, path: PathBuf) -> PyResult<String> {
        let (diagnosis, model) = (self.diagnosis.clone(), self.model.clone());
        py.detach(move || {
            let file = simgap_diag::export::corrected_mjcf(&model, &diagnosis).map_err(from_export)?;
            write_export(&path, &file)
        })
    }

    /// The HTML report as a string: a notebook (Jupyter, VS Code) shows it in place of the repr.
    fn _repr_html_(&self, py: Python<'_>) -> PyResult<String> {
        let (diagnosis, model) = (self.diagnosis.clone(), self.model.clone());
        py.detach(move || simgap_diag::html::render_html_for(&diagnosis, Some(&model))).map_err(|m| Kind::Simgap.err(format!("cannot draw the report: {m}")))
    }

    /// The terminal summary the CLI prints.
    fn summary(&self) -> String {
        self.diagnosis.report.summary()
    }

    /// Effects the diagnosis concludes explain the gap: dicts `{effect, joints, parameters,
    /// uncertainty}`; empty when nothing significant remains.
    #[getter]
    fn selected_effects<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.field(py, "selected_effects")
    }

    /// The selected effects with the 95 % half-widths of each interval method on its own:
    /// `{method: [effect dicts]}`; for a torque-residual fit `block_bootstrap`,
    /// `fold_jackknife`, `resampling` (the larger of the two, 1.96 σ), `pipeline_error` (1.96 |b|,
    /// the pipeline's measured error), `noise_resampling` (1.96 σ_n, the scatter that error does
    /// not make) and `pipeline_error_change` (1.96 |δ|, how far `b` moves measured again from the
    /// corrected values): the report's `uncertainty` is `|b| + 1.96 sqrt(σ_n² + δ²)`;
    /// `spread_or_bias` (1.96 max(σ, |b|), the rule before) and `bias_corrected` (the values less
    /// `b`, with the `resampling` half-widths); for a fit by multiple shooting
    /// `multiple_shooting`.
    #[getter]
    fn interval_variants<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        py.import("json")?.call_method1("loads", (self.diagnosis.interval_variants_json(),))
    }

    /// Every effect tried, ranked: dicts with `rank`, `effect`, `joints`, `parameters`,
    /// `uncertainty`, `cv_residual_reduction`, `holdout_l2_after`, `holdout_ratio`,
    /// `selected`, `reason`.
    #[getter]
    fn candidates<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.field(py, "candidates")
    }

    /// How far the gap shrinks: `headline` and `headline_reason`, `kstep` (held-out k-step
    /// prediction error per horizon before and after, and the constant-velocity floor),
    /// `holdout_l2_before`, `holdout_l2_after`, `ratio`, per joint and per run.
    #[getter]
    fn gap<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.field(py, "gap")
    }

    /// Effect sets these data cannot tell apart from the selected one: `{effects, why}`.
    #[getter]
    fn alternatives<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.field(py, "alternatives")
    }

    /// Warnings about the logs and the answer (glitches, inferred sensors, URDF pitfalls, what
    /// the residual still holds).
    #[getter]
    fn notes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.field(py, "notes")
    }

    /// What is left after the selected effects, per joint: `rms` [N·m], `share_of_torque`,
    /// `phase_rms` (forward, backward, near rest), `explained_by` (the share of the residual that
    /// follows position, velocity, acceleration, torque or time on held-out halves) and `kind`
    /// (`negligible`, `noise-like` or `structured`).
    #[getter]
    fn residual<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.field(py, "residual")
    }

    /// Where the gap lies (the report's `where`): `per_joint` shares, `worst_segments`,
    /// residual `correlations`.
    #[getter]
    fn location<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.field(py, "where")
    }

    /// The stepwise selection, step by step.
    #[getter]
    fn selection_log<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        self.field(py, "selection_log")
    }

    /// One-sentence conclusion.
    #[getter]
    fn verdict(&self) -> String {
        self.diagnosis.report.verdict.clone()
    }

    /// Formulation of C under test.
    #[getter]
    fn formulation(&self) -> String {
        self.diagnosis.report.formulation.clone()
    }

    /// Joint names, model order.
    #[getter]
    fn joints(&self) -> Vec<String> {
        self.diagnosis.report.joints.clone()
    }

    /// Robot name.
    #[getter]
    fn model(&self) -> String {
        self.diagnosis.report.model.clone()
    }

    /// Held-out runs as measured, aligned to the model's joints.
    #[getter]
    fn holdout<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        Self::runs(py, self.diagnosis.holdout.iter().cloned().map(Some))
    }

    /// Closed-loop simulations of the held-out runs with the nominal model (None where one
    /// failed).
    #[getter]
    fn holdout_nominal<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        Self::runs(py, self.diagnosis.holdout_nominal.iter().cloned())
    }

    /// Closed-loop simulations of the held-out runs with the selected effects added (None
    /// where one failed).
    #[getter]
    fn holdout_corrected<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        Self::runs(py, self.diagnosis.holdout_corrected.iter().cloned())
    }

    /// The fit runs as the diagnosis saw them, for plots: one dict per run with `log` (its
    /// name), `t` (N,) [s], and (N, dof) arrays `q`, `qd`, `qdd` (smoothed) and `residual`,
    /// the nominal torque residual τ_cmd − (H q̈ + C q̇ + g) [N·m].
    #[getter]
    fn fit_residuals<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let list = PyList::empty(py);
        for f in &self.diagnosis.fit_data {
            let (n, dof) = (f.len(), f.dof);
            let d = PyDict::new(py);
            d.set_item("log", f.name.as_str())?;
            d.set_item("t", crate::conv::to_array(py, f.t.clone(), &[n]))?;
            for (key, m) in [("q", &f.q), ("qd", &f.qd), ("qdd", &f.qdd), ("residual", &f.residual)] {
                d.set_item(key, crate::conv::to_array(py, m.clone(), &[n, dof]))?;
            }
            list.append(d)?;
        }
        Ok(list)
    }

    /// A report key, as in the JSON (`report["where"]`). Raises KeyError.
    fn __getitem__<'py>(&self, py: Python<'py>, key: &str) -> PyResult<Bound<'py, PyAny>> {
        let dict = self.dict(py)?;
        if !dict.contains(key)? {
            return Err(PyKeyError::new_err(key.to_owned()));
        }
        dict.get_item(key)
    }

    fn __contains__(&self, py: Python<'_>, key: &str) -> PyResult<bool> {
        self.dict(py)?.contains(key)
    }

    fn __str__(&self) -> String {
        self.summary()
    }

    fn __repr__(&self) -> String {
        let r = &self.diagnosis.report;
        let selected: Vec<String> =
            r.selected_effects.iter().map(|e| if e.joints.is_empty() { e.effect.to_string() } else { format!("{}[{}]", e.effect, e.joints.join(",")) }).collect();
        format!(
            "Report(model={:?}, formulation={:?}, selected_effects={:?}, holdout_l2_before={}, holdout_l2_after={})",
            r.model, r.formulation, selected, r.gap.holdout_l2_before, r.gap.holdout_l2_after
        )
    }
}
