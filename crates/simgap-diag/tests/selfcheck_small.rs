//! A small self-check: blind scenarios with hidden effects, scored against the truth.

use simgap_diag::selfcheck::{run_scenario, summarise};

#[test]
fn fit_recovers_known_effects_in_blind_scenarios() {
    let n: usize = std::env::var("SIMGAP_SELFCHECK_N").ok().and_then(|s| s.parse().ok()).unwrap_or(6);
    let scores: Vec<_> = (0..n).map(|i| run_scenario(42, i)).collect();
    for s in &scores {
        eprintln!(
            "{:>3} {:<10} exact={:<5} truth={:?} found={:?} ratio={:.3} perr={:?} {:?}",
            s.index, s.robot, s.exact, s.truth, s.found, s.holdout_ratio, s.parameter_errors, s.error
        );
    }
    let sum = summarise(&scores);
    eprintln!("{}", serde_json::to_string_pretty(&sum).unwrap());
    let exact = scores.iter().filter(|s| s.exact).count();
    assert!(sum.failures == 0, "scenarios failed to run");
    assert!(exact * 3 >= n * 2, "only {exact} of {n} scenarios diagnosed exactly");
}
