//! The simulator writing MCAP logs: what the MCAP sink writes is what the memory sink holds,
//! and a diverged run still leaves a readable file that says so.

use simgap_core::{Formulation, Model};
use simgap_log::{read_log, LogOptions, McapSink};
use simgap_sim::paper;
use simgap_sim::{simulate, MemorySink, Pd, Plant, Run, RunEnd, SensorParams, SimParams};

mod common;
use common::tmp;

fn assert_same_run(a: &Run, b: &Run) {
    assert_eq!(a.joints, b.joints);
    assert_eq!(a.len(), b.len());
    assert!(a.t.iter().zip(&b.t).all(|(x, y)| (x - y).abs() < 1e-9));
    assert_eq!((&a.q, &a.qd, &a.tau, &a.q_ref, &a.qd_ref), (&b.q, &b.qd, &b.tau, &b.q_ref, &b.qd_ref));
    assert_eq!(a.experiment, b.experiment);
}

#[test]
fn simulated_run_logged_to_mcap_reads_back_as_the_memory_run() {
    let model = Model::paper_arm();
    let plant = Plant::new(&model, Formulation::EulerLagrange, &[]).unwrap();
    let params = SimParams { duration: 0.5, ..SimParams::default() };
    let step = paper::reference();
    let pd = || paper::controller();
    let mut memory = MemorySink::new();
    simulate(&plant, &mut pd(), &step, &params, &mut memory, None).unwrap();
    let path = tmp("paper_pd.mcap");
    let mut sink = McapSink::create(&path).unwrap();
    let end = simulate(&plant, &mut pd(), &step, &params, &mut sink, None).unwrap();
    assert_eq!(end, RunEnd::Completed);
    drop(sink);
    let run = read_log(&path, &LogOptions::default()).unwrap();
    assert!(run.len() > 100);
    assert_same_run(&memory.into_run(), &run);
}

#[test]
fn diverged_simulation_leaves_a_readable_mcap() {
    let model = Model::paper_arm();
    let plant = Plant::new(&model, Formulation::EulerLagrange, &[]).unwrap();
    // a derivative gain far beyond what 2.5 ms sampling can stabilise
    let mut pd = Pd { kp: vec![64.72, 32.36], kv: vec![5000.0, 6.472] };
    let path = tmp("diverged.mcap");
    let mut sink = McapSink::create(&path).unwrap();
    let params = SimParams { sensor: SensorParams::exact(), ..SimParams::default() };
    let end = simulate(&plant, &mut pd, &paper::reference(), &params, &mut sink, None).unwrap();
    assert!(matches!(end, RunEnd::Diverged { .. }), "{end:?}");
    drop(sink);
    let run = read_log(&path, &LogOptions::default()).unwrap();
    assert!(!run.is_empty());
    let bytes = std::fs::read(&path).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    let statuses: Vec<String> =
        summary.metadata_indexes.iter().map(|i| mcap::read::metadata(&bytes, i).unwrap()).filter(|m| m.name == "simgap.run_end").map(|m| m.metadata["status"].clone()).collect();
    assert_eq!(statuses, vec!["diverged".to_string()]);
}
