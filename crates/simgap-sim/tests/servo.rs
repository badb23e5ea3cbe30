//! The `servo` controller and the drive effects (back-EMF, load friction, stick–slip) against
//! closed forms on the hand-checkable pendulum (`H = 0.6 kg·m²`, `g(q) = 9.81 sin q N·m`).

use std::collections::BTreeMap;

use simgap_core::{Formulation, Model, PENDULUM_URDF};
use simgap_sim::controller::{Servo, ServoParams};
use simgap_sim::effects::drive_torque;
use simgap_sim::reference::Step;
use simgap_sim::{controller_from_experiment, simulate, ControllerKind, Effect, Experiment, MemorySink, Plant, Run, RunEnd, SensorParams, SimParams, ZeroTorque};

/// m g l of the pendulum [N·m].
const MGL: f64 = 9.81;

fn pendulum() -> Model {
    Model::from_urdf_str(PENDULUM_URDF).unwrap()
}

fn run(effects: &[Effect], controller: &mut dyn simgap_sim::Controller, target: f64, params: &SimParams) -> Run {
    let plant = Plant::new(&pendulum(), Formulation::EulerLagrange, effects).unwrap();
    let mut sink = MemorySink::new();
    let end = simulate(&plant, controller, &Step { target: vec![target] }, params, &mut sink, None).unwrap();
    assert_eq!(end, RunEnd::Completed);
    sink.into_run()
}

fn params(duration: f64, q0: f64, qd0: f64) -> SimParams {
    SimParams { duration, sample_period: 0.002, sensor: SensorParams::exact(), q0: vec![q0], qd0: vec![qd0], substeps: 4, ..SimParams::default() }
}

/// A servo with `kt = 0.5 N·m/A`, `R = 2 Ω` at 12 V: 3 N·m per unit duty, back-EMF 0.125 N·m·s/rad.
fn servo(duty_gain: f64, max_duty: f64) -> Servo {
    Servo::new(vec![duty_gain], vec![max_duty], 12.0, vec![0.5], vec![2.0], None).unwrap()
}

fn last(r: &Run) -> (f64, f64) {
    (r.q[r.len() - 1], r.qd[r.len() - 1])
}

#[test]
fn a_servo_holding_against_gravity_settles_where_its_p_loop_balances_the_weight() {
    // kt/R V duty_gain (goal − q) = m g l sin q at rest: the P loop's static deflection
    // (viscous friction settles the lightly damped loop within the run)
    let (gain, goal) = (2.0, 0.6);
    let r = run(&[Effect::ViscousFriction { b: vec![2.0] }], &mut servo(gain, 1.0), goal, &params(20.0, 0.0, 0.0));
    let (q, qd) = last(&r);
    let balance = |q: f64| 3.0 * gain * (goal - q) - MGL * q.sin();
    assert!(qd.abs() < 1e-6, "still moving: {qd}");
    assert!(balance(q).abs() < 1e-6, "q = {q}: P loop {} against gravity {}", 3.0 * gain * (goal - q), MGL * q.sin());
}

#[test]
fn a_saturated_servo_without_load_runs_at_the_speed_its_back_emf_allows() {
    // no gravity on a horizontal axis: at full duty kt/R (V − kt q̇) = 0, so q̇ = V / kt = 24 rad/s
    let model = Model::from_urdf_str(&PENDULUM_URDF.replace(r#"<axis xyz="0 1 0"/>"#, r#"<axis xyz="0 0 1"/>"#)).unwrap();
    let plant = Plant::new(&model, Formulation::EulerLagrange, &[]).unwrap();
    let mut sink = MemorySink::new();
    let p = SimParams { divergence_bound: 1e3, ..params(30.0, 0.0, 0.0) };
    simulate(&plant, &mut servo(1.0, 1.0), &Step { target: vec![1e4] }, &p, &mut sink, None).unwrap();
    let (_, qd) = last(&sink.into_run());
    assert!((qd - 24.0).abs() < 1e-3, "no-load speed {qd}, expected V/kt = 24 rad/s");
}

#[test]
fn a_disabled_servo_lets_the_arm_swing_as_with_no_torque() {
    // torque off: no torque and no back-EMF, whatever the goal
    let mut exp = Experiment { controller: ControllerKind::Servo, joints: vec!["hinge".into()], kp: vec![], kv: vec![], sample_period: 0.002, extra: BTreeMap::new() };
    ServoParams { duty_gain: vec![2.0], max_duty: vec![1.0], supply_voltage: 12.0, kt: Some(vec![0.5]), r: Some(vec![2.0]), goal_rate_limit: None }.write_to(&mut exp);
    let mut log = Run::new(vec!["hinge".into()]);
    log.t = (0..=1500).map(|k| k as f64 * 0.002).collect();
    log.drive.torque_enable = vec![0.0; log.t.len()];
    let mut off = controller_from_experiment(&exp, &pendulum(), Some(&log)).unwrap();
    let swung = run(&[], off.as_mut(), -1.0, &params(3.0, 0.8, 0.0));
    let free = run(&[], &mut ZeroTorque, -1.0, &params(3.0, 0.8, 0.0));
    let worst = swung.q.iter().zip(&free.q).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    assert!(worst < 1e-12, "torque-off run differs from the free swing by {worst} rad");
    // and enabled, the same servo holds near its goal
    let held = run(&[Effect::ViscousFriction { b: vec![2.0] }], controller_from_experiment(&exp, &pendulum(), None).unwrap().as_mut(), -1.0, &params(6.0, 0.8, 0.0));
    assert!(last(&held).0 < -0.3, "enabled servo did not pull towards its goal: {}", last(&held).0);
}

#[test]
fn exact_dry_friction_holds_the_joint_at_rest_below_its_level_and_releases_it_above() {
    // released at q0 off vertical: gravity torque 9.81 sin q0 against a Coulomb level fc
    let q0: f64 = 0.3;
    let gravity = MGL * q0.sin();
    let stuck = run(&[Effect::CoulombFriction { fc: vec![1.1 * gravity], w: vec![0.0] }], &mut ZeroTorque, 0.0, &params(2.0, q0, 0.0));
    let moved = stuck.q.iter().map(|q| (q - q0).abs()).fold(0.0, f64::max);
    assert!(moved < 1e-9, "held joint moved {moved} rad");
    let slips = run(&[Effect::CoulombFriction { fc: vec![0.9 * gravity], w: vec![0.0] }], &mut ZeroTorque, 0.0, &params(2.0, q0, 0.0));
    assert!(slips.q.iter().any(|q| (q - q0).abs() > 0.01), "joint above its friction level did not move");
}

#[test]
fn a_swing_under_exact_dry_friction_comes_to_rest_and_stays() {
    let r = run(&[Effect::CoulombFriction { fc: vec![1.0], w: vec![0.0] }], &mut ZeroTorque, 0.0, &params(6.0, 1.0, 0.0));
    // it stops where gravity is below the friction level, and does not chatter there
    let tail = &r.q[r.len() - 500..];
    let spread = tail.iter().fold(f64::NEG_INFINITY, |m, q| m.max(*q)) - tail.iter().fold(f64::INFINITY, |m, q| m.min(*q));
    assert!(spread < 1e-9, "still moving at the end: spread {spread} rad");
    assert!(MGL * tail[0].sin().abs() <= 1.0 + 1e-9, "stopped at q = {} where gravity exceeds the friction level", tail[0]);
}

#[test]
fn the_drive_torque_has_the_documented_terms() {
    // τ_drive = en (k (τ_cmd − emf q̇) + offset − kb q̇); load friction −(fc + mu |τ_drive|) tanh(q̇/w)
    let effects = [
        Effect::TorqueGain { k: vec![0.8, 0.8] },
        Effect::TorqueOffset { offset: vec![0.1, 0.1] },
        Effect::BackEmf { kb: vec![0.05, 0.05] },
        Effect::LoadFriction { fc: vec![0.02, 0.02], mu: vec![0.3, 0.3], w: vec![0.01, 0.01] },
    ];
    let (cmd, emf, qd) = ([1.0, 1.0], [0.2, 0.2], [2.0, 2.0]);
    let (mut scratch, mut drive, mut out) = ([0.0; 2], [0.0; 2], [0.0; 2]);
    drive_torque(&effects, None, &cmd, &emf, &[1.0, 0.0], &qd, &mut scratch, &mut drive, &mut out);
    let tau = 0.8 * (1.0 - 0.2 * 2.0) + 0.1 - 0.05 * 2.0;
    assert!((drive[0] - tau).abs() < 1e-15 && drive[1] == 0.0, "{drive:?}");
    let friction = (0.02 + 0.3 * tau) * (2.0f64 / 0.01).tanh();
    assert!((out[0] - (tau - friction)).abs() < 1e-15, "{out:?}");
    assert!((out[1] + 0.02 * (2.0f64 / 0.01).tanh()).abs() < 1e-15, "a disabled drive keeps only the load-free level: {out:?}");
}

#[test]
fn load_friction_lets_a_servo_stall_short_of_its_goal() {
    // with mu = 0.5 the gearbox holds the joint while |τ_drive − m g l sin q| ≤ 0.5 |τ_drive|:
    // the servo stops short of where its P loop balances gravity
    let (gain, goal) = (1.0, 0.5);
    let damped = [Effect::ViscousFriction { b: vec![2.0] }];
    let free = run(&damped, &mut servo(gain, 1.0), goal, &params(10.0, 0.0, 0.0));
    let with_load = [damped[0].clone(), Effect::LoadFriction { fc: vec![0.0], mu: vec![0.5], w: vec![0.0] }];
    let stalled = run(&with_load, &mut servo(gain, 1.0), goal, &params(10.0, 0.0, 0.0));
    let (q_free, (q_stall, qd_stall)) = (last(&free).0, last(&stalled));
    assert!((3.0 * gain * (goal - q_free) - MGL * q_free.sin()).abs() < 1e-6, "free servo not balanced at {q_free}");
    assert!(qd_stall.abs() < 1e-9 && (q_stall - q_free).abs() > 1e-3, "stalled at {q_stall} (q̇ {qd_stall}), free balance at {q_free}");
    let drive = 3.0 * gain * (goal - q_stall);
    assert!((drive - MGL * q_stall.sin()).abs() <= 0.5 * drive.abs() + 1e-9, "stalled at {q_stall} outside the friction band: drive {drive}, gravity {}", MGL * q_stall.sin());
}

#[test]
fn a_load_stribeck_friction_rises_from_its_moving_level_to_its_level_at_rest() {
    // −(fc + mu |τ| + ((fs − fc) + (mus − mu) |τ|) e^{−(q̇/vs)²}) tanh(q̇/w) on the drive torque τ
    let (fc, mu, fs, mus, vs, w) = (0.02, 0.3, 0.05, 0.6, 0.1, 0.01);
    let effects = [Effect::LoadStribeckFriction { fc: vec![fc], mu: vec![mu], fs: vec![fs], mus: vec![mus], vs: vec![vs], w: vec![w] }];
    let (cmd, emf) = ([0.5], [0.0]);
    for qd in [0.0, 0.003, 0.05, 0.1, 2.0] {
        let (mut scratch, mut drive, mut out) = ([0.0], [0.0], [0.0]);
        drive_torque(&effects, None, &cmd, &emf, &[1.0], &[qd], &mut scratch, &mut drive, &mut out);
        let level = fc + mu * 0.5 + ((fs - fc) + (mus - mu) * 0.5) * (-(qd / vs).powi(2)).exp();
        assert!((out[0] - (0.5 - level * (qd / w).tanh())).abs() < 1e-15, "q̇ = {qd}: {out:?}");
        assert!((effects[0].load_level(0, qd, -0.5) - level).abs() < 1e-15, "the level takes |τ|");
    }
    // far above vs it is the load friction of its moving levels
    let moving = Effect::LoadFriction { fc: vec![fc], mu: vec![mu], w: vec![w] };
    assert!((effects[0].load_level(0, 2.0, 0.5) - moving.load_level(0, 2.0, 0.5)).abs() < 1e-15);
}

#[test]
fn a_servo_at_rest_stays_while_its_drive_is_below_the_level_at_rest_and_above_the_moving_level() {
    // at q = 0 (no weight) the drive is 3 N·m per unit duty × (goal − q) = 0.3 N·m: above the
    // moving level 0.5 × 0.3 = 0.15, below the level at rest 0.1 + 0.9 × 0.3 = 0.37
    let (gain, goal) = (1.0, 0.1);
    let moving = Effect::LoadFriction { fc: vec![0.0], mu: vec![0.5], w: vec![0.0] };
    let held = Effect::LoadStribeckFriction { fc: vec![0.0], mu: vec![0.5], fs: vec![0.1], mus: vec![0.9], vs: vec![0.05], w: vec![0.0] };
    let moved = run(&[moving], &mut servo(gain, 1.0), goal, &params(2.0, 0.0, 0.0));
    let stayed = run(&[held], &mut servo(gain, 1.0), goal, &params(2.0, 0.0, 0.0));
    assert!(last(&moved).0 > 0.01, "the moving level alone lets it go: q = {}", last(&moved).0);
    assert!(stayed.q.iter().all(|q| q.abs() < 1e-12), "held at rest: it reached {}", stayed.q.iter().fold(0.0f64, |m, q| m.max(q.abs())));
}

#[test]
fn a_servo_experiment_without_its_keys_is_refused_naming_them() {
    let exp = |extra: &[(&str, &str)]| Experiment {
        controller: ControllerKind::Servo,
        joints: vec!["hinge".into()],
        kp: vec![],
        kv: vec![],
        sample_period: 0.002,
        extra: extra.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect(),
    };
    let refuse = |e: Experiment| controller_from_experiment(&e, &pendulum(), None).err().expect("refused").to_string();
    assert!(refuse(exp(&[("supply_voltage", "12"), ("kt", "0.5"), ("R", "2")])).contains("duty_gain"));
    assert!(refuse(exp(&[("duty_gain", "2"), ("supply_voltage", "12"), ("kt", "0.5")])).contains("'R'"));
    assert!(refuse(exp(&[("duty_gain", "2"), ("kt", "0.5"), ("R", "2")])).contains("supply_voltage"));
    assert!(refuse(exp(&[("duty_gain", "2"), ("supply_voltage", "12")])).contains("motor constants"));
    assert!(refuse(exp(&[("duty_gain", "2"), ("max_duty", "1.5"), ("supply_voltage", "12"), ("kt", "0.5"), ("R", "2")])).contains("max_duty"));
}

#[test]
fn a_servo_on_a_light_link_logged_at_50_hz_runs_at_its_back_emf_speed_without_diverging() {
    // a wrist-like link of 1e-4 kg·m² about a vertical axis: the back-EMF kt²/R = 0.125
    // N·m·s/rad relaxes its speed within 1 ms, 20 times faster than the 20 ms sample; one RK4
    // step per sample diverges, so the stepper takes the steps that rate asks for
    let light = PENDULUM_URDF
        .replace(r#"<axis xyz="0 1 0"/>"#, r#"<axis xyz="0 0 1"/>"#)
        .replace(r#"<mass value="2.0"/>"#, r#"<mass value="0.0002"/>"#)
        .replace(r#"izz="0.02""#, r#"izz="0.00005""#);
    let model = Model::from_urdf_str(&light).unwrap();
    let plant = Plant::new(&model, Formulation::EulerLagrange, &[]).unwrap();
    let p =
        SimParams { duration: 2.0, sample_period: 0.02, sensor: SensorParams::exact(), q0: vec![0.0], qd0: vec![0.0], substeps: 1, divergence_bound: 1e3, ..SimParams::default() };
    let mut sink = MemorySink::new();
    let end = simulate(&plant, &mut servo(1.0, 1.0), &Step { target: vec![1e4] }, &p, &mut sink, None).unwrap();
    assert_eq!(end, RunEnd::Completed);
    let (_, qd) = last(&sink.into_run());
    assert!((qd - 24.0).abs() < 1e-3, "no-load speed {qd}, expected V/kt = 24 rad/s");
}

#[test]
fn a_stiff_servo_damping_integrated_implicitly_at_one_step_per_sample_tracks_as_the_adaptive_reference() {
    // a light link under gravity (H = 6e-5 kg·m², m g l = 0.0098 N·m): the back-EMF rate
    // 0.125 / 6e-5 = 2,083 /s would ask RK4 for 21 steps per 20 ms sample; ROS2 takes one,
    // and its positions follow Dormand–Prince at tight tolerances while the servo tracks
    let light = PENDULUM_URDF
        .replace(r#"<origin xyz="0 0 -0.5" rpy="0 0 0"/>"#, r#"<origin xyz="0 0 -0.05" rpy="0 0 0"/>"#)
        .replace(r#"<mass value="2.0"/>"#, r#"<mass value="0.02"/>"#)
        .replace(r#"ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.02""#, r#"ixx="0.00001" ixy="0" ixz="0" iyy="0.00001" iyz="0" izz="0.00001""#);
    let model = Model::from_urdf_str(&light).unwrap();
    let reference = simgap_sim::reference::Fourier { offset: vec![0.2], amplitudes: vec![vec![0.5, 0.1]], frequencies: vec![vec![0.5, 2.0]], phases: vec![] };
    let base =
        SimParams { duration: 4.0, sample_period: 0.02, sensor: SensorParams::exact(), q0: vec![0.2], qd0: vec![0.0], substeps: 1, divergence_bound: 1e3, ..SimParams::default() };
    // viscous friction (measured 1e-5 rad); then a Coulomb friction whose band (slope fc/w =
    // 0.2 N·m·s/rad) is stiffer still, which the implicit step takes too instead of raising
    // RK4's steps to 55 per sample: first order at the band's kinks, so a dry friction gets
    // four implicit steps per sample (measured 2.8 mrad; one step: 11.6 mrad)
    let cases = [(Effect::ViscousFriction { b: vec![0.005] }, 1e-4), (Effect::CoulombFriction { fc: vec![0.002], w: vec![0.01] }, 4e-3)];
    for (effect, tolerance) in cases {
        let plant = Plant::new(&model, Formulation::EulerLagrange, std::slice::from_ref(&effect)).unwrap();
        let simulate_with = |p: &SimParams| {
            let mut sink = MemorySink::new();
            assert_eq!(simulate(&plant, &mut servo(1.0, 1.0), &reference, p, &mut sink, None).unwrap(), RunEnd::Completed);
            sink.into_run()
        };
        let implicit = simulate_with(&base);
        let exact = simulate_with(&SimParams { integrator: simgap_sim::Integrator::Adaptive { rtol: 1e-10, atol: 1e-12 }, ..base.clone() });
        let worst = implicit.q.iter().zip(&exact.q).map(|(a, b)| (a - b).abs()).fold(0.0f64, f64::max);
        let travel = exact.q.iter().fold(f64::NEG_INFINITY, |m, q| m.max(*q)) - exact.q.iter().fold(f64::INFINITY, |m, q| m.min(*q));
        assert!(travel > 0.8, "{}: the servo tracks the reference: travel {travel}", effect.name());
        assert!(worst < tolerance, "{}: one ROS2 step per sample is {worst} rad from the adaptive reference", effect.name());
    }
}
