//! Reads a log (MCAP, rosbag2 bag folder, CSV, CSV.gz), prints a JSON summary, and optionally
//! writes it again.
//!
//! ```text
//! cargo run --release --example log_roundtrip -- IN.mcap [OUT.mcap|OUT.csv]
//! ```
//!
//! The summary: `joints`, `samples`, `start_ns` (absolute start [ns], or null), `t_first`,
//! `t_last` (time since the start [s]), `duration`, `q_first` / `q_last` / `qd_last` /
//! `tau_last` / `q_ref_last` / `tau_ff_last` / `tau_measured_last` (objects keyed by joint name),
//! `has_reference`, `experiment` (the `simgap.experiment` map, or null), `source` and `warnings`
//! (e.g. a file recovered without its summary). Used by the Python interop
//! tests (`tests/python/test_mcap_interop.py`).

use std::path::Path;
use std::process::ExitCode;

use serde_json::{json, Map, Value};
use simgap_log::{read_log_with_warnings, write_log, LogOptions};
use simgap_sim::{experiment_to_map, Run};

fn by_joint(run: &Run, m: &[f64], k: usize) -> Value {
    if m.is_empty() || run.is_empty() {
        return Value::Null;
    }
    let row = run.row(m, k);
    Value::Object(run.joints.iter().zip(row).map(|(j, x)| (j.clone(), json!(x))).collect::<Map<_, _>>())
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.is_empty() || args.len() > 2 || args[0].starts_with('-') {
        eprintln!("usage: log_roundtrip IN [OUT]   (.mcap, .csv, .csv.gz)");
        return ExitCode::from(2);
    }
    let (run, warnings) = match read_log_with_warnings(Path::new(&args[0]), &LogOptions::default()) {
        Ok(read) => (read.run, read.warnings),
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    };
    let last = run.len().saturating_sub(1);
    let summary = json!({
        "joints": run.joints,
        "samples": run.len(),
        "start_ns": run.start_ns,
        "t_first": run.t.first(),
        "t_last": run.t.last(),
        "duration": run.duration(),
        "q_first": by_joint(&run, &run.q, 0),
        "q_last": by_joint(&run, &run.q, last),
        "qd_last": by_joint(&run, &run.qd, last),
        "tau_last": by_joint(&run, &run.tau, last),
        "q_ref_last": by_joint(&run, &run.q_ref, last),
        "tau_ff_last": by_joint(&run, &run.tau_ff, last),
        "tau_measured_last": by_joint(&run, &run.tau_measured, last),
        "has_reference": !run.q_ref.is_empty(),
        "experiment": run.experiment.as_ref().map(experiment_to_map),
        "source": run.source,
        "warnings": warnings,
    });
    println!("{summary}");
    if let Some(out) = args.get(1) {
        if let Err(e) = write_log(&run, Path::new(out)) {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    }
    ExitCode::SUCCESS
}
