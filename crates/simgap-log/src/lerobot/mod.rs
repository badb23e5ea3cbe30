//! LeRobot datasets (`LeRobotDataset` v2.0, v2.1 and v3.0), read as runs: one run per episode.
//!
//! A dataset is a folder with `meta/info.json` and Parquet files under `data/`; `FOLDER#SEL`
//! picks episodes (`SEL` = comma-separated indices and inclusive ranges, `FOLDER#0,3-5`), a
//! bare folder means every episode. Each episode becomes a [`Run`] named `FOLDER#N`. The
//! layouts are described in [`episodes`]; `meta/info.json` is checked in [`info`]. Videos are
//! never opened.
//!
//! **What the columns are.** `observation.state` holds the measured state and `action` the goal
//! written to the servos (the `q_ref` of a `servo` experiment). Their `names` entries
//! `<joint>.pos` are joint positions, mapped to URDF joints by name (`.pos` stripped; a name
//! without any suffix, as LeRobot v2.0 wrote them, is a position too); `<joint>.vel` is the
//! joint's velocity (in the positions' unit per second); `<joint>.effort` and `<joint>.torque`
//! are the torque the drive reports [N·m] (`tau_measured`); `<joint>.temp` and
//! `<joint>.temperature` its temperature [°C]. `<joint>.load` and `<joint>.current` are register
//! readings without a torque scale: they are named in a warning and not used. Positions are
//! **degrees**, as LeRobot's motor bus writes them (`DEGREES` mode), unless the experiment says
//! `angle_unit = rad`.
//!
//! **Range-normalised joints.** LeRobot writes a gripper as 0–100 of its calibrated range
//! (`RANGE_0_100`), and arm joints recorded with `use_degrees=False` as −100…100
//! (`RANGE_M100_100`); neither is an angle. The rule: a joint named `gripper` (or ending in
//! `_gripper`, as bimanual robots prefix theirs) is 0–100; the experiment key
//! `range_normalised` (comma-separated joints, empty for none) replaces that default list, its
//! other joints being −100…100. Such a joint becomes an angle only with LeRobot's calibration
//! file ([`calibration`], `--calibration FILE`); without one it is left out of the run
//! ([`Run::left_out`]), with a warning and a note: a diagnosis then locks the model joint of
//! that name at its zero position. A value outside the mode's interval is an error (the joint
//! is then no range-normalised joint: fix `range_normalised`).
//!
//! **Time.** LeRobot's timestamps are nominal (`frame_index / fps`), so the run's times are
//! `frame_index / fps` and the experiment's sample period, when it gives none, is `1/fps`: the
//! run's notes say the timing is nominal (any delay must be inferred from the response).
//! Velocities a dataset does not hold are central differences of the positions.
//!
//! **The experiment** is the dataset's sidecar `meta/simgap.experiment.json` (the keys of the
//! `simgap.experiment` metadata), else the one given ([`LogOptions::experiment`]). A joint left
//! out of the run is left out of the experiment too (every list with one value per joint
//! loses that joint's value).
//!
//! **Why `parquet` without Arrow.** The reader needs three kinds of column (float lists, int64
//! and float scalars) and nothing Arrow computes; the `parquet` crate's column reader decodes
//! them directly ([`table`]), with only the codecs LeRobot's writers use (snappy, the pyarrow
//! and HF `datasets` default; zstd; gzip). Leaving out the `arrow` feature leaves out seven
//! `arrow-*` crates and most of the compile time.
//!
//! Every error names the folder, the file and the episode, and no content of a dataset makes
//! the reader panic, hang or allocate beyond bounds ([`info`] and [`table`] say which).

pub mod calibration;
pub(crate) mod episodes;
pub(crate) mod info;
pub(crate) mod table;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use simgap_sim::{central_difference, Experiment, Run};

use crate::error::{check_run, read_error, Result};
use crate::{LogOptions, LogRead};
pub use calibration::{Calibration, MotorCalibration, NormMode};
use episodes::{list_episodes, parse_selection, Episode};
use info::{read_info, Info};
use table::{read_columns, Column, RowGroups, Table};

/// The sidecar experiment file inside a dataset.
pub const SIDECAR: &str = "meta/simgap.experiment.json";
/// The experiment key naming the range-normalised joints (see the [module docs](self)).
pub const KEY_RANGE_NORMALISED: &str = "range_normalised";
/// The experiment key giving the unit of `.pos` values: `deg` (default) or `rad`.
pub const KEY_ANGLE_UNIT: &str = "angle_unit";

/// A dataset and the episodes a path selects.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DatasetPath {
    /// The dataset folder.
    pub folder: PathBuf,
    /// The selection after `#` (`None`: every episode).
    pub selection: Option<String>,
}

/// Whether `path` names a LeRobot dataset: a folder with `meta/info.json` (or a `meta/` folder
/// and no rosbag2 `metadata.yaml`), or `FOLDER#SEL` with `FOLDER` a folder and `SEL` made of
/// digits, commas, `-` and spaces.
pub fn dataset_path(path: &Path) -> Option<DatasetPath> {
    let looks_like = |p: &Path| p.is_dir() && (p.join("meta").join("info.json").is_file() || (p.join("meta").is_dir() && !p.join("metadata.yaml").is_file()));
    if looks_like(path) {
        return Some(DatasetPath { folder: path.to_path_buf(), selection: None });
    }
    if path.exists() {
        return None;
    }
    let text = path.to_str()?;
    let (folder, sel) = text.rsplit_once('#')?;
    let folder = Path::new(folder);
    (folder.is_dir() && sel.chars().all(|c| c.is_ascii_digit() || matches!(c, ',' | '-' | ' ')))
        .then(|| DatasetPath { folder: folder.to_path_buf(), selection: Some(sel.to_string()) })
}

/// The episode indices of a dataset folder, in order.
///
/// # Errors
/// [`Error::Read`](crate::Error::Read) naming the folder and the metadata file at fault.
pub fn episode_indices(folder: &Path) -> Result<Vec<i64>> {
    let info = read_info(folder).map_err(|m| read_error(folder, m))?;
    Ok(list_episodes(folder, &info).map_err(|m| read_error(folder, m))?.iter().map(|e| e.index).collect())
}

/// What one entry of `observation.state` (or `action`) is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Quantity {
    Position,
    Velocity,
    Torque,
    Temperature,
    /// A register reading without a torque scale (`.load`, `.current`).
    Unscaled,
}

/// Splits a `names` entry into joint and quantity (`None`: not a joint quantity).
fn split_name(name: &str) -> Option<(&str, Quantity)> {
    let Some((joint, suffix)) = name.rsplit_once('.') else { return Some((name, Quantity::Position)) };
    let q = match suffix {
        "pos" => Quantity::Position,
        "vel" => Quantity::Velocity,
        "effort" | "torque" => Quantity::Torque,
        "temp" | "temperature" => Quantity::Temperature,
        "load" | "current" => Quantity::Unscaled,
        _ => return None,
    };
    (!joint.is_empty()).then_some((joint, q))
}

/// Where each quantity of each joint sits in a vector feature.
#[derive(Default)]
struct Layout {
    /// Joint → index of each quantity.
    entries: BTreeMap<String, BTreeMap<&'static str, usize>>,
    /// Joints with a position, in feature order.
    joints: Vec<String>,
    /// Entries that are no joint quantity, or have no scale.
    ignored: Vec<String>,
}

impl Layout {
    fn of(names: &[String]) -> Layout {
        let mut l = Layout::default();
        for (i, n) in names.iter().enumerate() {
            let key = match split_name(n) {
                Some((_, Quantity::Unscaled)) | None => {
                    l.ignored.push(n.clone());
                    continue;
                }
                Some((j, Quantity::Position)) => {
                    l.joints.push(j.to_string());
                    (j, "pos")
                }
                Some((j, Quantity::Velocity)) => (j, "vel"),
                Some((j, Quantity::Torque)) => (j, "torque"),
                Some((j, Quantity::Temperature)) => (j, "temp"),
            };
            l.entries.entry(key.0.to_string()).or_default().insert(key.1, i);
        }
        l
    }

    fn index(&self, joint: &str, quantity: &str) -> Option<usize> {
        self.entries.get(joint).and_then(|m| m.get(quantity)).copied()
    }
}

/// How the `.pos` values of each joint become radians.
struct Conversion {
    /// The joints of the run, in `observation.state` order, and each one's mode.
    kept: Vec<(String, NormMode)>,
    /// Joints left out (range-normalised, no calibration).
    left_out: Vec<(String, NormMode)>,
    /// Radians per unit of a `Degrees` joint's values.
    scale: f64,
}

/// The range-normalised joints and their modes (module docs).
fn norm_modes(joints: &[String], experiment: Option<&Experiment>) -> BTreeMap<String, NormMode> {
    let gripper = |j: &str| j == "gripper" || j.ends_with("_gripper");
    let listed: Vec<String> = match experiment.and_then(|e| e.extra.get(KEY_RANGE_NORMALISED)) {
        Some(list) => list.split(',').map(|s| s.trim().to_string()).filter(|s| !s.is_empty()).collect(),
        None => joints.iter().filter(|j| gripper(j)).cloned().collect(),
    };
    joints
        .iter()
        .map(|j| {
            let mode = if !listed.contains(j) {
                NormMode::Degrees
            } else if gripper(j) {
                NormMode::Range0To100
            } else {
                NormMode::RangeM100To100
            };
            (j.clone(), mode)
        })
        .collect()
}

fn conversion(layout: &Layout, experiment: Option<&Experiment>, calibration: Option<&Calibration>) -> std::result::Result<Conversion, String> {
    let scale = match experiment.and_then(|e| e.extra.get(KEY_ANGLE_UNIT)).map(|s| s.trim().to_lowercase()) {
        None => std::f64::consts::PI / 180.0,
        Some(u) if matches!(u.as_str(), "deg" | "degree" | "degrees") => std::f64::consts::PI / 180.0,
        Some(u) if matches!(u.as_str(), "rad" | "radian" | "radians") => 1.0,
        Some(u) => return Err(format!("the experiment's {KEY_ANGLE_UNIT} is '{u}'; expected 'deg' or 'rad'")),
    };
    let modes = norm_modes(&layout.joints, experiment);
    if let Some(list) = experiment.and_then(|e| e.extra.get(KEY_RANGE_NORMALISED)) {
        if let Some(j) = list.split(',').map(str::trim).find(|j| !j.is_empty() && !layout.joints.iter().any(|k| k == j)) {
            return Err(format!("the experiment's {KEY_RANGE_NORMALISED} names '{j}', which has no position in observation.state (joints: {})", layout.joints.join(", ")));
        }
    }
    let (mut kept, mut left_out) = (Vec::new(), Vec::new());
    for j in &layout.joints {
        let mode = modes[j];
        let calibrated = calibration.is_some_and(|c| c.motors.contains_key(j));
        if mode == NormMode::Degrees || calibrated {
            kept.push((j.clone(), mode));
        } else {
            left_out.push((j.clone(), mode));
        }
    }
    if kept.is_empty() {
        return Err(format!("no joint of observation.state is an angle: {} are range-normalised and no calibration file gives their range", layout.joints.join(", ")));
    }
    Ok(Conversion { kept, left_out, scale })
}

/// The experiment without the joints `dropped` (a run's [`Run::left_out`]): `joints` and every
/// value list with one entry per joint (`kp`, `kv`, `duty_gain`, …) lose theirs.
pub fn without_joints(e: &Experiment, dropped: &[String]) -> Experiment {
    let n = e.joints.len();
    let keep: Vec<bool> = e.joints.iter().map(|j| !dropped.contains(j)).collect();
    if keep.iter().all(|k| *k) {
        return e.clone();
    }
    let pick = |v: &[f64]| if v.len() == n { v.iter().zip(&keep).filter(|(_, k)| **k).map(|(x, _)| *x).collect() } else { v.to_vec() };
    let mut out = e.clone();
    out.joints = e.joints.iter().zip(&keep).filter(|(_, k)| **k).map(|(j, _)| j.clone()).collect();
    out.kp = pick(&e.kp);
    out.kv = pick(&e.kv);
    for v in out.extra.values_mut() {
        let items: Vec<&str> = v.split(',').collect();
        if n > 1 && items.len() == n {
            *v = items.iter().zip(&keep).filter(|(_, k)| **k).map(|(x, _)| x.trim()).collect::<Vec<_>>().join(",");
        }
    }
    out
}

/// Reads the episodes `dataset` selects, one run each, in the order selected. `label` is the
/// folder as the user wrote it (runs are named `label#N`).
pub(crate) fn read_dataset(dataset: &DatasetPath, options: &LogOptions) -> Result<Vec<LogRead>> {
    let folder = &dataset.folder;
    let err = |m: String| read_error(folder, m);
    let info = read_info(folder).map_err(err)?;
    let all = list_episodes(folder, &info).map_err(err)?;
    let indices: Vec<i64> = all.iter().map(|e| e.index).collect();
    let chosen: Vec<&Episode> = match &dataset.selection {
        None if all.is_empty() => return Err(err("the dataset lists no episode".into())),
        None => all.iter().collect(),
        Some(sel) => parse_selection(sel, &indices).map_err(err)?.iter().filter_map(|i| all.iter().find(|e| e.index == *i)).collect(),
    };
    // the experiment: the dataset's sidecar, else the caller's
    let sidecar = folder.join(SIDECAR);
    let experiment = if sidecar.is_file() { Some(crate::experiment::read_experiment_file(&sidecar)?) } else { options.experiment.clone() };
    // which entries are which joint quantity, and how positions become radians
    let state = Layout::of(&info.state.names);
    let action = info.action.as_ref().map(|a| Layout::of(&a.names));
    let conv = conversion(&state, experiment.as_ref(), options.calibration.as_ref()).map_err(|m| err(format!("meta/info.json, observation.state: {m}")))?;
    let mut warnings = Vec::new();
    if !state.ignored.is_empty() {
        warnings.push(format!(
            "observation.state entries {} are not used (a .load or .current reading has no torque scale; other suffixes are no joint quantity)",
            state.ignored.join(", ")
        ));
    }
    for (j, mode) in &conv.left_out {
        warnings.push(format!(
            "joint '{j}' is {} and no calibration file gives its range (--calibration FILE): it is left out of the run, and a diagnosis locks it at its URDF zero",
            mode.describe()
        ));
    }
    // each data file read once, for the episodes chosen in it
    let mut by_file: BTreeMap<&Path, Vec<&Episode>> = BTreeMap::new();
    for e in &chosen {
        by_file.entry(e.file.as_path()).or_default().push(e);
    }
    let mut runs: BTreeMap<i64, Run> = BTreeMap::new();
    for (file, episodes) in by_file {
        let name = file.strip_prefix(folder).unwrap_or(file).display().to_string();
        let which = match episodes.as_slice() {
            [e] => format!("episode {}", e.index),
            many => format!("episodes {}", many.iter().map(|e| e.index.to_string()).collect::<Vec<_>>().join(", ")),
        };
        let ferr = |m: String| err(format!("{name} ({which}): {m}"));
        if !file.is_file() {
            return Err(ferr("the data file is missing".into()));
        }
        let rows =
            if episodes[0].shared_file { RowGroups::Containing { column: "episode_index".into(), values: episodes.iter().map(|e| e.index).collect() } } else { RowGroups::All };
        let mut names = vec!["observation.state", "frame_index", "episode_index"];
        if info.action.is_some() {
            names.push("action");
        }
        let table = read_columns(file, &names, &["episode_index"], &rows).map_err(ferr)?;
        check_columns(&table, &info).map_err(ferr)?;
        for e in episodes {
            let run = episode_run(&table, e, &info, &state, action.as_ref(), &conv, experiment.as_ref(), options.calibration.as_ref())
                .map_err(|m| err(format!("{name}, episode {}: {m}", e.index)))?
                .with_source(format!("{}#{}", folder.display(), e.index));
            check_run(&run, folder).map_err(|x| err(format!("{name}, episode {}: {}", e.index, strip_path(&x.to_string(), folder))))?;
            runs.insert(e.index, run);
        }
    }
    Ok(chosen.iter().filter_map(|e| runs.remove(&e.index)).map(|run| LogRead { run, warnings: warnings.clone() }).collect())
}

/// An error's text without the leading `path: ` it names again.
fn strip_path(message: &str, path: &Path) -> String {
    message.strip_prefix(&format!("{}: ", path.display())).unwrap_or(message).to_string()
}

trait WithSource {
    fn with_source(self, source: String) -> Run;
}

impl WithSource for Run {
    fn with_source(mut self, source: String) -> Run {
        self.source = source;
        self
    }
}

/// The columns of a data file against `meta/info.json`: floats of the declared width.
fn check_columns(table: &Table, info: &Info) -> std::result::Result<(), String> {
    let check = |key: &str, width: usize| -> std::result::Result<(), String> {
        let Some(c) = table.column(key) else { return Ok(()) };
        if c.integer {
            return Err(format!("column '{key}' holds integers; expected floats (joint positions)"));
        }
        if table.rows > 0 && (c.width != width || !c.list && width > 1) {
            return Err(format!("column '{key}' has {} numbers per row; meta/info.json declares {width}", c.width));
        }
        Ok(())
    };
    check("observation.state", info.state.names.len())?;
    if let Some(a) = &info.action {
        check("action", a.names.len())?;
    }
    Ok(())
}

/// One episode's run from the rows of `table` whose `episode_index` is its own.
#[allow(clippy::too_many_arguments)]
fn episode_run(
    table: &Table,
    e: &Episode,
    info: &Info,
    state: &Layout,
    action: Option<&Layout>,
    conv: &Conversion,
    experiment: Option<&Experiment>,
    calibration: Option<&Calibration>,
) -> std::result::Result<Run, String> {
    let empty = Column::default();
    let frame = table.column("frame_index").unwrap_or(&empty);
    // the episode's rows, in frame order
    let mut rows: Vec<usize> = match table.column("episode_index") {
        Some(ep) => (0..table.rows).filter(|&r| ep.values[r] == e.index as f64).collect(),
        None if e.shared_file => return Err("the data file has no episode_index column to find the episode's rows by".into()),
        None => (0..table.rows).collect(),
    };
    if !e.shared_file {
        if let Some(r) = rows.iter().position(|&r| table.column("episode_index").is_some_and(|c| c.values[r] != e.index as f64)) {
            return Err(format!("row {r} belongs to another episode"));
        }
    }
    if rows.is_empty() {
        return Err("the data file holds no frame of this episode".into());
    }
    if let Some(len) = e.length {
        if len != rows.len() as i64 {
            return Err(format!("the data file holds {} frames of the episode; the episode metadata says {len} (the file is cut or altered)", rows.len()));
        }
    }
    rows.sort_by(|a, b| frame.values[*a].total_cmp(&frame.values[*b]));
    if let Some(w) = rows.windows(2).find(|w| frame.values[w[0]] == frame.values[w[1]]) {
        return Err(format!("frame_index {} appears twice", frame.values[w[0]]));
    }
    if let Some(&r) = rows.iter().find(|&&r| !(frame.values[r].is_finite() && frame.values[r] >= 0.0)) {
        return Err(format!("frame_index {} is not a frame number", frame.values[r]));
    }
    // nominal time: frame_index / fps
    let t: Vec<f64> = rows.iter().map(|&r| frame.values[r] / info.fps).collect();
    let joints: Vec<String> = conv.kept.iter().map(|(j, _)| j.clone()).collect();
    let sc = table.column("observation.state").ok_or("no observation.state column")?;
    let position = |c: &Column, layout: &Layout, what: &str| -> std::result::Result<Vec<f64>, String> {
        let mut out = Vec::with_capacity(rows.len() * joints.len());
        for &r in &rows {
            for (j, mode) in &conv.kept {
                let i = layout.index(j, "pos").ok_or_else(|| format!("{what} has no entry '{j}.pos'"))?;
                let v = c.values[r * c.width + i];
                if let Some((lo, hi)) = mode.interval() {
                    if !(v >= lo - 1e-3 && v <= hi + 1e-3) {
                        return Err(format!(
                            "{what} '{j}.pos' is {v} at frame {}: outside the {} interval (if it is an angle, leave it out of the experiment's {KEY_RANGE_NORMALISED})",
                            frame.values[r],
                            mode.describe()
                        ));
                    }
                }
                out.push(match (mode, calibration) {
                    (NormMode::Degrees, _) => v * conv.scale,
                    (m, Some(cal)) => cal.angle_deg(j, *m, v).unwrap_or(f64::NAN).to_radians(),
                    (_, None) => f64::NAN,
                });
            }
        }
        Ok(out)
    };
    let per_joint = |quantity: &str, scale: f64| -> Option<Vec<f64>> {
        let idx: Vec<usize> = conv.kept.iter().map(|(j, _)| state.index(j, quantity)).collect::<Option<_>>()?;
        Some(rows.iter().flat_map(|&r| idx.iter().map(move |&i| sc.values[r * sc.width + i] * scale)).collect())
    };
    let mut run = Run::new(joints.clone());
    run.q = position(sc, state, "observation.state")?;
    run.t = t;
    // velocities: the dataset's when every kept joint has one in degrees/radians, else differences
    let all_angles = conv.kept.iter().all(|(_, m)| *m == NormMode::Degrees);
    match per_joint("vel", conv.scale).filter(|_| all_angles) {
        Some(qd) => run.qd = qd,
        None => {
            run.qd = central_difference(&run.t, &run.q, joints.len());
            run.notes.push("velocities are central differences of the positions (the dataset has none for every joint)".into());
        }
    }
    run.tau_measured = per_joint("torque", 1.0).unwrap_or_default();
    run.drive.temperature = per_joint("temp", 1.0).unwrap_or_default();
    // the goal: action's positions of the same joints
    if let (Some(ac), Some(layout)) = (table.column("action"), action) {
        if conv.kept.iter().all(|(j, _)| layout.index(j, "pos").is_some()) {
            run.q_ref = position(ac, layout, "action")?;
        } else if let Some((j, _)) = conv.kept.iter().find(|(j, _)| layout.index(j, "pos").is_none()) {
            return Err(format!("action has no entry '{j}.pos' (observation.state has one); expected a goal for every joint"));
        }
    }
    // the experiment, without the joints left out, its sample period 1/fps unless given
    let dropped: Vec<String> = conv.left_out.iter().map(|(j, _)| j.clone()).collect();
    run.experiment = experiment.map(|x| {
        let mut x = without_joints(x, &dropped);
        if x.sample_period.is_nan() {
            x.sample_period = 1.0 / info.fps;
        }
        x
    });
    run.left_out = dropped;
    run.notes.insert(
        0,
        format!(
            "LeRobot timestamps are nominal (frame_index / fps, {} Hz): the sample period is taken as {:.6} s and any delay is inferred from the response, never from the stamps",
            info.fps,
            1.0 / info.fps
        ),
    );
    for (j, mode) in &conv.left_out {
        run.notes.push(format!("joint '{j}' is {} without a calibration file: left out of the fit and locked at its URDF zero", mode.describe()));
    }
    Ok(run)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_map_to_joint_quantities() {
        let names: Vec<String> = ["shoulder_pan.pos", "shoulder_pan.vel", "gripper.pos", "gripper.current", "x.weird", "elbow"].iter().map(|s| s.to_string()).collect();
        let l = Layout::of(&names);
        assert_eq!(l.joints, vec!["shoulder_pan", "gripper", "elbow"]);
        assert_eq!(l.index("shoulder_pan", "vel"), Some(1));
        assert_eq!(l.ignored, vec!["gripper.current", "x.weird"]);
        let modes = norm_modes(&l.joints, None);
        assert_eq!(modes["gripper"], NormMode::Range0To100);
        assert_eq!(modes["shoulder_pan"], NormMode::Degrees);
    }

    #[test]
    fn a_joint_left_out_leaves_the_experiments_per_joint_lists() {
        let mut map = std::collections::BTreeMap::new();
        for (k, v) in [("controller", "servo"), ("joints", "a,gripper,b"), ("duty_gain", "1,2,3"), ("max_duty", "0.9"), ("supply_voltage", "12")] {
            map.insert(k.to_string(), v.to_string());
        }
        let e = simgap_sim::experiment_from_map(&map).unwrap();
        let out = without_joints(&e, &["gripper".to_string()]);
        assert_eq!(out.joints, vec!["a", "b"]);
        assert_eq!(out.extra["duty_gain"], "1,3");
        assert_eq!(out.extra["max_duty"], "0.9");
    }

    #[test]
    fn a_selection_after_a_hash_names_a_dataset() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(dir.path().join("ds/meta")).unwrap();
        std::fs::write(dir.path().join("ds/meta/info.json"), "{}").unwrap();
        let ds = dir.path().join("ds");
        assert_eq!(dataset_path(&ds).unwrap().selection, None);
        let sel = PathBuf::from(format!("{}#0,3-5", ds.display()));
        assert_eq!(dataset_path(&sel).unwrap(), DatasetPath { folder: ds.clone(), selection: Some("0,3-5".into()) });
        assert!(dataset_path(&dir.path().join("run.csv")).is_none());
    }
}
