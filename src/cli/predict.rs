//! `simgap predict`: how well a model (with or without effects) predicts logged runs k steps
//! ahead, restarted from the measured state, against constant-velocity extrapolation.
//!
//! This is the figure the diagnosis reports as `gap.kstep`, for any model: e.g. a published
//! identified model against the URDF plus the effects a diagnosis selected, on the same runs.

use std::path::PathBuf;

use anyhow::{bail, Context};
use simgap::core::Formulation;
use simgap::log::TopicMap;
use simgap::sim::Effect;

/// Arguments of `simgap predict`.
#[derive(clap::Args)]
pub(crate) struct Args {
    /// URDF of the robot.
    #[arg(long)]
    urdf: PathBuf,
    /// Tip link of the chain when the tree branches.
    #[arg(long)]
    tip: Option<String>,
    /// A log to predict, repeatable (MCAP, CSV, a rosbag2 bag folder, or a LeRobot dataset
    /// folder or FOLDER#EPISODES, one run per episode); windows of all logs are pooled.
    #[arg(long = "log", required = true)]
    logs: Vec<PathBuf>,
    /// An effect added to the model, repeatable, e.g. 'viscous_friction:b=0.01,0.02'.
    /// A dry friction without 'w' smooths its sign over the joint type's typical width
    /// (0.01 rad/s revolute, 0.002 m/s prismatic).
    #[arg(long)]
    effect: Vec<String>,
    /// Formulation of C: euler-lagrange or simplified.
    #[arg(long, default_value = "euler-lagrange")]
    formulation: Formulation,
    /// Prediction horizons [s], comma-separated, each in (0, 60].
    #[arg(long, default_value = "0.1,0.25,0.5", value_delimiter = ',')]
    horizon: Vec<f64>,
    /// Experiment file for logs without `simgap.experiment` metadata or sidecar.
    #[arg(long)]
    experiment: Option<PathBuf>,
    /// LeRobot's calibration file, which makes a range-normalised joint of a LeRobot dataset
    /// (the gripper's 0–100) an angle; without it such a joint is locked at its URDF zero.
    #[arg(long)]
    calibration: Option<PathBuf>,
    /// Topic map of MCAP logs and bags, e.g. 'states=/arm/joint_states,reference=/arm/ref'.
    #[arg(long = "topic", value_parser = super::diagnose::parse_topic_map)]
    topics: Option<TopicMap>,
    /// Write the figures as JSON here (the layout of a diagnosis report's `gap.kstep`).
    #[arg(long)]
    json: Option<PathBuf>,
}

pub(crate) fn run(args: Args) -> anyhow::Result<()> {
    let model = super::load_model(Some(&args.urdf), args.tip.as_deref())?;
    if let Some(h) = args.horizon.iter().find(|h| !(h.is_finite() && **h > 0.0 && **h <= 60.0)) {
        bail!("--horizon {h}: expected horizons in (0, 60] seconds");
    }
    let options = super::log_options(args.topics.clone().unwrap_or_default(), args.experiment.as_deref(), args.calibration.as_deref())?;
    let runs = super::read_runs(&args.logs, &options)?;
    // joints the logs record but not as positions (a LeRobot gripper without calibration) are
    // locked at their zero
    let locked = simgap::diag::model_for_runs(&model, &runs)?;
    if let Some(m) = &locked {
        eprintln!("note: {}", m.warnings().last().map(String::as_str).unwrap_or_default());
    }
    // effects are given for the joints simulated (without the locked ones)
    let joints = if locked.is_some() {
        format!(" (one value per joint simulated: {}; locked joints take none)", locked.as_ref().map(|m| m.joint_names().join(", ")).unwrap_or_default())
    } else {
        String::new()
    };
    let model = locked.unwrap_or(model);
    let effects: Vec<Effect> = args.effect.iter().map(|s| Effect::parse_for_model(s, &model).with_context(|| format!("--effect '{s}'{joints}"))).collect::<anyhow::Result<_>>()?;
    let k = simgap::diag::predict(&model, args.formulation, &effects, &runs, &args.horizon, simgap::diag::PrepareOptions::default().window)?;
    println!(
        "k-step prediction of {} log(s) by '{}'{} ({} windows)",
        runs.len(),
        model.name(),
        if effects.is_empty() { String::new() } else { format!(" with {}", effects.iter().map(|e| e.name()).collect::<Vec<_>>().join(", ")) },
        k.runs.iter().map(|r| r.windows).sum::<usize>()
    );
    let u = simgap::diag::Units::of(&model.joints().iter().map(|j| j.kind).collect::<Vec<_>>()).position;
    println!("  {:>10} {:>14} {:>14} {:>14}", "horizon", format!("model [{u}]"), format!("+effects [{u}]"), format!("floor [{u}]"));
    for (i, h) in k.horizons_s.iter().enumerate() {
        println!("  {:>9.3}s {:>14.4e} {:>14.4e} {:>14.4e}", h, k.before[i], k.after[i], k.floor[i]);
    }
    // the whole-run measure of feedback runs (servo identification tools report it)
    let maes: Vec<(f64, f64)> = k.runs.iter().filter_map(|r| r.whole_run_mae).collect();
    if !maes.is_empty() {
        let mean = |f: &dyn Fn(&(f64, f64)) -> f64| maes.iter().map(f).sum::<f64>() / maes.len() as f64;
        println!("  whole-run closed-loop mean absolute error, mean over {} log(s) [{u}]: model {:.4e}, +effects {:.4e}", maes.len(), mean(&|m| m.0), mean(&|m| m.1));
    }
    if let Some(path) = &args.json {
        std::fs::write(path, serde_json::to_string_pretty(&k)? + "\n").with_context(|| format!("{}: cannot write", path.display()))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
