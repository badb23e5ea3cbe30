//! The self-check's summary: scenario scores aggregated per number of hidden effects, per family,
//! into a confusion table and the coverage of the reported 95 % intervals ([`summarise`]).

use std::collections::{BTreeMap, BTreeSet};

use simgap_sim::EffectKind;

use super::score::ScenarioScore;

/// Aggregate of a self-check.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Summary {
    /// Random scenarios (`closed_loop`, `open_loop`) per number of hidden effects: (count,
    /// exactly right, right up to an alternative the data cannot tell apart).
    pub by_count: BTreeMap<usize, (usize, usize, usize)>,
    /// Per family: (scenarios, right by the family's rule, median held-out k-step after/before
    /// at 0.5 s over scenarios with a hidden difference).
    pub by_family: BTreeMap<String, (usize, usize, f64)>,
    /// Scenarios with a hidden time delay: (count, time delay selected).
    pub delays_found: (usize, usize),
    /// Found parameters with a reported 95 % interval: (truth inside, count).
    pub coverage: (usize, usize),
    /// The same for each interval method on its own.
    pub coverage_variants: BTreeMap<String, (usize, usize)>,
    /// Confusion counts: true effect (or `none`) → selected effect (or `nothing`) → count.
    pub confusion: BTreeMap<String, BTreeMap<String, usize>>,
    /// Median relative parameter error over correctly found effects.
    pub median_parameter_error: f64,
    /// Median held-out L² after/before where the true effects were found.
    pub median_holdout_ratio: f64,
    /// Selected effects the report's selection log last rejected
    /// ([`contradicted`](super::contradicted)): (count, selected).
    pub contradicted: (usize, usize),
    /// Selected effects ([`implausible`](super::implausible)): (outside their physical range or
    /// consistent with no effect, selected in all).
    pub implausible: (usize, usize),
    /// Scenarios that failed to run.
    pub failures: usize,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    }
}

/// Aggregates scenario scores.
pub fn summarise(scores: &[ScenarioScore]) -> Summary {
    let mut by_count: BTreeMap<usize, (usize, usize, usize)> = BTreeMap::new();
    let mut by_family: BTreeMap<String, (usize, usize, Vec<f64>)> = BTreeMap::new();
    let mut confusion: BTreeMap<String, BTreeMap<String, usize>> = BTreeMap::new();
    let mut coverage_variants: BTreeMap<String, (usize, usize)> = BTreeMap::new();
    let (mut coverage, mut delays_found) = ((0, 0), (0, 0));
    let mut perr = Vec::new();
    let mut ratios = Vec::new();
    let mut failures = 0;
    let mut implausible = (0, 0);
    let mut contradicted = (0, 0);
    let base = |s: &str| s.split('@').next().unwrap_or(s).to_string();
    for s in scores {
        let f = by_family.entry(s.family.clone()).or_insert((0, 0, Vec::new()));
        f.0 += 1;
        if s.error.is_some() {
            failures += 1;
            continue;
        }
        let true_effects: BTreeSet<String> = s.truth.iter().map(|x| base(x)).collect();
        let found_effects: BTreeSet<String> = s.found.iter().map(|x| base(x)).collect();
        if s.right {
            f.1 += 1;
        }
        if !true_effects.is_empty() {
            f.2.push(s.kstep_ratio);
        }
        if matches!(s.family.as_str(), "closed_loop" | "open_loop") {
            let e = by_count.entry(true_effects.len()).or_insert((0, 0, 0));
            e.0 += 1;
            if s.exact {
                e.1 += 1;
            }
            if s.exact || s.in_alternatives {
                e.2 += 1;
            }
        }
        if true_effects.contains(EffectKind::TimeDelay.as_str()) {
            delays_found.0 += 1;
            if found_effects.contains(EffectKind::TimeDelay.as_str()) {
                delays_found.1 += 1;
            }
        }
        coverage.0 += s.intervals.iter().filter(|i| i.4).count();
        coverage.1 += s.intervals.len();
        for (k, (inside, count)) in &s.interval_variants {
            let v = coverage_variants.entry(k.clone()).or_insert((0, 0));
            v.0 += inside;
            v.1 += count;
        }
        let rows: Vec<String> = if true_effects.is_empty() { vec!["none".into()] } else { true_effects.iter().cloned().collect() };
        let cols: Vec<String> = if found_effects.is_empty() { vec!["nothing".into()] } else { found_effects.iter().cloned().collect() };
        for r in &rows {
            for c in &cols {
                *confusion.entry(r.clone()).or_default().entry(c.clone()).or_default() += 1;
            }
        }
        perr.extend(s.parameter_errors.iter().map(|p| p.1));
        implausible.0 += s.implausible.len();
        implausible.1 += s.found.len();
        contradicted.0 += s.contradicted.len();
        contradicted.1 += s.found.len();
        if s.exact && !true_effects.is_empty() {
            ratios.push(s.holdout_ratio);
        }
    }
    let by_family = by_family.into_iter().map(|(k, (n, right, r))| (k, (n, right, median(r)))).collect();
    Summary {
        by_count,
        by_family,
        delays_found,
        coverage,
        coverage_variants,
        confusion,
        median_parameter_error: median(perr),
        median_holdout_ratio: median(ratios),
        implausible,
        contradicted,
        failures,
    }
}
