//! An encoder offset hidden in the paper's arm (the shoulder's measured zero 3° off) is found
//! blind, with its value, and held-out runs are predicted better.

use super::common::paper_arm_diagnosed as diagnosed;
use simgap_sim::{Effect, EffectKind};

#[test]
fn a_hidden_encoder_offset_is_found_with_its_value() {
    let delta = 3f64.to_radians();
    let d = diagnosed(&[Effect::EncoderOffset { offset: vec![delta, 0.0] }]);
    let names: Vec<EffectKind> = d.report.selected_effects.iter().map(|e| e.effect).collect();
    assert_eq!(names, [EffectKind::EncoderOffset], "{}", d.report.summary());
    let e = &d.report.selected_effects[0];
    assert_eq!(e.joints, ["shoulder"]);
    let found = e.value("offset", "shoulder").unwrap();
    assert!((found - delta).abs() < 0.1 * delta, "offset {found} against {delta}");
    assert_eq!(e.units["offset"], "rad");
    assert!(d.report.gap.kstep.after.iter().zip(&d.report.gap.kstep.before).all(|(a, b)| a < &(0.5 * b)), "{:?}", d.report.gap.kstep);
}

#[test]
fn an_offset_on_the_last_joint_is_one_parameter_not_an_inertial_correction() {
    // the last link turned by δ is that link with its centre of mass turned by δ: the two
    // explain the runs alike, and the offset does it with one parameter
    let delta = -3f64.to_radians();
    let d = diagnosed(&[Effect::EncoderOffset { offset: vec![0.0, delta] }]);
    let names: Vec<EffectKind> = d.report.selected_effects.iter().map(|e| e.effect).collect();
    assert_eq!(names, [EffectKind::EncoderOffset], "{}", d.report.summary());
    let found = d.report.selected_effects[0].value("offset", "elbow").unwrap();
    assert!((found - delta).abs() < 0.1 * delta.abs(), "offset {found} against {delta}");
}
