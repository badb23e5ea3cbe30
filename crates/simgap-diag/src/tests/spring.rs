//! A joint spring hidden in the paper's arm is found blind, with its stiffness and rest
//! position, and held out runs are predicted better.

use crate::check::bench::{demo_specs, generate};
use crate::{diagnose, DiagnoseOptions, Param};
use simgap_core::{Formulation, Model};
use simgap_sim::Effect;

#[test]
fn a_hidden_joint_spring_is_found_with_its_stiffness_and_rest_position() {
    let model = Model::paper_arm();
    let hidden = [Effect::JointSpring { k: vec![0.0, 4.0], q0: vec![0.0, 0.3] }];
    let (fit_specs, hold_specs) = demo_specs(1);
    let gen = |s| generate(&model, Formulation::EulerLagrange, &hidden, s, 0.0025, 1_024_000.0).unwrap();
    let fit: Vec<_> = fit_specs.iter().map(gen).collect();
    let hold: Vec<_> = hold_specs.iter().map(gen).collect();
    let d = diagnose(&model, Formulation::EulerLagrange, &fit, &hold, &DiagnoseOptions::default(), &mut |_| {}).unwrap();
    let names: Vec<&str> = d.report.selected_effects.iter().map(|e| e.effect.as_str()).collect();
    assert_eq!(names, ["joint_spring"], "{}", d.report.summary());
    let e = &d.report.selected_effects[0];
    assert_eq!(e.joints, ["elbow"]);
    let value = |key: &str| match &e.parameters[key] {
        Param::PerJoint(v) => v[0],
        other => panic!("{key}: {other:?}"),
    };
    let (k, q0) = (value("k"), value("q0"));
    assert!((k - 4.0).abs() < 0.1 * 4.0 && (q0 - 0.3).abs() < 0.03, "k = {k}, q0 = {q0}");
    assert_eq!(e.units["k"], "N·m/rad");
    assert_eq!(e.units["q0"], "rad");
    assert!(d.report.gap.kstep.after.iter().zip(&d.report.gap.kstep.before).all(|(a, b)| a < &(0.5 * b)), "{:?}", d.report.gap.kstep);
}

#[test]
fn a_torque_offset_on_a_sprung_joint_is_the_springs_rest_position() {
    // −k (q − q0) + o = −k (q − (q0 + o/k)): the same torque at every state, so no data tell an
    // offset on the spring's joint from the spring's rest position
    let (k, q0, o) = (2.0, 0.3, 0.5);
    let with_offset = [Effect::JointSpring { k: vec![0.0, k], q0: vec![0.0, q0] }, Effect::TorqueOffset { offset: vec![0.7, o] }];
    let folded = [Effect::JointSpring { k: vec![0.0, k], q0: vec![0.0, q0 + o / k] }, Effect::TorqueOffset { offset: vec![0.7, 0.0] }];
    let total = |effects: &[Effect], q: &[f64], qd: &[f64], tau: &[f64]| {
        let (mut passive, mut applied) = ([0.0; 2], [0.0; 2]);
        simgap_sim::friction_torque(effects, q, qd, &mut passive);
        simgap_sim::applied_torque(effects, tau, &mut applied);
        [passive[0] + applied[0], passive[1] + applied[1]]
    };
    for (q, qd, tau) in [([0.2, -0.4], [0.1, 0.3], [1.0, 2.0]), ([-1.0, 1.3], [-0.5, 0.0], [0.0, -3.0])] {
        let (a, b) = (total(&with_offset, &q, &qd, &tau), total(&folded, &q, &qd, &tau));
        assert!((a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12, "{a:?} against {b:?}");
    }
    // the self-check's truth: the spring, and the offset only where no spring is
    let model = Model::paper_arm();
    let truth = crate::check::selfcheck::truth_set(&model, &with_offset);
    let pairs: Vec<(&str, Option<&str>)> = truth.iter().map(|(e, j)| (e.as_str(), j.as_deref())).collect();
    assert_eq!(pairs, [("joint_spring", Some("elbow")), ("torque_offset", Some("shoulder"))]);
}
