//! The demo's bench robot (the paper's arm with its published friction and the elbow's 15 N·m
//! limit hidden) is diagnosed blind: the exact effect set, parameters within 10 % (the width `w`
//! of the dry friction's smoothed sign, which the hidden plant sets to 0.01 rad/s, within 50 %),
//! and the held-out gap shrinks.

use simgap_core::{Formulation, Model};
use simgap_diag::bench::{demo_effects, demo_specs, generate};
use simgap_diag::{diagnose, DiagnoseOptions, Param};

fn param(d: &simgap_diag::Diagnosis, effect: &str, key: &str, joint: &str) -> f64 {
    let e = d.report.selected_effects.iter().find(|e| e.effect.as_str() == effect).unwrap_or_else(|| panic!("{effect} not selected"));
    let i = e.joints.iter().position(|j| j == joint).unwrap_or_else(|| panic!("{effect} not on {joint}"));
    match &e.parameters[key] {
        Param::PerJoint(v) => v[i],
        other => panic!("{effect}.{key}: {other:?}"),
    }
}

#[test]
fn fit_recovers_known_parameters_from_synthetic_data() {
    let model = Model::paper_arm();
    let effects = demo_effects();
    let (fit, hold) = demo_specs(1);
    let gen = |s| generate(&model, Formulation::EulerLagrange, &effects, s, 0.0025, 1_024_000.0).unwrap();
    let fit: Vec<_> = fit.iter().map(gen).collect();
    let hold: Vec<_> = hold.iter().map(gen).collect();
    let d = diagnose(&model, Formulation::EulerLagrange, &fit, &hold, &DiagnoseOptions::default(), &mut |_| {}).unwrap();
    let mut names: Vec<&str> = d.report.selected_effects.iter().map(|e| e.effect.as_str()).collect();
    names.sort();
    assert_eq!(names, ["coulomb_friction", "torque_saturation", "viscous_friction"], "{}", d.report.summary());
    for (effect, key, joint, truth, tolerance) in [
        ("viscous_friction", "b", "shoulder", 2.288, 0.1),
        ("viscous_friction", "b", "elbow", 0.175, 0.1),
        ("coulomb_friction", "fc", "shoulder", 7.17, 0.1),
        ("coulomb_friction", "fc", "elbow", 1.734, 0.1),
        ("coulomb_friction", "w", "shoulder", 0.01, 0.5),
        ("coulomb_friction", "w", "elbow", 0.01, 0.5),
        ("torque_saturation", "limit", "elbow", 15.0, 0.1),
    ] {
        let found = param(&d, effect, key, joint);
        assert!((found - truth).abs() <= tolerance * truth, "{effect}.{key} on {joint}: found {found}, truth {truth}");
    }
    assert!(d.report.gap.holdout_l2_after < 0.05 * d.report.gap.holdout_l2_before, "{}", d.report.summary());
}
