//! `simgap selfcheck`: random blind scenarios diagnosed and scored against the hidden truth.

use std::path::PathBuf;

use rayon::prelude::*;
use simgap::diag::selfcheck::{run_mixed_scenario, summarise, ScenarioScore, Summary};

/// Arguments of `simgap selfcheck`.
#[derive(clap::Args)]
pub(crate) struct Args {
    /// Number of scenarios, 1 ≤ scenarios ≤ 100000.
    #[arg(long, default_value_t = 100)]
    scenarios: usize,
    /// Seed of the scenario generator.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Write every scenario's score and the summary as JSON.
    #[arg(long)]
    json: Option<PathBuf>,
}

fn pct(a: usize, b: usize) -> String {
    if b == 0 {
        "  –".into()
    } else {
        format!("{:5.1} %", 100.0 * a as f64 / b as f64)
    }
}

/// The human-readable table of a self-check.
fn table(sum: &Summary, n: usize, seed: u64) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(s, "simgap selfcheck: {n} blind scenarios, seed {seed}");
    let _ = writeln!(s, "\nrandom scenarios (closed_loop, open_loop)");
    let _ = writeln!(s, "hidden effects   scenarios   true set selected exactly   or among the alternatives");
    for (k, (count, exact, right)) in &sum.by_count {
        let label = match k {
            0 => "none".to_string(),
            1 => "one".to_string(),
            k => format!("{k}"),
        };
        let _ = writeln!(s, "  {label:<14} {count:>9}   {exact:>4}  ({})              {right:>4}  ({})", pct(*exact, *count), pct(*right, *count));
    }
    let _ = writeln!(s, "\nfamily                    scenarios   right              median held-out k-step after/before at 0.5 s");
    for (family, (count, right, ratio)) in &sum.by_family {
        // a family whose scenarios hide no difference has no ratio
        let ratio = if ratio.is_finite() { format!("{ratio:.4}") } else { "  –".into() };
        let _ = writeln!(s, "  {family:<24} {count:>9}   {right:>4}  ({})     {ratio}", pct(*right, *count));
    }
    let (delays, found) = sum.delays_found;
    let _ = writeln!(s, "\nhidden time delays found: {found} of {delays} ({})", pct(found, delays).trim());
    let (inside, count) = sum.coverage;
    let _ = writeln!(s, "true parameter within the reported 95 % interval: {inside} of {count} ({})", pct(inside, count).trim());
    for (name, (inside, count)) in &sum.coverage_variants {
        let _ = writeln!(s, "  with the {} interval alone: {inside} of {count} ({})", name.replace('_', " "), pct(*inside, *count).trim());
    }
    let (odd, selected) = sum.implausible;
    let _ = writeln!(s, "selected effects outside their physical range or whose interval holds no effect: {odd} of {selected}");
    let (odd, selected) = sum.contradicted;
    let _ = writeln!(s, "selected effects the report's own selection log last rejected: {odd} of {selected}");
    let _ = writeln!(s, "\nconfusion (rows: hidden effect, columns: selected effect; a scenario counts once per pair)");
    let mut cols: Vec<String> = sum.confusion.values().flat_map(|m| m.keys().cloned()).collect();
    cols.sort();
    cols.dedup();
    // whole names, each column as wide as its name
    let widths: Vec<usize> = cols.iter().map(|c| c.chars().count().max(3) + 2).collect();
    // the rows' names as wide as the longest
    let label = sum.confusion.keys().map(|r| r.chars().count()).fold(20, usize::max);
    let _ = write!(s, "  {:<label$}", "");
    for (c, w) in cols.iter().zip(&widths) {
        let _ = write!(s, "{c:>w$}");
    }
    let _ = writeln!(s);
    for (row, m) in &sum.confusion {
        let _ = write!(s, "  {row:<label$}");
        for (c, w) in cols.iter().zip(&widths) {
            let v = m.get(c).copied().unwrap_or(0);
            let _ = write!(s, "{:>w$}", if v == 0 { ".".to_string() } else { v.to_string() });
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(s, "\nmedian relative parameter error (correctly found effects): {:.2} %", 100.0 * sum.median_parameter_error);
    let _ = writeln!(s, "median held-out L2 after/before (true set found):          {:.4}", sum.median_holdout_ratio);
    if sum.failures > 0 {
        let _ = writeln!(s, "scenarios that failed to run: {}", sum.failures);
    }
    s
}

pub(crate) fn run(args: Args) -> anyhow::Result<()> {
    super::check_range("scenarios", args.scenarios as f64, 1.0, 100_000.0, "")?;
    // Ctrl-C: the scenarios running finish, the rest are skipped, the finished ones are scored
    super::interrupt::cooperate();
    // scenarios take from a second to a minute each, so no time estimate: the count and the
    // elapsed time, redrawn steadily
    let bar = super::progress_bar(args.scenarios as u64, "{spinner} self-check [{bar:30}] {pos}/{len} scenarios  {elapsed_precise}");
    let scores: Vec<Option<ScenarioScore>> = (0..args.scenarios)
        .into_par_iter()
        .map(|i| {
            if super::interrupt::requested() {
                return None;
            }
            let s = run_mixed_scenario(args.seed, i);
            bar.inc(1);
            Some(s)
        })
        .collect();
    bar.finish_and_clear();
    let scores: Vec<ScenarioScore> = scores.into_iter().flatten().collect();
    let interrupted = super::interrupt::requested();
    if interrupted {
        eprintln!("interrupted: scoring the {} scenarios that finished", scores.len());
    }
    for s in scores.iter().filter(|s| !s.right || !s.rule.is_empty()) {
        eprintln!(
            "  scenario {:>3} ({}, {}): {}, hidden {:?}, selected {:?}{}{}",
            s.index,
            s.family,
            s.robot,
            if s.right { "right" } else { "wrong" },
            s.truth,
            s.found,
            if s.rule.is_empty() { String::new() } else { format!("; {}", s.rule) },
            s.error.as_deref().map(|e| format!(" — {e}")).unwrap_or_default()
        );
    }
    for s in scores.iter().filter(|s| !s.implausible.is_empty()) {
        eprintln!("  scenario {:>3} ({}): implausible {:?}", s.index, s.family, s.implausible);
    }
    let sum = summarise(&scores);
    print!("{}", table(&sum, scores.len(), args.seed));
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&serde_json::json!({ "seed": args.seed, "summary": sum, "scenarios": scores }))?;
        super::diagnose::write_atomically(path, |tmp| std::fs::write(tmp, text).map_err(Into::into))?;
        println!("wrote {}", path.display());
    }
    if interrupted {
        return Err(super::Interrupted.into());
    }
    Ok(())
}
