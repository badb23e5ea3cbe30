//! A servo run's drive signals (duty, torque enable, temperature, supply voltage) survive a
//! write and a read, in CSV and in MCAP: a log written by simgap loses nothing; the sinks a
//! simulation streams to write a servo's as it logs them.

use std::collections::BTreeMap;

use simgap_log::{read_log, write_log, CsvSink, LogOptions, McapSink};
use simgap_sim::{ControllerKind, DriveSample, Experiment, Run, RunEnd, Sample, Sink};

/// A folder of this test's own, removed when the test ends (also when it fails).
fn tmp(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("simgap-log-servo-{name}-")).tempdir().unwrap()
}

/// Two servos for 1 s at 100 Hz: a goal, a duty that saturates, the torque switched off after
/// 0.6 s, a temperature that rises and a supply that sags.
fn servo_run() -> Run {
    let joints = vec!["shoulder".to_string(), "elbow".to_string()];
    let mut run = Run::new(joints.clone());
    let n = 101;
    run.t = (0..n).map(|k| k as f64 * 0.01).collect();
    for &t in &run.t {
        let (q0, q1) = (0.3 * t.sin(), -0.2 * (2.0 * t).sin());
        run.q.extend([q0, q1]);
        run.qd.extend([0.3 * t.cos(), -0.4 * (2.0 * t).cos()]);
        run.q_ref.extend([0.3 * (t + 0.05).sin(), -0.2 * (2.0 * t + 0.1).sin()]);
        run.drive.duty.extend([(3.0 * t - 1.0).clamp(-1.0, 1.0), -0.25 * t]);
        let on = if t < 0.6 { 1.0 } else { 0.0 };
        run.drive.torque_enable.extend([on, on]);
        run.drive.temperature.extend([27.0 + 3.0 * t, 31.5 + t]);
        run.drive.voltage.push(12.0 - 0.4 * t);
    }
    let extra: BTreeMap<String, String> = [("duty_gain".to_string(), "2.5,1.5".to_string()), ("supply_voltage".to_string(), "12".to_string())].into();
    run.experiment = Some(Experiment { controller: ControllerKind::Servo, joints, kp: vec![], kv: vec![], sample_period: 0.01, extra });
    run
}

fn round_trip(name: &str) {
    let run = servo_run();
    let dir = tmp(name);
    let path = dir.path().join(name);
    write_log(&run, &path).unwrap();
    let back = read_log(&path, &LogOptions::default()).unwrap_or_else(|e| panic!("{name}: {e}"));
    assert_eq!(back.drive.duty, run.drive.duty, "{name}: duty");
    assert_eq!(back.drive.torque_enable, run.drive.torque_enable, "{name}: torque enable");
    assert_eq!(back.drive.temperature, run.drive.temperature, "{name}: temperature");
    assert_eq!(back.drive.voltage, run.drive.voltage, "{name}: voltage");
    assert_eq!(back.q, run.q, "{name}: positions");
    assert_eq!(back.q_ref, run.q_ref, "{name}: goal");
    let e = back.experiment.as_ref().unwrap_or_else(|| panic!("{name}: no experiment"));
    assert_eq!(e.controller, ControllerKind::Servo, "{name}");
    assert_eq!(e.extra.get("duty_gain").map(String::as_str), Some("2.5,1.5"), "{name}");
}

#[test]
fn a_servo_runs_drive_signals_survive_a_csv_round_trip() {
    round_trip("servo.csv");
}

#[test]
fn a_servo_runs_drive_signals_survive_an_mcap_round_trip() {
    round_trip("servo.mcap");
}

/// The run streamed sample by sample through `sink`, as the simulator hands a servo's samples
/// (its drive signals, and the command it does not log).
fn stream(run: &Run, sink: &mut dyn Sink) {
    let n = run.dof();
    sink.begin(&run.joints, run.experiment.as_ref().unwrap()).unwrap();
    for k in 0..run.len() {
        let rows = |m: &[f64]| m[k * n..(k + 1) * n].to_vec();
        let (q, qd, q_ref, duty, enable) = (rows(&run.q), rows(&run.qd), rows(&run.q_ref), rows(&run.drive.duty), rows(&run.drive.torque_enable));
        let command: Vec<f64> = duty.iter().map(|d| 5.0 * d).collect();
        let drive = Some(DriveSample { duty: &duty, torque_enable: &enable, voltage: run.drive.voltage[k] });
        sink.record(&Sample { t: run.t[k], q: &q, qd: &qd, tau: &command, q_ref: &q_ref, qd_ref: &[0.0, 0.0], drive }).unwrap();
    }
    sink.finish(&RunEnd::Completed).unwrap();
}

fn streamed(name: &str) {
    let run = servo_run();
    let dir = tmp(&format!("stream-{name}"));
    let path = dir.path().join(name);
    if name.ends_with(".mcap") {
        stream(&run, &mut McapSink::create(&path).unwrap());
    } else {
        stream(&run, &mut CsvSink::create(&path).unwrap());
    }
    let back = read_log(&path, &LogOptions::default()).unwrap_or_else(|e| panic!("{name}: {e}"));
    assert_eq!(back.drive.duty, run.drive.duty, "{name}: duty");
    assert_eq!(back.drive.torque_enable, run.drive.torque_enable, "{name}: torque enable");
    assert_eq!(back.drive.voltage, run.drive.voltage, "{name}: voltage");
    assert!(back.drive.temperature.is_empty(), "{name}: a simulated servo has no temperature");
    assert!(back.tau.is_empty(), "{name}: a servo logs no torque, got {} values", back.tau.len());
    assert_eq!((back.q.clone(), back.q_ref.clone()), (run.q.clone(), run.q_ref.clone()), "{name}: positions and goal");
    assert_eq!(back.experiment.as_ref().map(|e| e.controller), Some(ControllerKind::Servo), "{name}");
}

#[test]
fn a_streamed_servo_run_is_written_as_a_servo_logs_it_in_csv() {
    streamed("servo.csv");
}

#[test]
fn a_streamed_servo_run_is_written_as_a_servo_logs_it_in_mcap() {
    streamed("servo.mcap");
}
