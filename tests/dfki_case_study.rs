//! The DFKI case study (docs/results/case-study-dfki.md) on real hardware data: `simgap diagnose` on the
//! DFKI double pendulum, design C.0, open-loop sys-id runs (`controller = replay`).
//!
//! Needs the data in `../shared/data/dfki-double-pendulum` (next to the repository); without it
//! the test prints why and passes. To keep it under a minute with a release binary, it fits on
//! the first 4 s of `trajectory_00` and `trajectory_03` and holds out the first 4 s of
//! `trajectory_04` (the case study itself uses the whole files, 00–03 against 04).
//!
//! The URDF is the published `design_C.0/model_3.1/acrobot.urdf`, used as it is: its `base_weld`
//! joint welds the root to the undefined link `world`, which simgap takes as the world frame (with
//! a warning on stderr).
//!
//! The binary is `$SIMGAP_BIN` when set; else `target/release/simgap` when it is newer than
//! every source file; else the debug binary cargo built for this test (as in `cli_diagnose.rs`).

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;
use simgap::log::csv::{read_csv_auto, write_csv};

mod common;
use common::bin;

fn data_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data/dfki-double-pendulum")
}

/// The first `seconds` of a DFKI record, written in the generic CSV convention.
fn head(src: &Path, seconds: f64, dst: &Path) {
    let mut run = read_csv_auto(src).unwrap_or_else(|e| panic!("{}: {e}", src.display()));
    let dof = run.dof();
    let t0 = run.t[0];
    let n = run.t.iter().take_while(|&&t| t - t0 <= seconds).count();
    run.t.truncate(n);
    for m in [&mut run.q, &mut run.qd, &mut run.tau, &mut run.q_ref, &mut run.qd_ref] {
        if !m.is_empty() {
            m.truncate(n * dof);
        }
    }
    write_csv(&run, dst).unwrap();
}

#[test]
fn dfki_c0_open_loop_diagnosis() {
    let data = data_dir();
    if !data.is_dir() {
        assert!(std::env::var_os("CI").is_none(), "dfki_c0_open_loop_diagnosis: the DFKI data is not at {} (CI is set: a test without its data fails)", data.display());
        println!("SKIPPED dfki_c0_open_loop_diagnosis: the DFKI data is not at {} (see docs/results/case-study-dfki.md)", data.display());
        return;
    }
    let dir = std::env::temp_dir().join(format!("simgap-dfki-case-study-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();

    // the published URDF as it is (its root is welded to the undefined link 'world')
    let urdf = data.join("system_identification/identified_parameters/design_C.0/model_3.1/acrobot.urdf");

    let records = data.join("experiment_records/design_C.0/20220914/sys_id");
    let mut logs = Vec::new();
    for i in ["00", "03", "04"] {
        let p = dir.join(format!("trajectory_{i}.csv"));
        head(&records.join(format!("trajectory_{i}.csv.gz")), 4.0, &p);
        logs.push(p);
    }
    let experiment = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/case-study-dfki/dfki-c0.experiment.json");
    let json = dir.join("report.json");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let started = std::time::Instant::now();
    let out = Command::new(bin())
        .args(["diagnose", "--urdf", &s(&urdf), "--log", &s(&logs[0]), "--log", &s(&logs[1]), "--holdout", &s(&logs[2])])
        .args(["--experiment", &s(&experiment), "--json", &s(&json)])
        .output()
        .expect("simgap runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    println!("{stdout}{}\n(diagnosis took {:.1} s with {})", String::from_utf8_lossy(&out.stderr), started.elapsed().as_secs_f64(), bin().display());
    assert!(out.status.success(), "simgap diagnose failed");

    let r: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).expect("the report is JSON");
    // every key of the report's JSON contract
    assert!(r["selected_effects"].is_array(), "selected_effects");
    let candidates = r["candidates"].as_array().expect("candidates");
    assert!(candidates.len() >= 10, "every effect tried: {}", candidates.len());
    for c in candidates {
        assert!(c["effect"].is_string() && c["parameters"].is_object() && c.get("holdout_l2_after").is_some(), "{c}");
    }
    for k in ["per_joint", "worst_segments", "correlations"] {
        assert!(!r["where"][k].is_null(), "where.{k}");
    }
    for j in ["Joint1", "Joint2"] {
        for k in ["q", "qd", "sign_qd", "qdd", "tau"] {
            assert!(r["where"]["correlations"][j][k].is_number(), "where.correlations.{j}.{k}");
        }
    }
    let before = r["gap"]["holdout_l2_before"].as_f64().expect("gap.holdout_l2_before is a number");
    let after = r["gap"]["holdout_l2_after"].as_f64().expect("gap.holdout_l2_after is a number");
    assert!(before.is_finite() && before > 0.0, "held-out L2 before {before}");
    assert!(after.is_finite() && after > 0.0, "held-out L2 after {after}");

    // selected effects: well formed, finite, aligned with their joints
    let selected = r["selected_effects"].as_array().unwrap();
    for e in selected {
        let joints = e["joints"].as_array().expect("joints");
        // per-joint parameters are lists aligned with the joints; whole-robot effects (no joints)
        // have numbers, or vectors such as a payload's centre of mass
        for (name, v) in e["parameters"].as_object().unwrap() {
            if let (Some(list), false) = (v.as_array(), joints.is_empty()) {
                assert_eq!(list.len(), joints.len(), "{name} aligned with joints: {e}");
            }
        }
    }
    // friction, where selected, is dissipative on the joints it names
    let friction: Vec<&Value> = selected.iter().filter(|e| matches!(e["effect"].as_str(), Some("viscous_friction" | "coulomb_friction" | "stribeck_friction"))).collect();
    // open-loop replays: "how far" is the k-step prediction, pooled per horizon
    assert_eq!(r["gap"]["headline"], "k_step", "{}", r["gap"]["headline_reason"]);
    let k = &r["gap"]["kstep"];
    let n = k["horizons_s"].as_array().expect("gap.kstep.horizons_s").len();
    for key in ["before", "after", "floor"] {
        let v = k[key].as_array().unwrap_or_else(|| panic!("gap.kstep.{key}"));
        assert_eq!(v.len(), n, "gap.kstep.{key} aligned with the horizons");
        assert!(v.iter().all(|x| x.as_f64().is_some_and(|x| x.is_finite() && x > 0.0)), "gap.kstep.{key}: {v:?}");
    }
    for e in friction {
        assert!(!e["joints"].as_array().unwrap().is_empty(), "friction on no joint: {e}");
        for (name, v) in e["parameters"].as_object().unwrap() {
            for x in v.as_array().unwrap() {
                let x = x.as_f64().unwrap_or(f64::NAN);
                assert!(x.is_finite() && x > 0.0, "{name} = {x}: {e}");
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
