//! Closed-loop simulation benchmarks, id `what/robot`:
//! - `simulate/paper_experiment`: the seed paper's experiment end to end (PD, 3 s at 2.5 ms =
//!   1201 samples, paper encoders, default substeps), without logging (a sink that drops
//!   samples); also `simulate/paper_experiment_memory` into a `MemorySink`,
//!   `simulate/paper_experiment_mcap` written as ROS 2 MCAP as it goes (logging cost), and
//!   `simulate/paper_experiment_friction` with the reported viscous and Coulomb friction;
//!   `simulate/paper_30s[_mcap]` and `simulate/paper_300s[_mcap]`, 30 s and 300 s unlogged and
//!   written as MCAP as they go (the 300 s ratio is the logging cost `simgap simulate --out`
//!   pays; target at most 2 on two cores), and `simulate/paper_300s_csv`, the same written as a
//!   CSV log as it goes (`simgap simulate --out RUN.csv`).
//! - `paper/euler_lagrange` and `paper/simplified`: what `simgap paper` simulates per model
//!   (2 s at 2.5 ms, RK4, paper encoders) into a `MemorySink`, plant built inside; and
//!   `paper/euler_lagrange_general`, the same run through the general algorithms (an armature
//!   of 1e-300 kg·m², which leaves H unchanged in floating point, sends the plant to bias
//!   torques + CRBA + Cholesky): the side-by-side reference of the two-joint closed form.
//! - `rk4_step/<robot>`: one RK4 step of the plant (four accelerations), throughput in steps
//!   per second, on the paper arm and a random 7-joint chain.
//! - `acceleration/<robot>`: one plant acceleration (bias torques, H, Cholesky).
//!
//! `cargo bench --bench sim`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use simgap::core::{Formulation, Model};
use simgap::log::{CsvSink, McapSink};
use simgap::sim::integrate::Rk4;
use simgap::sim::paper;
use simgap::sim::{simulate, Effect, Experiment, MemorySink, Plant, RunEnd, Sample, SimParams, Sink};

/// A sink that drops every sample.
struct NullSink;

impl Sink for NullSink {
    fn begin(&mut self, _: &[String], _: &Experiment) -> simgap::sim::Result<()> {
        Ok(())
    }
    fn record(&mut self, s: &Sample<'_>) -> simgap::sim::Result<()> {
        black_box(s.q[0]);
        Ok(())
    }
    fn finish(&mut self, _: &RunEnd) -> simgap::sim::Result<()> {
        Ok(())
    }
}

fn paper_experiment(c: &mut Criterion) {
    let model = Model::paper_arm();
    let reference = paper::reference();
    let params = SimParams::default();
    let mut group = c.benchmark_group("simulate");
    group.measurement_time(Duration::from_secs(5));
    let friction = [Effect::ViscousFriction { b: vec![2.288, 0.175] }, Effect::CoulombFriction { fc: vec![7.17, 1.734], w: vec![0.01; 2] }];
    for (id, effects) in [("paper_experiment", &[][..]), ("paper_experiment_friction", &friction[..])] {
        group.bench_function(id, |b| {
            b.iter(|| {
                // the plant is built inside: the diagnosis builds one per candidate
                let plant = Plant::new(black_box(&model), Formulation::EulerLagrange, effects).unwrap();
                let mut pd = paper::controller();
                simulate(&plant, &mut pd, &reference, &params, &mut NullSink, None).unwrap()
            })
        });
    }
    group.bench_function("paper_experiment_memory", |b| {
        b.iter(|| {
            let plant = Plant::new(black_box(&model), Formulation::EulerLagrange, &[]).unwrap();
            let mut pd = paper::controller();
            let mut sink = MemorySink::new();
            simulate(&plant, &mut pd, &reference, &params, &mut sink, None).unwrap();
            sink.into_run()
        })
    });
    // the cost of writing the run as ROS 2 MCAP (zstd chunks) as it goes, at 400 Hz
    let dir = std::env::temp_dir().join(format!("simgap-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("paper.mcap");
    group.bench_function("paper_experiment_mcap", |b| {
        b.iter(|| {
            let plant = Plant::new(black_box(&model), Formulation::EulerLagrange, &[]).unwrap();
            let mut pd = paper::controller();
            let mut sink = McapSink::create(&path).unwrap();
            simulate(&plant, &mut pd, &reference, &params, &mut sink, None).unwrap()
        })
    });
    // the same over 30 s (12001 samples), so the per-file cost (create, summary) is amortised
    let long = SimParams { duration: 30.0, ..params.clone() };
    group.sample_size(10);
    group.bench_function("paper_30s", |b| {
        b.iter(|| {
            let plant = Plant::new(black_box(&model), Formulation::EulerLagrange, &[]).unwrap();
            let mut pd = paper::controller();
            simulate(&plant, &mut pd, &reference, &long, &mut NullSink, None).unwrap()
        })
    });
    group.bench_function("paper_30s_mcap", |b| {
        b.iter(|| {
            let plant = Plant::new(black_box(&model), Formulation::EulerLagrange, &[]).unwrap();
            let mut pd = paper::controller();
            let mut sink = McapSink::create(&path).unwrap();
            simulate(&plant, &mut pd, &reference, &long, &mut sink, None).unwrap()
        })
    });
    // the logging cost as `simgap simulate --duration 300 --out RUN.mcap` pays it (120,001
    // samples, 38.7 MB of records in 3 MB of zstd chunks and 3.8 MB of message indexes): target
    // logged / unlogged <= 2 on two cores (the writer thread encodes and compresses on the
    // second)
    let day_part = SimParams { duration: 300.0, ..params.clone() };
    group.bench_function("paper_300s", |b| {
        b.iter(|| {
            let plant = Plant::new(black_box(&model), Formulation::EulerLagrange, &[]).unwrap();
            let mut pd = paper::controller();
            simulate(&plant, &mut pd, &reference, &day_part, &mut NullSink, None).unwrap()
        })
    });
    group.bench_function("paper_300s_mcap", |b| {
        b.iter(|| {
            let plant = Plant::new(black_box(&model), Formulation::EulerLagrange, &[]).unwrap();
            let mut pd = paper::controller();
            let mut sink = McapSink::create(&path).unwrap();
            simulate(&plant, &mut pd, &reference, &day_part, &mut sink, None).unwrap()
        })
    });
    // the same written as CSV as it goes (the writer thread formats the numbers)
    let csv = dir.join("paper.csv");
    group.bench_function("paper_300s_csv", |b| {
        b.iter(|| {
            let plant = Plant::new(black_box(&model), Formulation::EulerLagrange, &[]).unwrap();
            let mut pd = paper::controller();
            let mut sink = CsvSink::create(&csv).unwrap();
            simulate(&plant, &mut pd, &reference, &day_part, &mut sink, None).unwrap()
        })
    });
    let _ = std::fs::remove_dir_all(&dir);
    group.finish();
}

/// The paper's experiment as `simgap paper` runs it, per formulation, 2 s.
fn paper(c: &mut Criterion) {
    let model = Model::paper_arm();
    let reference = paper::reference();
    let params = SimParams { duration: 2.0, sample_period: paper::SAMPLE_PERIOD, ..SimParams::default() };
    let mut group = c.benchmark_group("paper");
    group.measurement_time(Duration::from_secs(3));
    let general = [Effect::Armature { ia: vec![1e-300; 2] }];
    for (id, formulation, effects) in [
        ("euler_lagrange", Formulation::EulerLagrange, &[][..]),
        ("simplified", Formulation::Simplified, &[][..]),
        ("euler_lagrange_general", Formulation::EulerLagrange, &general[..]),
    ] {
        group.bench_function(id, |b| {
            b.iter(|| {
                let plant = Plant::new(black_box(&model), formulation, effects).unwrap();
                let mut pd = paper::controller();
                let mut sink = MemorySink::new();
                simulate(&plant, &mut pd, &reference, &params, &mut sink, None).unwrap();
                sink.into_run()
            })
        });
    }
    group.finish();
}

fn steps(c: &mut Criterion) {
    let robots = [("paper_arm", Model::paper_arm()), ("chain7", Model::random_chain(7, 1))];
    for (name, model) in &robots {
        let n = model.dof();
        let plant = Plant::new(model, Formulation::EulerLagrange, &[]).unwrap();
        let mut pws = plant.workspace();
        let tau = vec![0.1; n];
        let mut y: Vec<f64> = (0..2 * n).map(|i| 0.1 * (i as f64 + 1.0).sin()).collect();
        let y0 = y.clone();
        let mut rk4 = Rk4::new(2 * n);
        let mut group = c.benchmark_group("rk4_step");
        group.throughput(Throughput::Elements(1));
        group.bench_function(*name, |b| {
            b.iter(|| {
                let mut f = |_t: f64, y: &[f64], dy: &mut [f64]| {
                    let (q, qd) = y.split_at(n);
                    let (dq, ddq) = dy.split_at_mut(n);
                    dq.copy_from_slice(qd);
                    plant.acceleration(&mut pws, q, qd, &tau, ddq);
                };
                y.copy_from_slice(&y0);
                rk4.step(&mut f, 0.0, black_box(1e-3), &mut y);
                black_box(y[0])
            })
        });
        group.finish();
        let mut group = c.benchmark_group("acceleration");
        let mut out = vec![0.0; n];
        group.bench_function(*name, |b| {
            b.iter(|| {
                plant.acceleration(&mut pws, black_box(&y0[..n]), black_box(&y0[n..]), &tau, &mut out);
                black_box(out[0])
            })
        });
        group.finish();
    }
}

criterion_group!(benches, paper_experiment, paper, steps);
criterion_main!(benches);
