//! LeRobot datasets: the SAGE SO-101 dataset (`../shared/data/sage-so101/lerobot`, v3.0, 38
//! episodes) read episode by episode, its degrees turned into SAGE's radians, the gripper left
//! out without a calibration file and an angle with one, and every kind of bad input an error
//! that names the folder, the file and the episode.
//!
//! Needs the shared data next to the repository: without it each test skips with a message,
//! and fails when `CI` is set. Datasets written from scratch in both versions (v2.1 and v3.0)
//! are tested from Python with pyarrow (`python/tests/test_lerobot.py`).

use std::io::Read;
use std::path::{Path, PathBuf};

use simgap_log::lerobot::{episode_indices, Calibration};
use simgap_log::{read_log, read_logs, read_logs_with_warnings, LogOptions};
use simgap_sim::{ControllerKind, Run};

mod common;

const ARM: [&str; 5] = ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"];

/// The SAGE SO-101 folder next to the workspace, or `None` (with a message) when it is absent.
fn sage() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/sage-so101");
    if dir.join("lerobot/meta/info.json").is_file() {
        Some(dir)
    } else {
        assert!(std::env::var_os("CI").is_none(), "the SAGE SO-101 data is not at {} (CI is set: a test without its data fails)", dir.display());
        eprintln!("SKIP: the SAGE SO-101 data is not at {}", dir.display());
        None
    }
}

fn with_hash(folder: &Path, sel: &str) -> PathBuf {
    PathBuf::from(format!("{}#{sel}", folder.display()))
}

/// A copy of the dataset in a temporary folder, to alter.
fn copy_dataset(src: &Path) -> (tempfile::TempDir, PathBuf) {
    let dir = common::folder();
    let dst = dir.path().join("lerobot");
    for rel in ["meta/info.json", "meta/stats.json", "meta/tasks.parquet", "meta/episodes/chunk-000/file-000.parquet", "data/chunk-000/file-000.parquet"] {
        let to = dst.join(rel);
        std::fs::create_dir_all(to.parent().unwrap()).unwrap();
        std::fs::copy(src.join(rel), &to).unwrap();
        let mut perm = std::fs::metadata(&to).unwrap().permissions();
        #[allow(clippy::permissions_set_readonly_false)]
        perm.set_readonly(false);
        std::fs::set_permissions(&to, perm).unwrap();
    }
    (dir, dst)
}

fn error_of(result: simgap_log::Result<Vec<Run>>) -> String {
    result.expect_err("expected an error").to_string()
}

/// SAGE's `positions` lists of a gzipped CSV, with the stamps [s].
fn sage_rows(path: &Path) -> (Vec<f64>, Vec<Vec<f64>>) {
    let mut text = String::new();
    flate2::read::GzDecoder::new(std::fs::File::open(path).unwrap()).read_to_string(&mut text).unwrap();
    let mut reader = csv::Reader::from_reader(text.as_bytes());
    let (mut t, mut rows) = (Vec::new(), Vec::new());
    for record in reader.records() {
        let r = record.unwrap();
        t.push(r[1].parse::<f64>().unwrap() * 1e-6);
        rows.push(r[2].trim_matches(|c| c == '[' || c == ']').split(',').map(|x| x.trim().parse::<f64>().unwrap()).collect());
    }
    (t, rows)
}

#[test]
fn an_episode_is_a_run_named_after_the_folder_and_its_index() {
    let Some(sage) = sage() else { return };
    let folder = sage.join("lerobot");
    let run = read_log(&with_hash(&folder, "1"), &LogOptions::default()).unwrap();
    assert_eq!(run.source, format!("{}#1", folder.display()));
    // the gripper is range-normalised (0–100): without calibration it is left out
    assert_eq!(run.joints, ARM);
    assert_eq!(run.left_out, vec!["gripper".to_string()]);
    assert_eq!(run.len(), 6018, "backlash_detection has 6018 frames");
    // nominal time: frame_index / fps
    assert_eq!(run.t[0], 0.0);
    assert!((run.t[1] - 0.02).abs() < 1e-15 && (run.t[6017] - 6017.0 / 50.0).abs() < 1e-12);
    assert_eq!(run.q_ref.len(), run.q.len(), "action is the goal");
    assert_eq!(run.qd.len(), run.q.len(), "velocities by central difference");
    assert!(run.notes.iter().any(|n| n.contains("nominal")), "{:?}", run.notes);
    assert!(run.notes.iter().any(|n| n.contains("'gripper'") && n.contains("locked")), "{:?}", run.notes);
    assert!(run.experiment.is_none(), "no sidecar, none given");
}

#[test]
fn degrees_become_sages_radians() {
    let Some(sage) = sage() else { return };
    let run = read_log(&with_hash(&sage.join("lerobot"), "0"), &LogOptions::default()).unwrap();
    // episode 0 is actuator_bandwidth; the dataset interpolated SAGE's states onto t0 + f/50 s
    // and wrote degrees as LeRobot does, (raw − mid)·360/4095: radians(state) is SAGE's angle
    // × 4096/4095 (the SAGE README, "LeRobot dataset")
    let (ts, states) = sage_rows(&sage.join("sage/actuator_bandwidth/state_motor.csv.gz"));
    let n = run.dof();
    let mut worst: f64 = 0.0;
    let mut k0 = 0;
    for (f, t) in run.t.iter().enumerate() {
        let at = ts[0] + t;
        while k0 + 2 < ts.len() && ts[k0 + 1] <= at {
            k0 += 1;
        }
        let s = ((at - ts[k0]) / (ts[k0 + 1] - ts[k0])).clamp(0.0, 1.0);
        for j in 0..n {
            let sage_rad = states[k0][j] + s * (states[k0 + 1][j] - states[k0][j]);
            worst = worst.max((run.q[f * n + j] - sage_rad * 4096.0 / 4095.0).abs());
        }
    }
    // float32 degrees hold about 7 digits: a few µrad
    assert!(worst < 5e-6, "largest difference from SAGE's radians: {worst} rad");
    // and the goal in force (zero-order hold of control.csv), written as degrees(goal)
    let (tc, goals) = sage_rows(&sage.join("sage/actuator_bandwidth/control.csv.gz"));
    let mut worst_goal: f64 = 0.0;
    let mut k = 0;
    for (f, t) in run.t.iter().enumerate() {
        while k + 1 < tc.len() && tc[k + 1] <= tc[0] + t + 1e-9 {
            k += 1;
        }
        for j in 0..n {
            worst_goal = worst_goal.max((run.q_ref[f * n + j] - goals[k][j]).abs());
        }
    }
    assert!(worst_goal < 5e-6, "largest difference from SAGE's goals: {worst_goal} rad");
}

#[test]
fn a_calibration_file_makes_the_gripper_an_angle() {
    let Some(sage) = sage() else { return };
    let dir = common::folder();
    let file = dir.path().join("so101.json");
    std::fs::write(&file, r#"{"gripper": {"id": 6, "drive_mode": 0, "homing_offset": 0, "range_min": 2000, "range_max": 3000}}"#).unwrap();
    let options = LogOptions { calibration: Some(Calibration::read(&file).unwrap()), ..LogOptions::default() };
    let run = read_log(&with_hash(&sage.join("lerobot"), "13"), &options).unwrap();
    assert_eq!(run.joints.last().map(String::as_str), Some("gripper"));
    assert!(run.left_out.is_empty());
    // gripper_cycles: SAGE's jaw 0–1 ×100 was written; angle = (v/100 − ½)·1000 counts
    let (ts, states) = sage_rows(&sage.join("sage/gripper_cycles/state_motor.csv.gz"));
    let jaw = states[0][5];
    let expected = (jaw - 0.5) * 1000.0 * 2.0 * std::f64::consts::PI / 4095.0;
    assert!((run.q[5] - expected).abs() < 1e-5, "gripper at frame 0: {} rad, expected {expected} rad (jaw {jaw}, t0 {})", run.q[5], ts[0]);
}

#[test]
fn a_bare_folder_is_every_episode_and_a_selection_picks_some() {
    let Some(sage) = sage() else { return };
    let folder = sage.join("lerobot");
    assert_eq!(episode_indices(&folder).unwrap(), (0..38).collect::<Vec<i64>>());
    let some = read_logs(&with_hash(&folder, "5,2-3"), &LogOptions::default()).unwrap();
    let names: Vec<&str> = some.iter().map(|r| r.source.rsplit('#').next().unwrap()).collect();
    assert_eq!(names, vec!["5", "2", "3"]);
    let all = read_logs_with_warnings(&folder, &LogOptions::default()).unwrap();
    assert_eq!(all.len(), 38);
    assert_eq!(all.iter().map(|r| r.run.len()).sum::<usize>(), 185_738, "total_frames");
    assert!(all[0].warnings.iter().any(|w| w.contains("gripper")), "{:?}", all[0].warnings);
    // one run per read_log: a folder of 38 episodes is refused with a way out
    let e = read_log(&folder, &LogOptions::default()).unwrap_err().to_string();
    assert!(e.contains("38 episodes") && e.contains("read_logs"), "{e}");
}

#[test]
fn the_experiment_comes_from_the_sidecar_without_the_left_out_joint() {
    let Some(sage) = sage() else { return };
    let (_dir, ds) = copy_dataset(&sage.join("lerobot"));
    let joints = "shoulder_pan,shoulder_lift,elbow_flex,wrist_flex,wrist_roll,gripper";
    std::fs::write(
        ds.join("meta/simgap.experiment.json"),
        format!(r#"{{"controller": "servo", "joints": "{joints}", "duty_gain": "2.66,2.66,2.66,2.66,2.66,1.5", "max_duty": 0.97, "supply_voltage": 12}}"#),
    )
    .unwrap();
    let run = read_log(&with_hash(&ds, "0"), &LogOptions::default()).unwrap();
    let e = run.experiment.expect("the sidecar's experiment");
    assert_eq!(e.controller, ControllerKind::Servo);
    assert_eq!(e.joints, ARM);
    assert_eq!(e.extra["duty_gain"], "2.66,2.66,2.66,2.66,2.66");
    assert!((e.sample_period - 0.02).abs() < 1e-15, "1/fps");
    // angle_unit = rad: the same values, read as radians
    std::fs::write(ds.join("meta/simgap.experiment.json"), r#"{"controller": "replay", "joints": "", "angle_unit": "rad"}"#).unwrap();
    let deg = read_log(&with_hash(&sage.join("lerobot"), "0"), &LogOptions::default()).unwrap();
    let rad = read_log(&with_hash(&ds, "0"), &LogOptions::default()).unwrap();
    assert!((rad.q[7] - deg.q[7].to_degrees()).abs() < 1e-9);
}

#[test]
fn bad_input_is_an_error_naming_folder_file_and_episode() {
    let Some(sage) = sage() else { return };
    let folder = sage.join("lerobot");
    let name = folder.display().to_string();
    // an episode the dataset lacks, an empty selection
    let e = error_of(read_logs(&with_hash(&folder, "0,38"), &LogOptions::default()));
    assert!(e.contains(&name) && e.contains("no episode 38") && e.contains("0 to 37"), "{e}");
    let e = error_of(read_logs(&with_hash(&folder, ""), &LogOptions::default()));
    assert!(e.contains("empty episode selection"), "{e}");
    // no meta/info.json
    let (dir, ds) = copy_dataset(&folder);
    std::fs::remove_file(ds.join("meta/info.json")).unwrap();
    let e = error_of(read_logs(&ds, &LogOptions::default()));
    assert!(e.contains(&ds.display().to_string()) && e.contains("meta/info.json"), "{e}");
    drop(dir);
    // hostile info.json values
    let info = std::fs::read_to_string(folder.join("meta/info.json")).unwrap();
    for (from, to, needle) in [
        ("\"fps\": 50", "\"fps\": 0", "fps"),
        ("\"fps\": 50", "\"fps\": -50", "fps"),
        ("\"total_episodes\": 38", "\"total_episodes\": -1", "total_episodes"),
        ("\"chunks_size\": 1000", "\"chunks_size\": -5", "chunks_size"),
        (
            "\"shape\": [\n                6\n            ],\n            \"names\": [\n                \"shoulder_pan.pos\"",
            "\"shape\": [\n                99999999999\n            ],\n            \"names\": [\n                \"shoulder_pan.pos\"",
            "shape",
        ),
        ("\"dtype\": \"float32\",\n            \"shape\": [\n                6", "\"dtype\": \"int64\",\n            \"shape\": [\n                6", "dtype"),
    ] {
        let (dir, ds) = copy_dataset(&folder);
        let text = info.replacen(from, to, 1);
        assert_ne!(text, info, "{from}");
        std::fs::write(ds.join("meta/info.json"), text).unwrap();
        let e = error_of(read_logs(&with_hash(&ds, "0"), &LogOptions::default()));
        assert!(e.contains(&ds.display().to_string()) && e.contains("meta/info.json") && e.contains(needle), "{to}: {e}");
        drop(dir);
    }
    // a truncated data file: the folder, the file and the episode
    let (_dir, ds) = copy_dataset(&folder);
    let data = ds.join("data/chunk-000/file-000.parquet");
    let bytes = std::fs::read(&data).unwrap();
    std::fs::write(&data, &bytes[..bytes.len() / 2]).unwrap();
    let e = error_of(read_logs(&with_hash(&ds, "3"), &LogOptions::default()));
    assert!(e.contains(&ds.display().to_string()) && e.contains("data/chunk-000/file-000.parquet") && e.contains("episode 3"), "{e}");
    // a data file that is not there
    std::fs::remove_file(&data).unwrap();
    let e = error_of(read_logs(&with_hash(&ds, "3"), &LogOptions::default()));
    assert!(e.contains("data/chunk-000/file-000.parquet") && e.contains("missing") && e.contains("episode 3"), "{e}");
}

#[test]
fn range_normalised_joints_must_be_joints_of_the_dataset() {
    let Some(sage) = sage() else { return };
    let (_dir, ds) = copy_dataset(&sage.join("lerobot"));
    std::fs::write(ds.join("meta/simgap.experiment.json"), r#"{"controller": "replay", "joints": "", "range_normalised": "jaw"}"#).unwrap();
    let e = error_of(read_logs(&with_hash(&ds, "0"), &LogOptions::default()));
    assert!(e.contains("'jaw'") && e.contains("range_normalised"), "{e}");
    // an empty list: no joint is range-normalised, the gripper's 0–100 read as degrees
    std::fs::write(ds.join("meta/simgap.experiment.json"), r#"{"controller": "replay", "joints": "", "range_normalised": ""}"#).unwrap();
    let run = read_log(&with_hash(&ds, "0"), &LogOptions::default()).unwrap();
    assert_eq!(run.dof(), 6);
}
