//! One file per subcommand.

pub(crate) mod demo;
pub(crate) mod diagnose;
pub(crate) mod paper;
pub(crate) mod predict;
pub(crate) mod selfcheck;
pub(crate) mod simulate;
pub(crate) mod terms;

use std::path::PathBuf;

use simgap::core::{Formulation, Model, UrdfOptions};

/// The model options shared by subcommands that default to the built-in paper arm.
#[derive(clap::Args)]
pub(crate) struct ModelArgs {
    /// URDF of the robot (default: the built-in paper arm).
    #[arg(long)]
    pub(crate) urdf: Option<PathBuf>,
    /// Tip link of the chain when the tree branches.
    #[arg(long)]
    pub(crate) tip: Option<String>,
    /// Formulation of C: euler-lagrange or simplified.
    #[arg(long, default_value = "euler-lagrange")]
    pub(crate) formulation: Formulation,
}

impl ModelArgs {
    /// Loads the model these options name (see [`load_model`]).
    pub(crate) fn load(&self) -> anyhow::Result<Model> {
        load_model(self.urdf.as_deref(), self.tip.as_deref())
    }
}

/// Loads the model named on the command line (`None` = the built-in paper arm), printing its
/// loading warnings to stderr.
pub(crate) fn load_model(urdf: Option<&std::path::Path>, tip: Option<&str>) -> anyhow::Result<Model> {
    let model = match urdf {
        Some(p) => Model::from_urdf_file_with(p, &UrdfOptions { tip: tip.map(str::to_string) })?,
        None => Model::paper_arm(),
    };
    for w in model.warnings() {
        eprintln!("warning: {w}");
    }
    Ok(model)
}

/// How the logs of a command are read: its topic map, its experiment file (for logs that carry
/// none) and LeRobot's calibration file.
pub(crate) fn log_options(topics: simgap::log::TopicMap, experiment: Option<&std::path::Path>, calibration: Option<&std::path::Path>) -> anyhow::Result<simgap::log::LogOptions> {
    Ok(simgap::log::LogOptions {
        topics,
        experiment: experiment.map(simgap::log::experiment::read_experiment_file).transpose()?,
        calibration: calibration.map(simgap::log::lerobot::Calibration::read).transpose()?,
        ..simgap::log::LogOptions::default()
    })
}

/// Reads every run of the logs `paths` (a LeRobot dataset path gives one run per episode it
/// selects), printing each log's warnings once to stderr; every run must carry an experiment.
pub(crate) fn read_runs(paths: &[PathBuf], options: &simgap::log::LogOptions) -> anyhow::Result<Vec<simgap::sim::Run>> {
    let mut runs = Vec::new();
    for p in paths {
        let reads = simgap::log::read_logs_with_warnings(p, options)?;
        // a dataset's episodes share their warnings: said once
        for w in reads.first().map(|r| r.warnings.as_slice()).unwrap_or_default() {
            eprintln!("warning: {}: {w}", p.display());
        }
        for read in reads {
            if read.run.experiment.is_none() {
                let sidecar = match simgap::log::lerobot::dataset_path(p) {
                    Some(d) => d.folder.join(simgap::log::lerobot::SIDECAR),
                    None => simgap::log::experiment::sidecar_path(p),
                };
                anyhow::bail!(
                    "{}: no simgap.experiment metadata (controller, joints, kp, kv, sample_period), needed to re-simulate the closed loop; \
                     give it with --experiment EXP.json, or as a sidecar file {}",
                    read.run.source,
                    sidecar.display()
                );
            }
            runs.push(read.run);
        }
    }
    Ok(runs)
}

/// The error a command returns after Ctrl-C: `main` exits with status 130 (128 + SIGINT), as a
/// shell does for an interrupted program.
#[derive(Debug)]
pub(crate) struct Interrupted;

impl std::fmt::Display for Interrupted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("interrupted")
    }
}

impl std::error::Error for Interrupted {}

/// Ctrl-C for every subcommand: one handler per process.
///
/// Commands that can stop cleanly (a simulation, a self-check) poll [`interrupt::requested`]
/// after [`interrupt::cooperate`] and return [`Interrupted`]; everywhere else, and on a second
/// Ctrl-C, the handler removes the temporary file being written (see
/// [`diagnose::write_atomically`]) and exits with status 130, so outputs are finished or absent.
pub(crate) mod interrupt {
    use std::path::PathBuf;
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::{Arc, LazyLock, Mutex};

    /// Raised by Ctrl-C (shared, so that a library call can watch it too).
    pub(crate) static STOP: LazyLock<Arc<AtomicBool>> = LazyLock::new(|| Arc::new(AtomicBool::new(false)));
    /// Whether the running command stops by itself on [`STOP`].
    static COOPERATIVE: AtomicBool = AtomicBool::new(false);
    /// Temporary files being written, removed on exit.
    pub(crate) static IN_PROGRESS: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

    /// Installs the handler (once per process).
    pub(crate) fn install() {
        static ONCE: std::sync::Once = std::sync::Once::new();
        ONCE.call_once(|| {
            let handler = || {
                if COOPERATIVE.load(Ordering::SeqCst) && !STOP.swap(true, Ordering::SeqCst) {
                    return;
                }
                if let Ok(paths) = IN_PROGRESS.lock() {
                    for p in paths.iter() {
                        let _ = std::fs::remove_file(p);
                    }
                }
                eprintln!("\ninterrupted: no output was left half-written");
                std::process::exit(130);
            };
            if let Err(e) = ctrlc::set_handler(handler) {
                eprintln!("warning: cannot install the Ctrl-C handler: {e}");
            }
        });
    }

    /// From now on the first Ctrl-C only raises [`STOP`]; the command stops by itself.
    pub(crate) fn cooperate() {
        install();
        COOPERATIVE.store(true, Ordering::SeqCst);
    }

    /// Has Ctrl-C been pressed?
    pub(crate) fn requested() -> bool {
        STOP.load(Ordering::SeqCst)
    }
}

/// A progress bar on stderr (hidden when stderr is not a terminal) that redraws every 100 ms,
/// so its spinner and elapsed time move even while one long step runs. `template` is an
/// indicatif template.
pub(crate) fn progress_bar(len: u64, template: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(len);
    bar.set_style(indicatif::ProgressStyle::with_template(template).unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()).progress_chars("=> "));
    bar.enable_steady_tick(std::time::Duration::from_millis(100));
    bar
}

/// Checks that `value` of option `--name` lies in `[lo, hi]` (and is finite).
pub(crate) fn check_range(name: &str, value: f64, lo: f64, hi: f64, unit: &str) -> anyhow::Result<()> {
    if !(value.is_finite() && value >= lo && value <= hi) {
        let unit = if unit.is_empty() { String::new() } else { format!(" {unit}") };
        anyhow::bail!("--{name} {}{unit} is out of range; expected {} ≤ {name} ≤ {}{unit}", number(value), number(lo), number(hi));
    }
    Ok(())
}

/// A number as people write it: plain between 0.001 and 10⁶, else in exponent form.
pub(crate) fn number(x: f64) -> String {
    if x == 0.0 || (x.abs() >= 1e-3 && x.abs() < 1e6) || !x.is_finite() {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}
