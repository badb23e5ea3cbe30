//! `simgap demo` and `simgap diagnose` as a user runs them: the JSON contract, the
//! blind recovery of the demo's hidden effects, and clear errors on bad input.
//!
//! The binary is `$SIMGAP_BIN` when set; else `target/release/simgap` when it is newer than
//! every source file (as after `make test`'s release build: the demo takes ~3 s there against
//! ~1 min in a debug build); else the debug binary cargo built for this test.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

use serde_json::Value;

mod common;
use common::{bin, Scratch};

fn simgap(args: &[&str]) -> Output {
    Command::new(bin()).args(args).output().expect("simgap runs")
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

fn scratch(name: &str) -> Scratch {
    Scratch::new("cli", name)
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

const PENDULUM: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/crates/simgap-core/models/pendulum.urdf");

/// Runs `simgap demo` once for every test that needs it.
fn demo() -> &'static (PathBuf, String, Value) {
    static DEMO: OnceLock<(PathBuf, String, Value)> = OnceLock::new();
    DEMO.get_or_init(|| {
        let dir = scratch("demo").keep();
        let o = simgap(&["demo", "--out-dir", s(&dir)]);
        assert!(o.status.success(), "simgap demo failed:\n{}", text(&o));
        let report: Value = serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap();
        (dir, text(&o), report)
    })
}

fn selected<'a>(report: &'a Value, effect: &str) -> &'a Value {
    report["selected_effects"].as_array().unwrap().iter().find(|e| e["effect"] == effect).unwrap_or_else(|| panic!("{effect} not selected: {}", report["selected_effects"]))
}

fn param(report: &Value, effect: &str, name: &str, joint: &str) -> f64 {
    let e = selected(report, effect);
    let j = e["joints"].as_array().unwrap().iter().position(|x| x == joint).unwrap_or_else(|| panic!("{effect} not on {joint}: {e}"));
    e["parameters"][name][j].as_f64().unwrap()
}

#[test]
fn demo_report_has_every_contract_key() {
    let (dir, _, r) = demo();
    for f in ["paper_arm.urdf", "fit-step.mcap", "holdout-excitation.mcap", "report.json", "report.html", "corrected.mcap"] {
        assert!(dir.join(f).is_file(), "{f} missing");
    }
    for e in r["selected_effects"].as_array().unwrap() {
        assert!(e["effect"].is_string() && e["joints"].is_array() && e["parameters"].is_object(), "{e}");
        for (_, v) in e["parameters"].as_object().unwrap() {
            if let Some(list) = v.as_array() {
                assert_eq!(list.len(), e["joints"].as_array().unwrap().len(), "per-joint parameters align with joints: {e}");
            }
        }
    }
    let candidates = r["candidates"].as_array().unwrap();
    assert!(candidates.len() >= 10);
    for (i, c) in candidates.iter().enumerate() {
        assert_eq!(c["rank"].as_u64(), Some(i as u64 + 1));
        assert!(c["effect"].is_string() && c["parameters"].is_object(), "{c}");
        // a held-out L² for every simulated candidate; null only with the reason it was not
        let simulated = c["holdout_l2_after"].is_number();
        assert!(simulated || c["reason"].as_str().is_some_and(|r| r.contains("not physical")), "{c}");
    }
    assert!(r["gap"]["holdout_l2_before"].as_f64().unwrap() > 0.0);
    assert!(r["gap"]["holdout_l2_after"].as_f64().unwrap() < 0.2 * r["gap"]["holdout_l2_before"].as_f64().unwrap());
    for k in ["per_joint", "worst_segments", "correlations"] {
        assert!(!r["where"][k].is_null(), "where.{k}");
    }
    let html = std::fs::read_to_string(dir.join("report.html")).unwrap();
    assert!(html.contains("<svg") && html.contains("viscous_friction") && !html.contains("<script"));
}

#[test]
fn demo_recovers_the_hidden_effects_within_15_percent() {
    let (_, out, r) = demo();
    for (effect, p, joint, truth) in [
        ("viscous_friction", "b", "shoulder", 2.288),
        ("viscous_friction", "b", "elbow", 0.175),
        ("coulomb_friction", "fc", "shoulder", 7.17),
        ("coulomb_friction", "fc", "elbow", 1.734),
        ("torque_saturation", "limit", "elbow", 15.0),
    ] {
        let v = param(r, effect, p, joint);
        assert!((v - truth).abs() <= 0.15 * truth, "{effect}.{p} on {joint}: found {v}, truth {truth}");
    }
    assert!(out.contains("HIDDEN TRUTH vs FOUND") && out.contains("simgap diagnose --urdf"), "{out}");
}

#[test]
fn diagnose_on_the_demo_files_reproduces_the_demo() {
    let (dir, _, r) = demo();
    let out = scratch("reproduce");
    let json = out.join("again.json");
    let mcap = out.join("again.mcap");
    let o = simgap(&[
        "diagnose",
        "--urdf",
        s(&dir.join("paper_arm.urdf")),
        "--log",
        s(&dir.join("fit-step.mcap")),
        "--log",
        s(&dir.join("fit-excitation.mcap")),
        "--log",
        s(&dir.join("fit-setpoints.mcap")),
        "--holdout",
        s(&dir.join("holdout-excitation.mcap")),
        "--json",
        s(&json),
        "--mcap",
        s(&mcap),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let again: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(again["selected_effects"], r["selected_effects"]);
    assert_eq!(again["gap"], r["gap"]);
    assert_eq!(again["verdict"], r["verdict"]);
    assert!(mcap.is_file());
    // no temporary file left behind
    let left: Vec<_> = std::fs::read_dir(&out).unwrap().filter_map(|e| e.ok()).filter(|e| e.file_name().to_string_lossy().ends_with(".tmp")).collect();
    assert!(left.is_empty(), "{left:?}");
}

#[test]
fn link_side_torque_tries_no_rotor_inertia_and_says_so() {
    // the demo's logs, told that their effort was measured on the link side of the gearbox
    let (dir, _, _) = demo();
    let out = scratch("link-side");
    let json = out.join("r.json");
    #[rustfmt::skip]
    let o = simgap(&[
        "diagnose", "--urdf", s(&dir.join("paper_arm.urdf")), "--log", s(&dir.join("fit-step.mcap")),
        "--log", s(&dir.join("fit-excitation.mcap")), "--holdout", s(&dir.join("holdout-excitation.mcap")),
        "--json", s(&json), "--link-side-torque",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let r: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    for key in ["selected_effects", "candidates"] {
        let effects: Vec<&str> = r[key].as_array().unwrap().iter().map(|e| e["effect"].as_str().unwrap()).collect();
        assert!(!effects.contains(&"armature") && !effects.contains(&"back_emf"), "{key}: {effects:?}");
    }
    let notes: Vec<&str> = r["notes"].as_array().unwrap().iter().filter_map(|n| n.as_str()).collect();
    assert!(notes.iter().any(|n| n.contains("link side of the gearbox")), "{notes:?}");
}

fn simulate_pendulum(path: &Path, target: &str, duration: &str) {
    let o = simgap(&["simulate", "--urdf", PENDULUM, "--kp", "20", "--kv", "2", "--target", target, "--duration", duration, "--out", s(path)]);
    assert!(o.status.success(), "{}", text(&o));
}

#[test]
fn held_out_log_of_another_robot_fails_naming_the_file_and_the_joint() {
    let d = scratch("other-robot");
    let (fit, other) = (d.join("fit.mcap"), d.join("pendulum.mcap"));
    let o = simgap(&["simulate", "--duration", "1", "--out", s(&fit)]);
    assert!(o.status.success(), "{}", text(&o));
    simulate_pendulum(&other, "0.5", "1");
    let o = simgap(&["diagnose", "--urdf", concat!(env!("CARGO_MANIFEST_DIR"), "/crates/simgap-core/models/paper_arm.urdf"), "--log", s(&fit), "--holdout", s(&other)]);
    let msg = text(&o);
    assert_eq!(o.status.code(), Some(1), "{msg}");
    assert!(msg.contains("pendulum.mcap") && msg.contains("shoulder"), "{msg}");
    assert!(!msg.contains("panicked"), "{msg}");
}

#[test]
fn too_short_log_fails_naming_the_file() {
    let d = scratch("short");
    let (short, hold) = (d.join("short.mcap"), d.join("hold.mcap"));
    simulate_pendulum(&short, "0.5", "0.05");
    simulate_pendulum(&hold, "0.5", "1");
    let o = simgap(&["diagnose", "--urdf", PENDULUM, "--log", s(&short), "--holdout", s(&hold)]);
    let msg = text(&o);
    assert_eq!(o.status.code(), Some(1), "{msg}");
    assert!(msg.contains("short.mcap") && msg.contains("too short"), "{msg}");
}

#[test]
fn missing_file_fails_naming_it() {
    let d = scratch("missing");
    let hold = d.join("hold.mcap");
    simulate_pendulum(&hold, "0.5", "1");
    let o = simgap(&["diagnose", "--urdf", PENDULUM, "--log", s(&d.join("nowhere.mcap")), "--holdout", s(&hold)]);
    let msg = text(&o);
    assert_eq!(o.status.code(), Some(1), "{msg}");
    assert!(msg.contains("nowhere.mcap"), "{msg}");
    let o = simgap(&["diagnose", "--urdf", s(&d.join("nowhere.urdf")), "--log", s(&hold), "--holdout", s(&hold)]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("nowhere.urdf"), "{}", text(&o));
}

#[test]
fn no_motion_says_cannot_tell() {
    // the pendulum hanging at rest, PD to the rest position: no gravity torque, no motion
    let d = scratch("rest");
    let (fit, hold, json, html) = (d.join("rest1.mcap"), d.join("rest2.mcap"), d.join("report.json"), d.join("report.html"));
    simulate_pendulum(&fit, "0", "1");
    simulate_pendulum(&hold, "0", "1");
    let o = simgap(&["diagnose", "--urdf", PENDULUM, "--log", s(&fit), "--holdout", s(&hold), "--json", s(&json), "--html", s(&html)]);
    assert!(o.status.success(), "{}", text(&o));
    let r: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!(r["verdict"].as_str().unwrap().contains("cannot tell"), "{}", r["verdict"]);
    assert_eq!(r["selected_effects"].as_array().unwrap().len(), 0);
    assert!(std::fs::read_to_string(&html).unwrap().contains("cannot tell"));
}

/// One recording is the common case: without `--holdout` each fit log is split in time (its
/// first 60 % fits, the rest is held out), the report says so, and the held-out part is judged.
#[test]
fn a_recording_without_holdout_is_split_in_time_and_says_so() {
    let (dir, _, _) = demo();
    let out = scratch("no-holdout");
    let json = out.join("one.json");
    let o = simgap(&["diagnose", "--urdf", s(&dir.join("paper_arm.urdf")), "--log", s(&dir.join("fit-excitation.mcap")), "--json", s(&json)]);
    assert!(o.status.success(), "{}", text(&o));
    let r: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let holdout = r["holdout_logs"].as_array().unwrap();
    assert_eq!(holdout.len(), 1);
    assert!(holdout[0].as_str().unwrap().contains("fit-excitation.mcap (from "), "{holdout:?}");
    assert!(r["fit_logs"][0].as_str().unwrap().contains("(first 60 %)"));
    assert!(r["notes"].as_array().unwrap().iter().any(|n| n.as_str().unwrap().contains("split in time")), "{}", r["notes"]);
    // the demo's dominant effect is found on the first 60 % alone
    assert!(r["selected_effects"].as_array().unwrap().iter().any(|e| e["effect"] == "coulomb_friction"), "{}", r["selected_effects"]);
}

/// A linear axis: one prismatic joint along x, a 5 kg carriage (the self-check's).
use simgap::diag::drives::SLIDER_URDF as SLIDER;

#[test]
fn a_prismatic_axis_is_diagnosed_and_reported_in_newtons_and_metres() {
    let dir = scratch("prismatic");
    let urdf = dir.join("slider.urdf");
    std::fs::write(&urdf, SLIDER).unwrap();
    // a ball-screw-like axis with viscous and dry friction (its sign smoothed over 2 mm/s),
    // tracked by a PD loop at 1 kHz
    let runs = [("fit1", "amplitude=0.1;frequency=0.7", "0"), ("fit2", "amplitude=0.15;frequency=0.3", "0.05"), ("hold", "amplitude=0.12;frequency=1.1", "0")];
    for (name, fourier, target) in runs {
        let out = dir.join(format!("{name}.mcap"));
        let o = simgap(&[
            "simulate",
            "--urdf",
            s(&urdf),
            "--kp",
            "2000",
            "--kv",
            "100",
            "--fourier",
            fourier,
            "--target",
            target,
            "--duration",
            "6",
            "--sample-period",
            "0.001",
            "--effect",
            "viscous_friction:b=30",
            "--effect",
            "coulomb_friction:fc=8;w=0.002",
            "--out",
            s(&out),
        ]);
        assert!(o.status.success(), "{}", text(&o));
        assert!(text(&o).contains("L2 tracking error [m]"), "{}", text(&o));
    }
    let json = dir.join("r.json");
    let html = dir.join("r.html");
    let o = simgap(&[
        "diagnose",
        "--urdf",
        s(&urdf),
        "--log",
        s(&dir.join("fit1.mcap")),
        "--log",
        s(&dir.join("fit2.mcap")),
        "--holdout",
        s(&dir.join("hold.mcap")),
        "--json",
        s(&json),
        "--html",
        s(&html),
    ]);
    let out = text(&o);
    assert!(o.status.success(), "{out}");
    let report: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(report["joint_types"], serde_json::json!(["prismatic"]));
    // the hidden effects found, in the axis's units
    let b = param(&report, "viscous_friction", "b", "axis");
    let fc = param(&report, "coulomb_friction", "fc", "axis");
    assert!((b - 30.0).abs() < 3.0 && (fc - 8.0).abs() < 0.8, "b = {b} N·s/m, fc = {fc} N");
    assert_eq!(selected(&report, "viscous_friction")["units"]["b"], "N·s/m");
    assert_eq!(selected(&report, "coulomb_friction")["units"]["fc"], "N");
    // the width of its smoothed sign stated in m/s (a linear axis's typical 2 mm/s here)
    assert_eq!(selected(&report, "coulomb_friction")["units"]["w"], "m/s");
    let w = param(&report, "coulomb_friction", "w", "axis");
    assert!((w - 0.002).abs() < 1e-9, "w = {w} m/s");
    // no rotational unit anywhere a user reads: terminal, verdict, notes, HTML
    let page = std::fs::read_to_string(&html).unwrap();
    for (what, text) in [("terminal", out.as_str()), ("HTML", page.as_str()), ("verdict", report["verdict"].as_str().unwrap())] {
        for unit in ["N·m", " rad", "rad/s", "[rad]", "kg·m²"] {
            assert!(!text.contains(unit), "the {what} of a linear axis says {unit:?}");
        }
    }
    for note in report["notes"].as_array().unwrap() {
        assert!(!note.as_str().unwrap().contains("N·m"), "note of a linear axis in N·m: {note}");
    }
    // asked to try friction that differs by direction, symmetric friction stays the simpler pair
    let o = simgap(&[
        "diagnose",
        "--urdf",
        s(&urdf),
        "--log",
        s(&dir.join("fit1.mcap")),
        "--log",
        s(&dir.join("fit2.mcap")),
        "--holdout",
        s(&dir.join("hold.mcap")),
        "--directional-friction",
    ]);
    assert!(o.status.success() && !text(&o).contains("directional_friction   "), "{}", text(&o));
    assert!(text(&o).contains("coulomb_friction     joints") && text(&o).contains("viscous_friction     joints"), "{}", text(&o));
}

#[test]
fn the_demo_page_links_the_exported_model_beside_it() {
    let (dir, _, _) = demo();
    let page = std::fs::read_to_string(dir.join("report.html")).unwrap();
    for file in ["corrected.urdf", "corrected.urdf.effects.json", "corrected.xml", "corrected.xml.effects.json"] {
        assert!(page.contains(&format!("<a href=\"{file}\">")), "the page does not link {file}");
        assert!(dir.join(file).is_file(), "{file} linked but not written");
    }
}

#[test]
fn friction_that_differs_with_the_direction_of_motion_is_found_in_place_of_the_symmetric_pair_when_asked_for() {
    let dir = scratch("directional");
    let urdf = dir.join("slider.urdf");
    std::fs::write(&urdf, SLIDER).unwrap();
    // a worn ball screw: viscous 30 N·s/m and dry 8 N moving forward, 45 N·s/m and 5 N moving
    // back (a published drive identification's kind of asymmetry), tracked by a PD loop at 1 kHz
    let runs = [("fit1", "amplitude=0.1;frequency=0.7", "0"), ("fit2", "amplitude=0.15;frequency=0.3", "0.05"), ("hold", "amplitude=0.12;frequency=1.1", "0")];
    for (name, fourier, target) in runs {
        let out = dir.join(format!("{name}.mcap"));
        #[rustfmt::skip]
        let o = simgap(&[
            "simulate", "--urdf", s(&urdf), "--kp", "2000", "--kv", "100", "--fourier", fourier, "--target", target,
            "--duration", "6", "--sample-period", "0.001",
            "--effect", "directional_friction:fc_pos=8;fc_neg=5;b_pos=30;b_neg=45;w=0.002", "--out", s(&out),
        ]);
        assert!(o.status.success(), "{}", text(&o));
    }
    let json = dir.join("r.json");
    #[rustfmt::skip]
    let o = simgap(&[
        "diagnose", "--urdf", s(&urdf), "--log", s(&dir.join("fit1.mcap")), "--log", s(&dir.join("fit2.mcap")),
        "--holdout", s(&dir.join("hold.mcap")), "--json", s(&json), "--directional-friction",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let r: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let names: Vec<&str> = r["selected_effects"].as_array().unwrap().iter().map(|e| e["effect"].as_str().unwrap()).collect();
    assert_eq!(names, ["directional_friction"], "{}", text(&o));
    for (key, truth) in [("fc_pos", 8.0), ("fc_neg", 5.0), ("b_pos", 30.0), ("b_neg", 45.0)] {
        let v = param(&r, "directional_friction", key, "axis");
        assert!((v - truth).abs() < 0.1 * truth, "{key} = {v}, truth {truth}\n{}", text(&o));
    }
    assert_eq!(selected(&r, "directional_friction")["units"]["b_neg"], "N·s/m");
}
