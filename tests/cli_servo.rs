//! `simgap diagnose` on position-controlled servo logs (CSV with the servo columns and a
//! `servo` sidecar): bad input gets a clear error naming the file and what was expected, and
//! simulated servo logs are diagnosed. (The real Rhoban BAM XL330 logs are diagnosed end to end
//! by the servo case study's fold in `tests/python/test_bam_servo_data.py`, which checks the
//! report against BAM's published models and what the diagnosis must say.)

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod common;
use common::{bin, Scratch};

const PENDULUM: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/crates/simgap-core/models/pendulum.urdf");

fn simgap(args: &[&str]) -> Output {
    Command::new(bin()).args(args).output().expect("simgap runs")
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

fn scratch(name: &str) -> Scratch {
    Scratch::new("servo", name)
}

const SIDECAR: &str = r#"{"controller": "servo", "joints": "hinge", "duty_gain": "2", "supply_voltage": "12"}"#;

/// A servo log of the pendulum: 4 s at 200 Hz, the goal a slow sine, the measured position
/// lagging it; `columns` picks the optional columns, `row` may change a sample.
fn write_log(dir: &Path, name: &str, sidecar: &str, goal: bool, duty: impl Fn(usize, f64) -> f64, enable: impl Fn(usize) -> u8, moving: bool) -> PathBuf {
    let csv = dir.join(format!("{name}.csv"));
    let mut text = String::from("time,q_hinge,qd_hinge");
    if goal {
        text.push_str(",q_ref_hinge");
    }
    text.push_str(",duty_hinge,torque_enable_hinge\n");
    for k in 0..800 {
        let t = k as f64 * 0.005;
        let (q, qd) = if moving { (0.3 * (t - 0.1).sin(), 0.3 * (t - 0.1).cos()) } else { (0.1, 0.0) };
        let q_ref = 0.3 * t.sin();
        text.push_str(&format!("{t},{q},{qd}"));
        if goal {
            text.push_str(&format!(",{q_ref}"));
        }
        text.push_str(&format!(",{},{}\n", duty(k, 2.0 * (q_ref - q)), enable(k)));
    }
    std::fs::write(&csv, text).unwrap();
    std::fs::write(dir.join(format!("{name}.experiment.json")), sidecar).unwrap();
    csv
}

fn refused(fit: &Path, hold: &Path) -> String {
    let o = simgap(&["diagnose", "--urdf", PENDULUM, "--log", fit.to_str().unwrap(), "--holdout", hold.to_str().unwrap()]);
    assert!(!o.status.success(), "accepted:\n{}", text(&o));
    text(&o)
}

#[test]
fn a_servo_log_without_goal_positions_is_refused_naming_it() {
    let d = scratch("no-goal");
    let good = write_log(&d, "good", SIDECAR, true, |_, x| x.clamp(-1.0, 1.0), |_| 1, true);
    // neither a goal nor a duty: nothing says what the servo drove
    let csv = d.join("no-goal.csv");
    let text_in: String = std::fs::read_to_string(&good).unwrap().lines().map(|l| l.split(',').take(3).collect::<Vec<_>>().join(",") + "\n").collect();
    std::fs::write(&csv, text_in).unwrap();
    std::fs::write(d.join("no-goal.experiment.json"), SIDECAR).unwrap();
    let e = refused(&csv, &good);
    assert!(e.contains("no-goal.csv") && e.contains("without goal positions"), "{e}");
}

#[test]
fn a_duty_outside_the_unit_interval_is_refused_naming_the_sample() {
    let d = scratch("duty");
    let good = write_log(&d, "good", SIDECAR, true, |_, x| x.clamp(-1.0, 1.0), |_| 1, true);
    let bad = write_log(&d, "bad-duty", SIDECAR, true, |k, x| if k == 123 { 1.5 } else { x.clamp(-1.0, 1.0) }, |_| 1, true);
    let e = refused(&bad, &good);
    assert!(e.contains("bad-duty.csv") && e.contains("duty of joint 'hinge' is 1.5") && e.contains("sample 123") && e.contains("[-1, 1]"), "{e}");
}

#[test]
fn a_torque_off_log_without_motion_is_refused_as_telling_nothing() {
    let d = scratch("off");
    let good = write_log(&d, "good", SIDECAR, true, |_, x| x.clamp(-1.0, 1.0), |_| 1, true);
    let still = write_log(&d, "still", SIDECAR, true, |_, _| 0.0, |_| 0, false);
    let e = refused(&still, &good);
    assert!(e.contains("still.csv") && e.contains("torque is off throughout") && e.contains("never moves"), "{e}");
}

#[test]
fn a_servo_sidecar_without_its_duty_gain_is_refused_naming_the_key() {
    let d = scratch("gain");
    let good = write_log(&d, "good", SIDECAR, true, |_, x| x.clamp(-1.0, 1.0), |_| 1, true);
    let bad = write_log(&d, "no-gain", r#"{"controller": "servo", "joints": "hinge", "supply_voltage": "12"}"#, true, |_, x| x.clamp(-1.0, 1.0), |_| 1, true);
    let e = refused(&bad, &good);
    assert!(e.contains("no-gain.experiment.json") && e.contains("duty_gain"), "{e}");
}

#[test]
fn servo_logs_whose_motor_constants_disagree_are_refused_naming_both() {
    let d = scratch("priors");
    let with = |kt: &str| format!(r#"{{"controller": "servo", "joints": "hinge", "duty_gain": "2", "supply_voltage": "12", "kt": "{kt}", "R": "2"}}"#);
    let fit = write_log(&d, "fit", &with("1"), true, |_, x| x.clamp(-1.0, 1.0), |_| 1, true);
    let hold = write_log(&d, "hold", &with("1.2"), true, |_, x| x.clamp(-1.0, 1.0), |_| 1, true);
    let e = refused(&fit, &hold);
    assert!(e.contains("hold.csv") && e.contains("fit.csv") && e.contains("kt = 1.2") && e.contains("same priors"), "{e}");
}

/// The shared BAM data folder beside the repository.
/// `simgap simulate --controller servo` with the servo constants of these tests; `extra`
/// appended.
fn simulate_servo(out: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["simulate", "--urdf", PENDULUM, "--controller", "servo", "--duty-gain", "2", "--supply-voltage", "12", "--kt", "1.5", "--resistance", "1.5"];
    args.extend(extra);
    args.extend(["--out", out.to_str().unwrap()]);
    simgap(&args)
}

#[test]
fn a_simulated_servo_logs_what_a_servo_logs_and_its_friction_is_diagnosed_from_it() {
    let d = scratch("simulated");
    // three runs of the servo with viscous friction b = 0.5 N·m·s/rad, one of them in MCAP
    let runs = [("a.csv", "0.6", "0.5"), ("b.mcap", "0.8", "0.3"), ("held.csv", "0.7", "0.4")];
    for (name, amplitude, hz) in runs {
        let fourier = format!("amplitude={amplitude};frequency={hz}");
        let o = simulate_servo(
            &d.join(name),
            &["--fourier", &fourier, "--target", "0.6", "--duration", "6", "--sample-period", "0.005", "--counts-per-rev", "4096", "--effect", "viscous_friction:b=0.5"],
        );
        assert!(o.status.success(), "{name}: {}", text(&o));
    }
    // the CSV log holds the goal, the duty, the torque enable and the voltage, and no torque
    let csv = std::fs::read_to_string(d.join("a.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(header, ["time", "q_hinge", "qd_hinge", "q_ref_hinge", "qd_ref_hinge", "duty_hinge", "torque_enable_hinge", "voltage"]);
    // every duty is the firmware's clip(duty_gain (goal − q), ±1) on the measured position
    let mut saturated = 0;
    for line in lines {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        let duty = (2.0 * (v[3] - v[1])).clamp(-1.0, 1.0);
        assert!((v[5] - duty).abs() < 1e-12, "t = {}: duty {} against {duty}", v[0], v[5]);
        assert_eq!((v[6], v[7]), (1.0, 12.0), "t = {}", v[0]);
        saturated += usize::from(v[5].abs() == 1.0);
    }
    assert!(saturated > 0, "the run never saturates the duty: the test would not see the clip");
    // the sidecar says what was simulated: a servo with its constants
    let exp: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(d.join("a.experiment.json")).unwrap()).unwrap();
    assert_eq!((exp["controller"].as_str(), exp["duty_gain"].as_str(), exp["kt"].as_str(), exp["R"].as_str()), (Some("servo"), Some("2"), Some("1.5"), Some("1.5")));
    // diagnosed from the logs alone (CSV and MCAP), the friction is found and the held-out
    // run predicted
    let json = d.join("report.json");
    let [a, b, held] = ["a.csv", "b.mcap", "held.csv"].map(|n| d.join(n).display().to_string());
    let o = simgap(&["diagnose", "--urdf", PENDULUM, "--log", &a, "--log", &b, "--holdout", &held, "--json", json.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let selected = r["selected_effects"].as_array().unwrap();
    let viscous = selected.iter().find(|e| e["effect"] == "viscous_friction").unwrap_or_else(|| panic!("no viscous friction selected:\n{}", text(&o)));
    let b = viscous["parameters"]["b"][0].as_f64().unwrap();
    assert!((b - 0.5).abs() < 0.025, "b = {b} against 0.5\n{}", text(&o));
    let k = &r["gap"]["kstep"];
    let (after, before) = (k["after"][2].as_f64().unwrap(), k["before"][2].as_f64().unwrap());
    assert!(after < 0.1 * before, "held-out 0.5 s error {after} against {before} before\n{}", text(&o));
}

#[test]
fn simulated_drops_with_the_torque_off_let_the_diagnosis_tell_back_emf_from_viscous_friction() {
    let d = scratch("simulated-drops");
    // three runs of the servo (kt = R = 1.5: kt/R = 1 N·m/V, kt²/R = 1.5 N·m·s/rad) with viscous
    // friction b = 0.5 N·m·s/rad, each dropped once with the torque off
    let runs = [("a.csv", "0.6", "0.5", "2:2.6"), ("b.csv", "0.8", "0.3", "3:3.5"), ("held.csv", "0.7", "0.4", "1.5:2.2")];
    for (name, amplitude, hz, off) in runs {
        let fourier = format!("amplitude={amplitude};frequency={hz}");
        let o = simulate_servo(
            &d.join(name),
            &[
                "--fourier",
                &fourier,
                "--target",
                "0.6",
                "--duration",
                "6",
                "--sample-period",
                "0.005",
                "--counts-per-rev",
                "4096",
                "--effect",
                "viscous_friction:b=0.5",
                "--torque-off",
                off,
            ],
        );
        assert!(o.status.success(), "{name}: {}", text(&o));
        // the log says when the torque was off, and the duty is 0 there
        let csv = std::fs::read_to_string(d.join(name)).unwrap();
        let (from, to) = off.split_once(':').map(|(a, b)| (a.parse::<f64>().unwrap(), b.parse::<f64>().unwrap())).unwrap();
        for line in csv.lines().skip(1) {
            let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
            let on = !(v[0] >= from - 1e-9 && v[0] < to - 1e-9);
            assert_eq!(v[6], if on { 1.0 } else { 0.0 }, "{name} t = {}: torque enable", v[0]);
            assert!(on || v[5] == 0.0, "{name} t = {}: duty {} with the torque off", v[0], v[5]);
        }
        // the motor constants left out: the diagnosis fits them
        let sidecar = d.join(name.replace(".csv", ".experiment.json"));
        let mut exp: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&sidecar).unwrap()).unwrap();
        exp.as_object_mut().unwrap().retain(|k, _| k != "kt" && k != "R");
        std::fs::write(&sidecar, exp.to_string()).unwrap();
    }
    let json = d.join("report.json");
    let [a, b, held] = ["a.csv", "b.csv", "held.csv"].map(|n| d.join(n).display().to_string());
    let o = simgap(&["diagnose", "--urdf", PENDULUM, "--log", &a, "--log", &b, "--holdout", &held, "--json", json.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    let r: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(r["servo"]["source"], "fitted", "{}", r["servo"]);
    let (kt, res) = (r["servo"]["kt"][0].as_f64().unwrap(), r["servo"]["R"][0].as_f64().unwrap());
    assert!((kt / res - 1.0).abs() < 0.03 && (kt * kt / res - 1.5).abs() < 0.03 * 1.5, "kt = {kt}, R = {res}: kt/R {} (1), kt²/R {} (1.5)\n{}", kt / res, kt * kt / res, text(&o));
    let viscous = r["selected_effects"].as_array().unwrap().iter().find(|e| e["effect"] == "viscous_friction").unwrap_or_else(|| panic!("no viscous friction:\n{}", text(&o)));
    let bv = viscous["parameters"]["b"][0].as_f64().unwrap();
    assert!((bv - 0.5).abs() < 0.025, "b = {bv} against 0.5\n{}", text(&o));
}

#[test]
fn a_servo_simulation_without_its_constants_or_with_a_pd_gain_is_refused_naming_the_flag() {
    let d = scratch("simulate-refused");
    let out = d.join("x.csv");
    let cases: [(&[&str], &str); 4] = [
        (&["simulate", "--urdf", PENDULUM, "--controller", "servo", "--supply-voltage", "12", "--kt", "1", "--resistance", "1", "--target", "0.3"], "--duty-gain"),
        (&["simulate", "--urdf", PENDULUM, "--controller", "servo", "--duty-gain", "2", "--supply-voltage", "12", "--kt", "1", "--target", "0.3"], "--resistance"),
        (
            &[
                "simulate",
                "--urdf",
                PENDULUM,
                "--controller",
                "servo",
                "--duty-gain",
                "2",
                "--supply-voltage",
                "12",
                "--kt",
                "1",
                "--resistance",
                "1",
                "--kp",
                "3",
                "--target",
                "0.3",
            ],
            "--kp",
        ),
        (&["simulate", "--urdf", PENDULUM, "--controller", "pd", "--kp", "3", "--kv", "1", "--kt", "1", "--target", "0.3"], "--kt"),
    ];
    for (args, flag) in cases {
        let mut args = args.to_vec();
        args.extend(["--out", out.to_str().unwrap()]);
        let o = simgap(&args);
        assert!(!o.status.success() && text(&o).contains(flag), "{args:?}: expected an error naming {flag}:\n{}", text(&o));
        assert!(!out.exists(), "{args:?}: a refused run wrote {}", out.display());
    }
    let o = simulate_servo(&out, &["--max-duty", "1.5", "--target", "0.3"]);
    assert!(!o.status.success() && text(&o).contains("--max-duty") && text(&o).contains("(0, 1]"), "{}", text(&o));
    let o = simulate_servo(&out, &["--torque-off", "2:1", "--target", "0.3"]);
    assert!(!o.status.success() && text(&o).contains("--torque-off '2:1'") && text(&o).contains("FROM < TO"), "{}", text(&o));
    assert!(!out.exists(), "a refused run wrote {}", out.display());
}
