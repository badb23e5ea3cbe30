//! The pieces of the reported 95 % intervals.

use crate::lsq::t_quantile_975;
use crate::select::refine::jackknife_variance;
use crate::select::uncertainty::interval_std;
use nalgebra::DVector;

#[test]
fn student_quantile_matches_tables() {
    // two-sided 95 % points of Student's t (any statistics table)
    for (nu, t) in [(1, 12.706), (2, 4.303), (3, 3.182), (4, 2.776), (9, 2.262), (14, 2.145), (29, 2.045), (100, 1.984)] {
        let got = t_quantile_975(nu);
        assert!((got - t).abs() <= 0.002 * t, "t(0.975, {nu}) = {got}, table {t}");
    }
    assert!(t_quantile_975(0).is_infinite());
}

#[test]
fn interval_takes_the_pipeline_error_where_it_exceeds_the_larger_resampling_spread() {
    let boot = DVector::from_vec(vec![1.0, 3.0, 2.0, 1.0]);
    let jack = DVector::from_vec(vec![2.0, 1.0, f64::NAN, 0.5]);
    let bias = DVector::from_vec(vec![0.0, 4.0, f64::NAN, -1.5]);
    let s = interval_std(&boot, &jack, Some(&bias));
    // the pipeline error (of either sign) where it shows beyond the scatter, else the scatter:
    // one synthetic refit carries a scatter of about σ itself, so |b| ≤ σ is no shared error
    assert_eq!(s.as_slice(), &[2.0, 4.0, 2.0, 1.5]);
    let boot = DVector::from_vec(vec![1.0, 3.0, 2.0]);
    let jack = DVector::from_vec(vec![2.0, 1.0, f64::NAN]);
    // no bias known: the resampling spread alone
    let s = interval_std(&boot, &jack, None);
    assert_eq!(s.as_slice(), &[2.0, 3.0, 2.0]);
}

#[test]
fn jackknife_variance_of_the_mean_is_the_sample_variance_over_n() {
    // for the mean, θ₍ᵢ₎ − θ̄ = (x̄ − xᵢ)/(n − 1), so (n − 1)/n Σ (θ₍ᵢ₎ − θ̄)² = s²/n exactly
    let x = [0.3, -1.2, 2.5, 0.9, 4.1, -0.7];
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let s2 = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    // two parameters: the mean of x and of 3x (its variance 9 times)
    let answers: Vec<DVector<f64>> = (0..x.len())
        .map(|out| {
            let m = x.iter().enumerate().filter(|(i, _)| *i != out).map(|(_, v)| v).sum::<f64>() / (n - 1.0);
            DVector::from_vec(vec![m, 3.0 * m])
        })
        .collect();
    let v = jackknife_variance(&answers);
    assert!((v[0] - s2 / n).abs() < 1e-12 * s2, "{} vs {}", v[0], s2 / n);
    assert!((v[1] - 9.0 * s2 / n).abs() < 1e-12 * s2, "{} vs {}", v[1], 9.0 * s2 / n);
    // one answer has no spread to measure
    assert_eq!(jackknife_variance(&answers[..1]), vec![0.0, 0.0]);
    assert!(jackknife_variance(&[]).is_empty());
}

/// The synthetic runs of an open-loop replay stay near its logged motion, and the torque they
/// record is the torque they applied: replayed open loop with the same effects, a synthetic run
/// reproduces its own positions.
#[test]
fn a_tracked_replay_stays_near_its_log_and_records_the_torque_it_applied() {
    use crate::check::bench::{gains_for, generate, random_fourier, RefSpec, RunSpec};
    use crate::prediction::resim::{resimulate, resimulate_tracked};
    use simgap_core::{Formulation, Model, UrdfOptions};
    use simgap_sim::{l2_between, ControllerKind, Effect, RunEnd};

    let model = Model::from_urdf_str_with(simgap_core::ARM7_URDF, "arm7.urdf", &UrdfOptions { tip: Some("panda_hand".into()) }).unwrap();
    let n = model.dof();
    let (kp, kv) = gains_for(&model, 2.0);
    let mut rng = <rand_chacha::ChaCha8Rng as rand::SeedableRng>::seed_from_u64(3);
    let spec = RunSpec { name: "log".into(), controller: ControllerKind::PdGravity, kp, kv, reference: RefSpec::Fourier(random_fourier(n, 0.5, &mut rng)), duration: 8.0 };
    let truth = vec![Effect::ViscousFriction { b: vec![0.6, 0.6, 0.5, 0.5, 0.2, 0.2, 0.1] }];
    let mut log = generate(&model, Formulation::EulerLagrange, &truth, &spec, 0.005, 1_048_576.0).unwrap();
    crate::check::selfcheck::as_replay(std::slice::from_mut(&mut log));
    // the fitted effects of a diagnosis are never exactly the truth
    let fitted = vec![Effect::ViscousFriction { b: vec![0.5, 0.7, 0.45, 0.55, 0.25, 0.15, 0.12] }];
    let (open, open_end) = resimulate(&model, Formulation::EulerLagrange, &fitted, &log).unwrap();
    let (tracked, end) = resimulate_tracked(&model, Formulation::EulerLagrange, &fitted, &log).unwrap();
    assert_eq!(end, RunEnd::Completed);
    let drift = if open_end == RunEnd::Completed { l2_between(&log, &open, None).unwrap().overall } else { f64::INFINITY };
    let near = l2_between(&log, &tracked, None).unwrap().overall;
    assert!(near < 0.2 * drift, "tracked L² {near} rad against open-loop {drift} rad");
    // labelled as the log was, and its torque replayed open loop is its own motion
    assert_eq!(tracked.experiment.as_ref().map(|e| e.controller), Some(ControllerKind::Replay));
    let (again, again_end) = resimulate(&model, Formulation::EulerLagrange, &fitted, &tracked).unwrap();
    assert_eq!(again_end, RunEnd::Completed);
    let replayed = l2_between(&tracked, &again, None).unwrap().overall;
    assert!(replayed <= 1e-9, "the recorded torque replayed open loop: L² {replayed} rad (tracking error {near} rad)");
}
