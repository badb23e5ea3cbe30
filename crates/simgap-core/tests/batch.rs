//! The batch functions equal the one-state functions to 1e-12 relative, at every lane width
//! this CPU offers (8, 4, and the one-state fallback), for batch sizes that leave lanes unused.

mod common;

use nalgebra::DMatrix;
use simgap_core::batch::set_batch_lanes;
use simgap_core::{
    batch, bias_torques_into, coriolis_matrix_into, coriolis_torques_into, gravity_torques_into, inverse_dynamics_into, mass_matrix_derivative_into, mass_matrix_into, Formulation,
    Model, Workspace,
};

use common::fixtures;

/// `count` states (q, q̇, q̈), state after state, from a fixed seed.
fn states(model: &Model, count: usize, seed: u64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let mut s = seed;
    let mut next = move || {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((s >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    };
    let n = model.dof() * count;
    let q = (0..n).map(|_| 3.0 * next()).collect();
    let qd = (0..n).map(|_| 3.0 * next()).collect();
    let qdd = (0..n).map(|_| 5.0 * next()).collect();
    (q, qd, qdd)
}

/// `got` equals `want` to 1e-12 relative to the largest entry of `want`.
fn assert_close(what: &str, got: &[f64], want: &[f64]) {
    let scale = want.iter().fold(1e-300_f64, |m, x| m.max(x.abs()));
    for (k, (g, w)) in got.iter().zip(want).enumerate() {
        assert!((g - w).abs() <= 1e-12 * scale, "{what}[{k}]: batch {g}, one state {w} (scale {scale})");
    }
}

fn row_major(m: &DMatrix<f64>) -> Vec<f64> {
    m.transpose().as_slice().to_vec()
}

fn check(model: &Model, count: usize) {
    let n = model.dof();
    let (q, qd, qdd) = states(model, count, 7 + count as u64);
    let mut ws = Workspace::new(model);
    let mut m = DMatrix::zeros(n, n);
    let mut v = vec![0.0; n];
    let (mut bh, mut bc, mut bv) = (vec![0.0; count * n * n], vec![0.0; count * n * n], vec![0.0; count * n]);
    let state = |x: &[f64], k: usize| x[k * n..(k + 1) * n].to_vec();

    batch::mass_matrix_batch(model, &q, &mut bh);
    for f in Formulation::ALL {
        batch::coriolis_matrix_batch(model, &q, &qd, f, &mut bc);
        for k in 0..count {
            coriolis_matrix_into(model, &mut ws, &state(&q, k), &state(&qd, k), f, &mut m);
            assert_close(&format!("{} C {f} state {k}", model.name()), &bc[k * n * n..(k + 1) * n * n], &row_major(&m));
        }
    }
    for k in 0..count {
        mass_matrix_into(model, &mut ws, &state(&q, k), &mut m);
        assert_close(&format!("{} H state {k}", model.name()), &bh[k * n * n..(k + 1) * n * n], &row_major(&m));
    }
    batch::mass_matrix_derivative_batch(model, &q, &qd, &mut bh);
    for k in 0..count {
        mass_matrix_derivative_into(model, &mut ws, &state(&q, k), &state(&qd, k), &mut m);
        assert_close(&format!("{} Hdot state {k}", model.name()), &bh[k * n * n..(k + 1) * n * n], &row_major(&m));
    }
    batch::gravity_torques_batch(model, &q, &mut bv);
    for k in 0..count {
        gravity_torques_into(model, &mut ws, &state(&q, k), &mut v);
        assert_close(&format!("{} g state {k}", model.name()), &bv[k * n..(k + 1) * n], &v);
    }
    for f in Formulation::ALL {
        batch::coriolis_torques_batch(model, &q, &qd, f, &mut bv);
        for k in 0..count {
            coriolis_torques_into(model, &mut ws, &state(&q, k), &state(&qd, k), f, &mut v);
            assert_close(&format!("{} C qd {f} state {k}", model.name()), &bv[k * n..(k + 1) * n], &v);
        }
        batch::bias_torques_batch(model, &q, &qd, f, &mut bv);
        for k in 0..count {
            bias_torques_into(model, &mut ws, &state(&q, k), &state(&qd, k), f, &mut v);
            assert_close(&format!("{} bias {f} state {k}", model.name()), &bv[k * n..(k + 1) * n], &v);
        }
        let mut g = vec![0.0; count * n];
        batch::dynamics_terms_batch(model, &q, &qd, f, &mut bh, &mut bc, &mut g);
        for k in 0..count {
            let t = simgap_core::dynamics_terms(model, &mut ws, &state(&q, k), &state(&qd, k), f);
            assert_close("terms H", &bh[k * n * n..(k + 1) * n * n], &row_major(&t.mass_matrix));
            assert_close("terms C", &bc[k * n * n..(k + 1) * n * n], &row_major(&t.coriolis_matrix));
            assert_close("terms g", &g[k * n..(k + 1) * n], t.gravity_torques.as_slice());
        }
    }
    batch::inverse_dynamics_batch(model, &q, &qd, &qdd, &mut bv);
    for k in 0..count {
        inverse_dynamics_into(model, &mut ws, &state(&q, k), &state(&qd, k), &state(&qdd, k), &mut v);
        assert_close(&format!("{} tau state {k}", model.name()), &bv[k * n..(k + 1) * n], &v);
    }
}

#[test]
fn batch_equals_one_state_functions_at_every_lane_width() {
    // one test, so that forcing the lane width cannot race another test of this file
    let mut models: Vec<Model> = fixtures().iter().map(|(_, m)| (**m).clone()).collect();
    models.extend([2usize, 5, 9, 16, 33].iter().map(|&n| Model::random_chain(n, 100 + n as u64)));
    for lanes in [8, 4, 1] {
        set_batch_lanes(Some(lanes));
        for model in &models {
            for count in [1, 3, 8, 13] {
                check(model, count);
            }
        }
    }
    set_batch_lanes(None);
}

#[test]
#[should_panic(expected = "expected a multiple of dof")]
fn batch_rejects_a_partial_state() {
    let model = Model::paper_arm();
    batch::mass_matrix_batch(&model, &[0.0; 3], &mut [0.0; 4]);
}
