//! Every unmodelled effect changes the run in the expected direction.

use simgap_core::robots::paper_arm;
use simgap_core::{gravity_torques, kinetic_energy, potential_energy, Formulation, Model, Workspace};
use simgap_sim::effects::{friction_slope_bound, smooth_sign};
use simgap_sim::paper;
use simgap_sim::{
    applied_torque, friction_torque, simulate, Controller, Effect, EffectKind, LinkDelta, MemorySink, Pd, Plant, Replay, Run, RunEnd, SensorParams, SimParams, ZeroTorque,
};

fn run(model: &Model, effects: &[Effect], controller: &mut dyn Controller, params: &SimParams) -> Run {
    let plant = Plant::new(model, Formulation::EulerLagrange, effects).unwrap();
    let mut sink = MemorySink::new();
    let end = simulate(&plant, controller, &paper::reference(), params, &mut sink, None).unwrap();
    assert_eq!(end, RunEnd::Completed);
    sink.into_run()
}

fn paper_pd() -> Pd {
    paper::controller()
}

fn exact(duration: f64) -> SimParams {
    SimParams { duration, sensor: SensorParams::exact(), ..SimParams::default() }
}

fn pd_run(effects: &[Effect], duration: f64) -> Run {
    run(&Model::paper_arm(), effects, &mut paper_pd(), &exact(duration))
}

fn last(run: &Run) -> Vec<f64> {
    run.row(&run.q, run.len() - 1).to_vec()
}

/// Total energy (nominal model) at every sample of a free-motion run.
fn energies(model: &Model, run: &Run) -> Vec<f64> {
    let mut ws = Workspace::new(model);
    (0..run.len()).map(|k| kinetic_energy(model, &mut ws, run.row(&run.q, k), run.row(&run.qd, k)) + potential_energy(model, &mut ws, run.row(&run.q, k))).collect()
}

fn free_params() -> SimParams {
    SimParams { duration: 3.0, sensor: SensorParams::exact(), q0: vec![1.0, -0.5], qd0: vec![1.0, 2.0], substeps: 8, ..SimParams::default() }
}

#[test]
fn every_effect_name_parses() {
    let specs = [
        "viscous_friction:b=2.288,0.175",
        "coulomb_friction:fc=7.17,1.734",
        "stribeck_friction:fc=1,1;fs=2,2;vs=0.1,0.1",
        "armature:ia=0.1,0.01",
        "payload:mass=0.5;com=0,0,-0.4",
        "inertial_error:joint=1;mass=0.2;com=0,0,-0.01;inertia=0.001,0,0,0.001,0,0.001",
        "torque_gain:k=0.9,1.1",
        "torque_offset:offset=0.5,-0.2",
        "torque_saturation:limit=200,15",
        "time_delay:delay=0.005",
        "cogging:amplitude=0.3,0.1;periods_per_rev=8,8",
        "coriolis_structure",
        "joint_spring:k=3,0.5;q0=0.1,-0.2",
        "directional_friction:fc_pos=1,2;fc_neg=0.5,1;b_pos=0.1,0.2;b_neg=0.3,0.4;w=0.01",
        "load_friction:fc=0.1,0.2;mu=0.3,0.1;w=0",
        "load_stribeck_friction:fc=0.1,0.2;mu=0.3,0.1;fs=0.2,0.3;mus=0.5,0.2;vs=0.05;w=0",
        "back_emf:kb=0.04,0.02",
        "encoder_offset:offset=0.05,-0.02",
        "backlash:width=0.02,0.01",
    ];
    assert_eq!(specs.len(), EffectKind::ALL.len(), "one spelling per effect");
    for (spec, kind) in specs.iter().zip(EffectKind::ALL) {
        let e = Effect::parse(spec, 2).unwrap_or_else(|err| panic!("{spec}: {err}"));
        assert_eq!(e.kind(), kind);
    }
    assert_eq!(Effect::parse("viscous_friction:b=2", 2).unwrap(), Effect::ViscousFriction { b: vec![2.0, 2.0] });
    assert!(Effect::parse("viscous_friction:b=1,2,3", 2).is_err());
    assert!(Effect::parse("viscous_friction:c=1", 2).is_err());
    assert!(Effect::parse("backlash", 2).is_err(), "backlash needs its width");
    assert!(Effect::parse("viscous_friction:b=-1,0", 2).is_err());
    assert_eq!(Effect::ViscousFriction { b: vec![0.0, 0.175] }.joints_acted(), vec![1]);
    assert_eq!(Effect::TorqueSaturation { limit: vec![f64::INFINITY, 15.0] }.joints_acted(), vec![1]);
}

#[test]
fn friction_torques_have_the_documented_values() {
    let (q, qd) = ([0.3, -0.2], [0.5, -2.0]);
    let mut out = [0.0; 2];
    let w = 0.01;
    friction_torque(&[Effect::ViscousFriction { b: vec![2.288, 0.175] }], &q, &qd, &mut out);
    assert!((out[0] + 2.288 * 0.5).abs() < 1e-15 && (out[1] - 0.175 * 2.0).abs() < 1e-15);
    friction_torque(&[Effect::CoulombFriction { fc: vec![7.17, 1.734], w: vec![w; 2] }], &q, &qd, &mut out);
    assert!((out[0] + 7.17).abs() < 1e-12 && (out[1] - 1.734).abs() < 1e-12);
    // Stribeck: fs near rest, fc at speed
    let st = [Effect::StribeckFriction { fc: vec![1.0, 1.0], fs: vec![2.0, 2.0], vs: vec![0.1, 0.1], w: vec![1e-4; 2] }];
    friction_torque(&st, &q, &[0.05, 10.0], &mut out);
    assert!((out[0] + (1.0 + (-0.25f64).exp())).abs() < 1e-9, "{out:?}");
    assert!((out[1] + 1.0).abs() < 1e-9);
    friction_torque(&[Effect::Cogging { amplitude: vec![0.3, 0.0], periods_per_rev: vec![8.0, 8.0] }], &q, &qd, &mut out);
    assert!((out[0] + 0.3 * (8.0f64 * 0.3).sin()).abs() < 1e-15 && out[1] == 0.0);
    assert_eq!(smooth_sign(0.0, w), 0.0);
    let mut slope = [0.0; 2];
    friction_slope_bound(&[Effect::CoulombFriction { fc: vec![7.17, 1.734], w: vec![w; 2] }], &mut slope);
    assert!((slope[1] - 173.4).abs() < 1e-9);
}

#[test]
fn directional_friction_differs_with_the_direction_of_motion() {
    let e = [Effect::DirectionalFriction { fc_pos: vec![2.0, 2.0], fc_neg: vec![1.0, 1.0], b_pos: vec![0.5, 0.5], b_neg: vec![0.1, 0.1], w: vec![1e-4, 0.0] }];
    let mut out = [0.0; 2];
    friction_torque(&e, &[0.0, 0.0], &[1.0, -1.0], &mut out);
    assert!((out[0] + (2.0 + 0.5)).abs() < 1e-12 && (out[1] - (1.0 + 0.1)).abs() < 1e-12, "{out:?}");
    // equal directions are Coulomb plus viscous friction
    let sym = [Effect::DirectionalFriction { fc_pos: vec![2.0; 2], fc_neg: vec![2.0; 2], b_pos: vec![0.5; 2], b_neg: vec![0.5; 2], w: vec![0.01; 2] }];
    let pair = [Effect::CoulombFriction { fc: vec![2.0; 2], w: vec![0.01; 2] }, Effect::ViscousFriction { b: vec![0.5; 2] }];
    let (mut a, mut b) = ([0.0; 2], [0.0; 2]);
    friction_torque(&sym, &[0.0, 0.0], &[0.004, -0.02], &mut a);
    friction_torque(&pair, &[0.0, 0.0], &[0.004, -0.02], &mut b);
    assert!((a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12, "{a:?} vs {b:?}");
    assert_eq!(EffectKind::DirectionalFriction.unit("b_neg", simgap_core::JointKind::Prismatic), Some("N·s/m"));
    assert_eq!(EffectKind::DirectionalFriction.unit("w", simgap_core::JointKind::Prismatic), Some("m/s"));
}

#[test]
fn a_joint_spring_pulls_back_to_its_rest_position() {
    let mut out = [0.0; 2];
    friction_torque(&[Effect::JointSpring { k: vec![3.0, 0.0], q0: vec![0.1, 5.0] }], &[0.4, -1.0], &[0.7, 0.7], &mut out);
    assert!((out[0] + 3.0 * 0.3).abs() < 1e-15 && out[1] == 0.0, "{out:?}");
    assert_eq!(Effect::JointSpring { k: vec![3.0, 0.0], q0: vec![0.1, 5.0] }.joints_acted(), vec![0]);
    assert!(Effect::parse("joint_spring:k=-1;q0=0", 2).is_err());
    assert_eq!(EffectKind::JointSpring.unit("k", simgap_core::JointKind::Prismatic), Some("N/m"));
    assert_eq!(EffectKind::JointSpring.unit("q0", simgap_core::JointKind::Revolute), Some("rad"));
}

#[test]
fn each_dry_friction_smooths_its_sign_with_its_own_width() {
    // tanh(q̇ / w) per joint: at q̇ = w the level is fc tanh(1), at q̇ = 0.1 w it is fc tanh(0.1)
    let (q, qd) = ([0.0, 0.0], [0.02, 0.002]);
    let mut out = [0.0; 2];
    friction_torque(&[Effect::CoulombFriction { fc: vec![2.0, 3.0], w: vec![0.02, 0.02] }], &q, &qd, &mut out);
    assert!((out[0] + 2.0 * 1.0f64.tanh()).abs() < 1e-12 && (out[1] + 3.0 * 0.1f64.tanh()).abs() < 1e-12, "{out:?}");
    // w = 0 is the exact sign
    friction_torque(&[Effect::CoulombFriction { fc: vec![2.0, 3.0], w: vec![0.0, 0.002] }], &q, &qd, &mut out);
    assert!((out[0] + 2.0).abs() < 1e-15 && (out[1] + 3.0 * 1.0f64.tanh()).abs() < 1e-12, "{out:?}");
    // the slope bound is fc / w per joint, nothing for the exact sign
    let mut slope = [0.0; 2];
    friction_slope_bound(&[Effect::CoulombFriction { fc: vec![2.0, 3.0], w: vec![0.0, 0.002] }], &mut slope);
    assert_eq!(slope[0], 0.0);
    assert!((slope[1] - 1500.0).abs() < 1e-9, "{slope:?}");
}

#[test]
fn an_exact_sign_never_asks_for_unbounded_substeps() {
    let model = Model::paper_arm();
    let params = SimParams { substeps: 2, ..SimParams::default() };
    let exact = Plant::new(&model, Formulation::EulerLagrange, &[Effect::CoulombFriction { fc: vec![7.17, 1.734], w: vec![0.0; 2] }]).unwrap();
    assert_eq!(simgap_sim::effective_substeps(&exact, &params), 2);
    // a narrow width raises them, a wider one less
    let narrow = Plant::new(&model, Formulation::EulerLagrange, &[Effect::CoulombFriction { fc: vec![7.17, 1.734], w: vec![1e-3; 2] }]).unwrap();
    let wide = Plant::new(&model, Formulation::EulerLagrange, &[Effect::CoulombFriction { fc: vec![7.17, 1.734], w: vec![1e-2; 2] }]).unwrap();
    let (n, w) = (simgap_sim::effective_substeps(&narrow, &params), simgap_sim::effective_substeps(&wide, &params));
    assert!(n > w && w > 2, "narrow {n}, wide {w}");
}

#[test]
fn a_dry_friction_width_is_parsed_or_defaulted() {
    let e = Effect::parse("coulomb_friction:fc=7.17,1.734;w=0.02,0", 2).unwrap();
    assert_eq!(e, Effect::CoulombFriction { fc: vec![7.17, 1.734], w: vec![0.02, 0.0] });
    let e = Effect::parse("coulomb_friction:fc=1", 2).unwrap();
    assert_eq!(e, Effect::CoulombFriction { fc: vec![1.0, 1.0], w: vec![simgap_sim::DEFAULT_COULOMB_WIDTH; 2] });
    let e = Effect::parse_with_width("stribeck_friction:fc=1;fs=2;vs=0.1", 2, 0.05).unwrap();
    assert_eq!(e, Effect::StribeckFriction { fc: vec![1.0; 2], fs: vec![2.0; 2], vs: vec![0.1; 2], w: vec![0.05; 2] });
    assert!(Effect::parse("coulomb_friction:fc=1;w=-0.01", 2).unwrap_err().to_string().contains("'w'"));
    assert!(Effect::parse_with_width("coulomb_friction:fc=1", 2, f64::NAN).is_err());
    // a width given beats the default
    assert_eq!(Effect::parse_with_width("coulomb_friction:fc=1;w=0.3", 2, f64::NAN).unwrap(), Effect::CoulombFriction { fc: vec![1.0; 2], w: vec![0.3; 2] });
}

#[test]
fn applied_torque_saturates_then_scales_then_offsets() {
    let effects = [Effect::TorqueGain { k: vec![0.5, 2.0] }, Effect::TorqueOffset { offset: vec![1.0, -1.0] }, Effect::TorqueSaturation { limit: vec![10.0, f64::INFINITY] }];
    let mut out = [0.0; 2];
    applied_torque(&effects, &[-50.0, 3.0], &mut out);
    assert_eq!(out, [0.5 * -10.0 + 1.0, 2.0 * 3.0 - 1.0]);
}

#[test]
fn viscous_friction_removes_energy() {
    let model = Model::paper_arm();
    let r = run(&model, &[Effect::ViscousFriction { b: vec![2.288, 0.175] }], &mut ZeroTorque, &free_params());
    let e = energies(&model, &r);
    // energy never increases (up to integration error) and drops substantially
    assert!(e.windows(2).all(|w| w[1] <= w[0] + 1e-9), "energy increased");
    assert!(e[e.len() - 1] < e[0] - 0.5 * (e[0] - e.iter().cloned().fold(f64::INFINITY, f64::min)).abs().min(1.0));
    let free = energies(&model, &run(&model, &[], &mut ZeroTorque, &free_params()));
    assert!(e[e.len() - 1] < free[free.len() - 1] - 1.0);
}

#[test]
fn coulomb_friction_removes_energy_and_stops_the_arm() {
    let model = Model::paper_arm();
    let effects = [Effect::CoulombFriction { fc: vec![7.17, 1.734], w: vec![0.01; 2] }];
    let r = run(&model, &effects, &mut ZeroTorque, &free_params());
    let e = energies(&model, &r);
    assert!(e.windows(2).all(|w| w[1] <= w[0] + 1e-9), "energy increased");
    let qd_end = r.row(&r.qd, r.len() - 1);
    assert!(qd_end.iter().all(|v| v.abs() < 0.05), "still moving: {qd_end:?}");
    // the stiffness guard raised the substeps beyond the requested 8
    let plant = Plant::new(&model, Formulation::EulerLagrange, &effects).unwrap();
    assert!(simgap_sim::effective_substeps(&plant, &free_params()) >= 8);
}

#[test]
fn armature_slows_the_response() {
    let nominal = pd_run(&[], 0.2);
    let heavy = pd_run(&[Effect::Armature { ia: vec![1.0, 0.1] }], 0.2);
    let (a, b) = (last(&nominal), last(&heavy));
    assert!(b[0] < a[0] && b[1] < a[1], "nominal {a:?}, with armature {b:?}");
}

#[test]
fn payload_and_heavier_links_increase_the_gravity_sag() {
    // PD without gravity compensation settles where Kp q̃ = g(q): more mass, more error
    let nominal = last(&pd_run(&[], 8.0));
    let payload = last(&pd_run(&[Effect::Payload { mass: 1.0, com: [0.0, 0.0, -0.45] }], 8.0));
    let heavier = last(&pd_run(&[Effect::InertialError { deltas: vec![LinkDelta { joint: 1, mass: 1.0, com: [0.0; 3], inertia: [0.0; 6] }] }], 8.0));
    for q in [&payload, &heavier] {
        assert!(q[0] < nominal[0], "shoulder: nominal {nominal:?}, loaded {q:?}");
    }
    // the steady state satisfies Kp q̃ = g of the loaded model
    let plant = Plant::new(&Model::paper_arm(), Formulation::EulerLagrange, &[Effect::Payload { mass: 1.0, com: [0.0, 0.0, -0.45] }]).unwrap();
    let g = gravity_torques(plant.model(), &mut Workspace::new(plant.model()), &payload);
    for i in 0..2 {
        assert!((paper::KP[i] * (paper::Q_DESIRED[i] - payload[i]) - g[i]).abs() < 1e-3);
    }
    // a negative payload that makes the link massless is refused
    assert!(Plant::new(&Model::paper_arm(), Formulation::EulerLagrange, &[Effect::Payload { mass: -10.0, com: [0.0; 3] }]).is_err());
}

#[test]
fn torque_gain_and_offset_shift_the_steady_state() {
    let nominal = last(&pd_run(&[], 8.0));
    let weak = last(&pd_run(&[Effect::TorqueGain { k: vec![0.8, 1.0] }], 8.0));
    assert!(weak[0] < nominal[0], "a weaker shoulder sags more: {nominal:?} vs {weak:?}");
    let pushed = last(&pd_run(&[Effect::TorqueOffset { offset: vec![0.0, 1.0] }], 8.0));
    assert!(pushed[1] > nominal[1], "a positive elbow offset raises the elbow: {nominal:?} vs {pushed:?}");
}

#[test]
fn an_encoder_offset_is_the_nominal_arm_read_through_a_shifted_zero() {
    // free motion: the arm with offset δ started at measured q0 is the nominal arm started at
    // q0 + δ, logged δ lower
    let model = Model::paper_arm();
    let delta = [0.05, -0.08];
    let offset = run(&model, &[Effect::EncoderOffset { offset: delta.to_vec() }], &mut ZeroTorque, &free_params());
    let p = free_params();
    let shifted_start = SimParams { q0: p.q0.iter().zip(delta).map(|(q, d)| q + d).collect(), ..p };
    let nominal = run(&model, &[], &mut ZeroTorque, &shifted_start);
    let d = offset.q.chunks(2).zip(nominal.q.chunks(2)).flat_map(|(a, b)| [a[0] + delta[0] - b[0], a[1] + delta[1] - b[1]]).fold(0.0f64, |m, x| m.max(x.abs()));
    assert!(d < 1e-9, "{d}");
    // under PD control on the measured angle, gravity acts at the true one: the sag differs
    let nominal_pd = last(&pd_run(&[], 8.0));
    let offset_pd = last(&pd_run(&[Effect::EncoderOffset { offset: delta.to_vec() }], 8.0));
    assert!((offset_pd[0] - nominal_pd[0]).abs() > 1e-4, "{nominal_pd:?} vs {offset_pd:?}");
}

#[test]
fn saturation_equals_replaying_clamped_commands() {
    // logged effort is the command; the plant applies the clamped command
    let model = Model::paper_arm();
    let limits = paper_arm::TORQUE_LIMITS.to_vec();
    let saturated = pd_run(&[Effect::TorqueSaturation { limit: limits.clone() }], 1.0);
    let max_elbow = saturated.column(&saturated.tau, 1).iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(max_elbow > 15.0, "the logged command is not clamped ({max_elbow})");
    let clamped: Vec<f64> = saturated.tau.chunks(2).flat_map(|r| [r[0].clamp(-limits[0], limits[0]), r[1].clamp(-limits[1], limits[1])]).collect();
    let replayed = run(&model, &[], &mut Replay::new(saturated.t.clone(), clamped).unwrap(), &exact(1.0));
    let d = saturated.q.iter().zip(&replayed.q).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    assert!(d < 1e-12, "{d}");
    // and the same comes from the model's effort limits
    let from_model = run(&model, &[], &mut paper_pd(), &SimParams { torque_limits_from_model: true, ..exact(1.0) });
    assert!(from_model.q.iter().zip(&saturated.q).all(|(a, b)| (a - b).abs() < 1e-12));
    // saturation slows the elbow
    let free = pd_run(&[], 1.0);
    assert!(saturated.q[2 * 20 + 1] < free.q[2 * 20 + 1]);
}

#[test]
fn time_delay_equals_replaying_shifted_commands() {
    let model = Model::paper_arm();
    let m = 3;
    let delayed = pd_run(&[Effect::TimeDelay { delay: m as f64 * paper::SAMPLE_PERIOD }], 1.0);
    // the plant applied τ_cmd,k−m (τ_cmd,0 before the start)
    let n = 2;
    let shifted: Vec<f64> = (0..delayed.len()).flat_map(|k| delayed.row(&delayed.tau, k.saturating_sub(m)).to_vec()).collect();
    let replayed = run(&model, &[], &mut Replay::new(delayed.t.clone(), shifted).unwrap(), &exact(1.0));
    let d = delayed.q.iter().zip(&replayed.q).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    assert!(d < 1e-12, "{d}");
    // a fractional delay lies between its neighbours
    let half = pd_run(&[Effect::TimeDelay { delay: 2.5 * paper::SAMPLE_PERIOD }], 1.0);
    let two = pd_run(&[Effect::TimeDelay { delay: 2.0 * paper::SAMPLE_PERIOD }], 1.0);
    let k = 40 * n;
    let (lo, hi) = (two.q[k].min(delayed.q[k]), two.q[k].max(delayed.q[k]));
    assert!(half.q[k] > lo && half.q[k] < hi, "{} not in [{lo}, {hi}]", half.q[k]);
}

#[test]
fn cogging_is_conservative_and_shifts_the_steady_state() {
    // −A sin(N q) = −∂V/∂q with V = A (1 − cos N q) / N, so energy plus V is conserved in
    // free motion
    let model = Model::paper_arm();
    let (a, nper) = (0.5, 8.0);
    let effects = [Effect::Cogging { amplitude: vec![a, 0.0], periods_per_rev: vec![nper, 0.0] }];
    let r = run(&model, &effects, &mut ZeroTorque, &SimParams { substeps: 16, ..free_params() });
    let e: Vec<f64> = energies(&model, &r).iter().enumerate().map(|(k, e)| e + a / nper * (1.0 - (nper * r.q[2 * k]).cos())).collect();
    let drift = e.iter().map(|x| (x - e[0]).abs()).fold(0.0, f64::max);
    assert!(drift < 1e-8 * e[0].abs(), "drift {drift}");
    let nominal = last(&pd_run(&[], 8.0));
    let cogged = last(&pd_run(&effects, 8.0));
    assert!((cogged[0] - nominal[0]).abs() > 1e-4);
}

#[test]
fn coriolis_structure_swaps_the_formulation() {
    let model = Model::paper_arm();
    let plant = Plant::new(&model, Formulation::EulerLagrange, &[Effect::CoriolisStructure]).unwrap();
    assert_eq!(plant.formulation(), Formulation::Simplified);
    let swapped = pd_run(&[Effect::CoriolisStructure], 1.5);
    let simplified = {
        let plant = Plant::new(&model, Formulation::Simplified, &[]).unwrap();
        let mut sink = MemorySink::new();
        simulate(&plant, &mut paper_pd(), &paper::reference(), &exact(1.5), &mut sink, None).unwrap();
        sink.into_run()
    };
    assert_eq!(swapped.q, simplified.q);
    let nominal = pd_run(&[], 1.5);
    assert!(nominal.q.iter().zip(&swapped.q).any(|(a, b)| (a - b).abs() > 1e-5));
}

#[test]
fn stribeck_friction_removes_energy() {
    let model = Model::paper_arm();
    let r = run(&model, &[Effect::StribeckFriction { fc: vec![2.0, 0.5], fs: vec![3.0, 0.8], vs: vec![0.1, 0.1], w: vec![0.01; 2] }], &mut ZeroTorque, &free_params());
    let e = energies(&model, &r);
    assert!(e.windows(2).all(|w| w[1] <= w[0] + 1e-9), "energy increased");
    assert!(e[e.len() - 1] < e[0]);
}

#[test]
fn a_non_physical_armature_diverges_instead_of_panicking() {
    // H + diag(ia) not positive definite: the plant reports NaN, the run ends as diverged
    let model = Model::paper_arm();
    let plant = Plant::new(&model, Formulation::EulerLagrange, &[Effect::Armature { ia: vec![0.0, -1.0] }]).unwrap();
    let mut sink = MemorySink::new();
    let end = simulate(&plant, &mut paper_pd(), &paper::reference(), &exact(1.0), &mut sink, None).unwrap();
    assert!(matches!(end, RunEnd::Diverged { .. }), "{end:?}");
    assert!(sink.into_run().q.iter().all(|x| x.is_finite()));
}
