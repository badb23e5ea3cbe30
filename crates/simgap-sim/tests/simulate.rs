//! Closed-loop simulation: integrator convergence, energy, divergence, interruption, replay.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use simgap_core::robots::paper_arm;
use simgap_core::{kinetic_energy, potential_energy, Formulation, Model, Workspace};
use simgap_sim::paper;
use simgap_sim::Effect;
use simgap_sim::{
    reference_from_run, simulate, simulate_experiment, Controller, ControllerKind, Experiment, Integrator, MemorySink, Pd, Plant, Replay, Run, RunEnd, SensorParams, SimParams,
    Step, Stepper, ZeroTorque, DEFAULT_SUBSTEPS,
};

fn paper_pd() -> Pd {
    paper::controller()
}

fn paper_step() -> Step {
    paper::reference()
}

fn run_with(plant: &Plant, controller: &mut dyn Controller, reference: &dyn simgap_sim::Reference, params: &SimParams) -> (Run, RunEnd) {
    let mut sink = MemorySink::new();
    let end = simulate(plant, controller, reference, params, &mut sink, None).unwrap();
    assert_eq!(sink.end.as_ref(), Some(&end), "the sink is finished with the run's end");
    (sink.into_run(), end)
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

fn reference_params(duration: f64, sensor: SensorParams) -> SimParams {
    SimParams { duration, sensor, integrator: Integrator::Adaptive { rtol: 1e-12, atol: 1e-12 }, ..SimParams::default() }
}

#[test]
fn rk4_converges_with_order_four() {
    let model = Model::paper_arm();
    let plant = Plant::new(&model, Formulation::EulerLagrange, &[]).unwrap();
    let exact = SensorParams::exact();
    let (reference, _) = run_with(&plant, &mut paper_pd(), &paper_step(), &reference_params(1.0, exact.clone()));
    let mut errors = Vec::new();
    for substeps in [1, 2, 4] {
        let params = SimParams { duration: 1.0, substeps, sensor: exact.clone(), ..SimParams::default() };
        let (run, end) = run_with(&plant, &mut paper_pd(), &paper_step(), &params);
        assert_eq!(end, RunEnd::Completed);
        errors.push(max_abs_diff(&run.q, &reference.q));
    }
    eprintln!("rk4 max position error for 1, 2, 4 substeps: {errors:?}");
    for w in errors.windows(2) {
        let ratio = w[0] / w[1];
        assert!((12.0..20.0).contains(&ratio), "halving the step divides the error by {ratio}; expected about 16 ({errors:?})");
    }
}

#[test]
fn paper_defaults_converge_to_a_micro_radian() {
    // the paper's experiment (3 s) with the default substeps against a Dormand–Prince
    // reference (rtol = atol = 1e-12): exact sensors isolate the integration error
    let model = Model::paper_arm();
    for formulation in [Formulation::EulerLagrange, Formulation::Simplified] {
        let plant = Plant::new(&model, formulation, &[]).unwrap();
        let (reference, _) = run_with(&plant, &mut paper_pd(), &paper_step(), &reference_params(3.0, SensorParams::exact()));
        for substeps in [DEFAULT_SUBSTEPS, 2 * DEFAULT_SUBSTEPS] {
            let params = SimParams { substeps, sensor: SensorParams::exact(), ..SimParams::default() };
            let (run, end) = run_with(&plant, &mut paper_pd(), &paper_step(), &params);
            assert_eq!(end, RunEnd::Completed);
            let err = max_abs_diff(&run.q, &reference.q);
            eprintln!("{formulation:?}: {substeps} substeps, max position error {err:e} rad");
            assert!(err < 1e-6, "{substeps} substeps give {err:e} rad; expected below 1e-6");
        }
    }
}

#[test]
fn with_the_paper_encoders_runs_agree_to_one_count() {
    // with quantised encoders an integration error can flip a measured count; the closed loop
    // absorbs it, so default RK4 and the reference agree to one count (6.1 µrad) plus 1e-6
    let model = Model::paper_arm();
    let count = std::f64::consts::TAU / paper_arm::COUNTS_PER_REV;
    for formulation in [Formulation::EulerLagrange, Formulation::Simplified] {
        let plant = Plant::new(&model, formulation, &[]).unwrap();
        let (reference, _) = run_with(&plant, &mut paper_pd(), &paper_step(), &reference_params(3.0, SensorParams::default()));
        let (run, _) = run_with(&plant, &mut paper_pd(), &paper_step(), &SimParams::default());
        let err = max_abs_diff(&run.q, &reference.q);
        eprintln!("{formulation:?}, paper encoders: max measured position difference {err:e} rad ({:.2} counts)", err / count);
        assert!(err <= count + 1e-6, "{err:e} rad");
    }
}

/// Total energy along a free-motion run, and the largest relative deviation from the start.
fn energy_drift(model: &Model, formulation: Formulation, q0: Vec<f64>, qd0: Vec<f64>, duration: f64, integrator: Integrator, substeps: usize) -> f64 {
    let plant = Plant::new(model, formulation, &[]).unwrap();
    let params = SimParams { duration, substeps, integrator, sensor: SensorParams::exact(), q0, qd0, ..SimParams::default() };
    let zero = Step { target: vec![0.0; model.dof()] };
    let (run, end) = run_with(&plant, &mut ZeroTorque, &zero, &params);
    assert_eq!(end, RunEnd::Completed);
    let mut ws = Workspace::new(model);
    let mut energy = |k: usize| kinetic_energy(model, &mut ws, run.row(&run.q, k), run.row(&run.qd, k)) + potential_energy(model, &mut ws, run.row(&run.q, k));
    let e0 = energy(0);
    let scale = e0.abs().max(kinetic_energy(model, &mut Workspace::new(model), run.row(&run.q, 0), run.row(&run.qd, 0)));
    (0..run.len()).map(|k| (energy(k) - e0).abs() / scale).fold(0.0, f64::max)
}

#[test]
fn free_motion_conserves_energy() {
    let arm = Model::paper_arm();
    let drift = energy_drift(&arm, Formulation::EulerLagrange, vec![1.0, -0.5], vec![2.0, -3.0], 10.0, Integrator::Rk4, 16);
    eprintln!("paper arm, Euler-Lagrange, RK4 x16: relative energy drift {drift:e}");
    assert!(drift < 1e-8, "relative energy drift {drift:e}");
    let chain = Model::random_chain(4, 7);
    let drift = energy_drift(&chain, Formulation::EulerLagrange, vec![0.3, -0.2, 0.1, 0.4], vec![0.5, -0.5, 0.2, 0.1], 10.0, Integrator::Adaptive { rtol: 1e-12, atol: 1e-12 }, 1);
    eprintln!("random chain, Euler-Lagrange, Dormand-Prince: relative energy drift {drift:e}");
    assert!(drift < 1e-8, "relative energy drift {drift:e}");
}

#[test]
fn simplified_model_also_conserves_energy() {
    // C = Ḣ/2 is symmetric and q̇ᵀ(Ḣ − 2C)q̇ = 0: the simplified model is energy-consistent
    // even though its C q̇ is not the true Coriolis torque
    let arm = Model::paper_arm();
    let drift = energy_drift(&arm, Formulation::Simplified, vec![1.0, -0.5], vec![2.0, -3.0], 10.0, Integrator::Rk4, 16);
    eprintln!("paper arm, simplified, RK4 x16: relative energy drift {drift:e}");
    assert!(drift < 1e-8, "relative energy drift {drift:e}");
    let chain = Model::random_chain(4, 7);
    let drift = energy_drift(&chain, Formulation::Simplified, vec![0.3, -0.2, 0.1, 0.4], vec![0.5, -0.5, 0.2, 0.1], 10.0, Integrator::Adaptive { rtol: 1e-12, atol: 1e-12 }, 1);
    eprintln!("random chain, simplified, Dormand-Prince: relative energy drift {drift:e}");
    assert!(drift < 1e-8, "relative energy drift {drift:e}");
}

#[test]
fn the_two_formulations_give_different_runs() {
    let model = Model::paper_arm();
    let params = SimParams::default();
    let el = run_with(&Plant::new(&model, Formulation::EulerLagrange, &[]).unwrap(), &mut paper_pd(), &paper_step(), &params).0;
    let simple = run_with(&Plant::new(&model, Formulation::Simplified, &[]).unwrap(), &mut paper_pd(), &paper_step(), &params).0;
    let d = max_abs_diff(&el.q, &simple.q);
    assert!(d > 1e-4 && d < 0.5, "max difference {d}");
}

#[test]
fn diverging_run_reports_time_and_joint_and_records_no_nan() {
    let model = Model::paper_arm();
    let plant = Plant::new(&model, Formulation::EulerLagrange, &[]).unwrap();
    // a derivative gain far beyond what 2.5 ms sampling can stabilise
    let mut pd = Pd { kp: vec![64.72, 32.36], kv: vec![5000.0, 6.472] };
    let mut sink = MemorySink::new();
    let end = simulate(&plant, &mut pd, &paper_step(), &SimParams { sensor: SensorParams::exact(), ..SimParams::default() }, &mut sink, None).unwrap();
    let RunEnd::Diverged { t, joint } = end.clone() else { panic!("expected divergence, got {end:?}") };
    assert!(t > 0.0 && t < 3.0, "diverged at {t}");
    // the fastest joint is named (the unstable shoulder loop throws the light elbow around)
    assert!(joint == "shoulder" || joint == "elbow", "joint {joint}");
    assert_eq!(sink.end, Some(end));
    let run = sink.into_run();
    assert!(!run.is_empty());
    for v in [&run.q, &run.qd, &run.tau, &run.q_ref, &run.qd_ref] {
        assert!(v.iter().all(|x| x.is_finite()), "the log holds a non-finite number");
    }
    assert!(*run.t.last().unwrap() < t);
}

/// A PD controller that raises a stop flag at a given time (as Ctrl-C would).
struct StopAt {
    pd: Pd,
    at: f64,
    flag: Arc<AtomicBool>,
}

impl Controller for StopAt {
    fn torque(&mut self, t: f64, q: &[f64], qd: &[f64], q_ref: &[f64], qd_ref: &[f64], out: &mut [f64]) {
        if t >= self.at {
            self.flag.store(true, Ordering::Relaxed);
        }
        self.pd.torque(t, q, qd, q_ref, qd_ref, out);
    }
}

#[test]
fn interruption_stops_and_finishes_the_sink() {
    let model = Model::paper_arm();
    let plant = Plant::new(&model, Formulation::EulerLagrange, &[]).unwrap();
    let flag = Arc::new(AtomicBool::new(false));
    let mut c = StopAt { pd: paper_pd(), at: 0.5, flag: flag.clone() };
    let mut sink = MemorySink::new();
    let end = simulate(&plant, &mut c, &paper_step(), &SimParams::default(), &mut sink, Some(&flag)).unwrap();
    let RunEnd::Interrupted { t } = end else { panic!("expected an interruption, got {end:?}") };
    assert!((t - 0.5).abs() < 1e-9, "interrupted at {t}");
    assert!(sink.end.is_some());
    let run = sink.into_run();
    assert!((run.t.last().unwrap() - 0.5).abs() < 1e-9);
}

#[test]
fn replaying_the_commanded_effort_reproduces_the_run() {
    let model = Model::paper_arm();
    let plant = Plant::new(&model, Formulation::EulerLagrange, &[]).unwrap();
    let params = SimParams { sensor: SensorParams::exact(), duration: 1.0, ..SimParams::default() };
    let (pd_run, _) = run_with(&plant, &mut paper_pd(), &paper_step(), &params);
    let mut replay = Replay::new(pd_run.t.clone(), pd_run.tau.clone()).unwrap();
    let (replayed, _) = run_with(&plant, &mut replay, &paper_step(), &params);
    let d = max_abs_diff(&pd_run.q, &replayed.q);
    assert!(d < 1e-12, "replay differs by {d}");
    assert_eq!(replayed.experiment.as_ref().unwrap().controller, ControllerKind::Replay);
}

#[test]
fn resimulating_a_logged_run_reproduces_it() {
    // what the diagnosis does: a logged run (here simulated, with the paper's sensors, started
    // at an absolute time) re-simulated from its metadata, reference and first sample
    let model = Model::paper_arm();
    let exp = Experiment {
        controller: ControllerKind::Pd,
        joints: vec!["elbow".into(), "shoulder".into()],
        kp: vec![paper::KP[1], paper::KP[0]],
        kv: vec![paper::KV[1], paper::KV[0]],
        sample_period: paper::SAMPLE_PERIOD,
        extra: Default::default(),
    };
    let params = SimParams { t0: 1000.0, duration: 1.5, ..SimParams::default() };
    let logged = simulate_experiment(&model, Formulation::EulerLagrange, &[], &exp, &paper_step(), &params, None).unwrap();
    assert_eq!(logged.len(), 601);
    assert_eq!(logged.experiment.as_ref(), Some(&exp));
    let again_params =
        SimParams { t0: logged.t[0], duration: logged.duration(), q0: logged.row(&logged.q, 0).to_vec(), qd0: logged.row(&logged.qd, 0).to_vec(), ..SimParams::default() };
    let again = simulate_experiment(&model, Formulation::EulerLagrange, &[], &exp, reference_from_run(&logged).as_ref(), &again_params, None).unwrap();
    assert_eq!(again.len(), logged.len());
    assert!(max_abs_diff(&again.q, &logged.q) < 1e-12);
    assert!(max_abs_diff(&again.t, &logged.t) < 1e-9);
}

#[test]
fn pd_reaches_the_paper_steady_state() {
    // PD without gravity compensation settles where Kp q̃ = g(q)
    let model = Model::paper_arm();
    let plant = Plant::new(&model, Formulation::EulerLagrange, &[]).unwrap();
    let params = SimParams { duration: 10.0, ..SimParams::default() };
    let (run, _) = run_with(&plant, &mut paper_pd(), &paper_step(), &params);
    let k = run.len() - 1;
    let q = run.row(&run.q, k);
    let g = simgap_core::gravity_torques(&model, &mut Workspace::new(&model), q);
    for i in 0..2 {
        let residual = paper::KP[i] * (paper::Q_DESIRED[i] - q[i]) - g[i];
        assert!(residual.abs() < 1e-3, "joint {i}: Kp q̃ − g = {residual}");
    }
}

#[test]
fn tracking_l2_computed_as_the_run_goes_equals_the_whole_run_l2_to_the_last_bit() {
    let plant = Plant::new(&Model::paper_arm(), Formulation::EulerLagrange, &[]).unwrap();
    let (run, _) = run_with(&plant, &mut paper_pd(), &paper_step(), &SimParams::default());
    let mut acc = simgap_sim::L2Accumulator::new(run.joints.clone());
    let n = run.dof();
    for k in 0..run.len() {
        let x: Vec<f64> = (0..n).map(|i| run.q_ref[k * n + i] - run.q[k * n + i]).collect();
        acc.push(run.t[k], &x);
    }
    let whole = simgap_sim::l2_tracking(&run, None).unwrap();
    assert_eq!(acc.report().unwrap(), whole);
    // the sink form, as `simgap simulate` uses it
    let mut sink = simgap_sim::TrackingL2Sink::new();
    simulate(&plant, &mut paper_pd(), &paper_step(), &SimParams::default(), &mut sink, None).unwrap();
    assert_eq!(sink.report().unwrap(), whole);
}

/// The per-sample step restarted from a state of a simulated run, driven by the run's logged
/// commands with its delay line primed from the log (as k-step prediction drives it), retraces
/// the simulation exactly: same step, same arithmetic.
#[test]
fn stepper_restarted_from_a_logged_state_with_the_logged_commands_retraces_the_run() {
    let model = Model::paper_arm();
    // a delay of 2.4 samples: the restart must prime the delay ring with commands before k0
    let effects = [simgap_sim::Effect::TimeDelay { delay: 0.006 }, simgap_sim::Effect::CoulombFriction { fc: vec![7.17, 1.734], w: vec![0.01; 2] }];
    let plant = Plant::new(&model, Formulation::EulerLagrange, &effects).unwrap();
    let params = SimParams { sensor: SensorParams::exact(), duration: 2.0, ..SimParams::default() };
    let (run, end) = run_with(&plant, &mut paper_pd(), &paper_step(), &params);
    assert_eq!(end, RunEnd::Completed);
    let n = run.dof();
    let mut stepper = simgap_sim::Stepper::new(&plant, &params, run.len()).unwrap();
    for k0 in [0, 1, 150, 611] {
        // exact sensors: the logged state is the true state
        let mut y = [run.row(&run.q, k0), run.row(&run.qd, k0)].concat();
        stepper.restart(k0, None, |i| run.row(&run.tau, i));
        for k in k0..k0 + 100 {
            stepper.set_command(run.row(&run.tau, k));
            stepper.advance(k, run.t[k], params.sample_period, &mut y);
            assert!(stepper.diverged(&y).is_none());
        }
        assert_eq!(&y[..n], run.row(&run.q, k0 + 100), "restarted at sample {k0}");
        assert_eq!(&y[n..], run.row(&run.qd, k0 + 100), "restarted at sample {k0}");
    }
}

#[test]
fn impossible_parameters_are_refused_naming_the_range() {
    let plant = Plant::new(&Model::paper_arm(), Formulation::EulerLagrange, &[]).unwrap();
    for (params, words) in [
        (SimParams { sample_period: 1e-12, ..SimParams::default() }, "sample_period: 1e-12 s is out of range; expected 1e-6 ≤ sample_period ≤ 1 s"),
        (SimParams { substeps: 1_000_000_000, ..SimParams::default() }, "substeps: 1e9 is out of range; expected 1 ≤ substeps ≤ 10000"),
        (SimParams { duration: 86_401.0, ..SimParams::default() }, "duration: 86401 s is out of range; expected 0 < duration ≤ 86400 s"),
        (SimParams { duration: 1000.0, substeps: 5000, ..SimParams::default() }, "integration steps; expected at most 1e9"),
    ] {
        let mut sink = MemorySink::new();
        let e = simulate(&plant, &mut paper_pd(), &paper_step(), &params, &mut sink, None).unwrap_err().to_string();
        assert!(e.contains(words), "{e}");
    }
    assert!(SimParams { duration: 86_400.0, ..SimParams::default() }.check_in_memory().unwrap_err().to_string().contains("at most 1e7"));
    assert!(SimParams { duration: 86_400.0, ..SimParams::default() }.validate(2).is_ok());
}

/// The embedded 7-DOF arm.
fn arm7() -> Model {
    Model::from_urdf_str_with(simgap_core::ARM7_URDF, "arm7.urdf", &simgap_core::UrdfOptions { tip: Some("panda_hand".into()) }).unwrap()
}

/// Stiff dry friction on every joint of the 7-DOF arm (Coulomb of width 0.003 rad/s, a Stribeck
/// hump, viscous friction) and its rotor inertias.
fn stiff_friction() -> Vec<Effect> {
    vec![
        Effect::Armature { ia: vec![0.2, 0.2, 0.15, 0.15, 0.02, 0.02, 0.005] },
        Effect::CoulombFriction { fc: vec![1.5, 2.0, 1.2, 1.0, 0.2, 0.2, 0.05], w: vec![0.003; 7] },
        Effect::StribeckFriction { fc: vec![0.0; 7], fs: vec![0.3, 0.3, 0.2, 0.2, 0.05, 0.05, 0.02], vs: vec![0.02; 7], w: vec![0.003; 7] },
        Effect::ViscousFriction { b: vec![1.2, 1.5, 0.9, 0.8, 0.08, 0.08, 0.02] },
    ]
}

/// The 7-DOF arm with [`stiff_friction`] tracking sines under PD + gravity at 200 Hz (3 Hz,
/// damping 0.7), stepped sample by sample for 10 s: (positions, integration steps taken).
fn stiff_friction_run(substeps: usize) -> (Vec<f64>, u64) {
    let plant = Plant::new(&arm7(), Formulation::EulerLagrange, &stiff_friction()).unwrap();
    tracking(&plant, substeps, 2000, |j, t| 0.4 * (std::f64::consts::TAU * (0.15 + 0.03 * j as f64) * t + j as f64).sin())
}

/// `plant` (the 7-DOF arm with effects) tracking `q0 + swing(joint, t)` under PD + gravity at
/// 200 Hz (3 Hz, damping 0.7) from the arm's usual pose, stepped sample by sample for `samples`
/// samples at `substeps` RK4 steps per sample or more: (positions, integration steps taken).
fn tracking(plant: &Plant, substeps: usize, samples: usize, swing: impl Fn(usize, f64) -> f64) -> (Vec<f64>, u64) {
    let model = plant.model().clone();
    let n = model.dof();
    let period = 0.005;
    let q0 = vec![0.0, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0];
    let params = SimParams { sample_period: period, substeps, sensor: SensorParams::exact(), q0: q0.clone(), ..SimParams::default() };
    let mut stepper = Stepper::new(plant, &params, samples).unwrap();
    let mut ws = simgap_core::Workspace::new(&model);
    let mut y: Vec<f64> = q0.iter().copied().chain(std::iter::repeat_n(0.0, n)).collect();
    let mut q = Vec::with_capacity(samples * n);
    let mut tau = vec![0.0; n];
    let kp = [457.0, 948.0, 444.0, 312.0, 17.0, 19.2, 2.59];
    let kv = [34.0, 70.4, 33.0, 23.1, 1.26, 1.43, 0.193];
    for k in 0..samples {
        let t = k as f64 * period;
        let g = simgap_core::gravity_torques(&model, &mut ws, &y[..n]);
        for (j, v) in tau.iter_mut().enumerate() {
            *v = g[j] + kp[j] * (q0[j] + swing(j, t) - y[j]) - kv[j] * y[n + j];
        }
        stepper.set_command(&tau);
        stepper.advance(k, t, period, &mut y);
        q.extend_from_slice(&y[..n]);
    }
    (q, stepper.steps_taken())
}

#[test]
fn substeps_raised_only_near_rest_match_substeps_raised_throughout() {
    // the stiff rate of the dry frictions asks for `full` RK4 steps per sample; the stepper
    // takes them only in intervals where some joint is near rest, fewer elsewhere, and is as
    // accurate
    let model = arm7();
    let plant = Plant::new(&model, Formulation::EulerLagrange, &stiff_friction()).unwrap();
    let q0 = vec![0.0, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0];
    let full = simgap_sim::effective_substeps(&plant, &SimParams { sample_period: 0.005, substeps: 1, q0, ..SimParams::default() });
    assert!(full >= 4, "the friction should be stiff at 200 Hz: {full} substeps");
    let (adaptive, taken) = stiff_friction_run(1);
    // substeps = full: nothing left to lower, every interval takes `full` steps
    let (throughout, taken_full) = stiff_friction_run(full);
    assert_eq!(taken_full, 2000 * full as u64);
    // both against steps 8 times smaller throughout
    let (fine, _) = stiff_friction_run(8 * full);
    let (e_adaptive, e_full) = (max_abs_diff(&adaptive, &fine), max_abs_diff(&throughout, &fine));
    let swing = fine.chunks(7).map(|q| (q[0] - fine[0]).abs()).fold(0.0f64, f64::max);
    eprintln!("{full} substeps near rest: {taken} steps against {taken_full}; max position error {e_adaptive:e} rad against {e_full:e} rad with {full} throughout (shoulder swing {swing:.2} rad)");
    assert!(swing > 0.3, "the arm should move: {swing}");
    // measured: 74 % of the steps, the same error (1.106e-5 rad against 1.107e-5)
    assert!(taken < taken_full * 9 / 10, "{taken} steps against {taken_full}");
    assert!(e_adaptive < 1.1 * e_full + 1e-9, "positions off by {e_adaptive:e} rad ({e_full:e} with {full} throughout)");
}

#[test]
fn a_friction_band_faster_than_the_samples_is_the_exact_sign_at_the_samples() {
    // Coulomb friction of width 1e-4 rad/s: on the light wrist joints its band's time constant
    // is microseconds, and RK4 would need hundreds of steps per 5 ms sample
    let model = arm7();
    let narrow = vec![
        Effect::Armature { ia: vec![0.2, 0.2, 0.15, 0.15, 0.02, 0.02, 0.005] },
        Effect::CoulombFriction { fc: vec![1.5, 2.0, 1.2, 1.0, 0.2, 0.2, 0.05], w: vec![1e-4; 7] },
        Effect::ViscousFriction { b: vec![1.2, 1.5, 0.9, 0.8, 0.08, 0.08, 0.02] },
    ];
    let plant = Plant::new(&model, Formulation::EulerLagrange, &narrow).unwrap();
    let params = SimParams { sample_period: 0.005, substeps: 1, q0: vec![0.0, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0], ..SimParams::default() };
    let full = simgap_sim::effective_substeps(&plant, &params);
    assert!(full > 100, "the band should be far too fast for 200 Hz: {full} substeps");
    let exact = simgap_sim::unresolved_bands_exact(&plant, &params, 16, true).expect("some joint's band needs more than 16 steps");
    let changed: Vec<usize> = match &exact[1] {
        Effect::CoulombFriction { w, .. } => (0..7).filter(|&i| w[i] == 0.0).collect(),
        other => panic!("the Coulomb friction should come second: {other:?}"),
    };
    assert!(changed.contains(&6), "the lightest joint's band is the fastest: {changed:?}");
    let exact = Plant::new(&model, Formulation::EulerLagrange, &exact).unwrap();
    // the narrow band resolved by RK4 against the exact sign as stick–slip, at the samples
    // a slow sweep that stops and reverses: every joint passes through rest
    let sweep = |j: usize, t: f64| 0.3 * (std::f64::consts::TAU * (0.4 + 0.05 * j as f64) * t + j as f64).sin();
    let (resolved, steps_resolved) = tracking(&plant, 1, 800, sweep);
    let (sign, steps_sign) = tracking(&exact, 1, 800, sweep);
    let e = max_abs_diff(&resolved, &sign);
    eprintln!("{full} substeps: {steps_resolved} steps resolved against {steps_sign} with the exact sign on joints {changed:?}; positions differ by {e:e} rad at most");
    // measured: 800 steps against 43,604 (175 substeps), 7.0e-4 rad at most over 4 s of
    // tracking (the stick–slip step is first order: 1.8e-4 rad with 4 steps per sample, 4.9e-5
    // with 16; RK4 at 175 against 700 substeps: 4e-7)
    assert!(steps_sign * 20 < steps_resolved, "{steps_sign} steps against {steps_resolved}");
    assert!(e < 1e-3, "positions differ by {e:e} rad");
    // a band the samples resolve is left as it is
    let wide = vec![Effect::CoulombFriction { fc: vec![0.1; 7], w: vec![0.5; 7] }];
    let plant = Plant::new(&model, Formulation::EulerLagrange, &wide).unwrap();
    assert!(simgap_sim::unresolved_bands_exact(&plant, &params, 16, true).is_none());
}

#[test]
fn a_load_friction_band_faster_than_the_samples_is_exact_where_the_drive_torque_is_held() {
    // a load-dependent friction of the default width on the 7-DOF arm's wrist: its band, like a
    // Coulomb friction's, is far too fast for 200 Hz
    let model = arm7();
    let mut mu = vec![0.0; 7];
    mu[6] = 0.5;
    let load = vec![Effect::LoadFriction { fc: vec![0.0; 7], mu, w: vec![simgap_sim::DEFAULT_COULOMB_WIDTH; 7] }];
    let plant = Plant::new(&model, Formulation::EulerLagrange, &load).unwrap();
    let params = SimParams { sample_period: 0.005, substeps: 1, q0: vec![0.0, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0], ..SimParams::default() };
    let width = |effects: &[Effect]| match &effects[0] {
        Effect::LoadFriction { w, .. } => w[6],
        other => panic!("the load friction should come first: {other:?}"),
    };
    // a torque-driven run holds its drive torque over each sample: the sign is made exact
    let held = simgap_sim::unresolved_bands_exact(&plant, &params, 16, true).expect("the wrist's band needs more than 16 steps");
    assert_eq!(width(&held), 0.0);
    // a servo's torque follows its back-EMF within the sample: its load friction keeps its band
    let servo = simgap_sim::unresolved_bands_exact(&plant, &params, 16, false);
    assert!(servo.as_ref().is_none_or(|e| width(e) == simgap_sim::DEFAULT_COULOMB_WIDTH), "{servo:?}");
}
