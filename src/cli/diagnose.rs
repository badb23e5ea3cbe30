//! `simgap diagnose`: where the gap lies, which effect causes it, how far it
//! shrinks on held-out runs.
//!
//! Outputs are written atomically (to `X.tmp`, then renamed), and Ctrl-C removes the temporary
//! file being written before exiting, so an interrupt never leaves a half-written report.
//!
//! The corrected MCAP (`--mcap`) holds every held-out run in one file, one topic prefix per run
//! (`<name>` = the log's file stem, as a ROS name: letters, digits and `_`):
//! - `/holdout/<name>/joint_states`: the closed-loop simulation **with** the selected effects;
//! - `/holdout/<name>/joint_reference`: the reference it tracked;
//! - `/holdout/<name>/nominal/joint_states`: the simulation of the nominal model;
//! - `/holdout/<name>/measured/joint_states`: the log as measured.
//!
//! All are `sensor_msgs/msg/JointState` in CDR with the logged (absolute) stamps to the
//! nanosecond, so Foxglove
//! or PlotJuggler overlay measured, nominal and corrected `position[i]` of a run in one plot.
//! Metadata: `simgap.diagnosis` (verdict, selected effects, L² before and after) and one
//! `simgap.holdout.<name>` record per run (its source log and `simgap.experiment` keys).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::Context;
use simgap::core::{Formulation, Model};
use simgap::diag::{diagnose, options_with, Diagnosis, Progress, SWITCHES};
use simgap::log::{McapWriter, RunTopics, TopicMap};
use simgap::sim::experiment_to_map;

/// Arguments of `simgap diagnose`.
#[derive(clap::Args)]
pub(crate) struct Args {
    /// URDF of the robot.
    #[arg(long)]
    urdf: PathBuf,
    /// Tip link of the chain when the tree branches.
    #[arg(long)]
    tip: Option<String>,
    /// A log to fit and select effects on, repeatable: MCAP, CSV, a rosbag2 bag folder, or a
    /// LeRobot dataset folder (every episode) or FOLDER#EPISODES (e.g. 'data#0,3-5').
    #[arg(long = "log", required = true)]
    logs: Vec<PathBuf>,
    /// A held-out log (of the same kinds), only used to measure how far the gap shrinks,
    /// repeatable. Without one, each fit log is split in time: the first 60 % fits, the rest is
    /// held out.
    #[arg(long = "holdout")]
    holdouts: Vec<PathBuf>,
    /// Formulation of C under test: euler-lagrange or simplified.
    #[arg(long, default_value = "euler-lagrange")]
    formulation: Formulation,
    /// Write the JSON report here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write a self-contained HTML report (tables and plots) here.
    #[arg(long)]
    html: Option<PathBuf>,
    /// Write the measured, nominal and corrected held-out runs to one MCAP file here.
    #[arg(long)]
    mcap: Option<PathBuf>,
    /// Write the URDF with the selected effects (corrected `<inertial>`, `<dynamics damping
    /// friction>`) here, and the effects a URDF cannot hold to PATH.effects.json.
    #[arg(long = "export-urdf", value_name = "PATH")]
    export_urdf: Option<PathBuf>,
    /// Write an MJCF of the corrected robot (inertials, joint armature, damping, frictionloss,
    /// motors with gear and forcerange, the logs' time step) here, and the effects it cannot
    /// hold to PATH.effects.json.
    #[arg(long = "export-mjcf", value_name = "PATH")]
    export_mjcf: Option<PathBuf>,
    /// Experiment file (controller, joints, kp, kv, sample_period) for logs that carry none
    /// (no `simgap.experiment` metadata, no sidecar `NAME.experiment.json`).
    #[arg(long)]
    experiment: Option<PathBuf>,
    /// LeRobot's calibration file of the robot (per motor: id, drive_mode, homing_offset,
    /// range_min, range_max), which makes a range-normalised joint of a LeRobot dataset (the
    /// gripper's 0–100) an angle; without it such a joint is locked at its URDF zero.
    #[arg(long)]
    calibration: Option<PathBuf>,
    /// Topics of MCAP logs and bags, e.g.
    /// `states=/arm/joint_states,reference=/arm_controller/controller_state,effort=/effort_controller/commands[j1;j2],measured_effort=/arm/effort`
    /// (defaults /joint_states, /joint_reference, /joint_effort_measured).
    #[arg(long = "topic", value_parser = parse_topic_map)]
    topics: Option<TopicMap>,
    /// The diagnosis' switches (`--directional-friction`, …), one flag per entry of
    /// [`simgap::diag::SWITCHES`].
    #[command(flatten)]
    switches: SwitchArgs,
    /// Print the wall time spent in each stage of the diagnosis to stderr when it ends.
    #[arg(long)]
    timings: bool,
}

/// Parses `--topic`.
pub(crate) fn parse_topic_map(s: &str) -> Result<TopicMap, String> {
    TopicMap::parse(s)
}

/// The flags of [`SWITCHES`], as the value of each (by name): one flag per entry of the table,
/// so that a new switch of the diagnosis is a flag without an edit here.
#[derive(Clone, Debug)]
pub(crate) struct SwitchArgs(pub(crate) Vec<(&'static str, bool)>);

impl clap::FromArgMatches for SwitchArgs {
    fn from_arg_matches(m: &clap::ArgMatches) -> Result<Self, clap::Error> {
        Ok(SwitchArgs(SWITCHES.iter().map(|s| (s.name, m.get_flag(s.name))).collect()))
    }

    fn update_from_arg_matches(&mut self, m: &clap::ArgMatches) -> Result<(), clap::Error> {
        *self = Self::from_arg_matches(m)?;
        Ok(())
    }
}

impl clap::Args for SwitchArgs {
    fn augment_args(cmd: clap::Command) -> clap::Command {
        SWITCHES.iter().fold(cmd, |cmd, s| cmd.arg(clap::Arg::new(s.name).long(s.flag).action(clap::ArgAction::SetTrue).help(s.help)))
    }

    fn augment_args_for_update(cmd: clap::Command) -> clap::Command {
        Self::augment_args(cmd)
    }
}

/// What to diagnose and where to write, shared by `simgap diagnose` and `simgap demo`.
pub(crate) struct Job<'a> {
    pub(crate) model: &'a Model,
    pub(crate) formulation: Formulation,
    pub(crate) logs: &'a [PathBuf],
    pub(crate) holdouts: &'a [PathBuf],
    pub(crate) experiment: Option<&'a Path>,
    /// LeRobot's calibration file, for range-normalised joints of LeRobot datasets.
    pub(crate) calibration: Option<&'a Path>,
    pub(crate) topics: TopicMap,
    pub(crate) json: Option<&'a Path>,
    pub(crate) html: Option<&'a Path>,
    pub(crate) mcap: Option<&'a Path>,
    /// The URDF the model was loaded from (needed by `export_urdf`).
    pub(crate) urdf: Option<&'a Path>,
    pub(crate) export_urdf: Option<&'a Path>,
    pub(crate) export_mjcf: Option<&'a Path>,
    /// The switches given, by name; every other switch is at its default
    /// ([`simgap::diag::SWITCHES`]).
    pub(crate) switches: Vec<(&'static str, bool)>,
    /// Print the wall time of each stage to stderr.
    pub(crate) timings: bool,
}

pub(crate) fn run(args: Args) -> anyhow::Result<()> {
    let model = super::load_model(Some(&args.urdf), args.tip.as_deref())?;
    execute(&Job {
        model: &model,
        formulation: args.formulation,
        logs: &args.logs,
        holdouts: &args.holdouts,
        experiment: args.experiment.as_deref(),
        calibration: args.calibration.as_deref(),
        topics: args.topics.unwrap_or_default(),
        json: args.json.as_deref(),
        html: args.html.as_deref(),
        mcap: args.mcap.as_deref(),
        urdf: Some(&args.urdf),
        export_urdf: args.export_urdf.as_deref(),
        export_mjcf: args.export_mjcf.as_deref(),
        switches: args.switches.0,
        timings: args.timings,
    })?;
    Ok(())
}

/// Reads the logs, diagnoses, prints the summary and writes the outputs.
pub(crate) fn execute(job: &Job<'_>) -> anyhow::Result<Diagnosis> {
    super::interrupt::install();
    // read: every error names its file
    let options = super::log_options(job.topics.clone(), job.experiment, job.calibration)?;
    let fit = super::read_runs(job.logs, &options)?;
    let holdout = super::read_runs(job.holdouts, &options)?;
    // joints the logs record but not as positions (a LeRobot gripper without calibration) are
    // locked at their zero
    let locked = simgap::diag::model_for_runs(job.model, fit.iter().chain(&holdout))?;
    if let Some(m) = &locked {
        eprintln!("note: {}", m.warnings().last().map(String::as_str).unwrap_or_default());
    }
    let model = locked.as_ref().unwrap_or(job.model);

    // diagnose with a progress bar naming the stage (hidden when stderr is not a terminal)
    let bar = super::progress_bar(1, "{spinner} {msg:<24} [{bar:30}] {pos}/{len}  {elapsed}");
    let mut stages = StageTimes::default();
    let mut on_progress = |p: Progress| {
        if job.timings {
            stages.enter(p.stage);
        }
        bar.set_message(p.stage);
        bar.set_length(p.total.max(1) as u64);
        bar.set_position(p.done as u64);
    };
    // Ctrl-C stops the diagnosis at its next step (exit 130, nothing written)
    super::interrupt::cooperate();
    let mut options = options_with(&job.switches).map_err(anyhow::Error::msg)?;
    options.stop = Some(super::interrupt::STOP.clone());
    let result = diagnose(model, job.formulation, &fit, &holdout, &options, &mut on_progress);
    bar.finish_and_clear();
    if job.timings {
        stages.enter("");
        eprint!("{stages}");
    }
    let diagnosis = match result {
        Err(simgap::diag::Error::Interrupted) => return Err(super::Interrupted.into()),
        other => other?,
    };

    println!("{}", diagnosis.report.summary());
    if let Some(path) = job.json {
        write_atomically(path, |tmp| std::fs::write(tmp, diagnosis.report.to_json() + "\n").map_err(Into::into))?;
        println!("wrote {}", path.display());
    }
    if let Some(path) = job.mcap {
        write_atomically(path, |tmp| write_corrected_mcap(&diagnosis, tmp))?;
        println!("wrote {} (topics /holdout/<run>/{{joint_states,joint_reference,nominal/joint_states,measured/joint_states}})", path.display());
    }
    let exported = write_exports(job, model, &diagnosis)?;
    // the page links the exported files: by name beside it, else by their absolute path
    if let Some(path) = job.html {
        let here = path.parent().map(|p| p.canonicalize().unwrap_or_else(|_| p.to_path_buf()));
        let links: Vec<simgap::diag::html::LinkedFile> = exported
            .iter()
            .map(|(what, file)| {
                let dir = file.parent().map(|p| p.canonicalize().unwrap_or_else(|_| p.to_path_buf()));
                let href = match (file.file_name(), dir == here) {
                    (Some(name), true) => name.to_string_lossy().to_string(),
                    _ => file.canonicalize().unwrap_or_else(|_| file.clone()).display().to_string(),
                };
                simgap::diag::html::LinkedFile { what: what.clone(), href }
            })
            .collect();
        write_atomically(path, |tmp| simgap::diag::html::write_html_linking(&diagnosis, Some(model), tmp, &links).map_err(Into::into))?;
        println!("wrote {}", path.display());
    }
    Ok(diagnosis)
}

/// Writes `--export-urdf` and `--export-mjcf`, each with its sidecar `PATH.effects.json`, from
/// the diagnosis alone (Python's `report.export_urdf` and `report.export_mjcf` write the same
/// files); returns the files written, each with what it is.
fn write_exports(job: &Job<'_>, model: &Model, diagnosis: &Diagnosis) -> anyhow::Result<Vec<(String, PathBuf)>> {
    use simgap::diag::export::{corrected_mjcf, corrected_urdf, sidecar_path, ExportedFile};
    let mut written: Vec<(String, PathBuf)> = Vec::new();
    let mut write = |path: &Path, file: &ExportedFile, what: &str| -> anyhow::Result<()> {
        write_atomically(path, |tmp| std::fs::write(tmp, &file.text).map_err(Into::into))?;
        let side = sidecar_path(path);
        write_atomically(&side, |tmp| std::fs::write(tmp, file.sidecar.to_json() + "\n").map_err(Into::into))?;
        let left = match file.sidecar.selected_effects.len() {
            0 => "it holds every selected effect".to_string(),
            1 => "1 selected effect it does not hold".to_string(),
            k => format!("{k} selected effects it does not hold"),
        };
        println!("wrote {} and {} ({left})", path.display(), side.display());
        written.push((what.to_string(), path.to_path_buf()));
        written.push((format!("sidecar of the {what}, in the report's selected_effects form: {left}"), side));
        Ok(())
    };
    // the URDF the model came from, with the selected effects written in
    if let Some(path) = job.export_urdf {
        let urdf = job.urdf.context("--export-urdf needs the URDF the model was loaded from")?;
        let text = std::fs::read_to_string(urdf).with_context(|| format!("{}: cannot read the URDF to export", urdf.display()))?;
        let file = corrected_urdf(&text, &urdf.display().to_string(), model, diagnosis).with_context(|| format!("cannot export the corrected URDF to {}", path.display()))?;
        write(path, &file, "corrected URDF (Pinocchio, Gazebo, Isaac)")?;
    }
    // the MJCF of the corrected robot
    if let Some(path) = job.export_mjcf {
        let file = corrected_mjcf(model, diagnosis).with_context(|| format!("cannot export the corrected MJCF to {}", path.display()))?;
        write(path, &file, "corrected MJCF (MuJoCo)")?;
    }
    Ok(written)
}

/// Writes `path` through `X.tmp` and a rename, so it is either the old file or the whole new one.
pub(crate) fn write_atomically(path: &Path, write: impl FnOnce(&Path) -> anyhow::Result<()>) -> anyhow::Result<()> {
    let mut name = path.file_name().with_context(|| format!("{}: not a file name", path.display()))?.to_os_string();
    name.push(".tmp");
    let tmp = path.with_file_name(name);
    super::interrupt::IN_PROGRESS.lock().map(|mut v| v.push(tmp.clone())).ok();
    let result = write(&tmp).and_then(|()| std::fs::rename(&tmp, path).with_context(|| format!("{}: cannot rename {} into place", path.display(), tmp.display())));
    super::interrupt::IN_PROGRESS.lock().map(|mut v| v.retain(|p| p != &tmp)).ok();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.with_context(|| format!("cannot write {}", path.display()))
}

/// A ROS 2 name segment from a log name: its file stem, with anything but letters, digits and
/// `_` replaced by `_`, never starting with a digit.
pub(crate) fn topic_name(source: &str) -> String {
    let base = source.split(" (").next().unwrap_or(source);
    let stem = Path::new(base).file_name().map(|s| s.to_string_lossy().to_string()).unwrap_or_else(|| base.to_string());
    let stem = stem.strip_suffix(".gz").unwrap_or(&stem);
    let stem = Path::new(stem).file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_default();
    let mut s: String = stem.chars().map(|c| if c.is_ascii_alphanumeric() || c == '_' { c } else { '_' }).collect();
    if s.is_empty() || s.starts_with(|c: char| c.is_ascii_digit()) {
        s.insert_str(0, "run_");
    }
    s
}

/// Writes the held-out runs (measured, nominal, corrected) into one MCAP file (module docs).
fn write_corrected_mcap(d: &Diagnosis, path: &Path) -> anyhow::Result<()> {
    let mut w = McapWriter::create(path)?;

    // the diagnosis as metadata
    let r = &d.report;
    let mut meta = BTreeMap::from([
        ("verdict".to_string(), r.verdict.clone()),
        ("model".to_string(), r.model.clone()),
        ("formulation".to_string(), r.formulation.clone()),
        ("holdout_l2_before".to_string(), format!("{}", r.gap.holdout_l2_before)),
        ("holdout_l2_after".to_string(), format!("{}", r.gap.holdout_l2_after)),
    ]);
    meta.insert("selected_effects".to_string(), serde_json::to_string(&r.selected_effects).unwrap_or_default());
    w.metadata("simgap.diagnosis", meta)?;

    let mut used: Vec<String> = Vec::new();
    for (i, measured) in d.holdout.iter().enumerate() {
        // a unique prefix per run
        let mut name = topic_name(&measured.source);
        if used.contains(&name) {
            name = format!("{name}_{i}");
        }
        used.push(name.clone());
        let mut run_meta = measured.experiment.as_ref().map(experiment_to_map).unwrap_or_default();
        run_meta.insert("source".into(), measured.source.clone());
        w.metadata(&format!("simgap.holdout.{name}"), run_meta)?;

        // every stream stamped from the measured log's start, as the log was
        let start = measured.start_ns;
        let only_states = |topic: String| RunTopics { states: topic, reference: None, measured_effort: None, servo: Default::default() };
        w.write_run(measured, &only_states(format!("/holdout/{name}/measured/joint_states")), start)?;
        if let Some(Some(nominal)) = d.holdout_nominal.get(i) {
            w.write_run(nominal, &only_states(format!("/holdout/{name}/nominal/joint_states")), start)?;
        }
        if let Some(Some(corrected)) = d.holdout_corrected.get(i) {
            let topics = RunTopics {
                states: format!("/holdout/{name}/joint_states"),
                reference: Some(format!("/holdout/{name}/joint_reference")),
                measured_effort: None,
                servo: Default::default(),
            };
            w.write_run(corrected, &topics, start)?;
        }
    }
    w.finish()?;
    Ok(())
}

/// Wall time per stage of a diagnosis, with the sets scored and the RK4 steps integrated in it
/// ([`simgap::diag::cost`]), in the order the stages were first entered (a stage entered again
/// adds to its totals).
#[derive(Default)]
struct StageTimes {
    current: Option<(&'static str, std::time::Instant, simgap::diag::cost::Cost)>,
    totals: Vec<(&'static str, f64, simgap::diag::cost::Cost)>,
}

impl StageTimes {
    /// Closes the current stage and enters `stage` ("" to only close).
    fn enter(&mut self, stage: &'static str) {
        if self.current.is_some_and(|(s, _, _)| s == stage) {
            return;
        }
        let now = std::time::Instant::now();
        let cost = simgap::diag::cost::cost();
        if let Some((s, since, before)) = self.current.take() {
            let dt = now.duration_since(since).as_secs_f64();
            let spent = cost - before;
            match self.totals.iter_mut().find(|(name, _, _)| *name == s) {
                Some(t) => {
                    t.1 += dt;
                    t.2.sets_scored += spent.sets_scored;
                    t.2.steps += spent.steps;
                }
                None => self.totals.push((s, dt, spent)),
            }
        }
        if !stage.is_empty() {
            self.current = Some((stage, now, cost));
        }
    }
}

impl std::fmt::Display for StageTimes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let total: f64 = self.totals.iter().map(|t| t.1).sum();
        let (sets, steps): (u64, u64) = self.totals.iter().fold((0, 0), |a, t| (a.0 + t.2.sets_scored, a.1 + t.2.steps));
        writeln!(f, "wall time by stage [s], sets scored by prediction, RK4 steps of k-step predictions [millions]:")?;
        for (stage, dt, c) in &self.totals {
            writeln!(f, "  {stage:<40} {dt:8.2}  {:5.1} %  {:>6}  {:>9.2}", 100.0 * dt / total.max(1e-12), c.sets_scored, c.steps as f64 * 1e-6)?;
        }
        writeln!(f, "  {:<40} {total:8.2}  {:>7}  {sets:>6}  {:>9.2}", "total", "", steps as f64 * 1e-6)
    }
}
