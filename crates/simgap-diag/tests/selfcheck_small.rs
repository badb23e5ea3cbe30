//! A small self-check: one cycle of blind scenarios (random ones and one of every named
//! family), scored against the hidden truth.

use rayon::prelude::*;
use simgap_diag::selfcheck::{family_of, run_scenario, run_servo_scenario, summarise, FAMILIES};

#[test]
fn fit_recovers_known_effects_in_blind_scenarios() {
    // one cycle: four random scenarios and one of each named family (a second cycle draws four
    // 7-DOF scenarios of minutes each, and its 7-DOF delay is missed: that is left to the
    // 200-scenario run; SIMGAP_SELFCHECK_N=26 runs it)
    let n: usize = std::env::var("SIMGAP_SELFCHECK_N").ok().and_then(|s| s.parse().ok()).unwrap_or(13);
    let scores: Vec<_> = (0..n).into_par_iter().map(|i| run_scenario(42, i)).collect();
    for s in &scores {
        eprintln!(
            "{:>3} {:<22} {:<15} right={:<5} truth={:?} found={:?} kstep={:.3} intervals={:?} {} {:?}",
            s.index, s.family, s.robot, s.right, s.truth, s.found, s.kstep_ratio, s.intervals, s.rule, s.error
        );
    }
    let sum = summarise(&scores);
    eprintln!("{}", serde_json::to_string_pretty(&sum).unwrap());
    assert!(sum.failures == 0, "scenarios failed to run");
    if n >= 13 {
        for f in &FAMILIES[2..] {
            assert!(scores.iter().any(|s| s.family == *f), "family {f} not drawn in {n} scenarios");
        }
    }
    // the 200-scenario run's targets, adjusted to this size: at least 90 % right (12 of 13),
    // every effect-free scenario left clean, two thirds of the hidden delays found
    let right = scores.iter().filter(|s| s.right).count();
    assert!(right * 10 >= n * 9, "only {right} of {n} scenarios right (the target is 90 %)");
    if let Some((count, _, _)) = sum.by_count.get(&0) {
        assert_eq!(sum.by_count[&0].1, *count, "an effect-free scenario selected an effect: {:?}", sum.by_count);
    }
    let (delays, found) = sum.delays_found;
    assert!(found * 3 >= delays * 2, "hidden delays found: {found} of {delays}");
    // the families whose scoring has its own rule, and the delay, are right here
    for s in scores.iter().filter(|s| matches!(s.family.as_str(), "glitch" | "passive_joint" | "friction_shape" | "delay")) {
        assert!(s.right, "scenario {} ({}) is wrong: hidden {:?}, selected {:?}; {}", s.index, s.family, s.truth, s.found, s.rule);
    }
    // the reported intervals hold the truth at least as often as the block bootstrap's, on the
    // scenarios fitted on the torque residual (multiple shooting has no bootstrap)
    let same: Vec<_> = scores.iter().filter(|s| s.interval_variants.contains_key("block_bootstrap")).collect();
    let inside_same: usize = same.iter().map(|s| s.intervals.iter().filter(|i| i.4).count()).sum();
    let count_same: usize = same.iter().map(|s| s.intervals.len()).sum();
    let (boot, boot_count) = same.iter().map(|s| s.interval_variants["block_bootstrap"]).fold((0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    assert_eq!(count_same, boot_count);
    assert!(inside_same >= boot, "reported intervals hold {inside_same} of {count_same} true values, the block bootstrap's {boot}");
    // one cycle reports too few intervals (7 on seed 42) to measure a 90–98 % coverage: it must
    // hold two thirds of them here; the 200-scenario run measures the coverage
    let (inside, count) = sum.coverage;
    assert!(count == 0 || inside * 3 >= count * 2, "reported intervals hold only {inside} of {count} true values");
    every_report_states_what_its_log_kept(&scores);
}

/// No report states an effect its own selection log last rejected.
fn every_report_states_what_its_log_kept(scores: &[simgap_diag::selfcheck::ScenarioScore]) {
    for s in scores {
        assert!(s.contradicted.is_empty(), "scenario {} ({}): selected {:?}, which its selection log last rejected", s.index, s.family, s.contradicted);
    }
}

#[test]
fn families_cycle_through_every_named_family() {
    let named: Vec<&str> = (0..13).map(family_of).filter(|f| *f != "random").collect();
    assert_eq!(named, FAMILIES[2..].to_vec());
    assert_eq!((0..13).filter(|i| family_of(*i) == "random").count(), 4);
}

/// A different torque gain on each joint of the paper's arm (scenario 74 of seed 1: k = 1.146,
/// 0.860). The torque-residual selection takes an inertial correction first (it absorbs most of
/// what the gains do to the residual); the exchange step must replace it by the gains, which
/// predict the fit runs about ten times better.
#[test]
fn per_joint_gains_are_exchanged_for_the_inertial_correction_taken_first() {
    use simgap_core::Formulation;
    use simgap_diag::{diagnose, selfcheck::scenario, DiagnoseOptions};
    use simgap_sim::Effect;
    let sc = scenario(1, 74).expect("scenario 74 of seed 1");
    assert_eq!(sc.family, "per_joint_gains");
    let Some(Effect::TorqueGain { k: truth }) = sc.effects.first().cloned() else { panic!("a torque gain is hidden: {:?}", sc.effects) };
    let d = diagnose(&sc.diagnosis_model, Formulation::EulerLagrange, &sc.fit, &sc.holdout, &DiagnoseOptions::default(), &mut |_| {}).expect("diagnosis");
    let names: Vec<&str> = d.report.selected_effects.iter().map(|e| e.effect.as_str()).collect();
    assert_eq!(names, ["torque_gain"], "selected {names:?}");
    let gain = &d.report.selected_effects[0];
    let Some(simgap_diag::Param::PerJoint(k)) = gain.parameters.get("k") else { panic!("no gains in {:?}", gain.parameters) };
    for (j, (found, true_k)) in k.iter().zip(&truth).enumerate() {
        assert!((found - true_k).abs() <= 0.02 * true_k, "joint {j}: gain {found} against {true_k}");
    }
    assert!(
        d.report.selection_log.iter().any(|s| s.effect.as_str() == "inertial_error" && s.reason.starts_with("exchanged for torque_gain")),
        "the inertial correction was not exchanged"
    );
}

#[test]
fn servo_scenarios_find_the_hidden_mechanics_and_the_motor_constants() {
    // twelve servo scenarios: blind servo logs, no motor-constant priors; three of them (1, 5
    // and 9) with a torque limit below the gravity torque, three (3, 7 and 11) with a load
    // friction rising at rest, diagnosed with it tried
    let scores: Vec<_> = (0..12usize).into_par_iter().map(|i| run_servo_scenario(1, i)).collect();
    for s in &scores {
        eprintln!("seed scenario {} {:<15} right={:<5} truth={:?} found={:?} kstep={:.3} {} {:?}", s.index, s.robot, s.right, s.truth, s.found, s.kstep_ratio, s.rule, s.error);
        assert_eq!(s.family, ["servo", "servo_saturation", "servo", "servo_breakaway"][s.index % 4]);
    }
    let limited: Vec<_> = scores.iter().filter(|s| s.family == "servo_saturation").collect();
    assert_eq!(limited.len(), 3);
    assert!(limited.iter().all(|s| s.found.iter().any(|f| f.starts_with("torque_saturation@"))), "a hidden limit not found");
    let breakaway: Vec<_> = scores.iter().filter(|s| s.family == "servo_breakaway").collect();
    let risen = breakaway.iter().filter(|s| s.found.iter().any(|f| f.starts_with("load_stribeck_friction@"))).count();
    // measured 2 of 3: scenario 11's torque-residual set (a load-independent Stribeck friction
    // with viscous friction) beat the servo's sets, its motor constants fitted 60 % off
    assert!(risen >= 2, "a load friction rising at rest found in {risen} of 3");
    let right = scores.iter().filter(|s| s.right).count();
    // measured 11 of 12 (91.7 %, the 90 % target): scenario 11 above is wrong. It was 10 of 12
    // while a correction of the motor constants and a mechanical term whose intervals both
    // held no effect were tested in the set's order: scenario 5 then kept a load-dependent
    // friction beside its limit and viscous friction (the mechanical terms are now tested
    // first, see the pipeline's plausibility rounds).
    assert!(right >= 11, "{right} of {} servo scenarios right", scores.len());
    // scenario 5, named above
    let five = &scores[5];
    assert!(five.right && !five.found.iter().any(|f| f.starts_with("load_friction@")), "scenario 5: found {:?}, {}", five.found, five.rule);
    every_report_states_what_its_log_kept(&scores);
}

#[test]
fn real_drive_families_are_diagnosed_right_with_plausible_effects() {
    use simgap_diag::{drives::DRIVE_FAMILIES, selfcheck::run_drive_scenario};
    // one cycle of the real-drive families on seed 1 (joint spring, Coulomb trap, directional
    // friction on a linear axis, load friction, filtered signals); the servo family has its
    // test above and link-side sensing its own (`link_side.rs`: a 7-DOF diagnosis of about a
    // minute); SIMGAP_DRIVES_N=14 SIMGAP_DRIVES_SEED=2 runs two cycles of another seed, all
    // families
    let n: Option<usize> = std::env::var("SIMGAP_DRIVES_N").ok().and_then(|s| s.parse().ok());
    let seed: u64 = std::env::var("SIMGAP_DRIVES_SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(1);
    let indices: Vec<usize> = match n {
        Some(n) => (0..n).collect(),
        None => (0..DRIVE_FAMILIES.len()).filter(|i| !matches!(DRIVE_FAMILIES[*i], "servo" | "link_side")).collect(),
    };
    let scores: Vec<_> = indices.par_iter().map(|i| run_drive_scenario(seed, *i)).collect();
    for s in &scores {
        eprintln!(
            "{:>3} {:<22} {:<15} right={:<5} truth={:?} found={:?} kstep={:.3} intervals={:?} implausible={:?} {} {:?}",
            s.index, s.family, s.robot, s.right, s.truth, s.found, s.kstep_ratio, s.intervals, s.implausible, s.rule, s.error
        );
    }
    let sum = summarise(&scores);
    assert_eq!(sum.failures, 0, "scenarios failed to run");
    // every family drawn is right on seed 1, `filtered` (signals low-pass filtered by the
    // recorder) too: its seed-1 scenario read the filter's flattened torque peaks as saturations
    // on both joints beside the Coulomb friction until a recorder's filter was told from the
    // positions (a saturation is then not tried)
    let right = scores.iter().filter(|s| s.right).count();
    if n.is_none() {
        assert_eq!(right, scores.len(), "{right} of {} real-drive scenarios right", scores.len());
    }
    assert_eq!(sum.implausible.0, 0, "selected effects outside their physical range or consistent with no effect");
    every_report_states_what_its_log_kept(&scores);
}

#[test]
fn encoder_offsets_on_servo_arms_are_found_and_not_invented() {
    use simgap_diag::selfcheck::run_encoder_offset_scenario;
    // six servo scenarios with a joint's measured zero 1-5 degrees off (two of them nulls,
    // indices 2 and 5, without one): the offsets found, with their values, and none invented
    let seed: u64 = std::env::var("SIMGAP_OFFSET_SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(1);
    let scores: Vec<_> = (0..6usize).into_par_iter().map(|i| run_encoder_offset_scenario(seed, i)).collect();
    for s in &scores {
        eprintln!(
            "seed {seed} scenario {} {:<15} right={:<5} truth={:?} found={:?} kstep={:.3} {:?} {} {:?}",
            s.index, s.robot, s.right, s.truth, s.found, s.kstep_ratio, s.parameter_errors, s.rule, s.error
        );
    }
    let right = scores.iter().filter(|s| s.right).count();
    assert!(right >= 5, "{right} of {} encoder-offset scenarios right", scores.len());
    let invented = scores.iter().filter(|s| s.index % 3 == 2 && s.found.iter().any(|f| f.starts_with("encoder_offset@"))).count();
    assert_eq!(invented, 0, "an encoder offset found where none was hidden");
}

#[test]
fn backlash_on_servo_arms_is_found_and_not_invented() {
    use simgap_diag::selfcheck::run_backlash_scenario;
    // six servo scenarios with rotor inertias and 0.5-2 degrees of play in their gears (two of
    // them nulls, indices 2 and 5, with the rotor inertias alone): the play found on the joints
    // that have it, and none invented
    let seed: u64 = std::env::var("SIMGAP_BACKLASH_SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(1);
    let scores: Vec<_> = (0..6usize).into_par_iter().map(|i| run_backlash_scenario(seed, i)).collect();
    for s in &scores {
        eprintln!(
            "seed {seed} scenario {} {:<15} right={:<5} truth={:?} found={:?} kstep={:.3} {:?} {} {:?}",
            s.index, s.robot, s.right, s.truth, s.found, s.kstep_ratio, s.parameter_errors, s.rule, s.error
        );
    }
    let play = |names: &[String]| -> Vec<String> { names.iter().filter(|f| f.starts_with("backlash@")).cloned().collect() };
    let found = scores.iter().filter(|s| s.index % 3 != 2 && !play(&s.truth).is_empty() && play(&s.found) == play(&s.truth)).count();
    let right = scores.iter().filter(|s| s.right).count();
    eprintln!("seed {seed}: play found on its joints in {found} of 4 scenarios; {right} of 6 right in every effect");
    // (measured: 3 of 4 on both seeds, 2 of 4 on seed 1 before a set holding play was fitted
    // without the samples where its gap is open; where it is missed, a stand-in the selection
    // took before the play stage predicts better than the play with the rotor)
    assert!(found >= 3, "play found on its joints in {found} of 4 scenarios");
    let invented = scores.iter().filter(|s| s.index % 3 == 2 && !play(&s.found).is_empty()).count();
    assert_eq!(invented, 0, "backlash found where none was hidden");
}

#[test]
fn a_larger_shooting_set_replaces_the_selection_only_when_its_gain_holds_fold_by_fold() {
    use simgap_core::Formulation;
    use simgap_diag::{diagnose, drives, DiagnoseOptions};
    // a pendulum whose logs a recorder low-pass filtered, with viscous friction hidden (the
    // `filtered` family, seed 2, index 41 of the 200-scenario run): shooting's set of an
    // inertial correction with Coulomb and viscous friction and a rotor inertia predicts the
    // fit runs 2.6 % better than the selected viscous friction, pooled, but not fold by fold
    // (measured: upper bound of the ratio 1.57, worst fold 3.1); before that was asked, it
    // replaced the selection and the report named a rotor inertia and an inertial correction
    // the logs do not have
    let sc = drives::drive_scenario(2, 41).expect("scenario");
    assert_eq!(sc.family, "filtered");
    let options = DiagnoseOptions { directional_friction: sc.directional_friction, load_stribeck_friction: sc.load_stribeck_friction, ..DiagnoseOptions::default() };
    let d = diagnose(&sc.diagnosis_model, Formulation::EulerLagrange, &sc.fit, &sc.holdout, &options, &mut |_| {}).expect("diagnosis");
    let found: Vec<&str> = d.report.selected_effects.iter().map(|e| e.effect.as_str()).collect();
    assert_eq!(found, ["viscous_friction"], "notes: {:#?}", d.report.notes);
    assert!(d.report.notes.iter().any(|n| n.contains("does not replace the selected set")), "notes: {:#?}", d.report.notes);
}
