//! A replayed run's k-step windows predicted in groups in parallel are the windows predicted in
//! one pass, to the bit: each window restarts from the log, and a replay has no controller or
//! sensor whose state runs on from one window to the next.

use std::collections::BTreeMap;

use crate::prediction::kstep::{predict, predict_split};
use crate::prepare::windows::{PredictionRun, MAX_WINDOWS_PER_RUN};
use crate::PrepareOptions;
use simgap_core::{Formulation, Model};
use simgap_sim::paper::{KP, KV, Q_DESIRED};
use simgap_sim::{simulate_experiment, ControllerKind, Effect, Experiment, Fourier, SensorParams, SimParams};

#[test]
fn a_replay_predicted_in_groups_of_windows_is_the_replay_predicted_in_one_pass() {
    let model = Model::paper_arm();
    let joints: Vec<String> = model.joint_names().iter().map(|s| s.to_string()).collect();
    let exp = Experiment { controller: ControllerKind::Pd, joints, kp: KP.to_vec(), kv: KV.to_vec(), sample_period: 0.0025, extra: BTreeMap::new() };
    let reference = Fourier {
        offset: Q_DESIRED.to_vec(),
        amplitudes: vec![vec![0.5, 0.15], vec![0.35, 0.2]],
        frequencies: vec![vec![0.6, 1.7], vec![0.9, 2.1]],
        phases: vec![vec![0.3, 1.1], vec![0.0, 2.4]],
    };
    // stiff dry friction (more substeps near rest) and a delay line restarted every window
    let effects = [Effect::CoulombFriction { fc: vec![3.0, 1.0], w: vec![0.01; 2] }, Effect::TimeDelay { delay: 0.006 }];
    let params = SimParams { duration: 12.0, sample_period: 0.0025, sensor: SensorParams { counts_per_rev: Some(1_024_000.0), ..SensorParams::default() }, ..SimParams::default() };
    let mut run = simulate_experiment(&model, Formulation::EulerLagrange, &effects, &exp, &reference, &params, None).expect("simulates");
    if let Some(e) = run.experiment.as_mut() {
        e.controller = ControllerKind::Replay;
    }
    let horizons = [0.1, 0.25, 0.5];
    let pr = PredictionRun::new(run, &horizons, PrepareOptions::default().window, SensorParams::exact(), 0, MAX_WINDOWS_PER_RUN);
    assert!(pr.windows() >= 4 * rayon::current_num_threads(), "{} windows: too few to be split", pr.windows());
    // the model predicting them lacks the delay and half the friction: windows differ
    let model_effects = [Effect::CoulombFriction { fc: vec![1.5, 0.5], w: vec![0.01; 2] }];
    let one = predict(&model, Formulation::EulerLagrange, &model_effects, &pr, &horizons, &|_| true).expect("predicts");
    let split = predict_split(&model, Formulation::EulerLagrange, &model_effects, &pr, &horizons).expect("predicts");
    assert_eq!(one.sq.len(), split.sq.len());
    let finite = one.sq.iter().filter(|v| v.is_finite() && **v > 0.0).count();
    assert!(finite > pr.windows(), "{finite} nonzero errors: nothing to compare");
    for (i, (a, b)) in one.sq.iter().zip(&split.sq).enumerate() {
        assert_eq!(a.to_bits(), b.to_bits(), "cell {i}: {a:e} in one pass, {b:e} in groups");
    }
}
