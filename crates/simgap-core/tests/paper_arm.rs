//! The seed paper's arm (Sánchez-Sánchez & Arteaga-Pérez 2012, Table 2): every printed
//! coefficient of eqs. (106)–(125) recomputed from the physical parameters, then simgap's H, g
//! and both C matrices checked against the paper's closed forms at random states.
//!
//! Finding (a result, not a tolerance problem): the paper's Euler–Lagrange C, eqs. (110)–(113),
//!
//! ```text
//! c11 = −2h s q̇2,   c12 = −h s q̇2,   c21 = h s q̇1,   c22 = 0     (h = m2 l1 lc2, s = sin q2)
//! ```
//!
//! is a valid factorisation of the Coriolis/centrifugal torque (its C q̇ is the true torque) but
//! it is *not* the Christoffel-symbol matrix that simgap's Euler–Lagrange C is defined to be:
//!
//! ```text
//! c11 = −h s q̇2,    c12 = −h s (q̇1 + q̇2),   c21 = h s q̇1,   c22 = 0
//! ```
//!
//! The difference N = C_simgap − C_paper = h s [[q̇2, −q̇1], [0, 0]] satisfies N q̇ = 0, so both
//! give the same torque; but Ḣ − 2 C_paper = h s [[2 q̇2, q̇2], [−(2 q̇1 + q̇2), 0]] has a non-zero
//! diagonal and is not skew-symmetric, so the paper's matrix lacks the passivity property that
//! the Christoffel choice guarantees. The simplified C = Ḣ/2 of eqs. (120)–(123) is reproduced
//! exactly.

mod common;

use common::config;
use nalgebra::{DMatrix, DVector, Matrix2, Vector2};
use proptest::prelude::*;
use simgap_core::robots::paper_arm::*;
use simgap_core::*;

/// Tolerance of the printed coefficients (printed to 10 significant digits or more).
const PRINTED: f64 = 1e-9;

/// Coefficients of the closed forms, from Table 2.
struct Coefficients {
    /// h11 = a + b cos q2.
    a: f64,
    b: f64,
    /// h12 = h21 = d + h cos q2; h22 = d.
    d: f64,
    /// m2 l1 lc2: the Coriolis coefficient.
    h: f64,
    /// g1 = g_a sin q1 + g_b sin(q1 + q2); g2 = g_b sin(q1 + q2).
    g_a: f64,
    g_b: f64,
}

fn coefficients() -> Coefficients {
    Coefficients {
        a: M1 * LC1 * LC1 + M2 * (L1 * L1 + LC2 * LC2) + I1 + I2,
        b: 2.0 * M2 * L1 * LC2,
        d: M2 * LC2 * LC2 + I2,
        h: M2 * L1 * LC2,
        g_a: (M1 * LC1 + M2 * L1) * G,
        g_b: M2 * LC2 * G,
    }
}

#[track_caller]
fn assert_printed(computed: f64, printed: f64, what: &str) {
    assert!((computed - printed).abs() <= PRINTED, "{what}: recomputed {computed:.12}, printed {printed:.12}");
}

#[test]
fn printed_coefficients_of_eqs_106_to_125_follow_from_table_2() {
    let k = coefficients();
    // Euler–Lagrange model, eqs. (106)–(115)
    assert_printed(k.a, 2.3515719820, "(106) h11 constant: m1 lc1² + m2 (l1² + lc2²) + I1 + I2");
    assert_printed(k.b, 0.167616000, "(106) h11 cos q2: 2 m2 l1 lc2");
    assert_printed(k.d, 0.1019395200, "(107), (108) h12 = h21 constant: m2 lc2² + I2");
    assert_printed(k.h, 0.083808000, "(107), (108) h12 = h21 cos q2: m2 l1 lc2");
    assert_printed(k.d, 0.1019395200, "(109) h22: m2 lc2² + I2");
    assert_printed(2.0 * k.h, 0.167616000, "(110) c11: −2 m2 l1 lc2 sin q2 q̇2");
    assert_printed(k.h, 0.083808000, "(111) c12: −m2 l1 lc2 sin q2 q̇2");
    assert_printed(k.h, 0.083808000, "(112) c21: m2 l1 lc2 sin q2 q̇1");
    assert_printed(k.g_a, 38.46581442, "(114) g1 sin q1: (m1 lc1 + m2 l1) g");
    assert_printed(k.g_b, 1.827014400, "(114), (115) sin(q1 + q2): m2 lc2 g");
    // simplified model, eqs. (116)–(125): same H and g, C = Ḣ/2
    assert_printed(k.a, 2.3515719820, "(116) h11 constant");
    assert_printed(k.b, 0.167616000, "(116) h11 cos q2");
    assert_printed(k.d, 0.1019395200, "(117)–(119) h12, h21 constant, h22");
    assert_printed(k.h, 0.083808000, "(117), (118) h12, h21 cos q2");
    assert_printed(k.b / 2.0, 0.08380800000, "(120) c11 = ½ ḣ11: −½ · 2 m2 l1 lc2 sin q2 q̇2");
    assert_printed(k.h / 2.0, 0.04190400000, "(121), (122) c12 = c21 = ½ ḣ12: −½ m2 l1 lc2 sin q2 q̇2");
    assert_printed(k.g_a, 38.46581442, "(124) g1 sin q1");
    assert_printed(k.g_b, 1.827014400, "(124), (125) sin(q1 + q2)");
}

/// H(q), eqs. (106)–(109) = (116)–(119).
fn paper_h(q: &[f64]) -> Matrix2<f64> {
    let k = coefficients();
    let c2 = q[1].cos();
    Matrix2::new(k.a + k.b * c2, k.d + k.h * c2, k.d + k.h * c2, k.d)
}

/// g(q), eqs. (114)–(115) = (124)–(125).
fn paper_g(q: &[f64]) -> Vector2<f64> {
    let k = coefficients();
    let s12 = (q[0] + q[1]).sin();
    Vector2::new(k.g_a * q[0].sin() + k.g_b * s12, k.g_b * s12)
}

/// The paper's Euler–Lagrange C, eqs. (110)–(113).
fn paper_c_euler_lagrange(q: &[f64], qd: &[f64]) -> Matrix2<f64> {
    let (h, s) = (coefficients().h, q[1].sin());
    Matrix2::new(-2.0 * h * s * qd[1], -h * s * qd[1], h * s * qd[0], 0.0)
}

/// The Christoffel-symbol C of the same H (what simgap's Euler–Lagrange C is defined to be).
fn christoffel_c(q: &[f64], qd: &[f64]) -> Matrix2<f64> {
    let (h, s) = (coefficients().h, q[1].sin());
    Matrix2::new(-h * s * qd[1], -h * s * (qd[0] + qd[1]), h * s * qd[0], 0.0)
}

/// The paper's simplified C, eqs. (120)–(123).
fn paper_c_simplified(q: &[f64], qd: &[f64]) -> Matrix2<f64> {
    let (h, s) = (coefficients().h, q[1].sin());
    Matrix2::new(-h * s * qd[1], -0.5 * h * s * qd[1], -0.5 * h * s * qd[1], 0.0)
}

/// Ḣ of the closed-form H.
fn paper_hdot(q: &[f64], qd: &[f64]) -> Matrix2<f64> {
    let (h, s) = (coefficients().h, q[1].sin());
    Matrix2::new(-2.0 * h * s * qd[1], -h * s * qd[1], -h * s * qd[1], 0.0)
}

fn m2(m: &DMatrix<f64>) -> Matrix2<f64> {
    Matrix2::new(m[(0, 0)], m[(0, 1)], m[(1, 0)], m[(1, 1)])
}

fn v2(v: &DVector<f64>) -> Vector2<f64> {
    Vector2::new(v[0], v[1])
}

#[track_caller]
fn assert_mat(a: &Matrix2<f64>, b: &Matrix2<f64>, what: &str) {
    assert!((a - b).norm() <= 1e-9 * (1.0 + b.norm()), "{what}: simgap {a} closed form {b}");
}

fn states() -> impl Strategy<Value = ([f64; 2], [f64; 2])> {
    let pi = std::f64::consts::PI;
    ([-pi..pi, -pi..pi], [-4.0..4.0, -4.0..4.0])
}

proptest! {
    #![proptest_config(config(64, 0x5167_0002))]

    #[test]
    fn mass_matrix_equals_eqs_106_to_109((q, _qd) in states()) {
        for model in [Model::paper_arm(), Model::from_urdf_str(PAPER_ARM_URDF).unwrap()] {
            let mut ws = Workspace::new(&model);
            assert_mat(&m2(&mass_matrix(&model, &mut ws, &q)), &paper_h(&q), "H");
        }
    }

    #[test]
    fn gravity_torques_equal_eqs_114_115((q, _qd) in states()) {
        for model in [Model::paper_arm(), Model::from_urdf_str(PAPER_ARM_URDF).unwrap()] {
            let mut ws = Workspace::new(&model);
            let g = v2(&gravity_torques(&model, &mut ws, &q));
            let expected = paper_g(&q);
            prop_assert!((g - expected).norm() <= 1e-9 * (1.0 + expected.norm()), "g: simgap {g} paper {expected}");
        }
    }

    #[test]
    fn simplified_coriolis_matrix_equals_eqs_120_to_123((q, qd) in states()) {
        let model = Model::paper_arm();
        let mut ws = Workspace::new(&model);
        let c = m2(&coriolis_matrix(&model, &mut ws, &q, &qd, Formulation::Simplified));
        assert_mat(&c, &paper_c_simplified(&q, &qd), "simplified C vs (120)–(123)");
        let hdot = m2(&mass_matrix_derivative(&model, &mut ws, &q, &qd));
        assert_mat(&hdot, &paper_hdot(&q, &qd), "Ḣ vs d/dt of (106)–(109)");
    }

    #[test]
    fn euler_lagrange_coriolis_matrix_is_christoffel_and_torque_equals_eqs_110_to_113((q, qd) in states()) {
        let model = Model::paper_arm();
        let mut ws = Workspace::new(&model);
        let c = m2(&coriolis_matrix(&model, &mut ws, &q, &qd, Formulation::EulerLagrange));
        let qd_v = Vector2::new(qd[0], qd[1]);
        // simgap's C is the Christoffel matrix, exactly
        assert_mat(&c, &christoffel_c(&q, &qd), "EL C vs Christoffel closed form");
        // its torque is the paper's (110)–(113) times q̇, and the true torque of inverse dynamics
        let paper = paper_c_euler_lagrange(&q, &qd);
        let torque = c * qd_v;
        prop_assert!((torque - paper * qd_v).norm() <= 1e-9 * (1.0 + (paper * qd_v).norm()), "C q̇ {torque} vs paper C q̇ {}", paper * qd_v);
        let ct = v2(&coriolis_torques(&model, &mut ws, &q, &qd, Formulation::EulerLagrange));
        prop_assert!((ct - paper * qd_v).norm() <= 1e-9 * (1.0 + ct.norm()));
        // the difference N = C_simgap − C_paper is h s [[q̇2, −q̇1], [0, 0]], with N q̇ = 0
        let (h, s) = (coefficients().h, q[1].sin());
        let n = c - paper;
        assert_mat(&n, &Matrix2::new(h * s * qd[1], -h * s * qd[0], 0.0, 0.0), "C_simgap − C_paper");
        prop_assert!((n * qd_v).norm() <= 1e-9 * (1.0 + n.norm() * qd_v.norm()));
        // Ḣ − 2C is skew-symmetric for simgap's C but not for the paper's
        let hdot = paper_hdot(&q, &qd);
        let skew = hdot - 2.0 * c;
        prop_assert!((skew + skew.transpose()).norm() <= 1e-9 * (1.0 + hdot.norm()));
        let not_skew = hdot - 2.0 * paper;
        assert_mat(&(not_skew + not_skew.transpose()), &(2.0 * h * s * Matrix2::new(2.0 * qd[1], -qd[0], -qd[0], 0.0)), "paper's (Ḣ − 2C) + (Ḣ − 2C)ᵀ");
    }

    #[test]
    fn simplified_torque_differs_from_true_torque_by_the_skew_part((q, qd) in states()) {
        // the true torque C_EL q̇ and the simplified ½ Ḣ q̇ in closed form
        let model = Model::paper_arm();
        let mut ws = Workspace::new(&model);
        let qd_v = Vector2::new(qd[0], qd[1]);
        let true_torque = v2(&coriolis_torques(&model, &mut ws, &q, &qd, Formulation::EulerLagrange));
        let simplified = v2(&coriolis_torques(&model, &mut ws, &q, &qd, Formulation::Simplified));
        let (h, s) = (coefficients().h, q[1].sin());
        // true: (−h s (2 q̇1 q̇2 + q̇2²), h s q̇1²); simplified ½Ḣq̇: (−h s (q̇1 q̇2 + ½ q̇2²), −½ h s q̇1 q̇2)
        let expected_true = Vector2::new(-h * s * (2.0 * qd[0] * qd[1] + qd[1] * qd[1]), h * s * qd[0] * qd[0]);
        let expected_simplified = Vector2::new(-h * s * (qd[0] * qd[1] + 0.5 * qd[1] * qd[1]), -0.5 * h * s * qd[0] * qd[1]);
        prop_assert!((true_torque - expected_true).norm() <= 1e-9 * (1.0 + expected_true.norm()));
        prop_assert!((simplified - expected_simplified).norm() <= 1e-9 * (1.0 + expected_simplified.norm()));
        prop_assert!((simplified - paper_c_simplified(&q, &qd) * qd_v).norm() <= 1e-9 * (1.0 + simplified.norm()));
    }
}

#[test]
fn paper_matrix_is_not_skew_at_a_specific_state() {
    // a concrete witness of the finding: q2 = π/2, q̇ = (1, 1)
    let (q, qd) = ([0.0, std::f64::consts::FRAC_PI_2], [1.0, 1.0]);
    let n = paper_hdot(&q, &qd) - 2.0 * paper_c_euler_lagrange(&q, &qd);
    let h = coefficients().h;
    assert!((n[(0, 0)] - 2.0 * h).abs() < 1e-15, "(Ḣ − 2C_paper)_11 = {} ≠ 0", n[(0, 0)]);
    let model = Model::paper_arm();
    let mut ws = Workspace::new(&model);
    let c = m2(&coriolis_matrix(&model, &mut ws, &q, &qd, Formulation::EulerLagrange));
    let n = m2(&mass_matrix_derivative(&model, &mut ws, &q, &qd)) - 2.0 * c;
    assert!(n[(0, 0)].abs() < 1e-12 && n[(1, 1)].abs() < 1e-12 && (n[(0, 1)] + n[(1, 0)]).abs() < 1e-12, "simgap: {n}");
}
