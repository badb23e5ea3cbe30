//! The actuation delay is written once (`simgap_sim::DelayLine`): the simulator, the torque
//! fit (`FitData::delayed_torque`) and the k-step prediction form the same delayed command,
//! to the last bit, at exact multiples of the sample period and in between.

use std::collections::BTreeMap;

use crate::prediction::kstep::predict;
use crate::prepare::windows::PredictionRun;
use crate::{FitData, PrepareOptions};
use simgap_core::{Formulation, Model};
use simgap_sim::paper::{KP, KV, Q_DESIRED};
use simgap_sim::{simulate_experiment, ControllerKind, Effect, Experiment, Fourier, Run, SensorParams, SimParams, Step};

const PERIOD: f64 = 0.0025;

/// Delays [s]: none, exact multiples of the period written as decimals (0.0175 / 0.0025 is
/// 7.000000000000001 in floating point), and fractions of a sample.
const DELAYS: [f64; 6] = [0.0, 0.0025, 0.0075, 0.0175, 0.0035, 0.00625];

fn joints(model: &Model) -> Vec<String> {
    model.joint_names().iter().map(|s| s.to_string()).collect()
}

/// The paper arm under PD control toward a moving reference, with an actuation delay, exact
/// sensors, 1.5 s at 2.5 ms.
fn delayed_pd_run(model: &Model, delay: f64) -> Run {
    let exp = Experiment { controller: ControllerKind::Pd, joints: joints(model), kp: KP.to_vec(), kv: KV.to_vec(), sample_period: PERIOD, extra: BTreeMap::new() };
    let reference = Fourier {
        offset: Q_DESIRED.to_vec(),
        amplitudes: vec![vec![0.4, 0.1], vec![0.3, 0.2]],
        frequencies: vec![vec![0.7, 1.9], vec![1.1, 2.3]],
        phases: vec![vec![0.0, 1.0], vec![0.5, 2.0]],
    };
    let params = SimParams { duration: 1.5, sample_period: PERIOD, sensor: SensorParams::exact(), ..SimParams::default() };
    simulate_experiment(model, Formulation::EulerLagrange, &[Effect::TimeDelay { delay }], &exp, &reference, &params, None).expect("simulates")
}

/// `run`'s commands replayed open loop (`tau` row-major), without a delay, from the same
/// initial state.
fn replayed(model: &Model, run: &Run, tau: Vec<f64>) -> Run {
    let exp = Experiment { controller: ControllerKind::Replay, joints: joints(model), kp: vec![], kv: vec![], sample_period: PERIOD, extra: BTreeMap::new() };
    let mut log = run.clone();
    log.tau = tau;
    let n = model.dof();
    let params =
        SimParams { duration: run.duration(), sample_period: PERIOD, sensor: SensorParams::exact(), q0: run.q[..n].to_vec(), qd0: run.qd[..n].to_vec(), ..SimParams::default() };
    simulate_experiment(model, Formulation::EulerLagrange, &[], &exp, &Step { target: vec![0.0; n] }, &params, Some(&log)).expect("replays")
}

#[test]
fn fit_side_delayed_command_drives_the_simulator_exactly_as_its_delay_line() {
    let model = Model::paper_arm();
    let n = model.dof();
    for delay in DELAYS {
        let run = delayed_pd_run(&model, delay);
        let fd = FitData::new(&model, Formulation::EulerLagrange, run.clone(), &PrepareOptions::default()).expect("fit data");
        // the fit's delayed command of every sample, applied without delay, moves the arm as
        // the simulator's delay line did
        let tau: Vec<f64> = (0..run.len()).flat_map(|k| (0..n).map(move |j| (k, j))).map(|(k, j)| fd.delayed_torque(k, delay, PERIOD, j)).collect();
        let again = replayed(&model, &run, tau);
        assert_eq!(again.len(), run.len());
        let worst = run.q.iter().zip(&again.q).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(worst == 0.0, "delay {delay} s: the replay of the fit's delayed commands strays {worst:e} rad from the simulator's run");
    }
}

#[test]
fn kstep_replays_a_simulated_delayed_run_to_float_noise() {
    let model = Model::paper_arm();
    let horizons = [0.05, 0.2, 0.5];
    for delay in DELAYS {
        let mut run = delayed_pd_run(&model, delay);
        // the logged commands replayed open loop, from the exact simulated states
        if let Some(e) = run.experiment.as_mut() {
            e.controller = ControllerKind::Replay;
        }
        let mut pr = PredictionRun::new(run, &horizons, PrepareOptions::default().window, SensorParams::exact(), 0, 40);
        assert!(pr.windows() >= 10, "{} windows", pr.windows());
        pr.q_hat = pr.run.q.clone();
        pr.qd_hat = pr.run.qd.clone();
        let e = predict(&model, Formulation::EulerLagrange, &[Effect::TimeDelay { delay }], &pr, &horizons, &|_| true).expect("predicts");
        let finite: Vec<f64> = e.sq.iter().copied().filter(|v| v.is_finite()).collect();
        assert!(finite.len() >= pr.windows() * model.dof(), "{} errors", finite.len());
        let worst = finite.iter().fold(0.0f64, |m, v| m.max(v.sqrt()));
        assert!(worst < 1e-12, "delay {delay} s: k-step replay of the simulator's own run is {worst:e} rad off");
        // the delay matters: predicted without it, the same windows are visibly off
        if delay > 0.0 {
            let e0 = predict(&model, Formulation::EulerLagrange, &[], &pr, &horizons, &|_| true).expect("predicts");
            let off = e0.sq.iter().copied().filter(|v| v.is_finite()).fold(0.0f64, |m, v| m.max(v.sqrt()));
            assert!(off > 1e-6, "delay {delay} s: without the delay the prediction is only {off:e} rad off");
        }
    }
}

/// The paper arm under PD control with an actuation delay of `delay` seconds, logged as a
/// robot logs: encoder of 1,024,000 counts per revolution, velocity by backward difference.
fn logged_delayed_pd_run(model: &Model, delay: f64, duration: f64) -> Run {
    let exp = Experiment { controller: ControllerKind::Pd, joints: joints(model), kp: KP.to_vec(), kv: KV.to_vec(), sample_period: PERIOD, extra: BTreeMap::new() };
    let reference = Fourier {
        offset: Q_DESIRED.to_vec(),
        amplitudes: vec![vec![0.5, 0.15], vec![0.35, 0.2]],
        frequencies: vec![vec![0.6, 1.7], vec![0.9, 2.1]],
        phases: vec![vec![0.3, 1.1], vec![0.0, 2.4]],
    };
    let sensor = SensorParams { counts_per_rev: Some(1_024_000.0), ..SensorParams::default() };
    let params = SimParams { duration, sample_period: PERIOD, sensor, ..SimParams::default() };
    let mut run = simulate_experiment(model, Formulation::EulerLagrange, &[Effect::TimeDelay { delay }], &exp, &reference, &params, None).expect("simulates");
    run.source = format!("pd, {} ms delay", 1e3 * delay);
    run
}

#[test]
fn closed_loop_resimulation_with_the_true_delay_is_closer_than_without_it() {
    let model = Model::paper_arm();
    let delay = 2.0 * PERIOD;
    let run = logged_delayed_pd_run(&model, delay, 4.0);
    // the whole run, and its last 40 % as a held-out split of a fit log (re-simulated from its
    // first logged state, the delay line holding its first command)
    let tail = run.slice(run.len() * 3 / 5..run.len());
    for log in [&run, &tail] {
        let (with, _) = crate::prediction::resim::gap(&model, Formulation::EulerLagrange, &[Effect::TimeDelay { delay }], log);
        let (without, _) = crate::prediction::resim::gap(&model, Formulation::EulerLagrange, &[], log);
        assert!(with.status == "completed" && without.status == "completed", "{} / {}", with.status, without.status);
        assert!(without.l2 > 1e-4, "{} samples: the delay changes the closed loop by only {:e} rad", log.len(), without.l2);
        assert!(with.l2 < 0.5 * without.l2, "{} samples: closed-loop L² {:e} rad with the true delay, {:e} rad without", log.len(), with.l2, without.l2);
    }
}
