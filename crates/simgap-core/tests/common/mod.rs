//! Shared helpers of the integration tests: the fixture models, fixed-seed proptest
//! configuration, strategies for robots and states, and relative comparisons.

#![allow(dead_code, unreachable_pub)]

use std::path::PathBuf;
use std::sync::{Arc, OnceLock};

use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;
use proptest::test_runner::{Config, RngAlgorithm, RngSeed};
use simgap_core::{Model, UrdfOptions};

/// Path of a file under `crates/simgap-core/models/`.
pub fn model_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("models").join(name)
}

/// arm7.urdf with the chain ending at `tip`.
pub fn arm7_with_tip(tip: &str) -> Model {
    let options = UrdfOptions { tip: Some(tip.to_string()) };
    Model::from_urdf_file_with(model_path("arm7.urdf"), &options).expect("arm7.urdf loads with a tip")
}

/// The real robots every identity is checked on: the paper's arm (built in), the pendulum,
/// arm7 to its hand (7 revolute/continuous joints, fingers merged) and arm7 to its left finger
/// (8 DOF, the last one prismatic).
pub fn fixtures() -> &'static [(&'static str, Arc<Model>)] {
    static FIXTURES: OnceLock<Vec<(&'static str, Arc<Model>)>> = OnceLock::new();
    FIXTURES.get_or_init(|| {
        vec![
            ("paper_arm", Arc::new(Model::paper_arm())),
            ("pendulum", Arc::new(Model::from_urdf_file(model_path("pendulum.urdf")).expect("pendulum.urdf loads"))),
            ("arm7 to panda_hand", Arc::new(arm7_with_tip("panda_hand"))),
            ("arm7 to panda_leftfinger", Arc::new(arm7_with_tip("panda_leftfinger"))),
        ]
    })
}

/// A fixed-seed proptest configuration (ChaCha, no failure files), so every run checks the
/// same cases. For a soak run, `SIMGAP_TEST_SEED` and `SIMGAP_TEST_CASES` override the seed
/// (added to `seed`) and the number of cases.
pub fn config(cases: u32, seed: u64) -> Config {
    let env = |name: &str| std::env::var(name).ok().and_then(|v| v.parse::<u64>().ok());
    Config {
        cases: env("SIMGAP_TEST_CASES").map_or(cases, |c| c as u32),
        rng_algorithm: RngAlgorithm::ChaCha,
        rng_seed: RngSeed::Fixed(seed.wrapping_add(env("SIMGAP_TEST_SEED").unwrap_or(0))),
        failure_persistence: None,
        ..Config::default()
    }
}

/// A robot under test: one of the [`fixtures`], or a [`Model::random_chain`] of 2..=8 joints.
pub fn robot() -> impl Strategy<Value = Arc<Model>> {
    let fixture = (0..fixtures().len()).prop_map(|k| fixtures()[k].1.clone());
    let random = (2usize..=8, any::<u64>()).prop_map(|(n, seed)| Arc::new(Model::random_chain(n, seed)));
    prop_oneof![1 => fixture, 2 => random]
}

/// A robot and a state: positions in [−π, π] (revolute) or [−0.5, 0.5] m (prismatic),
/// velocities in [−3, 3], accelerations in [−5, 5].
#[derive(Clone, Debug)]
pub struct Case {
    pub model: Arc<Model>,
    pub q: Vec<f64>,
    pub qd: Vec<f64>,
    pub qdd: Vec<f64>,
}

pub fn case() -> impl Strategy<Value = Case> {
    robot().prop_flat_map(|model| {
        let n = model.dof();
        let positions: Vec<BoxedStrategy<f64>> =
            model.joints().iter().map(|j| if j.kind.is_rotational() { (-std::f64::consts::PI..std::f64::consts::PI).boxed() } else { (-0.5..0.5).boxed() }).collect();
        (Just(model), positions, prop::collection::vec(-3.0..3.0, n), prop::collection::vec(-5.0..5.0, n)).prop_map(|(model, q, qd, qdd)| Case { model, q, qd, qdd })
    })
}

/// `‖a − b‖ ≤ tol · max(scale, ‖a‖, ‖b‖)` (Frobenius norms), with a message naming `what`.
#[track_caller]
pub fn assert_close(a: &DMatrix<f64>, b: &DMatrix<f64>, tol: f64, scale: f64, what: &str) {
    assert_eq!(a.shape(), b.shape(), "{what}: shapes differ");
    let err = (a - b).norm();
    let reference = scale.max(a.norm()).max(b.norm());
    assert!(err <= tol * reference, "{what}: ‖a − b‖ = {err:e} > {tol:e} · {reference:e}\na = {a}\nb = {b}");
}

/// Vector form of [`assert_close`].
#[track_caller]
pub fn assert_close_vec(a: &DVector<f64>, b: &DVector<f64>, tol: f64, scale: f64, what: &str) {
    let (a, b) = (DMatrix::from_column_slice(a.len(), 1, a.as_slice()), DMatrix::from_column_slice(b.len(), 1, b.as_slice()));
    assert_close(&a, &b, tol, scale, what);
}

/// `v + s · w`, element-wise.
pub fn axpy(v: &[f64], s: f64, w: &[f64]) -> Vec<f64> {
    v.iter().zip(w).map(|(a, b)| a + s * b).collect()
}

/// The unit vector `e_k` of length `n`.
pub fn unit(n: usize, k: usize) -> Vec<f64> {
    let mut e = vec![0.0; n];
    e[k] = 1.0;
    e
}
