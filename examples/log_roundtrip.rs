//! Reads a log (MCAP, CSV, CSV.gz), prints a JSON summary, and optionally writes it again.
//!
//! ```text
//! cargo run --release --example log_roundtrip -- IN.mcap [OUT.mcap|OUT.csv]
//! ```
//!
//! The summary: `joints`, `samples`, `t_first`, `t_last`, `duration`, `q_first` / `q_last` /
//! `qd_last` / `tau_last` / `q_ref_last` (objects keyed by joint name), `has_reference`,
//! `experiment` (the `simgap.experiment` map, or null) and `source`. Used by the Python interop
//! tests (`tests/python/test_mcap_interop.py`).

use std::path::Path;
use std::process::ExitCode;

use serde_json::{json, Map, Value};
use simgap_sim::log::{experiment_to_map, read_log, write_log};
use simgap_sim::Run;

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
    let run = match read_log(Path::new(&args[0])) {
        Ok(run) => run,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::FAILURE;
        }
    };
    let last = run.len().saturating_sub(1);
    let summary = json!({
        "joints": run.joints,
        "samples": run.len(),
        "t_first": run.t.first(),
        "t_last": run.t.last(),
        "duration": run.duration(),
        "q_first": by_joint(&run, &run.q, 0),
        "q_last": by_joint(&run, &run.q, last),
        "qd_last": by_joint(&run, &run.qd, last),
        "tau_last": by_joint(&run, &run.tau, last),
        "q_ref_last": by_joint(&run, &run.q_ref, last),
        "has_reference": !run.q_ref.is_empty(),
        "experiment": run.experiment.as_ref().map(experiment_to_map),
        "source": run.source,
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
