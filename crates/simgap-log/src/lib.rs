//! Robot logs as ROS 2 users record them, read and written for simgap's runs
//! ([`simgap_sim::Run`]).
//!
//! - **MCAP** (`.mcap`): the ROS 2 profile rosbag2 writes; any message type, decoded with the
//!   `ros2msg` definition stored in the file; topics mapped to roles ([`TopicMap`]).
//! - **rosbag2 bag folders** (`metadata.yaml` + split `.mcap` files), wherever a file is
//!   accepted.
//! - **CSV** (`.csv`, `.csv.gz`) with a column mapping ([`csv::CsvMapping`]); the DFKI pendulum
//!   files are recognised by their header.
//! - **LeRobot datasets** (`LeRobotDataset` v2.0, v2.1, v3.0: `meta/info.json` and Parquet
//!   under `data/`), one run per episode; `FOLDER#0,3-5` picks episodes ([`lerobot`]).
//!
//! The API is four things: [`read_log`] and [`read_logs`] (with [`LogOptions`]; a dataset
//! folder holds many runs), [`write_log`], and the [`McapSink`] a simulation writes into as it
//! runs.
//!
//! ```no_run
//! use simgap_log::{read_log, write_log, LogOptions, TopicMap};
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let options = LogOptions { topics: TopicMap::parse("states=/arm/joint_states")?, ..LogOptions::default() };
//! let run = read_log("bags/teleop_0".as_ref(), &options)?;
//! println!("{} samples of {} joints from t = 0 (absolute start {:?} ns)", run.len(), run.dof(), run.start_ns);
//! write_log(&run, "teleop_0.mcap".as_ref())?;
//! # Ok(()) }
//! ```
//!
//! **Every log carries its own experiment** when it can: the `simgap.experiment` metadata
//! record of an MCAP file, else a sidecar `NAME.experiment.json` beside `NAME.mcap`,
//! `NAME.csv[.gz]` or the bag folder `NAME/`, else [`LogOptions::experiment`].
//!
//! **Time** is integer nanoseconds until the run is built: a run read from MCAP has `start_ns`
//! (the first state's stamp) and `t` in seconds since then; writing it back gives the same
//! stamps to the nanosecond.
//!
//! **No file crashes the reader.** The MCAP reader is a linear scan that checks every length
//! against the bytes that remain before allocating, so memory stays within a constant times
//! the file's size; a panic anyway would be a bug, and is returned as an error (never
//! unwound into the caller). A file without summary (its recorder was killed) is read up to its
//! last complete record, with a warning saying how much was recovered
//! ([`read_log_with_warnings`]).

pub mod bag;
pub mod csv;
pub mod csv_sink;
pub mod error;
pub mod experiment;
pub mod lerobot;
pub mod mcap;
pub mod partial;
pub mod topics;

use std::fs::File;
use std::io::BufReader;
use std::path::{Path, PathBuf};

use simgap_sim::{reorder_joints, Experiment, Run};

pub use crate::csv_sink::CsvSink;
pub use crate::error::{Error, Result};
pub use crate::mcap::write::{write_mcap, write_mcap_ended, Compression};
pub use crate::mcap::{McapSink, McapWriter, RunTopics, SinkOptions};
pub use crate::topics::{Role, TopicMap, TopicSpec};

use crate::error::{check_run, read_error, write_error};
use crate::mcap::read::{read_sources, Source};

/// The log formats simgap reads and writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LogFormat {
    /// ROS 2 MCAP (`.mcap`).
    Mcap,
    /// A rosbag2 bag folder of MCAP files.
    Bag,
    /// CSV (`.csv`), gzip-compressed when the name ends in `.gz`.
    Csv,
    /// A LeRobot dataset folder, or `FOLDER#SEL` (read only).
    LeRobot,
}

impl LogFormat {
    /// The format of a path: a LeRobot dataset ([`lerobot::dataset_path`]), else a folder is a
    /// bag, else by extension (`.mcap`, `.csv`, `.csv.gz`, case-insensitive).
    ///
    /// # Errors
    /// [`Error::Read`] for any other extension.
    pub fn from_path(path: &Path) -> Result<LogFormat> {
        if lerobot::dataset_path(path).is_some() {
            return Ok(LogFormat::LeRobot);
        }
        if path.is_dir() {
            return Ok(LogFormat::Bag);
        }
        let name = path.file_name().map(|s| s.to_string_lossy().to_lowercase()).unwrap_or_default();
        if name.ends_with(".mcap") {
            Ok(LogFormat::Mcap)
        } else if name.ends_with(".csv") || name.ends_with(".csv.gz") {
            Ok(LogFormat::Csv)
        } else if !path.exists() {
            Err(read_error(path, "unknown log format and no such file or folder (a log is a .mcap, .csv or .csv.gz file, a rosbag2 bag folder or a LeRobot dataset folder, FOLDER or FOLDER#EPISODES)"))
        } else {
            Err(read_error(path, "unknown log format: expected a .mcap, .csv or .csv.gz file, a rosbag2 bag folder or a LeRobot dataset folder (FOLDER or FOLDER#EPISODES)"))
        }
    }
}

/// How to read a log.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LogOptions {
    /// Which topic holds what (MCAP and bags; default `/joint_states`, `/joint_reference`,
    /// `/joint_effort_measured` and the `/servo/…` topics of [`TopicMap`]).
    pub topics: TopicMap,
    /// The experiment of logs that carry none (no metadata record, no sidecar file).
    pub experiment: Option<Experiment>,
    /// The column mapping of CSV logs (default: detected from the header).
    pub csv_mapping: Option<csv::CsvMapping>,
    /// LeRobot's calibration file, which makes range-normalised joints (a gripper's 0–100)
    /// angles; without it they are left out of the runs ([`lerobot`]).
    pub calibration: Option<lerobot::Calibration>,
}

/// A run read from a log, and what the reader had to warn about (a recovered file, a run that
/// did not complete).
#[derive(Clone, Debug, PartialEq)]
pub struct LogRead {
    /// The run.
    pub run: Run,
    /// Warnings, one sentence each (without the file name).
    pub warnings: Vec<String>,
}

/// Reads a log: an MCAP file, a rosbag2 bag folder or a CSV file (see the [crate docs](crate)).
/// Warnings go to the `log` crate (`warn!`); [`read_log_with_warnings`] returns them.
///
/// # Errors
/// [`Error::Read`] naming the file and the problem (unknown format, unreadable or corrupt file,
/// missing topic, undecodable message, a joint missing from a sample, non-finite values, time
/// going backwards, a malformed experiment), never a panic.
pub fn read_log(path: &Path, options: &LogOptions) -> Result<Run> {
    let read = read_log_with_warnings(path, options)?;
    for w in &read.warnings {
        log::warn!("{}: {w}", path.display());
    }
    Ok(read.run)
}

/// [`read_log`], returning the warnings with the run.
///
/// # Errors
/// As [`read_log`].
pub fn read_log_with_warnings(path: &Path, options: &LogOptions) -> Result<LogRead> {
    guarded(path, || match lerobot::dataset_path(path) {
        Some(dataset) => {
            let mut reads = lerobot::read_dataset(&dataset, options)?;
            match reads.len() {
                1 => Ok(reads.remove(0)),
                n => {
                    Err(read_error(path, format!("selects {n} episodes of a LeRobot dataset, and one log is one run: pick one episode (FOLDER#N) or read them all with read_logs")))
                }
            }
        }
        None => read_any(path, options),
    })
}

/// Reads every run a log holds: the episodes a LeRobot dataset path selects (one run each, in
/// the order selected), else the one run of an MCAP file, bag folder or CSV file. Warnings go to
/// the `log` crate, as [`read_log`]'s.
///
/// # Errors
/// As [`read_log`]; for a dataset, [`Error::Read`] naming the folder, the file and the episode.
pub fn read_logs(path: &Path, options: &LogOptions) -> Result<Vec<Run>> {
    let reads = read_logs_with_warnings(path, options)?;
    // a dataset's warnings are the same for every episode: said once
    if let Some(first) = reads.first() {
        for w in &first.warnings {
            log::warn!("{}: {w}", path.display());
        }
    }
    Ok(reads.into_iter().map(|r| r.run).collect())
}

/// [`read_logs`], returning each run with its warnings.
///
/// # Errors
/// As [`read_logs`].
pub fn read_logs_with_warnings(path: &Path, options: &LogOptions) -> Result<Vec<LogRead>> {
    guarded(path, || match lerobot::dataset_path(path) {
        Some(dataset) => lerobot::read_dataset(&dataset, options),
        None => read_any(path, options).map(|r| vec![r]),
    })
}

/// Reads a log and puts its joints in `joints` order (a model's order); joints of the log that
/// are not in `joints` are an error unless `drop_extra`.
///
/// # Errors
/// As [`read_log`], and [`Error::Run`] with a joint mismatch naming the joint.
pub fn read_log_for(path: &Path, joints: &[String], drop_extra: bool, options: &LogOptions) -> Result<Run> {
    let run = read_log(path, options)?;
    Ok(reorder_joints(&run, joints, drop_extra)?)
}

/// Reads an MCAP file held in memory (`name` is used in messages). The experiment is the file's,
/// else `options.experiment`.
///
/// # Errors
/// As [`read_log`].
pub fn read_mcap_bytes(name: &str, bytes: &[u8], options: &LogOptions) -> Result<LogRead> {
    let label = PathBuf::from(name);
    guarded(&label, || {
        let source = Source { name: name.to_string(), input: Box::new(bytes), len: bytes.len() as u64 };
        read_sources(&label, vec![source], &options.topics, options.experiment.as_ref())
    })
}

/// Runs a read; a panic (a bug) becomes an [`Error::Read`] instead of unwinding into the caller.
fn guarded<T>(path: &Path, f: impl FnOnce() -> Result<T>) -> Result<T> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).unwrap_or_else(|payload| {
        let what = payload.downcast_ref::<&str>().map(|s| s.to_string()).or_else(|| payload.downcast_ref::<String>().cloned()).unwrap_or_else(|| "unknown".into());
        Err(read_error(path, format!("internal error while reading ({what}); please report it with this file")))
    })
}

fn open_source(path: &Path) -> Result<Source<'static>> {
    let file = File::open(path).map_err(|e| read_error(path, format!("cannot open: {e}")))?;
    let len = file.metadata().map_err(|e| read_error(path, format!("cannot open: {e}")))?.len();
    let name = path.file_name().map(|s| s.to_string_lossy().to_string()).unwrap_or_default();
    Ok(Source { name, input: Box::new(BufReader::with_capacity(1 << 16, file)), len })
}

fn read_any(path: &Path, options: &LogOptions) -> Result<LogRead> {
    let format = LogFormat::from_path(path)?;
    // the experiment of logs without a metadata record: sidecar, else the caller's
    let sidecar = crate::experiment::read_sidecar(path)?;
    let fallback = sidecar.as_ref().or(options.experiment.as_ref());
    match format {
        LogFormat::Mcap => read_sources(path, vec![open_source(path)?], &options.topics, fallback),
        LogFormat::Bag => {
            let sources = crate::bag::bag_files(path)?.iter().map(|f| open_source(f)).collect::<Result<Vec<_>>>()?;
            read_sources(path, sources, &options.topics, fallback)
        }
        LogFormat::LeRobot => Err(read_error(path, "is a LeRobot dataset; read it with read_logs")),
        LogFormat::Csv => {
            let mut warnings = Vec::new();
            let mut run = match &options.csv_mapping {
                Some(m) => crate::csv::read_csv_warned(path, m, &mut warnings)?,
                None => crate::csv::read_csv_auto_warned(path, &mut warnings)?,
            };
            if run.experiment.is_none() {
                run.experiment = fallback.cloned();
                simgap_sim::fill_sample_period(&mut run);
                check_run(&run, path)?;
            }
            Ok(LogRead { run, warnings })
        }
    }
}

/// Writes a run as a log, the format chosen by extension (`.mcap`, `.csv`, `.csv.gz`).
///
/// MCAP logs hold the experiment in their metadata; CSV logs get it in a sidecar JSON file
/// ([`experiment::sidecar_path`]). Runs with `start_ns` are written with absolute stamps.
///
/// # Errors
/// [`Error::Write`] for an unknown extension, an invalid run or a file that cannot be written.
pub fn write_log(run: &Run, path: &Path) -> Result<()> {
    simgap_sim::validate_run(run).map_err(|e| match e {
        simgap_sim::Error::Log { message, .. } => write_error(path, format!("invalid run: {message}")),
        other => Error::Run(other),
    })?;
    let format = if path.is_dir() { Err(write_error(path, "is a folder; give a .mcap, .csv or .csv.gz file")) } else { Ok(()) }
        .and_then(|()| LogFormat::from_path(path).map_err(|_| write_error(path, "unknown log format: expected a .mcap, .csv or .csv.gz file")))?;
    match format {
        LogFormat::LeRobot => Err(write_error(path, "names a LeRobot dataset, which simgap reads but does not write; give a .mcap, .csv or .csv.gz file")),
        LogFormat::Mcap | LogFormat::Bag => write_mcap(run, path),
        LogFormat::Csv => {
            crate::csv::write_csv(run, path)?;
            if let Some(e) = &run.experiment {
                crate::experiment::write_experiment_file(e, &crate::experiment::sidecar_path(path))?;
            }
            Ok(())
        }
    }
}
