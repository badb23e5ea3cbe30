//! The pieces of the reported 95 % intervals.

use crate::lsq::t_quantile_975;
use crate::select::refine::jackknife_variance;
use crate::select::uncertainty::{interval_std, method_disagreement, spread_or_bias_std, PipelineMeasure};
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
fn interval_is_the_measured_pipeline_error_plus_the_scatter_it_does_not_explain() {
    const Z: f64 = crate::lsq::Z95;
    let boot = DVector::from_vec(vec![1.0, 3.0, 2.0, 1.0, 5.0]);
    let jack = DVector::from_vec(vec![2.0, 1.0, f64::NAN, 0.5, 1.0]);
    // σ = 2, 3, 2, 1, 5; the synthetic runs scatter by σ_s; b measured again moves by δ
    let measured = PipelineMeasure {
        bias: DVector::from_vec(vec![0.0, 4.0, f64::NAN, -1.5, 2.0]),
        spread: DVector::from_vec(vec![0.0, 3.0, 1.0, 0.6, f64::NAN]),
        change: Some(DVector::from_vec(vec![0.0, 0.5, 0.0, -0.6, 0.1])),
    };
    let s = interval_std(&boot, &jack, Some(&measured));
    let want = [
        // no error, no synthetic scatter: the resampling spread
        2.0,
        // all the scatter the pipeline's own: |b| and δ only
        4.0 / Z + 0.5,
        // b unknown: the resampling spread
        2.0,
        // σ_n = sqrt(1 − 0.36) = 0.8, with δ = 0.6 in quadrature: 1.0
        1.5 / Z + 1.0,
        // σ_s unknown: |b| beyond the whole resampling spread
        2.0 / Z + 5.0,
    ];
    for (i, (got, w)) in s.iter().zip(want).enumerate() {
        assert!((got - w).abs() < 1e-12, "parameter {i}: {got} against {w}");
    }
    // δ not measured: |b| beyond the whole resampling spread
    let once = PipelineMeasure { change: None, ..measured };
    assert!((interval_std(&boot, &jack, Some(&once))[1] - (4.0 / Z + 3.0)).abs() < 1e-12);
    // no error measured: the resampling spread alone
    let s = interval_std(&boot, &jack, None);
    assert_eq!(s.as_slice(), &[2.0, 3.0, 2.0, 1.0, 5.0]);
}

#[test]
fn the_rule_before_took_the_larger_of_the_spread_and_the_pipeline_error() {
    let boot = DVector::from_vec(vec![1.0, 3.0, 2.0, 1.0]);
    let jack = DVector::from_vec(vec![2.0, 1.0, f64::NAN, 0.5]);
    let bias = DVector::from_vec(vec![0.0, 4.0, f64::NAN, -1.5]);
    assert_eq!(spread_or_bias_std(&boot, &jack, Some(&bias)).as_slice(), &[2.0, 4.0, 2.0, 1.5]);
}

#[test]
fn two_methods_disagree_by_at_most_the_torque_residual_fits_own_error_and_the_scatter() {
    // runs that follow the fitted model: the torque-residual fit's error explains the
    // disagreement, which counts whole
    assert_eq!(method_disagreement(-0.03, Some(0.025), 0.01), 0.03);
    // a real robot: the excess over that error and 1.96 σ is model mismatch, not counted
    // (C.0's Coulomb friction on its second joint: d ≈ 0.07, own σ 0.007)
    let counted = method_disagreement(0.07, Some(0.01), 0.007);
    assert!((counted - (0.01 + crate::lsq::Z95 * 0.007)).abs() < 1e-12, "{counted}");
    // unmeasured: the whole disagreement counts (wide, not understated)
    assert_eq!(method_disagreement(0.07, None, 0.007), 0.07);
    assert_eq!(method_disagreement(0.07, Some(f64::NAN), 0.007), 0.07);
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
