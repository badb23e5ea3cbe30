//! The cost of logging a simulation as ROS 2 MCAP as it runs: the paper's experiment at 400 Hz
//! for 30 s (12,001 samples), unlogged and logged, alternated so both see the same machine load;
//! the best of each is reported with their ratio.
//!
//! `cargo run --release -p simgap-log --example logging_cost [ROUNDS] [zstd|lz4|none] [DURATION_S]`
//! (default 15 rounds, zstd, 30 s)

use std::time::{Duration, Instant};

use simgap_core::{Formulation, Model};
use simgap_log::{Compression, McapSink, SinkOptions};
use simgap_sim::paper;
use simgap_sim::{simulate, Experiment, Plant, RunEnd, Sample, SimParams, Sink};

/// A sink that drops every sample.
struct NullSink;

impl Sink for NullSink {
    fn begin(&mut self, _: &[String], _: &Experiment) -> simgap_sim::Result<()> {
        Ok(())
    }
    fn record(&mut self, s: &Sample<'_>) -> simgap_sim::Result<()> {
        std::hint::black_box(s.q[0]);
        Ok(())
    }
    fn finish(&mut self, _: &RunEnd) -> simgap_sim::Result<()> {
        Ok(())
    }
}

fn main() {
    let rounds: usize = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(15);
    let compression = match std::env::args().nth(2).as_deref() {
        Some("none") => Compression::None,
        Some("lz4") => Compression::Lz4,
        _ => SinkOptions::default().compression,
    };
    let options = SinkOptions { compression, ..SinkOptions::default() };
    let model = Model::paper_arm();
    let reference = paper::reference();
    let duration: f64 = std::env::args().nth(3).and_then(|s| s.parse().ok()).unwrap_or(30.0);
    let params = SimParams { duration, ..SimParams::default() };
    let path = std::env::temp_dir().join(format!("simgap-logging-cost-{}.mcap", std::process::id()));
    let once = |logged: bool| -> Duration {
        let start = Instant::now();
        let plant = Plant::new(&model, Formulation::EulerLagrange, &[]).unwrap();
        let mut pd = paper::controller();
        let end = if logged {
            let mut sink = McapSink::create_with_options(&path, options.clone()).unwrap();
            let end = simulate(&plant, &mut pd, &reference, &params, &mut sink, None).unwrap();
            drop(sink); // the file finished: summary written, thread joined
            end
        } else {
            simulate(&plant, &mut pd, &reference, &params, &mut NullSink, None).unwrap()
        };
        assert_eq!(end, RunEnd::Completed);
        start.elapsed()
    };
    let (mut bare, mut logged) = (Duration::MAX, Duration::MAX);
    for _ in 0..rounds {
        bare = bare.min(once(false));
        logged = logged.min(once(true));
    }
    let size = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
    let _ = std::fs::remove_file(&path);
    println!(
        "paper experiment, {duration} s at 400 Hz, best of {rounds}: unlogged {:.2} ms, logged to MCAP {:.2} ms ({size} bytes): ratio {:.2}",
        bare.as_secs_f64() * 1e3,
        logged.as_secs_f64() * 1e3,
        logged.as_secs_f64() / bare.as_secs_f64()
    );
}
