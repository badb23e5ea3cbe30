//! `simgap demo`: a bench robot with hidden effects, diagnosed blind through the same code path
//! as `simgap diagnose`.
//!
//! The paper's arm is given its published friction (viscous and Coulomb) and the elbow motor's
//! 15 N·m limit ([`simgap::diag::bench::demo_effects`]); three fit runs and one held-out run
//! are simulated (Euler–Lagrange plant, 2.5 ms, 1,024,000 counts/rev, backward-difference
//! velocity) and written as MCAP logs with the paper arm's URDF. The diagnosis reads the logs
//! back, sees only them and the nominal URDF, and at the end the hidden truth is printed next
//! to what was found. The corrected model is written as `corrected.urdf` and `corrected.xml`
//! (MJCF) with their `.effects.json` sidecars, and one line each says how to load them in
//! Pinocchio and MuJoCo.

use std::path::{Path, PathBuf};

use anyhow::Context;
use simgap::core::{Formulation, Model, PAPER_ARM_URDF};
use simgap::diag::bench::{demo_effects, demo_specs, generate};
use simgap::diag::Report;
use simgap::log::write_mcap;
use simgap::sim::{Effect, EffectKind};

use super::diagnose::{execute, write_atomically, Job};

/// Arguments of `simgap demo`.
#[derive(clap::Args)]
pub(crate) struct Args {
    /// Output folder for the logs, the URDF and the reports; created if missing.
    #[arg(long, default_value = "simgap-demo")]
    out_dir: PathBuf,
    /// Seed of the random excitations.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

/// Sample period of the generated logs [s].
const SAMPLE_PERIOD: f64 = 0.0025;
/// Encoder resolution of the generated logs [counts/rev].
const COUNTS_PER_REV: f64 = 1_024_000.0;

pub(crate) fn run(args: Args) -> anyhow::Result<()> {
    // Ctrl-C: the file being written is removed, finished files stay whole
    super::interrupt::install();
    let dir = &args.out_dir;
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    println!("simgap demo: the paper's arm with hidden effects, diagnosed blind; files in {}", dir.display());

    // the bench robot: URDF and logs, written as a user would have them
    let urdf = dir.join("paper_arm.urdf");
    write_atomically(&urdf, |tmp| std::fs::write(tmp, PAPER_ARM_URDF).map_err(Into::into))?;
    let model = Model::from_urdf_file(&urdf)?;
    let hidden = demo_effects();
    let (fit_specs, hold_specs) = demo_specs(args.seed);
    let write = |specs: &[simgap::diag::bench::RunSpec]| -> anyhow::Result<Vec<PathBuf>> {
        specs
            .iter()
            .map(|s| {
                let run = generate(&model, Formulation::EulerLagrange, &hidden, s, SAMPLE_PERIOD, COUNTS_PER_REV)?;
                let path = dir.join(format!("{}.mcap", s.name));
                write_atomically(&path, |tmp| write_mcap(&run, tmp).map_err(Into::into))?;
                println!("  generated {} ({:.1} s, {} samples)", path.display(), run.duration(), run.len());
                Ok(path)
            })
            .collect()
    };
    let logs = write(&fit_specs)?;
    let holdouts = write(&hold_specs)?;
    println!();

    // the diagnosis, blind, from the files
    let (json, html, mcap) = (dir.join("report.json"), dir.join("report.html"), dir.join("corrected.mcap"));
    let (corrected_urdf, corrected_mjcf) = (dir.join("corrected.urdf"), dir.join("corrected.xml"));
    let diagnosis = execute(&Job {
        model: &model,
        formulation: Formulation::EulerLagrange,
        logs: &logs,
        holdouts: &holdouts,
        experiment: None,
        calibration: None,
        topics: Default::default(),
        json: Some(&json),
        html: Some(&html),
        mcap: Some(&mcap),
        urdf: Some(&urdf),
        export_urdf: Some(&corrected_urdf),
        export_mjcf: Some(&corrected_mjcf),
        switches: Vec::new(),
        timings: false,
    })?;

    // the hidden truth next to the answer
    println!();
    println!("{}", truth_table(&hidden, &model, &diagnosis.report));
    println!("Reproduce the diagnosis from the files:");
    println!("{}", reproduce_command(&urdf, &logs, &holdouts, &json, &html, &mcap, &corrected_urdf, &corrected_mjcf));
    println!();
    println!("Load the corrected model (effects the formats cannot hold are in the .effects.json beside each):");
    println!("{}", load_lines(&corrected_urdf, &corrected_mjcf));
    Ok(())
}

/// The hidden effects as (effect, parameter, joint, value) rows.
fn truth_rows(effects: &[Effect], model: &Model) -> Vec<(EffectKind, &'static str, String, f64)> {
    let names = model.joint_names();
    let mut rows = Vec::new();
    let mut per_joint = |effect: EffectKind, param: &'static str, v: &[f64]| {
        for (j, x) in v.iter().enumerate() {
            if x.is_finite() && *x != 0.0 {
                rows.push((effect, param, names[j].to_string(), *x));
            }
        }
    };
    for e in effects {
        match e {
            Effect::ViscousFriction { b } => per_joint(e.kind(), "b", b),
            Effect::CoulombFriction { fc, .. } => per_joint(e.kind(), "fc", fc),
            Effect::TorqueSaturation { limit } => per_joint(e.kind(), "limit", limit),
            _ => {}
        }
    }
    rows
}

fn truth_table(effects: &[Effect], model: &Model, report: &Report) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(s, "HIDDEN TRUTH vs FOUND");
    let _ = writeln!(s, "  {:<18} {:<6} {:<9} {:>10} {:>10} {:>9}", "effect", "param", "joint", "true", "found", "rel. err");
    for (effect, param, joint, truth) in truth_rows(effects, model) {
        let found = report.selected_effects.iter().find(|e| e.effect == effect).and_then(|e| e.value(param, &joint));
        let (f, r) = match found {
            Some(v) => (format!("{v:.4}"), format!("{:.1} %", 100.0 * (v - truth).abs() / truth.abs())),
            None => ("not found".to_string(), "–".to_string()),
        };
        let _ = writeln!(s, "  {:<18} {param:<6} {joint:<9} {truth:>10.4} {f:>10} {r:>9}", effect.as_str());
    }
    // anything selected that was not hidden
    for e in &report.selected_effects {
        let hidden = truth_rows(effects, model);
        for j in if e.joints.is_empty() { vec![String::new()] } else { e.joints.clone() } {
            if !hidden.iter().any(|(he, _, hj, _)| *he == e.effect && (j.is_empty() || *hj == j)) {
                let _ = writeln!(s, "  {:<18} {:<6} {:<9} {:>10} {:>10} {:>9}", e.effect.as_str(), "", j, "absent", "selected", "spurious");
            }
        }
    }
    s
}

/// One Python line each that loads the exported files, in Pinocchio and in MuJoCo.
fn load_lines(urdf: &Path, mjcf: &Path) -> String {
    let py = |p: &Path| format!("{:?}", p.display().to_string());
    let quote = |code: String| shell_quote(&code);
    format!(
        "  python -c {}\n  python -c {}",
        quote(format!("import pinocchio; print(pinocchio.buildModelFromUrdf({}))", py(urdf))),
        quote(format!("import mujoco; print(mujoco.MjModel.from_xml_path({}).nv)", py(mjcf)))
    )
}

#[allow(clippy::too_many_arguments)]
fn reproduce_command(urdf: &Path, logs: &[PathBuf], holdouts: &[PathBuf], json: &Path, html: &Path, mcap: &Path, export_urdf: &Path, export_mjcf: &Path) -> String {
    let q = |p: &Path| shell_quote(&p.display().to_string());
    let mut c = format!("simgap diagnose --urdf {}", q(urdf));
    for l in logs {
        c += &format!(" --log {}", q(l));
    }
    for h in holdouts {
        c += &format!(" --holdout {}", q(h));
    }
    c += &format!(" --json {} --html {} --mcap {} --export-urdf {} --export-mjcf {}", q(json), q(html), q(mcap), q(export_urdf), q(export_mjcf));
    c
}

fn shell_quote(s: &str) -> String {
    if !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || "/._-+=:,".contains(c)) {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', "'\\''"))
    }
}
