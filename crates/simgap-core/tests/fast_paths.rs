//! The fast paths equal the general algorithms: the articulated-body algorithm equals CRBA +
//! Cholesky forward dynamics, the closed form of a two-joint arm equals H, C, g and q̈ of the
//! general algorithms, and that of a one-joint arm q̈, to 1e-10 relative.

mod common;

use nalgebra::{DMatrix, DVector, Vector3};
use simgap_core::{
    bias_torques, coriolis_matrix, dynamics_terms, forward_dynamics_aba_into, forward_dynamics_armature_into, forward_dynamics_crba_into, forward_dynamics_into, gravity_torques,
    mass_matrix, Formulation, JointKind, Model, Workspace,
};

use common::fixtures;

fn state(n: usize, seed: u64) -> [Vec<f64>; 3] {
    let mut s = seed;
    let mut next = move |scale: f64| {
        s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        scale * (((s >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0)
    };
    [(0..n).map(|_| next(3.0)).collect(), (0..n).map(|_| next(3.0)).collect(), (0..n).map(|_| next(20.0)).collect()]
}

fn assert_close(what: &str, got: &[f64], want: &[f64], tol: f64) {
    let scale = want.iter().fold(1e-300_f64, |m, x| m.max(x.abs()));
    for (k, (g, w)) in got.iter().zip(want).enumerate() {
        assert!((g - w).abs() <= tol * scale, "{what}[{k}]: {g} vs {w} (scale {scale})");
    }
}

#[test]
fn articulated_body_algorithm_equals_crba_cholesky_forward_dynamics() {
    let mut models: Vec<Model> = fixtures().iter().map(|(_, m)| (**m).clone()).collect();
    models.extend([1usize, 2, 3, 5, 7, 12, 16, 24, 32, 48, 64].iter().map(|&n| Model::random_chain(n, 7 * n as u64)));
    for model in &models {
        let n = model.dof();
        let mut ws = Workspace::new(model);
        let (mut aba, mut crba, mut auto) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for seed in 0..20 {
            let [q, qd, tau] = state(n, seed);
            for f in Formulation::ALL {
                forward_dynamics_aba_into(model, &mut ws, &q, &qd, &tau, f, &mut aba);
                forward_dynamics_crba_into(model, &mut ws, &q, &qd, &tau, f, &mut crba);
                forward_dynamics_into(model, &mut ws, &q, &qd, &tau, f, &mut auto);
                // long random chains have H with condition numbers near 1e6: q̈ carries that
                assert_close(&format!("{} ({n} dof) {f} aba", model.name()), &aba, &crba, 1e-10 * (n as f64).max(1.0));
                assert_close(&format!("{} ({n} dof) {f} auto", model.name()), &auto, &crba, 1e-10 * (n as f64).max(1.0));
            }
        }
    }
}

#[test]
fn rotor_inertia_in_the_pivots_equals_solving_with_h_plus_diag_armature() {
    let mut models: Vec<Model> = fixtures().iter().map(|(_, m)| (**m).clone()).collect();
    models.extend([1usize, 2, 3, 7, 16].iter().map(|&n| Model::random_chain(n, 11 * n as u64)));
    for model in &models {
        let n = model.dof();
        let mut ws = Workspace::new(model);
        let mut got = vec![0.0; n];
        for seed in 0..10 {
            let [q, qd, tau] = state(n, seed);
            let ia: Vec<f64> = (0..n).map(|j| 0.05 * (1 + (j + seed as usize) % 4) as f64).collect();
            for f in Formulation::ALL {
                // (H + diag(ia)) q̈ = τ − (C q̇ + g), solved densely
                let h = mass_matrix(model, &mut ws, &q) + DMatrix::from_diagonal(&DVector::from_column_slice(&ia));
                let rhs = DVector::from_column_slice(&tau) - bias_torques(model, &mut ws, &q, &qd, f);
                let want = h.cholesky().expect("positive definite").solve(&rhs);
                assert!(forward_dynamics_armature_into(model, &mut ws, &q, &qd, &tau, &ia, f, &mut got));
                assert_close(&format!("{} ({n} dof) {f} armature", model.name()), &got, want.as_slice(), 1e-10 * (n as f64).max(1.0));
            }
        }
        // a rotor inertia that makes H + diag(ia) indefinite is reported, not solved
        let [q, qd, tau] = state(n, 99);
        let h = mass_matrix(model, &mut ws, &q);
        let mut ia = vec![0.0; n];
        ia[n - 1] = -2.0 * h[(n - 1, n - 1)];
        assert!(!forward_dynamics_armature_into(model, &mut ws, &q, &qd, &tau, &ia, Formulation::EulerLagrange, &mut got), "{}", model.name());
    }
}

#[test]
#[should_panic(expected = "not positive definite")]
fn articulated_body_algorithm_rejects_a_singular_mass_matrix() {
    // a massless tail link: its joint carries no inertia
    let mut joints = Model::random_chain(3, 1).joints().to_vec();
    joints[2].inertia = simgap_core::SpatialInertia::ZERO;
    let model = Model::new("massless tail", "base", joints).unwrap();
    let mut out = [0.0; 3];
    forward_dynamics_aba_into(&model, &mut Workspace::new(&model), &[0.1; 3], &[0.2; 3], &[0.3; 3], Formulation::EulerLagrange, &mut out);
}

/// Two-joint arms whose joints rotate: the paper's arm, and random ones (random placements,
/// axes and inertias), with gravity along −z and along a tilted direction.
fn two_joint_arms() -> Vec<Model> {
    let mut arms = vec![Model::paper_arm()];
    let mut seed = 0;
    while arms.len() < 8 {
        seed += 1;
        let m = Model::random_chain(2, seed);
        if m.joints().iter().all(|j| j.kind != JointKind::Prismatic) {
            arms.push(m);
        }
    }
    let mut tilted = arms[3].clone();
    tilted.set_gravity(Vector3::new(1.0, -2.0, -9.0));
    arms.push(tilted);
    arms
}

fn row_major(m: &DMatrix<f64>) -> Vec<f64> {
    m.transpose().as_slice().to_vec()
}

#[test]
fn two_joint_closed_form_equals_the_general_algorithms() {
    for model in two_joint_arms() {
        let mut ws = Workspace::new(&model);
        for seed in 0..50 {
            let [q, qd, tau] = state(2, seed);
            for f in Formulation::ALL {
                let what = format!("{} {f} state {seed}", model.name());
                let t = dynamics_terms(&model, &mut ws, &q, &qd, f);
                assert_close(&format!("{what} H"), &row_major(&t.mass_matrix), &row_major(&mass_matrix(&model, &mut ws, &q)), 1e-10);
                assert_close(&format!("{what} C"), &row_major(&t.coriolis_matrix), &row_major(&coriolis_matrix(&model, &mut ws, &q, &qd, f)), 1e-10);
                assert_close(&format!("{what} g"), t.gravity_torques.as_slice(), gravity_torques(&model, &mut ws, &q).as_slice(), 1e-10);
                let (mut fast, mut general) = ([0.0; 2], [0.0; 2]);
                forward_dynamics_into(&model, &mut ws, &q, &qd, &tau, f, &mut fast);
                forward_dynamics_crba_into(&model, &mut ws, &q, &qd, &tau, f, &mut general);
                assert_close(&format!("{what} qdd"), &fast, &general, 1e-10);
            }
        }
    }
}

#[test]
fn one_joint_closed_form_equals_the_general_algorithms() {
    // turning and sliding joints (random chains of one joint draw both), gravity tilted
    let mut arms: Vec<Model> = (1..=12).map(|seed| Model::random_chain(1, seed)).collect();
    assert!(arms.iter().any(|m| m.joints()[0].kind == JointKind::Prismatic) && arms.iter().any(|m| m.joints()[0].kind != JointKind::Prismatic));
    for i in 0..arms.len() {
        let mut tilted = arms[i].clone();
        tilted.set_gravity(Vector3::new(1.0, -2.0, -9.0));
        arms.push(tilted);
    }
    for model in &arms {
        let mut ws = Workspace::new(model);
        for seed in 0..50 {
            let [q, qd, tau] = state(1, seed);
            let ia = [0.05 * (1 + seed % 4) as f64];
            for f in Formulation::ALL {
                let what = format!("{} {f} state {seed}", model.name());
                let (mut fast, mut general) = ([0.0], [0.0]);
                forward_dynamics_into(model, &mut ws, &q, &qd, &tau, f, &mut fast);
                forward_dynamics_crba_into(model, &mut ws, &q, &qd, &tau, f, &mut general);
                assert_close(&format!("{what} qdd"), &fast, &general, 1e-10);
                // with a rotor inertia: (H + ia) q̈ = τ − (C q̇ + g), solved densely
                let h = mass_matrix(model, &mut ws, &q)[(0, 0)] + ia[0];
                let want = (tau[0] - bias_torques(model, &mut ws, &q, &qd, f)[0]) / h;
                assert!(forward_dynamics_armature_into(model, &mut ws, &q, &qd, &tau, &ia, f, &mut fast));
                assert_close(&format!("{what} qdd with ia"), &fast, &[want], 1e-10);
            }
        }
    }
}

#[test]
fn two_joint_closed_form_follows_gravity_and_inertia_changes() {
    let mut model = Model::paper_arm();
    model.set_gravity(Vector3::new(0.0, 0.0, -1.62));
    let mut inertia = model.joints()[1].inertia;
    inertia.mass *= 2.0;
    inertia.first_moment *= 2.0;
    inertia.rotational *= 2.0;
    model.set_link_inertia(1, inertia).unwrap();
    let mut ws = Workspace::new(&model);
    let (q, qd) = ([0.4, -1.1], [0.7, 2.0]);
    let t = dynamics_terms(&model, &mut ws, &q, &qd, Formulation::EulerLagrange);
    assert_close("g", t.gravity_torques.as_slice(), gravity_torques(&model, &mut ws, &q).as_slice(), 1e-10);
    assert_close("H", &row_major(&t.mass_matrix), &row_major(&mass_matrix(&model, &mut ws, &q)), 1e-10);
}

#[test]
fn one_workspace_serves_two_joint_arms_of_other_parameters() {
    // the closed form lives in the workspace: meeting another arm (or the same arm changed),
    // the workspace regenerates it instead of using the first arm's
    let arms = two_joint_arms();
    let mut shared = Workspace::new(&arms[0]);
    let (q, qd, tau) = ([0.4, -1.1], [0.7, 2.0], [1.5, -0.3]);
    for round in 0..2 {
        for (k, model) in arms.iter().enumerate() {
            let what = format!("arm {k}, round {round}");
            let mut own = Workspace::new(model);
            let t = dynamics_terms(model, &mut shared, &q, &qd, Formulation::EulerLagrange);
            assert_close(&format!("{what} H"), &row_major(&t.mass_matrix), &row_major(&mass_matrix(model, &mut own, &q)), 1e-10);
            assert_close(&format!("{what} g"), t.gravity_torques.as_slice(), gravity_torques(model, &mut own, &q).as_slice(), 1e-10);
            let (mut fast, mut general) = ([0.0; 2], [0.0; 2]);
            forward_dynamics_into(model, &mut shared, &q, &qd, &tau, Formulation::Simplified, &mut fast);
            forward_dynamics_crba_into(model, &mut own, &q, &qd, &tau, Formulation::Simplified, &mut general);
            assert_close(&format!("{what} qdd"), &fast, &general, 1e-10);
        }
    }
    // a parameter changed after the workspace met the model
    let mut model = Model::paper_arm();
    let mut ws = Workspace::new(&model);
    let before = dynamics_terms(&model, &mut ws, &q, &qd, Formulation::EulerLagrange);
    model.set_gravity(Vector3::new(0.0, 0.0, -1.62));
    let after = dynamics_terms(&model, &mut ws, &q, &qd, Formulation::EulerLagrange);
    assert_close("g after set_gravity", after.gravity_torques.as_slice(), gravity_torques(&model, &mut Workspace::new(&model), &q).as_slice(), 1e-10);
    assert!((after.gravity_torques[0] - before.gravity_torques[0]).abs() > 1.0, "g did not follow the new gravity");
}

#[test]
fn a_singular_mass_matrix_is_reported_by_every_forward_dynamics_path_without_a_panic() {
    // a massless tail link: its joint moves no inertia, H is singular at every q
    for n in [1usize, 2, 3, 7] {
        let mut model = Model::random_chain(n, 5 * n as u64);
        model.set_link_inertia(n - 1, simgap_core::SpatialInertia::from_com(0.0, Vector3::zeros(), nalgebra::Matrix3::zeros())).unwrap();
        let mut ws = Workspace::new(&model);
        let mut out = vec![0.0; n];
        let [q, qd, tau] = state(n, 1);
        for f in Formulation::ALL {
            assert!(!simgap_core::try_forward_dynamics_into(&model, &mut ws, &q, &qd, &tau, f, &mut out), "{n} dof, {f}: a singular H must be reported");
        }
        // and a physical one is solved as by the panicking form
        let model = Model::random_chain(n, 5 * n as u64);
        let mut ws = Workspace::new(&model);
        let mut want = vec![0.0; n];
        assert!(simgap_core::try_forward_dynamics_into(&model, &mut ws, &q, &qd, &tau, Formulation::EulerLagrange, &mut out));
        forward_dynamics_into(&model, &mut ws, &q, &qd, &tau, Formulation::EulerLagrange, &mut want);
        assert_eq!(out, want);
    }
}
