//! `simgap simulate --out RUN.csv` (and `RUN.csv.gz`) writes its log as the run goes, through the
//! CSV sink and its writer thread: the file is `RUN.partial.csv` while the run goes and gets its
//! name when the run ends. A process killed with SIGKILL at any instant leaves the partial file,
//! which the reader reads up to its last complete row (a cut last line, a gzip member cut short,
//! dropped) with a warning; the rows recovered are exactly the simulation's (compared with the
//! same run simulated in this process), and for a plain CSV they are every line the file ends.

use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use simgap::core::{Formulation, Model};
use simgap::log::{read_log_with_warnings, LogOptions};
use simgap::sim::{simulate, MemorySink, Pd, Plant, SimParams, Step};

mod common;
use common::bin;

/// The CLI's default run (the paper's experiment) simulated here for `duration` seconds.
fn reference_run(duration: f64) -> simgap::sim::Run {
    let model = Model::paper_arm();
    let plant = Plant::new(&model, Formulation::EulerLagrange, &[]).unwrap();
    let mut pd = Pd { kp: simgap::sim::paper::KP.to_vec(), kv: simgap::sim::paper::KV.to_vec() };
    let mut sink = MemorySink::new();
    let params = SimParams { duration, ..SimParams::default() };
    simulate(&plant, &mut pd, &Step { target: simgap::sim::paper::Q_DESIRED.to_vec() }, &params, &mut sink, None).unwrap();
    sink.into_run()
}

#[test]
fn csv_simulate_killed_at_random_instants_leaves_every_complete_row_readable() {
    let dir = std::env::temp_dir().join(format!("simgap-killed-csv-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(20261202);
    let mut recovered_runs = 0;
    for kill in 0..6 {
        let name = if kill % 2 == 0 { format!("long-{kill}.csv") } else { format!("long-{kill}.csv.gz") };
        let path = dir.join(&name);
        let partial = simgap::log::csv_sink::partial_path(&path);
        // 20,000 s of the paper's experiment (8e6 samples, within a CSV log's bound): far
        // longer than the test waits
        let mut child = Command::new(bin())
            .args(["simulate", "--duration", "20000", "--out", path.to_str().unwrap()])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("simgap runs");
        let after = Duration::from_millis(rng.random_range(150..1500));
        let start = Instant::now();
        while start.elapsed() < after {
            assert!(child.try_wait().unwrap().is_none(), "kill {kill}: simulate ended before it was killed");
            std::thread::sleep(Duration::from_millis(5));
        }
        child.kill().unwrap(); // SIGKILL: no handler, no destructor, no rename
        child.wait().unwrap();
        assert!(!path.exists(), "kill {kill}: {} exists although the run never ended", path.display());
        let bytes = std::fs::read(&partial).unwrap_or_else(|e| panic!("kill {kill}: {} is not there: {e}", partial.display()));
        let read = read_log_with_warnings(&partial, &LogOptions::default());
        println!("kill {kill} after {after:?}: {name}: {} bytes", bytes.len());
        let read = match read {
            Ok(read) => read,
            // killed before the first row was written: a clean error
            Err(e) if bytes.len() < 4096 => {
                println!("  no row yet: {e}");
                continue;
            }
            Err(e) => panic!("kill {kill}: {} bytes but the read failed: {e}", bytes.len()),
        };
        let w = read.warnings.join("; ");
        assert!(w.contains("did not finish") && w.contains("complete rows recovered"), "kill {kill}: warning {w}");
        let run = read.run;
        println!("  {} rows recovered; {w}", run.len());
        assert!(run.experiment.is_some(), "kill {kill}: the sidecar is written when the run begins");
        if !name.ends_with(".gz") {
            // every line the file ends is a row: header + rows, a cut last line dropped
            let lines = bytes.iter().filter(|&&b| b == b'\n').count();
            assert_eq!(run.len(), lines - 1, "kill {kill}: {lines} lines ended");
        }
        // the rows are the simulation's, bit for bit
        let expected = reference_run(run.duration());
        assert_eq!(run.len(), expected.len(), "kill {kill}");
        assert_eq!(run.t, expected.t, "kill {kill}: t");
        assert_eq!(run.q, expected.q, "kill {kill}: q");
        assert_eq!(run.qd, expected.qd, "kill {kill}: qd");
        assert_eq!(run.tau, expected.tau, "kill {kill}: tau");
        assert_eq!(run.q_ref, expected.q_ref, "kill {kill}: q_ref");
        assert_eq!(run.qd_ref, expected.qd_ref, "kill {kill}: qd_ref");
        recovered_runs += 1;
    }
    assert!(recovered_runs >= 4, "only {recovered_runs} of 6 killed runs had a complete row");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A run that ends (here, completes) leaves its log at the requested name, the partial name
/// gone, with the same rows as the run simulated here.
#[test]
fn csv_simulate_renames_the_partial_log_when_the_run_ends() {
    let dir = std::env::temp_dir().join(format!("simgap-streaming-csv-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    for name in ["run.csv", "run.csv.gz"] {
        let path = dir.join(name);
        let status = Command::new(bin()).args(["simulate", "--duration", "30", "--out", path.to_str().unwrap()]).stdout(Stdio::null()).status().unwrap();
        assert!(status.success());
        assert!(path.exists() && !simgap::log::csv_sink::partial_path(&path).exists(), "{name}");
        let read = read_log_with_warnings(&path, &LogOptions::default()).unwrap();
        assert!(read.warnings.is_empty(), "{name}: {:?}", read.warnings);
        let expected = reference_run(30.0);
        assert_eq!(read.run.len(), 12_001, "{name}");
        assert_eq!(read.run.q, expected.q, "{name}");
        assert_eq!(read.run.tau, expected.tau, "{name}");
    }
    let mut names: Vec<String> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().to_string()).collect();
    names.sort();
    assert_eq!(names, ["run.csv", "run.csv.gz", "run.experiment.json"]);
    let _ = std::fs::remove_dir_all(&dir);
}
