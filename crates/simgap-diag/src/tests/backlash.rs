//! Backlash hidden in the paper's arm (the elbow's gear train with play, its rotor inertia
//! known to the truth) is found blind by prediction, and held-out runs are predicted better.

use super::common::paper_arm_diagnosed as diagnosed;
use simgap_sim::{Effect, EffectKind};

#[test]
fn play_in_the_elbows_gears_is_found_beside_its_rotor_inertia() {
    // 1.5°, between two widths of the search's grid
    let width = 1.5f64.to_radians();
    let d = diagnosed(&[Effect::Armature { ia: vec![0.0, 0.5] }, Effect::Backlash { width: vec![0.0, width] }]);
    let names: Vec<EffectKind> = d.report.selected_effects.iter().map(|e| e.effect).collect();
    assert_eq!(names, [EffectKind::Armature, EffectKind::Backlash], "{}", d.report.summary());
    let play = &d.report.selected_effects[1];
    assert_eq!(play.joints, ["elbow"]);
    let found = play.value("width", "elbow").unwrap();
    assert!((found / width).ln().abs() < 0.2f64.ln_1p(), "width {found} against {width}");
    // inside the widths searched: known to the search's step, no end of the search to name
    let note = d.report.notes.iter().find(|n| n.starts_with("backlash on elbow: a width of")).unwrap_or_else(|| panic!("no note of the width's precision: {:?}", d.report.notes));
    assert!(note.contains("a factor of √2") && !note.contains("may be"), "{note}");
    assert!(d.report.gap.kstep.after.iter().zip(&d.report.gap.kstep.before).all(|(a, b)| a < &(0.5 * b)), "{:?}", d.report.gap.kstep);
    // the shoulder, skipped on every pass of the search (no rotor inertia there), gets one note
    let shoulder = d.report.notes.iter().filter(|n| n.starts_with("backlash not tried on shoulder")).count();
    assert!(shoulder <= 1, "{:?}", d.report.notes);
}

#[test]
fn a_rotor_inertia_without_play_gets_no_backlash() {
    let d = diagnosed(&[Effect::Armature { ia: vec![0.0, 0.5] }]);
    let names: Vec<EffectKind> = d.report.selected_effects.iter().map(|e| e.effect).collect();
    assert_eq!(names, [EffectKind::Armature], "{}", d.report.summary());
    assert!(d.report.notes.iter().any(|n| n.starts_with("backlash tried on elbow")), "{:?}", d.report.notes);
}

#[test]
fn play_as_wide_as_the_widest_width_searched_is_found() {
    // 4°, the widest of the grid: found, the search refining one step past it
    let width = 4f64.to_radians();
    let d = diagnosed(&[Effect::Armature { ia: vec![0.0, 0.5] }, Effect::Backlash { width: vec![0.0, width] }]);
    let play = d.report.selected_effects.iter().find(|e| e.effect == EffectKind::Backlash).unwrap_or_else(|| panic!("no play: {:?}", d.report.notes));
    let found = play.value("width", "elbow").unwrap();
    assert!(found >= width * 0.8 && found <= width * 2f64.sqrt() * 1.001, "width {found} against {width}");
    // the report says the width is known to the search's step, and that it lies at the end of the
    // widths searched (a wider play would read the same)
    let note = d.report.notes.iter().find(|n| n.starts_with("backlash on elbow: a width of")).unwrap_or_else(|| panic!("no note of the width's precision: {:?}", d.report.notes));
    assert!(note.contains("a factor of √2") && note.contains("the play may be wider"), "{note}");
}
