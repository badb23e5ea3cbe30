//! `simgap predict` and `simgap diagnose` on a LeRobot dataset (`FOLDER#SEL`): the SAGE SO-101
//! dataset against the published SO-101 URDF, whose gripper the dataset gives as 0–100 (locked
//! without a calibration file), and bad input named with the folder and the episode.
//!
//! Needs `../shared/data/sage-so101`: without it each test skips with a message, and fails when
//! `CI` is set.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod common;
use common::{bin, Scratch};

fn simgap(args: &[&str]) -> Output {
    Command::new(bin()).args(args).output().expect("simgap runs")
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

fn sage() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/sage-so101");
    if dir.join("lerobot/meta/info.json").is_file() {
        Some(dir)
    } else {
        assert!(std::env::var_os("CI").is_none(), "the SAGE SO-101 data is not at {} (CI is set: a test without its data fails)", dir.display());
        eprintln!("SKIP: the SAGE SO-101 data is not at {}", dir.display());
        None
    }
}

/// The SO-101's servo experiment (Rhoban BAM's STS3215 law at firmware P 16: 16 · 0.166 duty per
/// radian), all six joints: the reader drops the gripper it leaves out.
const EXPERIMENT: &str = r#"{"controller": "servo", "joints": "shoulder_pan,shoulder_lift,elbow_flex,wrist_flex,wrist_roll,gripper",
  "duty_gain": 2.656, "max_duty": 0.97, "supply_voltage": 12, "goal_rate_limit": 5.2, "kt": 1.2116, "R": 2.676}"#;

#[test]
fn predict_reads_episodes_and_locks_the_gripper_the_dataset_leaves_out() {
    let Some(sage) = sage() else { return };
    let dir = Scratch::new("lerobot", "predict");
    let exp = dir.join("so101.experiment.json");
    std::fs::write(&exp, EXPERIMENT).unwrap();
    let urdf = sage.join("so101_new_calib.urdf");
    let log = format!("{}#29,36", sage.join("lerobot").display());
    let out = simgap(&["predict", "--urdf", urdf.to_str().unwrap(), "--log", &log, "--experiment", exp.to_str().unwrap()]);
    let t = text(&out);
    assert!(out.status.success(), "{t}");
    assert!(t.contains("k-step prediction of 2 log(s)"), "{t}");
    assert!(t.contains("[\"gripper\"] are locked at their zero position"), "{t}");
    assert_eq!(t.matches("is range-normalised 0–100").count(), 1, "the dataset's warning once: {t}");
    // an effect is given per joint simulated: a neutral one predicts as the model does, and one
    // value per URDF joint (the locked gripper's too) is refused naming the joints simulated
    let neutral = simgap(&["predict", "--urdf", urdf.to_str().unwrap(), "--log", &log, "--experiment", exp.to_str().unwrap(), "--effect", "viscous_friction:b=0,0,0,0,0"]);
    let n = text(&neutral);
    assert!(neutral.status.success(), "{n}");
    let row = n.lines().find(|l| l.trim_start().starts_with("0.500s")).expect("a 0.5 s row");
    let cols: Vec<&str> = row.split_whitespace().collect();
    assert_eq!(cols[1], cols[2], "a neutral effect predicts as the model: {row}");
    let six = simgap(&["predict", "--urdf", urdf.to_str().unwrap(), "--log", &log, "--experiment", exp.to_str().unwrap(), "--effect", "viscous_friction:b=0,0,0,0,0,0"]);
    let s6 = text(&six);
    assert!(!six.status.success() && s6.contains("wrist_roll; locked joints take none") && s6.contains("expected 5"), "{s6}");
}

#[test]
fn bad_episodes_and_files_are_named() {
    let Some(sage) = sage() else { return };
    let urdf = sage.join("so101_new_calib.urdf");
    let folder = sage.join("lerobot");
    let dir = Scratch::new("lerobot", "bad");
    let exp = dir.join("so101.experiment.json");
    std::fs::write(&exp, EXPERIMENT).unwrap();
    // an episode the dataset lacks
    let log = format!("{}#0", folder.display());
    let hold = format!("{}#99", folder.display());
    let out = simgap(&["diagnose", "--urdf", urdf.to_str().unwrap(), "--log", &log, "--holdout", &hold, "--experiment", exp.to_str().unwrap()]);
    let t = text(&out);
    assert!(!out.status.success());
    assert!(t.contains(&folder.display().to_string()) && t.contains("no episode 99") && t.contains("0 to 37"), "{t}");
    // no experiment: the sidecar inside the dataset is named
    let out = simgap(&["diagnose", "--urdf", urdf.to_str().unwrap(), "--log", &log]);
    let t = text(&out);
    assert!(!out.status.success() && t.contains("meta/simgap.experiment.json") && t.contains("lerobot#0"), "{t}");
    // a calibration file that is not there
    let out = simgap(&["predict", "--urdf", urdf.to_str().unwrap(), "--log", &log, "--calibration", "/nonexistent/so101.json"]);
    let t = text(&out);
    assert!(!out.status.success() && t.contains("/nonexistent/so101.json") && t.contains("calibration"), "{t}");
}
