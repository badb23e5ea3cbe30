//! The identities of H(q) q̈ + C(q, q̇) q̇ + g(q) = τ (see the crate root), checked over random
//! states on the fixture robots and on random serial chains of 2..=8 joints (mixed revolute,
//! continuous and prismatic, rotated placements), with fixed proptest seeds.
//!
//! Tolerances: relative 1e-9 for exact identities, 1e-6 for central finite differences.

mod common;

use common::{assert_close, assert_close_vec, axpy, case, config, unit, Case};
use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;
use simgap_core::*;

/// Relative tolerance of identities that hold exactly in exact arithmetic.
const EXACT: f64 = 1e-9;
/// Relative tolerance of central finite differences.
const FD: f64 = 1e-6;
/// Step of central finite differences (truncation ~ε², round-off ~1e-16/ε).
const EPS: f64 = 1e-5;
/// Cases per property.
const CASES: u32 = 64;

fn c_matrix(c: &Case, ws: &mut Workspace, f: Formulation) -> DMatrix<f64> {
    coriolis_matrix(&c.model, ws, &c.q, &c.qd, f)
}

fn qd_vec(c: &Case) -> DVector<f64> {
    DVector::from_column_slice(&c.qd)
}

/// Scale of a dynamics term at this state: ‖H‖ (1 + ‖q̇‖²), for absolute floors.
fn scale(c: &Case, ws: &mut Workspace) -> f64 {
    let h = mass_matrix(&c.model, ws, &c.q);
    let v = qd_vec(c).norm();
    h.norm() * (1.0 + v * v)
}

proptest! {
    #![proptest_config(config(CASES, 0x5167_0001))]

    #[test]
    fn mass_matrix_is_symmetric_positive_definite(c in case()) {
        let mut ws = Workspace::new(&c.model);
        let h = mass_matrix(&c.model, &mut ws, &c.q);
        assert_close(&h, &h.transpose(), 0.0, 0.0, "H − Hᵀ");
        let eig = h.clone().symmetric_eigen().eigenvalues;
        let (min, max) = (eig.min(), eig.max());
        prop_assert!(min > 1e-12 * max, "eigenvalues of H: {eig}");
        prop_assert!(h.clone().cholesky().is_some());
    }

    #[test]
    fn hdot_minus_2c_is_skew_symmetric(c in case()) {
        let mut ws = Workspace::new(&c.model);
        let s = scale(&c, &mut ws);
        let hdot = mass_matrix_derivative(&c.model, &mut ws, &c.q, &c.qd);
        let n = &hdot - 2.0 * c_matrix(&c, &mut ws, Formulation::EulerLagrange);
        assert_close(&n, &(-n.transpose()), EXACT, s, "Ḣ − 2C vs −(Ḣ − 2C)ᵀ");
        // energy consistency of both formulations: q̇ᵀ (Ḣ − 2C) q̇ = 0
        for f in Formulation::ALL {
            let n = &hdot - 2.0 * c_matrix(&c, &mut ws, f);
            let qd = qd_vec(&c);
            let power = qd.dot(&(&n * &qd));
            prop_assert!(power.abs() <= EXACT * s * (1.0 + qd.norm_squared()), "{f}: q̇ᵀ(Ḣ − 2C)q̇ = {power:e}");
        }
    }

    #[test]
    fn hdot_equals_c_plus_c_transpose(c in case()) {
        let mut ws = Workspace::new(&c.model);
        let s = scale(&c, &mut ws);
        let hdot = mass_matrix_derivative(&c.model, &mut ws, &c.q, &c.qd);
        let cm = c_matrix(&c, &mut ws, Formulation::EulerLagrange);
        assert_close(&hdot, &(&cm + cm.transpose()), EXACT, s, "Ḣ vs C + Cᵀ");
    }

    #[test]
    fn coriolis_times_qd_plus_gravity_equals_inverse_dynamics_at_zero_acceleration(c in case()) {
        let mut ws = Workspace::new(&c.model);
        let s = scale(&c, &mut ws);
        let n = c.model.dof();
        let zero = vec![0.0; n];
        let id = inverse_dynamics(&c.model, &mut ws, &c.q, &c.qd, &zero);
        let g = gravity_torques(&c.model, &mut ws, &c.q);
        let s = s.max(g.norm());
        let c_el = c_matrix(&c, &mut ws, Formulation::EulerLagrange);
        let c_simple = c_matrix(&c, &mut ws, Formulation::Simplified);
        // Euler–Lagrange: the true torque
        assert_close_vec(&(&c_el * qd_vec(&c) + &g), &id, EXACT, s, "C_EL q̇ + g vs inverse dynamics(q, q̇, 0)");
        assert_close_vec(&bias_torques(&c.model, &mut ws, &c.q, &c.qd, Formulation::EulerLagrange), &id, EXACT, s, "bias_torques(EL) vs ID(q, q̇, 0)");
        // simplified: the true torque minus the dropped skew-symmetric part (C_EL − C_simpl) q̇
        let dropped = (&c_el - &c_simple) * qd_vec(&c);
        let bias = bias_torques(&c.model, &mut ws, &c.q, &c.qd, Formulation::Simplified);
        assert_close_vec(&(&c_simple * qd_vec(&c) + &g), &bias, EXACT, s, "C_simpl q̇ + g vs bias_torques(simplified)");
        assert_close_vec(&bias, &(&id - dropped), EXACT, s, "bias_torques(simplified) vs ID(q, q̇, 0) − (C_EL − C_simpl) q̇");
    }

    #[test]
    fn coriolis_torques_equal_coriolis_matrix_times_qd(c in case()) {
        let mut ws = Workspace::new(&c.model);
        let s = scale(&c, &mut ws);
        for f in Formulation::ALL {
            let ct = coriolis_torques(&c.model, &mut ws, &c.q, &c.qd, f);
            let cm = c_matrix(&c, &mut ws, f);
            assert_close_vec(&ct, &(cm * qd_vec(&c)), EXACT, s, &format!("{f}: coriolis_torques vs C q̇"));
        }
        // the simplified torque is ½ Ḣ q̇
        let hdot = mass_matrix_derivative(&c.model, &mut ws, &c.q, &c.qd);
        let ct = coriolis_torques(&c.model, &mut ws, &c.q, &c.qd, Formulation::Simplified);
        assert_close_vec(&ct, &(0.5 * hdot * qd_vec(&c)), EXACT, s, "simplified coriolis_torques vs ½ Ḣ q̇");
    }

    #[test]
    fn simplified_c_is_symmetric_and_half_hdot(c in case()) {
        let mut ws = Workspace::new(&c.model);
        let s = scale(&c, &mut ws);
        let cs = c_matrix(&c, &mut ws, Formulation::Simplified);
        let hdot = mass_matrix_derivative(&c.model, &mut ws, &c.q, &c.qd);
        assert_close(&cs, &cs.transpose(), 0.0, 0.0, "C_simpl − C_simplᵀ");
        assert_close(&cs, &(0.5 * &hdot), EXACT, s, "C_simpl vs ½ Ḣ");
        assert_close(&hdot, &hdot.transpose(), 0.0, 0.0, "Ḣ − Ḣᵀ");
    }

    #[test]
    fn hdot_equals_central_finite_difference_along_qd(c in case()) {
        let mut ws = Workspace::new(&c.model);
        let s = scale(&c, &mut ws);
        let hdot = mass_matrix_derivative(&c.model, &mut ws, &c.q, &c.qd);
        let plus = mass_matrix(&c.model, &mut ws, &axpy(&c.q, EPS, &c.qd));
        let minus = mass_matrix(&c.model, &mut ws, &axpy(&c.q, -EPS, &c.qd));
        assert_close(&hdot, &((plus - minus) / (2.0 * EPS)), FD, s, "Ḣ vs (H(q + εq̇) − H(q − εq̇)) / 2ε");
    }

    #[test]
    fn euler_lagrange_c_equals_christoffel_symbols_by_finite_differences(c in case()) {
        let mut ws = Workspace::new(&c.model);
        let s = scale(&c, &mut ws);
        let n = c.model.dof();
        // dh[k] = ∂H/∂q_k by central differences
        let dh: Vec<DMatrix<f64>> = (0..n)
            .map(|k| {
                let e = unit(n, k);
                let plus = mass_matrix(&c.model, &mut ws, &axpy(&c.q, EPS, &e));
                let minus = mass_matrix(&c.model, &mut ws, &axpy(&c.q, -EPS, &e));
                (plus - minus) / (2.0 * EPS)
            })
            .collect();
        // C_ij = Σ_k ½ (∂H_ij/∂q_k + ∂H_ik/∂q_j − ∂H_jk/∂q_i) q̇_k
        let christoffel = DMatrix::from_fn(n, n, |i, j| {
            (0..n).map(|k| 0.5 * (dh[k][(i, j)] + dh[j][(i, k)] - dh[i][(j, k)]) * c.qd[k]).sum::<f64>()
        });
        let cm = c_matrix(&c, &mut ws, Formulation::EulerLagrange);
        assert_close(&cm, &christoffel, FD, s, "C_EL vs Christoffel symbols of finite-difference ∂H/∂q");
    }

    #[test]
    fn gravity_is_gradient_of_potential_energy(c in case()) {
        let mut ws = Workspace::new(&c.model);
        let n = c.model.dof();
        let g = gravity_torques(&c.model, &mut ws, &c.q);
        let grad = DVector::from_fn(n, |k, _| {
            let e = unit(n, k);
            let plus = potential_energy(&c.model, &mut ws, &axpy(&c.q, EPS, &e));
            let minus = potential_energy(&c.model, &mut ws, &axpy(&c.q, -EPS, &e));
            (plus - minus) / (2.0 * EPS)
        });
        let s = c.model.total_mass() * c.model.gravity().norm();
        assert_close_vec(&g, &grad, FD, s, "g vs ∂U/∂q by central differences");
    }

    #[test]
    fn kinetic_energy_is_half_qd_h_qd(c in case()) {
        let mut ws = Workspace::new(&c.model);
        let h = mass_matrix(&c.model, &mut ws, &c.q);
        let qd = qd_vec(&c);
        let expected = 0.5 * qd.dot(&(&h * &qd));
        let t = kinetic_energy(&c.model, &mut ws, &c.q, &c.qd);
        prop_assert!((t - expected).abs() <= EXACT * expected.abs().max(1e-12), "T = {t}, ½ q̇ᵀHq̇ = {expected}");
        prop_assert!(t >= 0.0);
    }

    #[test]
    fn coriolis_vanishes_at_zero_velocity(c in case()) {
        let mut ws = Workspace::new(&c.model);
        let n = c.model.dof();
        let zero = vec![0.0; n];
        for f in Formulation::ALL {
            let cm = coriolis_matrix(&c.model, &mut ws, &c.q, &zero, f);
            prop_assert!(cm.iter().all(|&x| x == 0.0), "{f}: C(q, 0) = {cm}");
            let ct = coriolis_torques(&c.model, &mut ws, &c.q, &zero, f);
            prop_assert!(ct.iter().all(|&x| x == 0.0), "{f}: C(q, 0)·0 = {ct}");
        }
        let hdot = mass_matrix_derivative(&c.model, &mut ws, &c.q, &zero);
        prop_assert!(hdot.iter().all(|&x| x == 0.0), "Ḣ(q, 0) = {hdot}");
        prop_assert_eq!(kinetic_energy(&c.model, &mut ws, &c.q, &zero), 0.0);
    }

    #[test]
    fn forward_dynamics_inverts_inverse_dynamics(c in case()) {
        let mut ws = Workspace::new(&c.model);
        let n = c.model.dof();
        let h = mass_matrix(&c.model, &mut ws, &c.q);
        let g = gravity_torques(&c.model, &mut ws, &c.q);
        // Euler–Lagrange: forward_dynamics(inverse_dynamics(q̈)) = q̈
        let tau = inverse_dynamics(&c.model, &mut ws, &c.q, &c.qd, &c.qdd);
        let qdd = forward_dynamics(&c.model, &mut ws, &c.q, &c.qd, tau.as_slice(), Formulation::EulerLagrange);
        let s = tau.norm().max(scale(&c, &mut ws)).max(g.norm());
        let c_el = coriolis_matrix(&c.model, &mut ws, &c.q, &c.qd, Formulation::EulerLagrange);
        assert_close_vec(&(&h * &qdd + &c_el * qd_vec(&c) + &g), &tau, EXACT, s, "EL: H q̈ + C q̇ + g vs τ");
        let cond = {
            let eig = h.clone().symmetric_eigen().eigenvalues;
            eig.max() / eig.min()
        };
        assert_close_vec(&qdd, &DVector::from_column_slice(&c.qdd), EXACT * cond.max(1.0), 1.0, "EL: forward(inverse(q̈)) vs q̈");
        // simplified: forward dynamics uses the simplified bias, H q̈ + C_simpl q̇ + g = τ
        let tau = DVector::from_fn(n, |i, _| c.qdd[i] * 10.0);
        let qdd = forward_dynamics(&c.model, &mut ws, &c.q, &c.qd, tau.as_slice(), Formulation::Simplified);
        let c_s = coriolis_matrix(&c.model, &mut ws, &c.q, &c.qd, Formulation::Simplified);
        assert_close_vec(&(&h * &qdd + &c_s * qd_vec(&c) + &g), &tau, EXACT, s, "simplified: H q̈ + C_simpl q̇ + g vs τ");
    }

    #[test]
    fn energy_rate_equals_power_of_applied_torques(c in case()) {
        // d(T + U)/dt = q̇ᵀτ along q̈ = forward_dynamics(τ), for both formulations: the simplified
        // C is energy-consistent too, since q̇ᵀ(Ḣ − 2C)q̇ = 0 for any C with Ḣ = C + Cᵀ or 2C
        let mut ws = Workspace::new(&c.model);
        let tau: Vec<f64> = c.qdd.iter().map(|x| 10.0 * x).collect();
        let energy = |ws: &mut Workspace, q: &[f64], qd: &[f64]| kinetic_energy(&c.model, ws, q, qd) + potential_energy(&c.model, ws, q);
        for f in Formulation::ALL {
            let qdd = forward_dynamics(&c.model, &mut ws, &c.q, &c.qd, &tau, f);
            let plus = energy(&mut ws, &axpy(&c.q, EPS, &c.qd), &axpy(&c.qd, EPS, qdd.as_slice()));
            let minus = energy(&mut ws, &axpy(&c.q, -EPS, &c.qd), &axpy(&c.qd, -EPS, qdd.as_slice()));
            let rate = (plus - minus) / (2.0 * EPS);
            let power: f64 = c.qd.iter().zip(&tau).map(|(a, b)| a * b).sum();
            let s = energy(&mut ws, &c.q, &c.qd).abs() + c.model.total_mass() * 9.81 + power.abs();
            prop_assert!((rate - power).abs() <= FD * s * (1.0 + qdd.norm()), "{f}: dE/dt = {rate}, q̇ᵀτ = {power}");
        }
    }

    #[test]
    fn gravity_torques_equal_inverse_dynamics_at_rest(c in case()) {
        let mut ws = Workspace::new(&c.model);
        let zero = vec![0.0; c.model.dof()];
        let g = gravity_torques(&c.model, &mut ws, &c.q);
        let id = inverse_dynamics(&c.model, &mut ws, &c.q, &zero, &zero);
        let s = c.model.total_mass() * c.model.gravity().norm();
        assert_close_vec(&g, &id, EXACT, s, "g(q) vs inverse_dynamics(q, 0, 0)");
        for f in Formulation::ALL {
            assert_close_vec(&bias_torques(&c.model, &mut ws, &c.q, &zero, f), &g, EXACT, s, &format!("{f}: bias_torques(q, 0) vs g"));
        }
    }

    #[test]
    fn dynamics_terms_equal_separate_calls(c in case()) {
        let mut ws = Workspace::new(&c.model);
        let s = scale(&c, &mut ws);
        for f in Formulation::ALL {
            let terms = dynamics_terms(&c.model, &mut ws, &c.q, &c.qd, f);
            let h = mass_matrix(&c.model, &mut ws, &c.q);
            let cm = coriolis_matrix(&c.model, &mut ws, &c.q, &c.qd, f);
            let g = gravity_torques(&c.model, &mut ws, &c.q);
            assert_close(&terms.mass_matrix, &h, EXACT, s, &format!("{f}: terms.H vs mass_matrix"));
            assert_close(&terms.coriolis_matrix, &cm, EXACT, s, &format!("{f}: terms.C vs coriolis_matrix"));
            assert_close_vec(&terms.gravity_torques, &g, EXACT, s, &format!("{f}: terms.g vs gravity_torques"));
        }
    }

    #[test]
    fn into_variants_equal_allocating_variants(c in case()) {
        // every `_into` writes its whole output: start from NaN and from a previous result
        let (model, q, qd, qdd) = (&*c.model, &c.q[..], &c.qd[..], &c.qdd[..]);
        let n = model.dof();
        let mut ws = Workspace::new(model);
        let nan_m = || DMatrix::from_element(n, n, f64::NAN);
        let nan_v = || vec![f64::NAN; n];

        let mut out = nan_m();
        mass_matrix_into(model, &mut ws, q, &mut out);
        prop_assert_eq!(&out, &mass_matrix(model, &mut ws, q));
        let mut out = nan_m();
        mass_matrix_derivative_into(model, &mut ws, q, qd, &mut out);
        prop_assert_eq!(&out, &mass_matrix_derivative(model, &mut ws, q, qd));
        for f in Formulation::ALL {
            let mut out = nan_m();
            coriolis_matrix_into(model, &mut ws, q, qd, f, &mut out);
            prop_assert_eq!(&out, &coriolis_matrix(model, &mut ws, q, qd, f));
            // reusing a buffer filled by the other formulation
            coriolis_matrix_into(model, &mut ws, q, qd, f.other(), &mut out);
            coriolis_matrix_into(model, &mut ws, q, qd, f, &mut out);
            prop_assert_eq!(&out, &coriolis_matrix(model, &mut ws, q, qd, f));

            let mut out = nan_v();
            coriolis_torques_into(model, &mut ws, q, qd, f, &mut out);
            prop_assert_eq!(DVector::from_column_slice(&out), coriolis_torques(model, &mut ws, q, qd, f));
            let mut out = nan_v();
            bias_torques_into(model, &mut ws, q, qd, f, &mut out);
            prop_assert_eq!(DVector::from_column_slice(&out), bias_torques(model, &mut ws, q, qd, f));
            let mut out = nan_v();
            forward_dynamics_into(model, &mut ws, q, qd, qdd, f, &mut out);
            prop_assert_eq!(DVector::from_column_slice(&out), forward_dynamics(model, &mut ws, q, qd, qdd, f));

            let mut terms = DynamicsTerms { mass_matrix: nan_m(), coriolis_matrix: nan_m(), gravity_torques: DVector::from_element(n, f64::NAN) };
            dynamics_terms_into(model, &mut ws, q, qd, f, &mut terms);
            prop_assert_eq!(&terms, &dynamics_terms(model, &mut ws, q, qd, f));
        }
        let mut out = nan_v();
        gravity_torques_into(model, &mut ws, q, &mut out);
        prop_assert_eq!(DVector::from_column_slice(&out), gravity_torques(model, &mut ws, q));
        let mut out = nan_v();
        inverse_dynamics_into(model, &mut ws, q, qd, qdd, &mut out);
        prop_assert_eq!(DVector::from_column_slice(&out), inverse_dynamics(model, &mut ws, q, qd, qdd));
    }

    #[test]
    fn results_do_not_depend_on_workspace_history(c in case(), other in case()) {
        // a workspace used at another state (of the same model) gives the same results as a fresh one
        let (model, q, qd) = (&*c.model, &c.q[..], &c.qd[..]);
        let mut fresh = Workspace::new(model);
        let mut used = Workspace::new(model);
        let n = model.dof();
        let q2: Vec<f64> = (0..n).map(|i| other.q.get(i).copied().unwrap_or(0.3)).collect();
        let qd2: Vec<f64> = (0..n).map(|i| other.qd.get(i).copied().unwrap_or(-1.1)).collect();
        let _ = dynamics_terms(model, &mut used, &q2, &qd2, Formulation::EulerLagrange);
        let _ = inverse_dynamics(model, &mut used, &q2, &qd2, &qd2);
        for f in Formulation::ALL {
            prop_assert_eq!(dynamics_terms(model, &mut used, q, qd, f), dynamics_terms(model, &mut fresh, q, qd, f));
            prop_assert_eq!(bias_torques(model, &mut used, q, qd, f), bias_torques(model, &mut fresh, q, qd, f));
        }
    }
}

#[test]
fn urdf_paper_arm_equals_builtin_paper_arm() {
    let builtin = Model::paper_arm();
    let from_str = Model::from_urdf_str(PAPER_ARM_URDF).expect("PAPER_ARM_URDF loads");
    let from_file = Model::from_urdf_file(common::model_path("paper_arm.urdf")).expect("models/paper_arm.urdf loads");
    for (what, m) in [("PAPER_ARM_URDF", &from_str), ("models/paper_arm.urdf", &from_file)] {
        assert!(m.warnings().is_empty(), "{what}: {:?}", m.warnings());
        assert_eq!(m.joint_names(), builtin.joint_names(), "{what}");
        assert_eq!(m.base_link(), builtin.base_link(), "{what}");
        assert_eq!(m.gravity(), builtin.gravity(), "{what}");
        for (a, b) in m.joints().iter().zip(builtin.joints()) {
            assert_eq!((a.kind, &a.link), (b.kind, &b.link), "{what}: joint {}", a.name);
            assert!((a.axis - b.axis).norm() < 1e-15, "{what}: axis of {}", a.name);
            assert!((a.placement.rotation - b.placement.rotation).norm() < 1e-15, "{what}: placement of {}", a.name);
            assert!((a.placement.translation - b.placement.translation).norm() < 1e-15, "{what}: placement of {}", a.name);
            assert!((a.inertia.mass - b.inertia.mass).abs() < 1e-12, "{what}: mass of {}", a.link);
            assert!((a.inertia.first_moment - b.inertia.first_moment).norm() < 1e-12, "{what}: first moment of {}", a.link);
            assert!((a.inertia.rotational - b.inertia.rotational).norm() < 1e-12, "{what}: inertia of {}", a.link);
            // the URDF writes π to 15 digits
            let (la, lb) = (a.limits, b.limits);
            assert!((la.lower - lb.lower).abs() < 1e-13 && (la.upper - lb.upper).abs() < 1e-13, "{what}: limits of {}", a.name);
            assert_eq!((la.effort, la.velocity), (lb.effort, lb.velocity), "{what}: limits of {}", a.name);
        }
        // and every dynamics term at a spread of states
        let (mut wa, mut wb) = (Workspace::new(m), Workspace::new(&builtin));
        for k in 0..25 {
            let t = k as f64;
            let q = [(0.7 * t).sin() * 3.0, (1.3 * t).cos() * 3.0];
            let qd = [(0.4 * t).cos() * 2.0, (2.1 * t).sin() * 2.0];
            for f in Formulation::ALL {
                let (ta, tb) = (dynamics_terms(m, &mut wa, &q, &qd, f), dynamics_terms(&builtin, &mut wb, &q, &qd, f));
                assert_close(&ta.mass_matrix, &tb.mass_matrix, 1e-12, 1.0, what);
                assert_close(&ta.coriolis_matrix, &tb.coriolis_matrix, 1e-12, 1.0, what);
                assert_close_vec(&ta.gravity_torques, &tb.gravity_torques, 1e-12, 1.0, what);
            }
        }
    }
}

#[test]
fn random_chain_is_deterministic_and_mixed() {
    assert_eq!(Model::random_chain(6, 42), Model::random_chain(6, 42));
    assert_ne!(Model::random_chain(6, 42), Model::random_chain(6, 43));
    // over a few seeds every joint kind appears, and axes are unit vectors
    let models: Vec<Model> = (0..8).map(|s| Model::random_chain(8, s)).collect();
    for kind in [JointKind::Revolute, JointKind::Continuous, JointKind::Prismatic] {
        assert!(models.iter().flat_map(|m| m.joints()).any(|j| j.kind == kind), "no {kind:?} joint");
    }
    for j in models.iter().flat_map(|m| m.joints()) {
        assert!((j.axis.norm() - 1.0).abs() < 1e-12);
        assert!(j.inertia.mass > 0.0);
        assert!((j.placement.rotation - nalgebra::Matrix3::identity()).norm() > 1e-6, "placement of {} has no rotation", j.name);
    }
}
