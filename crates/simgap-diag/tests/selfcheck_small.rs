//! A small self-check: one cycle of blind scenarios (random ones and one of every named
//! family), scored against the hidden truth.

use rayon::prelude::*;
use simgap_diag::selfcheck::{family_of, run_scenario, summarise, FAMILIES};

#[test]
fn fit_recovers_known_effects_in_blind_scenarios() {
    // one cycle: four random scenarios and one of each named family
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
    let right = scores.iter().filter(|s| s.right).count();
    assert!(right * 3 >= n * 2 - 2, "only {right} of {n} scenarios right");
    // the families whose scoring has its own rule, and the delay, are right here
    for s in scores.iter().filter(|s| matches!(s.family.as_str(), "glitch" | "passive_joint" | "friction_shape" | "delay")) {
        assert!(s.right, "scenario {} ({}) is wrong: hidden {:?}, selected {:?}; {}", s.index, s.family, s.truth, s.found, s.rule);
    }
    // the reported intervals hold the truth at least as often as the block bootstrap's
    let (inside, count) = sum.coverage;
    let (boot, boot_count) = sum.coverage_variants.get("block_bootstrap").copied().unwrap_or((0, 0));
    assert_eq!(count, boot_count);
    assert!(inside >= boot, "reported intervals hold {inside} of {count} true values, the block bootstrap's {boot}");
    assert!(count == 0 || inside * 3 >= count * 2, "reported intervals hold only {inside} of {count} true values");
}

#[test]
fn families_cycle_through_every_named_family() {
    let named: Vec<&str> = (0..13).map(family_of).filter(|f| *f != "random").collect();
    assert_eq!(named, FAMILIES[2..].to_vec());
    assert_eq!((0..13).filter(|i| family_of(*i) == "random").count(), 4);
}
