//! Times the diagnosis `simgap demo` runs: the paper's arm with its published friction and the
//! elbow's 15 N·m limit hidden, three 4 s fit runs and one 8 s held-out run (seed 1, 2.5 ms,
//! 1,024,000 counts/rev), diagnosed in memory. Prints the wall and CPU time of each repetition
//! (CPU time of the whole process, all threads) and the selected effects.
//!
//! `RAYON_NUM_THREADS=1 cargo run --release --example diagnose_demo [-- --reps 3 --seed 1]`

use std::time::Instant;

use simgap::core::{Formulation, Model};
use simgap::diag::bench::{demo_effects, demo_specs, generate};
use simgap::diag::{diagnose, DiagnoseOptions};

/// CPU time of this process so far (user + system, all threads) [s], from `/proc/self/stat`
/// (NaN where it cannot be read).
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else { return f64::NAN };
    // fields after the command name (which may hold spaces, closed by the last ')')
    let Some(rest) = stat.rfind(')').map(|i| &stat[i + 2..]) else { return f64::NAN };
    let f: Vec<&str> = rest.split_whitespace().collect();
    // utime and stime are fields 14 and 15 of the line, 12 and 13 after the state
    let ticks = |i: usize| f.get(i).and_then(|s| s.parse::<f64>().ok()).unwrap_or(f64::NAN);
    // clock ticks per second: 100 on every Linux configuration in use
    (ticks(11) + ticks(12)) / 100.0
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let arg =
        |name: &str, default: u64| -> Result<u64, std::num::ParseIntError> { args.iter().position(|a| a == name).and_then(|i| args.get(i + 1)).map_or(Ok(default), |s| s.parse()) };
    let (reps, seed) = (arg("--reps", 3)?, arg("--seed", 1)?);
    let model = Model::paper_arm();
    let hidden = demo_effects();
    let (fit_specs, hold_specs) = demo_specs(seed);
    let gen = |s| generate(&model, Formulation::EulerLagrange, &hidden, s, 0.0025, 1_024_000.0);
    let fit: Vec<_> = fit_specs.iter().map(gen).collect::<Result<_, _>>()?;
    let hold: Vec<_> = hold_specs.iter().map(gen).collect::<Result<_, _>>()?;
    println!("paper-arm demo, seed {seed}: {} fit runs, {} held-out run(s), {} rayon thread(s)", fit.len(), hold.len(), rayon::current_num_threads());
    for rep in 0..reps {
        let (t, c) = (Instant::now(), cpu_seconds());
        let d = diagnose(&model, Formulation::EulerLagrange, &fit, &hold, &DiagnoseOptions::default(), &mut |_| {})?;
        let (wall, cpu) = (t.elapsed().as_secs_f64(), cpu_seconds() - c);
        let mut names: Vec<String> = d.report.selected_effects.iter().map(|e| format!("{} on {}", e.effect, e.joints.join(","))).collect();
        names.sort();
        println!("rep {rep}: diagnosis {wall:.3} s wall, {cpu:.2} s CPU; selected: {}", names.join("; "));
        if rep + 1 == reps {
            println!("fit k-step CV after: {:?}; held-out k-step after: {:?}", d.report.gap.fit_kstep_cv_after, d.report.gap.kstep.after);
        }
    }
    Ok(())
}
