//! Diagnoses one scenario of `simgap selfcheck` and prints its hidden effects, the report's
//! summary (selected effects, alternatives, held-out k-step errors against the
//! constant-velocity floor) and its notes: how a figure quoted for one scenario is reproduced.
//!
//! `cargo run --release --example selfcheck_scenario -- SEED KIND INDEX [--link-side-torque]
//! [--truth] [--steps] [--priors] [--write DIR] [--score]`
//!
//! KIND is `cycle` for the scenarios of the cycle of 13 (INDEX as `simgap selfcheck` numbers
//! them), `drive` for the real-drive families (INDEX as the family table of its output numbers
//! them), `servo` for the servo scenarios, `backlash` and `offset` for the
//! `servo_backlash` and `servo_encoder_offset` families. `--link-side-torque` diagnoses as
//! `simgap diagnose --link-side-torque` does. `--truth` prints the simulated effects with their
//! parameters and stops; `--steps` adds the selection's steps (each decision and why);
//! `--priors` gives a servo scenario's logs the true motor constants as priors; `--write DIR`
//! writes its fit and held-out logs there as CSV with their sidecars (`fit-<i>.csv`,
//! `holdout-<i>.csv`), to be read or diagnosed with `simgap diagnose`; `--score` scores the
//! scenario by its family's rule, as `simgap selfcheck` does, and prints the rule and the verdict.

use simgap::core::Formulation;
use simgap::diag::{diagnose, drives, selfcheck, DiagnoseOptions};
use simgap::sim::controller::servo_keys;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: selfcheck_scenario SEED cycle|drive|servo|backlash|offset INDEX [--link-side-torque] [--truth] [--steps] [--priors] [--write DIR] [--score]";
    let (Some(seed), Some(kind), Some(index)) = (args.first().and_then(|s| s.parse::<u64>().ok()), args.get(1), args.get(2).and_then(|s| s.parse::<usize>().ok())) else {
        eprintln!("{usage}");
        std::process::exit(2);
    };
    let scenario = match kind.as_str() {
        "cycle" => selfcheck::scenario(seed, index),
        "drive" => drives::drive_scenario(seed, index),
        "servo" => selfcheck::servo_scenario(seed, index),
        "backlash" => selfcheck::backlash_scenario(seed, index),
        "offset" => selfcheck::encoder_offset_scenario(seed, index),
        other => {
            eprintln!("unknown kind '{other}'; {usage}");
            std::process::exit(2);
        }
    };
    let scenario = match scenario {
        Ok(s) => s,
        Err(e) => {
            eprintln!("scenario {seed}/{kind}/{index}: {e}");
            std::process::exit(1);
        }
    };
    // `--priors`: every log's experiment states the servos' true kt and R, as a datasheet would
    let mut scenario = scenario;
    if let (true, Some(s)) = (args.iter().any(|a| a == "--priors"), scenario.servo.clone()) {
        let list = |v: &[f64]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>().join(",");
        for run in scenario.fit.iter_mut().chain(scenario.holdout.iter_mut()) {
            if let Some(e) = run.experiment.as_mut() {
                e.extra.insert(servo_keys::KT.into(), list(&s.kt));
                e.extra.insert(servo_keys::R.into(), list(&s.r));
            }
        }
    }
    let mut options =
        DiagnoseOptions { directional_friction: scenario.directional_friction, load_stribeck_friction: scenario.load_stribeck_friction, ..DiagnoseOptions::default() };
    options.prepare.link_side_torque = args.iter().any(|a| a == "--link-side-torque");
    println!("family {}, hidden: {:?}", scenario.family, scenario.truth);
    println!("simulated with: {:?}", scenario.effects);
    if let Some(s) = &scenario.servo {
        let per_joint = |f: &dyn Fn(usize) -> f64| (0..s.kt.len()).map(|j| format!("{:.4}", f(j))).collect::<Vec<_>>().join(", ");
        println!(
            "servos: supply {:.3} V, kt [{}] N·m/A, R [{}] Ω, kt/R [{}] N·m/V, kt²/R [{}] N·m·s/rad",
            s.volts,
            per_joint(&|j| s.kt[j]),
            per_joint(&|j| s.r[j]),
            per_joint(&|j| s.kt[j] / s.r[j]),
            per_joint(&|j| s.kt[j] * s.kt[j] / s.r[j])
        );
    }
    if let Some(dir) = args.iter().position(|a| a == "--write").map(|i| args.get(i + 1)) {
        let Some(dir) = dir else {
            eprintln!("--write needs a folder; {usage}");
            std::process::exit(2);
        };
        let dir = std::path::Path::new(dir);
        let named =
            scenario.fit.iter().enumerate().map(|(i, r)| (format!("fit-{i}.csv"), r)).chain(scenario.holdout.iter().enumerate().map(|(i, r)| (format!("holdout-{i}.csv"), r)));
        for (name, run) in named {
            if let Err(e) = std::fs::create_dir_all(dir).map_err(|e| e.to_string()).and_then(|_| simgap::log::write_log(run, &dir.join(&name)).map_err(|e| e.to_string())) {
                eprintln!("writing {}: {e}", dir.join(&name).display());
                std::process::exit(1);
            }
        }
        println!("logs written to {}", dir.display());
    }
    if args.iter().any(|a| a == "--truth") {
        return;
    }
    if args.iter().any(|a| a == "--score") {
        let score = match kind.as_str() {
            "cycle" => selfcheck::run_scenario(seed, index),
            "drive" => selfcheck::run_drive_scenario(seed, index),
            "backlash" => selfcheck::run_backlash_scenario(seed, index),
            "offset" => selfcheck::run_encoder_offset_scenario(seed, index),
            _ => selfcheck::run_servo_scenario(seed, index),
        };
        println!("found {:?}\n{}: {}", score.found, if score.right { "right" } else { "wrong" }, score.rule);
        return;
    }
    match diagnose(&scenario.diagnosis_model, Formulation::EulerLagrange, &scenario.fit, &scenario.holdout, &options, &mut |_| {}) {
        Ok(d) => {
            println!("{}", d.report.summary());
            if args.iter().any(|a| a == "--steps") {
                println!("SELECTION STEPS");
                for s in &d.report.selection_log {
                    println!("  {} {:?} {}: {}", s.effect, s.joint, if s.accepted { "in" } else { "out" }, s.reason);
                }
            }
        }
        Err(e) => {
            eprintln!("diagnosis failed: {e}");
            std::process::exit(1);
        }
    }
}
