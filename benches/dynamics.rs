//! One criterion group per public dynamics function, id `function/robot`
//! (`mass_matrix/panda`), on the paper arm, UR5, Panda (fingers locked) and random chains of
//! 2 to 64 joints. The `_into` variants are timed (no allocation); each iteration takes the
//! next of 64 random states, passed through `black_box`.
//!
//! `cargo bench --bench dynamics` (all), `cargo bench --bench dynamics -- panda` (a filter).
//! UR5 and Panda come from `example-robot-data`: see `benches/support/robots.rs`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkGroup, Criterion};
use nalgebra::DMatrix;
use simgap::core::{
    bias_torques_into, coriolis_matrix_into, coriolis_torques_into, dynamics_terms_into, forward_dynamics_into, gravity_torques_into,
    inverse_dynamics_into, mass_matrix_derivative_into, mass_matrix_into, DynamicsTerms, Formulation, Model, Workspace,
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
fn run<M: criterion::measurement::Measurement>(group: &mut BenchmarkGroup<'_, M>, b: &mut Bench, f: impl Fn(&Model, &mut Workspace, &State, &mut DMatrix<f64>, &mut [f64], &mut DynamicsTerms)) {
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
    let functions: [(&str, F); 10] = [
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

criterion_group!(benches, dynamics);
criterion_main!(benches);
