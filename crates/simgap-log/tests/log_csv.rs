//! CSV logs: the DFKI files load unedited, generic CSV round trips, experiment sidecars, and
//! errors that name the file and the problem.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use simgap_log::csv::{detect_mapping, read_csv, read_header, write_csv, CsvMapping, DFKI_DOUBLE_PENDULUM_JOINTS, DFKI_SIMPLE_PENDULUM_JOINT};
use simgap_log::experiment::{read_experiment_file, sidecar_path};
use simgap_log::{write_log, Error, LogOptions};
use simgap_sim::{validate_run, ControllerKind, Experiment, Run};

mod common;
use common::tmp;

fn read_log(path: &Path) -> simgap_log::Result<Run> {
    simgap_log::read_log(path, &LogOptions::default())
}

fn read_log_for(path: &Path, joints: &[String]) -> simgap_log::Result<Run> {
    simgap_log::read_log_for(path, joints, false, &LogOptions::default())
}

/// `../shared/data` next to the workspace, or `None` (with a message) when it is absent.
fn data_dir() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    if dir.is_dir() {
        Some(dir)
    } else {
        assert!(std::env::var_os("CI").is_none(), "shared data not found at {} (CI is set: a test without its data fails)", dir.display());
        eprintln!("SKIP: shared data not found at {} (the DFKI records live outside the repository)", dir.display());
        None
    }
}

fn names(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

fn assert_error_names<T: std::fmt::Debug>(result: simgap_log::Result<T>, path: &Path, needle: &str) {
    let m = result.expect_err("expected an error").to_string();
    assert!(m.contains(&path.display().to_string()), "error '{m}' does not name {}", path.display());
    assert!(m.contains(needle), "error '{m}' does not say '{needle}'");
}

fn check_dfki(run: &Run, joints: &[&str], n: usize, duration: f64) {
    assert_eq!(run.joints, names(joints));
    assert_eq!(run.len(), n, "{}", run.source);
    assert!((run.duration() - duration).abs() < 0.05, "{}: duration {}", run.source, run.duration());
    assert_eq!(run.q.len(), n * joints.len());
    assert_eq!(run.qd.len(), n * joints.len());
    assert_eq!(run.tau.len(), n * joints.len());
    validate_run(run).unwrap();
    // angles in radians, torques within the motors' peak
    assert!(run.q.iter().all(|q| q.abs() < 10.0));
    assert!(run.tau.iter().all(|t| t.abs() <= 20.0));
}

#[test]
fn dfki_double_pendulum_records_load_unedited() {
    let Some(data) = data_dir() else { return };
    let dp = data.join("dfki-double-pendulum/experiment_records");
    // design C.0 sys-id: documented layout, 500 Hz, 10 s, open-loop torques
    let expected = [4993, 4974, 4979, 4993, 4999];
    for (i, n) in expected.iter().enumerate() {
        let path = dp.join(format!("design_C.0/20220914/sys_id/trajectory_0{i}.csv.gz"));
        let run = read_log(&path).unwrap();
        check_dfki(&run, &DFKI_DOUBLE_PENDULUM_JOINTS, *n, 10.0);
        assert!(run.q_ref.is_empty(), "sys-id runs have no reference");
        assert!(run.experiment.is_none());
        assert!(run.tau.iter().any(|t| t.abs() > 0.3), "tau_con is the commanded torque");
    }
    // design A.0 sys-id: short layout, 300 Hz, 75 s, PD tracking
    let path = dp.join("design_A.0/20220812/sys_id/20220812-061157-PM_measured.csv.gz");
    let run = read_log(&path).unwrap();
    check_dfki(&run, &DFKI_DOUBLE_PENDULUM_JOINTS, 21969, 75.0);
    assert!(run.q.iter().any(|q| q.abs() > 2.0), "joints sweep ±3 rad");
    // ... mapped to a model's order by name
    let swapped = read_log_for(&path, &names(&["Joint2", "Joint1"])).unwrap();
    assert_eq!(swapped.row(&swapped.q, 100), &[run.row(&run.q, 100)[1], run.row(&run.q, 100)[0]]);
    match read_log_for(&path, &names(&["shoulder", "elbow"])) {
        Err(Error::Run(simgap_sim::Error::JointMismatch { joint, .. })) => assert_eq!(joint, "shoulder"),
        other => panic!("expected JointMismatch, got {other:?}"),
    }
}

#[test]
fn dfki_joint_names_are_those_of_the_dfki_urdfs() {
    let Some(data) = data_dir() else { return };
    let urdf = std::fs::read_to_string(data.join("dfki-double-pendulum/system_identification/identified_parameters/design_C.0/model_3.1/acrobot.urdf")).unwrap();
    for j in DFKI_DOUBLE_PENDULUM_JOINTS {
        assert!(urdf.contains(&format!("<joint name=\"{j}\" type=\"revolute\">")), "{j}");
    }
    let urdf = std::fs::read_to_string(data.join("dfki-simple-pendulum/urdf/simplependul_dfki_pino_Modi.urdf")).unwrap();
    assert!(urdf.contains(&format!("<joint name=\"{DFKI_SIMPLE_PENDULUM_JOINT}\" type=\"revolute\">")));
}

#[test]
fn dfki_simple_pendulum_records_load_unedited() {
    let Some(data) = data_dir() else { return };
    let sp = data.join("dfki-simple-pendulum");
    let run = read_log(&sp.join("control_method_gravity_compensation/data_measured.csv.gz")).unwrap();
    check_dfki(&run, &[DFKI_SIMPLE_PENDULUM_JOINT], 30000, 30.02);
    let run = read_log(&sp.join("control_method_pd/system_identification/data_measured.csv.gz")).unwrap();
    check_dfki(&run, &[DFKI_SIMPLE_PENDULUM_JOINT], 1170, 3.9);
    // the desired file as a reference, through a mapping of one's own
    let desired = sp.join("control_method_pd/system_identification/data_desired.csv.gz");
    let mapping = CsvMapping::new("time").position("pendulum", "position").velocity("pendulum", "velocity");
    let reference = read_csv(&desired, &mapping).unwrap();
    assert_eq!(reference.len(), 1170);
    assert!(reference.tau.is_empty());
    assert!((reference.q.last().unwrap() - std::f64::consts::PI).abs() < 1e-9, "swing-up to π");
    // the other URDF's joint name
    let renamed = CsvMapping::dfki_simple_pendulum().with_joint_names(&["Joint_1"]);
    let run = read_csv(&sp.join("control_method_pd/system_identification/data_measured.csv.gz"), &renamed).unwrap();
    assert_eq!(run.joints, names(&["Joint_1"]));
}

#[test]
fn excitation_trajectory_reads_with_an_explicit_mapping_only() {
    let Some(data) = data_dir() else { return };
    let path = data.join("dfki-double-pendulum/system_identification/excitation_trajectories/trajectory-pos-20.csv.gz");
    // header time,pos1,pos2,vel1,vel2,acc1,acc2: no torque, so no preset
    assert!(detect_mapping(&read_header(&path).unwrap()).is_none());
    assert_error_names(read_log(&path), &path, "cannot tell what the columns are");
    let mapping = CsvMapping::from_suffixes("time", &DFKI_DOUBLE_PENDULUM_JOINTS, &["1", "2"], "pos", Some("vel"), None, None, None);
    let run = read_csv(&path, &mapping).unwrap();
    assert_eq!(run.len(), 22500);
    assert!((run.duration() - 74.9967).abs() < 1e-3);
}

fn sample_run() -> Run {
    let mut run = Run::new(names(&["shoulder", "elbow"]));
    for k in 0..400 {
        let t = 5.0 + k as f64 * 0.0025;
        run.t.push(t);
        for j in 0..2 {
            let x = t * (j + 1) as f64;
            run.q.push(x.sin() / 7.0);
            run.qd.push(x.cos() * 1e-9);
            run.tau.push(x * 3.3333333333333335);
            run.q_ref.push(0.1 * j as f64);
            run.qd_ref.push(0.0);
        }
    }
    run.experiment = Some(Experiment {
        controller: ControllerKind::Pd,
        joints: names(&["shoulder", "elbow"]),
        kp: vec![64.72, 32.36],
        kv: vec![48.54, 6.472],
        sample_period: 0.0025,
        extra: BTreeMap::from([("robot".to_string(), "paper arm".to_string())]),
    });
    run
}

#[test]
fn csv_written_and_read_back_is_identical() {
    for name in ["roundtrip.csv", "roundtrip.csv.gz"] {
        let run = sample_run();
        let path = tmp(name);
        write_log(&run, &path).unwrap();
        assert!(sidecar_path(&path).exists());
        assert!(sidecar_path(&path).to_string_lossy().ends_with("roundtrip.experiment.json"));
        let mut back = read_log(&path).unwrap();
        back.source.clear();
        assert_eq!(back, run, "{name}");
    }
    // gzip is detected by content too
    let run = sample_run();
    let gz = tmp("content.csv.gz");
    write_csv(&run, &gz).unwrap();
    let renamed = tmp("content_is_gzip.csv");
    std::fs::copy(&gz, &renamed).unwrap();
    assert_eq!(read_log(&renamed).unwrap().q, run.q);
}

#[test]
fn csv_and_mcap_carry_the_same_run() {
    let run = sample_run();
    let csv = tmp("same.csv");
    let mcap = tmp("same.mcap");
    write_log(&run, &csv).unwrap();
    write_log(&run, &mcap).unwrap();
    let (a, b) = (read_log(&csv).unwrap(), read_log(&mcap).unwrap());
    assert_eq!(a.q, b.q);
    assert_eq!(a.tau, b.tau);
    assert_eq!(a.experiment, b.experiment);
    // MCAP runs count time from their first stamp, which they keep as `start_ns`
    assert_eq!(b.start_ns, Some(5_000_000_000));
    for (x, y) in a.t.iter().zip(&b.t) {
        assert!((x - 5.0 - y).abs() < 1e-9);
    }
}

#[test]
fn generic_csv_without_velocity_or_effort() {
    let path = tmp("generic.csv");
    std::fs::write(&path, "time,q_b,q_a\n0,0,1\n0.5,1,1\n1,2,1\n").unwrap();
    let run = read_log(&path).unwrap();
    assert_eq!(run.joints, names(&["b", "a"]));
    assert_eq!(run.qd, vec![2.0, 0.0, 2.0, 0.0, 2.0, 0.0]);
    assert!(run.source.contains("central difference"));
    assert!(run.tau.is_empty());
    assert!(run.q_ref.is_empty());
}

#[test]
fn experiment_files_in_json_and_key_value_form() {
    let kv = tmp("exp.experiment");
    std::fs::write(&kv, "# paper arm\ncontroller = pd_gravity\njoints = shoulder, elbow\nkp = 64.72, 32.36\nkv = 48.54,6.472\nsample_period = 0.0025\nrobot = paper arm\n")
        .unwrap();
    let e = read_experiment_file(&kv).unwrap();
    assert_eq!(e.controller, ControllerKind::PdGravity);
    assert_eq!(e.joints, names(&["shoulder", "elbow"]));
    assert_eq!(e.kp, vec![64.72, 32.36]);
    assert_eq!(e.extra["robot"], "paper arm");
    let json = tmp("exp.json");
    std::fs::write(&json, r#"{"controller": "replay", "joints": ["a"], "kp": [1], "kv": "0.5", "sample_period": 0.001}"#).unwrap();
    let e = read_experiment_file(&json).unwrap();
    assert_eq!((e.controller, e.kp, e.kv, e.sample_period), (ControllerKind::Replay, vec![1.0], vec![0.5], 0.001));

    let bad = tmp("bad.experiment");
    std::fs::write(&bad, "controller = pd\njoints = a\nkp = 1\nsample_period = 0.01\n").unwrap();
    assert_error_names(read_experiment_file(&bad), &bad, "key 'kv' is missing");
    std::fs::write(&bad, "controller pd\n").unwrap();
    assert_error_names(read_experiment_file(&bad), &bad, "expected 'key = value'");
    let bad = tmp("bad.json");
    std::fs::write(&bad, "{\"controller\": ").unwrap();
    assert_error_names(read_experiment_file(&bad), &bad, "not valid JSON");

    // a malformed sidecar makes reading the log fail
    let path = tmp("with_bad_sidecar.csv");
    std::fs::write(&path, "time,q_a\n0,0\n1,1\n").unwrap();
    std::fs::write(sidecar_path(&path), r#"{"controller": "pd", "joints": "a", "kp": "x", "kv": "1", "sample_period": "1"}"#).unwrap();
    assert_error_names(read_log(&path), &sidecar_path(&path), "'x' is not a number");
}

#[test]
fn csv_errors_name_the_file_and_the_problem() {
    let case = |name: &str, text: &str, needle: &str| {
        let path = tmp(name);
        std::fs::write(&path, text).unwrap();
        assert_error_names(read_log(&path), &path, needle);
    };
    case("nan.csv", "time,q_a,qd_a\n0,0,0\n1,nan,0\n", "q of joint 'a' is NaN at t = 1 s");
    case("backwards.csv", "time,q_a\n0,0\n2,0\n1,0\n", "time is not strictly increasing");
    case("repeated.csv", "time,q_a\n0,0\n1,0\n1,0\n", "time is not strictly increasing");
    case("text.csv", "time,q_a\n0,0\n1,abc\n", "line 3, column 'q_a': 'abc' is not a number");
    case("unknown.csv", "t,x,y\n0,0,0\n", "cannot tell what the columns are");
    case("partial.csv", "time,q_a,q_b,qd_a\n0,0,0,0\n", "column 'qd_b' (velocity of joint 'b') is not in the header");
    case("empty.csv", "time,q_a\n", "no data rows");
    let path = tmp("dfki_missing.csv");
    std::fs::write(&path, "time,pos1,pos2,vel1,vel2\n0,0,0,0,0\n").unwrap();
    let mapping = CsvMapping::dfki_double_pendulum_sysid();
    assert_error_names(read_csv(&path, &mapping), &path, "column 'tau1' (effort of joint 'Joint1') is not in the header");
}
