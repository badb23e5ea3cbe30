//! A log whose writer was killed: a child process simulates a long run into an MCAP sink and is
//! killed with SIGKILL mid-write; the file, without summary or footer, is read back by a linear
//! scan up to its last complete chunk, with a warning saying what was recovered.
//!
//! The child is this test binary run again with an environment variable set.

use std::process::Command;
use std::time::{Duration, Instant};

use simgap_core::{Formulation, Model};
use simgap_log::{read_log_with_warnings, LogOptions, McapSink, SinkOptions};
use simgap_sim::paper;
use simgap_sim::{simulate, Plant, SimParams};

const CHILD_ENV: &str = "SIMGAP_LOG_KILLED_WRITER_PATH";
const TEST_NAME: &str = "killed_writer_leaves_a_log_recovered_by_a_linear_scan";

/// The child: an hour of the paper's experiment, written as it goes.
fn child(path: &str) {
    let model = Model::paper_arm();
    let plant = Plant::new(&model, Formulation::EulerLagrange, &[]).unwrap();
    let mut pd = paper::controller();
    let params = SimParams { duration: 3600.0, ..SimParams::default() };
    let mut sink = McapSink::create_with_options(path.as_ref(), SinkOptions { chunk_size: 32 * 1024, ..SinkOptions::default() }).unwrap();
    simulate(&plant, &mut pd, &paper::reference(), &params, &mut sink, None).unwrap();
    unreachable!("the parent kills this process long before an hour is simulated");
}

#[test]
fn killed_writer_leaves_a_log_recovered_by_a_linear_scan() {
    if let Ok(path) = std::env::var(CHILD_ENV) {
        child(&path);
        return;
    }
    // removed when the test ends, also when it fails
    let scratch = tempfile::Builder::new().prefix("simgap-log-killed-").tempdir().unwrap();
    let path = scratch.path().join("killed.mcap");
    let mut child = Command::new(std::env::current_exe().unwrap()).args(["--exact", TEST_NAME, "--nocapture", "--test-threads=1"]).env(CHILD_ENV, &path).spawn().unwrap();
    // kill it once it has written a few hundred kilobytes
    let deadline = Instant::now() + Duration::from_secs(60);
    while std::fs::metadata(&path).map_or(0, |m| m.len()) < 300_000 {
        assert!(Instant::now() < deadline, "the child wrote too little in 60 s");
        assert!(child.try_wait().unwrap().is_none(), "the child ended before it was killed");
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap(); // SIGKILL: no destructor, no summary
    child.wait().unwrap();
    let size = std::fs::metadata(&path).unwrap().len();

    let read = read_log_with_warnings(&path, &LogOptions::default()).unwrap();
    let w = read.warnings.join("; ");
    println!("killed writer: file of {size} bytes, {} samples over {:.3} s recovered; warning: {w}", read.run.len(), read.run.duration());
    assert!(w.contains("no summary") && w.contains(&format!("of {size}")), "{w}");
    assert!(read.run.len() > 1000, "{} samples", read.run.len());
    // the run is the simulation's first seconds: it starts at rest and tracks the step
    assert_eq!(read.run.row(&read.run.q, 0), &[0.0, 0.0]);
    assert!((read.run.t[1] - 0.0025).abs() < 1e-12);
    assert!(read.run.experiment.is_some(), "the experiment record is written first");
}
