//! One criterion group per public dynamics function, id `function/robot`
//! (`mass_matrix/panda`), on the paper arm, UR5, Panda (fingers locked) and random chains of
//! 2 to 64 joints. The `_into` variants are timed (no allocation); each iteration takes the
//! next of 64 random states, passed through `black_box`.
//!
//! Also, per robot: `forward_dynamics_crba` and `forward_dynamics_aba` (the two algorithms
//! `forward_dynamics` picks from, side by side); `h_c_g_general` (three calls of the general
//! algorithms, the reference of the two-joint closed form behind `dynamics_terms/paper_arm`);
//! `forward_dynamics_armature` (rotor inertias of 0.01 on every joint: the two-joint closed form
//! with them on H's diagonal on the paper arm, the articulated-body algorithm elsewhere);
//! and the batch functions on 1000 states, `mass_matrix_batch/panda/1000` etc., beside
//! `mass_matrix_loop/panda/1000` etc. (the one-state function in a loop over the same states).
//!
//! `cargo bench --bench dynamics` (all), `cargo bench --bench dynamics -- panda` (a filter).
//! UR5 and Panda come from `example-robot-data`: see `benches/support/robots.rs`.

use std::hint::black_box;
use std::time::Duration;

use criterion::Throughput;
use criterion::{criterion_group, criterion_main, BenchmarkGroup, Criterion};
use nalgebra::DMatrix;
use simgap::core::{
    bias_torques_into, coriolis_matrix_into, coriolis_torques_into, dynamics_terms_into, forward_dynamics_aba_into, forward_dynamics_armature_into, forward_dynamics_crba_into,
    forward_dynamics_into, gravity_torques_into, inverse_dynamics_into, mass_matrix_derivative_into, mass_matrix_into, DynamicsTerms, Formulation, Model, Workspace,
};

#[path = "support/robots.rs"]
mod robots;

use robots::{all_robots, random_states, State};

const STATES: usize = 64;

/// Buffers of one robot, made once outside the timed loops.
struct Bench {
    name: String,
    model: Model,
    ws: Workspace,
    states: Vec<State>,
    matrix: DMatrix<f64>,
    vector: Vec<f64>,
    terms: DynamicsTerms,
}

/// Times `f(bench, state)` cycling through the states.
fn run<M: criterion::measurement::Measurement>(
    group: &mut BenchmarkGroup<'_, M>,
    b: &mut Bench,
    f: impl Fn(&Model, &mut Workspace, &State, &mut DMatrix<f64>, &mut [f64], &mut DynamicsTerms),
) {
    let Bench { name, model, ws, states, matrix, vector, terms } = b;
    group.bench_function(name.as_str(), |bencher| {
        let mut k = 0;
        bencher.iter(|| {
            k = (k + 1) % STATES;
            f(model, ws, black_box(&states[k]), matrix, vector, terms);
            black_box((&*matrix, &*vector, &*terms));
        })
    });
}

/// Rotor inertias [kg·m² or kg] of `forward_dynamics_armature` (the first `dof` of them).
const ROTOR_INERTIAS: [f64; 64] = [0.01; 64];

fn dynamics(c: &mut Criterion) {
    let mut benches: Vec<Bench> = all_robots(true)
        .into_iter()
        .map(|r| {
            let n = r.model.dof();
            Bench {
                states: random_states(&r.model, STATES, 7),
                ws: Workspace::new(&r.model),
                matrix: DMatrix::zeros(n, n),
                vector: vec![0.0; n],
                terms: DynamicsTerms::new(&r.model),
                model: r.model,
                name: r.name,
            }
        })
        .collect();
    type F = fn(&Model, &mut Workspace, &State, &mut DMatrix<f64>, &mut [f64], &mut DynamicsTerms);
    let functions: [(&str, F); 14] = [
        ("mass_matrix", |m, ws, s, h, _, _| mass_matrix_into(m, ws, &s.q, h)),
        ("coriolis_matrix/euler_lagrange", |m, ws, s, c, _, _| coriolis_matrix_into(m, ws, &s.q, &s.qd, Formulation::EulerLagrange, c)),
        ("coriolis_matrix/simplified", |m, ws, s, c, _, _| coriolis_matrix_into(m, ws, &s.q, &s.qd, Formulation::Simplified, c)),
        ("coriolis_torques", |m, ws, s, _, v, _| coriolis_torques_into(m, ws, &s.q, &s.qd, Formulation::EulerLagrange, v)),
        ("gravity_torques", |m, ws, s, _, v, _| gravity_torques_into(m, ws, &s.q, v)),
        ("mass_matrix_derivative", |m, ws, s, hd, _, _| mass_matrix_derivative_into(m, ws, &s.q, &s.qd, hd)),
        ("bias_torques", |m, ws, s, _, v, _| bias_torques_into(m, ws, &s.q, &s.qd, Formulation::EulerLagrange, v)),
        ("inverse_dynamics", |m, ws, s, _, v, _| inverse_dynamics_into(m, ws, &s.q, &s.qd, &s.qdd, v)),
        ("forward_dynamics", |m, ws, s, _, v, _| forward_dynamics_into(m, ws, &s.q, &s.qd, &s.tau, Formulation::EulerLagrange, v)),
        ("dynamics_terms", |m, ws, s, _, _, t| dynamics_terms_into(m, ws, &s.q, &s.qd, Formulation::EulerLagrange, t)),
        ("forward_dynamics_crba", |m, ws, s, _, v, _| forward_dynamics_crba_into(m, ws, &s.q, &s.qd, &s.tau, Formulation::EulerLagrange, v)),
        ("forward_dynamics_aba", |m, ws, s, _, v, _| forward_dynamics_aba_into(m, ws, &s.q, &s.qd, &s.tau, Formulation::EulerLagrange, v)),
        ("forward_dynamics_armature", |m, ws, s, _, v, _| {
            forward_dynamics_armature_into(m, ws, &s.q, &s.qd, &s.tau, &ROTOR_INERTIAS[..m.dof()], Formulation::EulerLagrange, v);
        }),
        ("h_c_g_general", |m, ws, s, _, _, t| {
            mass_matrix_into(m, ws, &s.q, &mut t.mass_matrix);
            coriolis_matrix_into(m, ws, &s.q, &s.qd, Formulation::EulerLagrange, &mut t.coriolis_matrix);
            gravity_torques_into(m, ws, &s.q, t.gravity_torques.as_mut_slice());
        }),
    ];
    for (function, f) in functions {
        let mut group = c.benchmark_group(function);
        group.measurement_time(Duration::from_secs(1)).warm_up_time(Duration::from_millis(300)).sample_size(20);
        for b in &mut benches {
            run(&mut group, b, f);
        }
        group.finish();
    }
}

/// States in one batch call.
const BATCH: usize = 1000;

/// The batch functions on [`BATCH`] states, and the one-state functions looped over the same
/// states, id `function/robot/1000`, throughput in states.
fn batches(c: &mut Criterion) {
    use simgap::core::batch;
    for robot in all_robots(false).into_iter().chain([robots::Robot { name: "chain16".into(), model: Model::random_chain(16, 58), source: String::new() }]) {
        let (model, n) = (&robot.model, robot.model.dof());
        let states = random_states(model, BATCH, 11);
        let q: Vec<f64> = states.iter().flat_map(|s| s.q.iter().copied()).collect();
        let qd: Vec<f64> = states.iter().flat_map(|s| s.qd.iter().copied()).collect();
        let qdd: Vec<f64> = states.iter().flat_map(|s| s.qdd.iter().copied()).collect();
        let (mut h, mut cm, mut g) = (vec![0.0; BATCH * n * n], vec![0.0; BATCH * n * n], vec![0.0; BATCH * n]);
        let mut ws = Workspace::new(model);
        let mut terms = DynamicsTerms::new(model);
        let mut m = DMatrix::zeros(n, n);
        let id = format!("{}/{BATCH}", robot.name);
        let el = Formulation::EulerLagrange;
        let mut group = |name: &str, f: &mut dyn FnMut()| {
            let mut group = c.benchmark_group(name);
            group.throughput(Throughput::Elements(BATCH as u64)).measurement_time(Duration::from_secs(1)).warm_up_time(Duration::from_millis(300)).sample_size(20);
            group.bench_function(id.as_str(), |b| b.iter(&mut *f));
            group.finish();
        };
        group("mass_matrix_batch", &mut || batch::mass_matrix_batch(model, black_box(&q), &mut h));
        group("mass_matrix_loop", &mut || {
            for s in &states {
                mass_matrix_into(model, &mut ws, black_box(&s.q), &mut m);
            }
        });
        group("dynamics_terms_batch", &mut || batch::dynamics_terms_batch(model, black_box(&q), &qd, el, &mut h, &mut cm, &mut g));
        group("dynamics_terms_loop", &mut || {
            for s in &states {
                dynamics_terms_into(model, &mut ws, black_box(&s.q), &s.qd, el, &mut terms);
            }
        });
        group("coriolis_matrix_batch", &mut || batch::coriolis_matrix_batch(model, black_box(&q), &qd, el, &mut cm));
        group("gravity_torques_batch", &mut || batch::gravity_torques_batch(model, black_box(&q), &mut g));
        group("bias_torques_batch", &mut || batch::bias_torques_batch(model, black_box(&q), &qd, el, &mut g));
        group("inverse_dynamics_batch", &mut || batch::inverse_dynamics_batch(model, black_box(&q), &qd, &qdd, &mut g));
    }
}

criterion_group!(benches, dynamics, batches);
criterion_main!(benches);
