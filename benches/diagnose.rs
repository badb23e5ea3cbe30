//! Diagnosis benchmarks on the demo's bench robot (the paper's arm with its published friction
//! and the elbow's 15 N·m limit hidden; three 4 s fit runs and one 8 s held-out run, seed 1,
//! 2.5 ms, 1,024,000 counts/rev), all on **one thread** (a one-thread rayon pool), id
//! `what/robot`:
//! - `diagnose/paper_arm_demo`: the whole diagnosis `simgap demo` runs, logs in memory;
//! - `kstep_predict/paper_arm_demo`: k-step prediction of every window of the held-out run,
//!   nominal and with the hidden effects (horizons 0.1, 0.25, 0.5 s; `simgap_diag::predict`):
//!   the unit of work the cross-validated scoring repeats per candidate set and fold.
//!
//! `cargo bench --bench diagnose` (a diagnosis takes about a second: criterion's ten samples
//! take a minute or two).

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use simgap::core::{Formulation, Model};
use simgap::diag::bench::{demo_effects, demo_specs, generate};
use simgap::diag::{diagnose, predict, DiagnoseOptions, PrepareOptions};
use simgap::sim::Run;

/// The demo's fit and held-out runs (seed 1).
fn demo_runs(model: &Model) -> (Vec<Run>, Vec<Run>) {
    let hidden = demo_effects();
    let (fit, hold) = demo_specs(1);
    let gen = |s| generate(model, Formulation::EulerLagrange, &hidden, s, 0.0025, 1_024_000.0).expect("the demo's runs simulate");
    (fit.iter().map(gen).collect(), hold.iter().map(gen).collect())
}

fn diagnosis(c: &mut Criterion) {
    let model = Model::paper_arm();
    let (fit, hold) = demo_runs(&model);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("a one-thread pool");
    let mut group = c.benchmark_group("diagnose");
    group.sample_size(10).measurement_time(Duration::from_secs(20));
    group.bench_function("paper_arm_demo", |b| {
        b.iter(|| pool.install(|| diagnose(black_box(&model), Formulation::EulerLagrange, &fit, &hold, &DiagnoseOptions::default(), &mut |_| {}).expect("diagnoses")))
    });
    group.finish();
}

fn kstep(c: &mut Criterion) {
    let model = Model::paper_arm();
    let (_, hold) = demo_runs(&model);
    let hidden = demo_effects();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("a one-thread pool");
    let mut group = c.benchmark_group("kstep_predict");
    group.sample_size(20).measurement_time(Duration::from_secs(10));
    group.bench_function("paper_arm_demo", |b| {
        b.iter(|| pool.install(|| predict(black_box(&model), Formulation::EulerLagrange, &hidden, &hold, &[0.1, 0.25, 0.5], PrepareOptions::default().window).expect("predicts")))
    });
    group.finish();
}

criterion_group!(benches, diagnosis, kstep);
criterion_main!(benches);
