//! Backlash against closed forms on a pendulum turning about a vertical axis (no gravity torque,
//! link inertia `M = 0.02 kg·m²`).

use simgap_core::{Formulation, Model, PENDULUM_URDF};
use simgap_sim::reference::Step;
use simgap_sim::{simulate, Effect, Integrator, MemorySink, Plant, Replay, Run, RunEnd, SensorParams, SimParams};

/// The link's own inertia about the vertical axis [kg·m²].
const M: f64 = 0.02;
const PERIOD: f64 = 0.001;

fn horizontal() -> Model {
    Model::from_urdf_str(&PENDULUM_URDF.replace(r#"<axis xyz="0 1 0"/>"#, r#"<axis xyz="0 0 1"/>"#)).unwrap()
}

fn params(duration: f64) -> SimParams {
    SimParams { duration, sample_period: PERIOD, sensor: SensorParams::exact(), q0: vec![0.0], qd0: vec![0.0], substeps: 4, ..SimParams::default() }
}

/// `+tau` for `reverse_at` seconds, then `−tau`, replayed open loop.
fn reversing(tau: f64, reverse_at: f64, duration: f64) -> Replay {
    let t: Vec<f64> = (0..=(duration / PERIOD).round() as usize).map(|k| k as f64 * PERIOD).collect();
    let u = t.iter().map(|t| if *t < reverse_at - 1e-12 { tau } else { -tau }).collect();
    Replay::new(t, u).unwrap()
}

fn run(effects: &[Effect], tau: f64, reverse_at: f64, duration: f64) -> Run {
    let plant = Plant::new(&horizontal(), Formulation::EulerLagrange, effects).unwrap();
    let mut sink = MemorySink::new();
    let end = simulate(&plant, &mut reversing(tau, reverse_at, duration), &Step { target: vec![0.0] }, &params(duration), &mut sink, None).unwrap();
    assert_eq!(end, RunEnd::Completed);
    sink.into_run()
}

#[test]
fn after_a_torque_reversal_the_link_runs_ahead_by_the_play_times_the_rotors_share_of_the_inertia() {
    // at the reversal the link coasts while the rotor crosses the gap w under −τ in
    // t* = √(2 w ia / τ); the plastic impact keeps the joint's momentum, so afterwards the speed is
    // the one without play and the link is ahead by ½ τ t*² / (M + ia) = w ia / (M + ia)
    let (ia, w, tau) = (0.01, 0.04, 0.5);
    let armature = Effect::Armature { ia: vec![ia] };
    let rigid = run(std::slice::from_ref(&armature), tau, 0.2, 0.5);
    let play = run(&[armature, Effect::Backlash { width: vec![w] }], tau, 0.2, 0.5);
    let k = rigid.len() - 1;
    let (dq, dqd) = (play.q[k] - rigid.q[k], play.qd[k] - rigid.qd[k]);
    let expected = w * ia / (M + ia);
    assert!((dq - expected).abs() < 0.01 * expected, "lead {dq}, expected {expected}");
    assert!(dqd.abs() < 1e-3 * rigid.qd[k].abs().max(1.0), "speed after the impact {} against {}", play.qd[k], rigid.qd[k]);
    // before the reversal the play is taken up and nothing differs
    let before = (0.19 / PERIOD) as usize;
    assert!((play.q[before] - rigid.q[before]).abs() < 1e-12);
    // and while the gap is open (t* = 40 ms) the link coasts at its speed of the reversal
    let (reversal, inside) = ((0.2 / PERIOD) as usize, (0.23 / PERIOD) as usize);
    assert!((play.qd[inside] - play.qd[reversal]).abs() < 1e-9, "{} vs {}", play.qd[inside], play.qd[reversal]);
}

#[test]
fn play_without_a_rotor_inertia_or_of_no_width_leaves_the_run_unchanged() {
    let rigid = run(&[], 0.5, 0.2, 0.4);
    let massless = run(&[Effect::Backlash { width: vec![0.04] }], 0.5, 0.2, 0.4);
    assert_eq!(rigid.q, massless.q);
    let armature = Effect::Armature { ia: vec![0.01] };
    let with_ia = run(std::slice::from_ref(&armature), 0.5, 0.2, 0.4);
    let closed = run(&[armature, Effect::Backlash { width: vec![0.0] }], 0.5, 0.2, 0.4);
    assert_eq!(with_ia.q, closed.q);
}

#[test]
fn backlash_is_refused_by_the_adaptive_integrator_with_a_reason() {
    let plant = Plant::new(&horizontal(), Formulation::EulerLagrange, &[Effect::Armature { ia: vec![0.01] }, Effect::Backlash { width: vec![0.02] }]).unwrap();
    let p = SimParams { integrator: Integrator::Adaptive { rtol: 1e-8, atol: 1e-10 }, ..params(0.1) };
    let err = simulate(&plant, &mut reversing(0.5, 0.05, 0.1), &Step { target: vec![0.0] }, &p, &mut MemorySink::new(), None).unwrap_err().to_string();
    assert!(err.contains("backlash") && err.contains("integrator"), "{err}");
}

#[test]
fn backlash_is_spelled_and_refuses_a_negative_width() {
    let e = Effect::parse("backlash:width=0.02", 1).unwrap();
    assert_eq!(e, Effect::Backlash { width: vec![0.02] });
    let err = Effect::parse("backlash:width=-0.02", 1).unwrap_err().to_string();
    assert!(err.contains("backlash") && err.contains("width"), "{err}");
}
