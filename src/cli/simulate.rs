//! `simgap simulate`: one closed-loop run of a model with effects, written to MCAP.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use simgap::core::Model;
use simgap::log::{CsvSink, McapSink};
use simgap::sim::{
    simulate, Controller, Effect, Experiment, Fourier, Pd, PdGravity, Plant, Reference, RunEnd, Sample, SensorParams, SimParams, Sink, Step, TrackingL2Sink, VelocityEstimate,
};

/// Arguments of `simgap simulate`.
#[derive(clap::Args)]
pub(crate) struct Args {
    #[command(flatten)]
    model: super::ModelArgs,
    /// Controller: pd, pd_gravity (gravity from the nominal model, without effects) or servo
    /// (a position-controlled servo: duty = clip(duty_gain (q_ref − q), ±max_duty), torque
    /// (kt/R) (V duty − kt q̇); its log holds the duty, torque enable and voltage, no torque).
    #[arg(long, default_value = "pd")]
    controller: String,
    /// Servo: duty per unit of position error [1/rad or 1/m], comma-separated in model order.
    #[arg(long)]
    duty_gain: Option<String>,
    /// Servo: largest duty magnitude in (0, 1], comma-separated (default 1).
    #[arg(long)]
    max_duty: Option<String>,
    /// Servo: supply voltage [V].
    #[arg(long)]
    supply_voltage: Option<f64>,
    /// Servo: motor torque constant through the gearbox [N·m/A or N/A], comma-separated.
    #[arg(long)]
    kt: Option<String>,
    /// Servo: winding resistance R [Ω], comma-separated.
    #[arg(long)]
    resistance: Option<String>,
    /// Servo: largest rate of the goal [rad/s or m/s] (default: none).
    #[arg(long)]
    goal_rate_limit: Option<f64>,
    /// Servo: a time span 'FROM:TO' [s] with every drive's torque off (the bridge open: no
    /// torque, no back-EMF), repeatable; e.g. '--torque-off 2:3' drops the arm for a second.
    #[arg(long)]
    torque_off: Vec<String>,
    /// Proportional gains [N·m/rad], comma-separated in model order (default: the paper's for
    /// the paper arm).
    #[arg(long)]
    kp: Option<String>,
    /// Derivative gains [N·m·s/rad], comma-separated in model order.
    #[arg(long)]
    kv: Option<String>,
    /// Step target [rad], comma-separated (default: the paper's (π/4, π/2) for the paper arm);
    /// with --fourier, the offset of the sinusoids (default zeros).
    #[arg(long, allow_hyphen_values = true)]
    target: Option<String>,
    /// One harmonic per joint added to the reference, repeatable:
    /// 'amplitude=A1,A2;frequency=F1,F2[;phase=P1,P2]' (rad, Hz, rad).
    #[arg(long, allow_hyphen_values = true)]
    fourier: Vec<String>,
    /// Initial positions [rad], comma-separated (default zeros).
    #[arg(long, allow_hyphen_values = true)]
    q0: Option<String>,
    /// Initial velocities [rad/s], comma-separated (default zeros).
    #[arg(long, allow_hyphen_values = true)]
    qd0: Option<String>,
    /// Duration [s], 0 < duration ≤ 86400 (a CSV log at most 10⁷ samples).
    #[arg(long, default_value_t = 3.0)]
    duration: f64,
    /// Controller sample period [s], 10⁻⁶ ≤ T ≤ 1.
    #[arg(long, default_value_t = 0.0025)]
    sample_period: f64,
    /// Minimum RK4 steps per sample, 1 ≤ substeps ≤ 10000 (at most 10⁹ steps in all).
    #[arg(long, default_value_t = simgap::sim::DEFAULT_SUBSTEPS)]
    substeps: usize,
    /// An effect of the plant, repeatable, e.g. 'viscous_friction:b=2.288,0.175',
    /// 'coulomb_friction:fc=7.17,1.734', 'time_delay:delay=0.005', 'coriolis_structure'.
    /// A dry friction without 'w' smooths its sign over the joint type's typical width
    /// (0.01 rad/s revolute, 0.002 m/s prismatic).
    #[arg(long, allow_hyphen_values = true)]
    effect: Vec<String>,
    /// Saturate applied torques at the URDF effort limits.
    #[arg(long)]
    torque_limits: bool,
    /// Encoder counts per revolution, 0 (exact positions) or 1 ≤ counts ≤ 10¹².
    #[arg(long, default_value_t = 1_024_000.0)]
    counts_per_rev: f64,
    /// Measure the exact velocity instead of the backward difference.
    #[arg(long)]
    exact_velocity: bool,
    /// Standard deviation of the position noise [rad], 0 ≤ noise ≤ 1.
    #[arg(long, default_value_t = 0.0)]
    noise: f64,
    /// Seed of the noise.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output log, its format chosen by the extension: `.mcap` (ROS 2 profile), `.csv` or
    /// `.csv.gz` (with the experiment in a sidecar `.experiment.json`); without it, only the
    /// summary is printed.
    #[arg(long)]
    out: Option<PathBuf>,
}

pub(crate) fn parse_list(what: &str, s: &str, n: usize) -> anyhow::Result<Vec<f64>> {
    let v: Vec<f64> = s.split(',').map(|x| x.trim().parse::<f64>().with_context(|| format!("--{what}: '{x}' is not a number"))).collect::<anyhow::Result<_>>()?;
    if v.len() == 1 && n > 1 {
        return Ok(vec![v[0]; n]);
    }
    if v.len() != n {
        bail!("--{what}: expected {n} values (one per joint), got {}", v.len());
    }
    if let Some(x) = v.iter().find(|x| !x.is_finite()) {
        bail!("--{what}: expected finite numbers, got {x}");
    }
    Ok(v)
}

fn parse_fourier(specs: &[String], offset: Vec<f64>, n: usize) -> anyhow::Result<Fourier> {
    let mut f = Fourier { offset, amplitudes: vec![Vec::new(); n], frequencies: vec![Vec::new(); n], phases: vec![Vec::new(); n] };
    for spec in specs {
        let (mut a, mut fr, mut ph) = (None, None, None);
        for part in spec.split(';').map(str::trim).filter(|p| !p.is_empty()) {
            let (k, v) = part.split_once('=').with_context(|| format!("--fourier: '{part}' is not key=values"))?;
            match k.trim() {
                "amplitude" => a = Some(parse_list("fourier amplitude", v, n)?),
                "frequency" => fr = Some(parse_list("fourier frequency", v, n)?),
                "phase" => ph = Some(parse_list("fourier phase", v, n)?),
                other => bail!("--fourier: unknown key '{other}'; expected amplitude, frequency, phase"),
            }
        }
        let (a, fr) = (a.context("--fourier: missing amplitude=")?, fr.context("--fourier: missing frequency=")?);
        let ph = ph.unwrap_or_else(|| vec![0.0; n]);
        for i in 0..n {
            f.amplitudes[i].push(a[i]);
            f.frequencies[i].push(fr[i]);
            f.phases[i].push(ph[i]);
        }
    }
    Ok(f)
}

/// Records into two sinks.
pub(crate) struct Tee<'a>(pub(crate) &'a mut dyn Sink, pub(crate) &'a mut dyn Sink);

impl Sink for Tee<'_> {
    fn begin(&mut self, joints: &[String], experiment: &Experiment) -> simgap::sim::Result<()> {
        self.0.begin(joints, experiment)?;
        self.1.begin(joints, experiment)
    }
    fn record(&mut self, sample: &Sample<'_>) -> simgap::sim::Result<()> {
        self.0.record(sample)?;
        self.1.record(sample)
    }
    fn finish(&mut self, end: &RunEnd) -> simgap::sim::Result<()> {
        let a = self.0.finish(end);
        let b = self.1.finish(end);
        a.and(b)
    }
}

fn is_paper_arm(model: &Model) -> bool {
    model.joint_names() == ["shoulder", "elbow"] && model.dof() == 2
}

/// Most samples a CSV log may have: about 2 GB of text, which every reader reads back whole
/// (both logs are written as the run goes, in bounded memory; an MCAP log has no such bound).
const MAX_CSV_SAMPLES: f64 = 1e7;

/// The options the library does not check (the encoder's 0 meaning exact positions, `--out`'s
/// extension, the length of a CSV log), before anything is simulated; every other range is
/// [`SimParams::validate`]'s, the same for the CLI and Python.
fn check_args(args: &Args) -> anyhow::Result<()> {
    use super::number;
    if args.counts_per_rev != 0.0 && !(args.counts_per_rev >= 1.0 && args.counts_per_rev <= 1e12) {
        bail!("--counts-per-rev {} is out of range; expected 0 (exact positions) or 1 ≤ counts-per-rev ≤ 1e12", number(args.counts_per_rev));
    }
    if let Some(path) = &args.out {
        let samples = args.duration / args.sample_period;
        if log_format(path)? == "csv" && samples > MAX_CSV_SAMPLES {
            bail!(
                "--out {}: --duration {} s at --sample-period {} s gives {} samples; a CSV log holds at most {} (about 2 GB of text, read back whole); write .mcap, which has no such bound",
                path.display(),
                number(args.duration),
                number(args.sample_period),
                number(samples.round()),
                number(MAX_CSV_SAMPLES)
            );
        }
    }
    Ok(())
}

/// The log format `path` names by its extension, or an error saying which are known.
fn log_format(path: &Path) -> anyhow::Result<&'static str> {
    let name = path.file_name().map(|s| s.to_string_lossy().to_lowercase()).unwrap_or_default();
    if name.ends_with(".mcap") {
        Ok("mcap")
    } else if name.ends_with(".csv") || name.ends_with(".csv.gz") {
        Ok("csv")
    } else {
        bail!("--out {}: unknown log format; expected a file ending in .mcap, .csv or .csv.gz", path.display())
    }
}

/// A sink that counts samples on a progress bar and passes them on, keeping the number of
/// samples and the time span.
struct Counting<'a> {
    inner: &'a mut dyn Sink,
    bar: &'a indicatif::ProgressBar,
    samples: u64,
    span: Option<(f64, f64)>,
}

impl Sink for Counting<'_> {
    fn begin(&mut self, joints: &[String], experiment: &Experiment) -> simgap::sim::Result<()> {
        self.inner.begin(joints, experiment)
    }
    fn record(&mut self, sample: &Sample<'_>) -> simgap::sim::Result<()> {
        self.bar.inc(1);
        self.samples += 1;
        self.span = Some((self.span.map_or(sample.t, |s| s.0), sample.t));
        self.inner.record(sample)
    }
    fn finish(&mut self, end: &RunEnd) -> simgap::sim::Result<()> {
        self.inner.finish(end)
    }
}

/// A servo constant's flag given on the command line, if any.
fn servo_flag(args: &Args) -> Option<&'static str> {
    let given = [
        ("duty-gain", args.duty_gain.is_some()),
        ("max-duty", args.max_duty.is_some()),
        ("supply-voltage", args.supply_voltage.is_some()),
        ("kt", args.kt.is_some()),
        ("resistance", args.resistance.is_some()),
        ("goal-rate-limit", args.goal_rate_limit.is_some()),
        ("torque-off", !args.torque_off.is_empty()),
    ];
    given.into_iter().find(|(_, g)| *g).map(|(f, _)| f)
}

/// The servo of `--controller servo`, its constants checked flag by flag.
fn servo(args: &Args, n: usize) -> anyhow::Result<simgap::sim::Servo> {
    if args.kp.is_some() || args.kv.is_some() {
        bail!("--kp and --kv are a PD controller's gains; a servo's loop is --duty-gain (duty per unit of position error)");
    }
    let required = |flag: &str, v: &Option<String>, what: &str| -> anyhow::Result<Vec<f64>> {
        let s = v.as_deref().with_context(|| format!("--controller servo needs --{flag} ({what})"))?;
        let values = parse_list(flag, s, n)?;
        if let Some(x) = values.iter().find(|x| **x <= 0.0) {
            bail!("--{flag}: {x}; expected positive numbers ({what})");
        }
        Ok(values)
    };
    let duty_gain = required("duty-gain", &args.duty_gain, "duty per unit of position error, one per joint")?;
    let max_duty = match &args.max_duty {
        Some(s) => parse_list("max-duty", s, n)?,
        None => vec![1.0; n],
    };
    if let Some(x) = max_duty.iter().find(|x| !(**x > 0.0 && **x <= 1.0)) {
        bail!("--max-duty: {x}; expected a duty in (0, 1]");
    }
    let volts = args.supply_voltage.context("--controller servo needs --supply-voltage (volts)")?;
    if !(volts.is_finite() && volts > 0.0) {
        bail!("--supply-voltage: {volts}; expected a positive number of volts");
    }
    let kt = required("kt", &args.kt, "torque constant [N·m/A], one per joint")?;
    let r = required("resistance", &args.resistance, "winding resistance [Ω], one per joint")?;
    if let Some(g) = args.goal_rate_limit.filter(|g| !(g.is_finite() && *g > 0.0)) {
        bail!("--goal-rate-limit: {g}; expected a positive rate");
    }
    let mut off = Vec::new();
    for span in &args.torque_off {
        let parsed = span.split_once(':').and_then(|(a, b)| Some((a.trim().parse::<f64>().ok()?, b.trim().parse::<f64>().ok()?)));
        match parsed {
            Some((from, to)) if from.is_finite() && to.is_finite() && from < to => off.push((from, to)),
            _ => bail!("--torque-off '{span}': expected FROM:TO, two times in seconds with FROM < TO"),
        }
    }
    Ok(simgap::sim::Servo::new(duty_gain, max_duty, volts, kt, r, args.goal_rate_limit)?.with_torque_off(off))
}

pub(crate) fn run(args: Args) -> anyhow::Result<()> {
    use simgap::sim::paper;
    check_args(&args)?;
    let model = args.model.load()?;
    let n = model.dof();
    let on_paper_arm = is_paper_arm(&model);
    // gains and reference (the paper's experiment by default on the paper arm)
    let gains = |what: &str, given: &Option<String>, default: &[f64]| -> anyhow::Result<Vec<f64>> {
        match given {
            Some(s) => parse_list(what, s, n),
            None if on_paper_arm => Ok(default.to_vec()),
            None => bail!("--{what} is required for a model other than the paper arm"),
        }
    };
    let mut controller: Box<dyn Controller> = match args.controller.as_str() {
        "pd" => Box::new(Pd { kp: gains("kp", &args.kp, &paper::KP)?, kv: gains("kv", &args.kv, &paper::KV)? }),
        "pd_gravity" => Box::new(PdGravity::new(gains("kp", &args.kp, &paper::KP)?, gains("kv", &args.kv, &paper::KV)?, model.clone())),
        "servo" => Box::new(servo(&args, n)?),
        other => bail!("--controller: unknown '{other}'; expected pd, pd_gravity or servo"),
    };
    if args.controller != "servo" {
        if let Some(flag) = servo_flag(&args) {
            bail!("--{flag} is a servo's constant; it needs --controller servo (got {})", args.controller);
        }
    }
    let reference: Box<dyn Reference> = if args.fourier.is_empty() {
        let target = match &args.target {
            Some(s) => parse_list("target", s, n)?,
            None if on_paper_arm => paper::Q_DESIRED.to_vec(),
            None => bail!("--target or --fourier is required for a model other than the paper arm"),
        };
        Box::new(Step { target })
    } else {
        let offset = match &args.target {
            Some(s) => parse_list("target", s, n)?,
            None => vec![0.0; n],
        };
        Box::new(parse_fourier(&args.fourier, offset, n)?)
    };
    let effects: Vec<Effect> = args.effect.iter().map(|s| Effect::parse_for_model(s, &model).with_context(|| format!("--effect '{s}'"))).collect::<anyhow::Result<_>>()?;
    let plant = Plant::new(&model, args.model.formulation, &effects)?;
    let params = SimParams {
        duration: args.duration,
        sample_period: args.sample_period,
        substeps: args.substeps,
        torque_limits_from_model: args.torque_limits,
        sensor: SensorParams {
            counts_per_rev: (args.counts_per_rev > 0.0).then_some(args.counts_per_rev),
            velocity: if args.exact_velocity { VelocityEstimate::Exact } else { VelocityEstimate::BackwardDifference },
            noise_std: args.noise,
            seed: args.seed,
        },
        q0: args.q0.as_deref().map(|s| parse_list("q0", s, n)).transpose()?.unwrap_or_default(),
        qd0: args.qd0.as_deref().map(|s| parse_list("qd0", s, n)).transpose()?.unwrap_or_default(),
        ..SimParams::default()
    };
    params.validate(n)?;
    // simulate with a progress bar, the tracking L² computed as the run goes; the log is
    // written as it goes, in bounded memory (a CSV log as NAME.partial.csv until the run ends);
    // Ctrl-C stops the run cleanly
    super::interrupt::cooperate();
    let samples = params.intervals() as u64 + 1;
    let bar = super::progress_bar(samples, "{spinner} simulating  [{bar:30}] {pos}/{len} samples  {elapsed}");
    let mut l2 = TrackingL2Sink::new();
    let mut log: Option<Box<dyn Sink>> = match &args.out {
        Some(path) if log_format(path)? == "mcap" => Some(Box::new(McapSink::create(path)?)),
        Some(path) => Some(Box::new(CsvSink::create(path)?)),
        None => None,
    };
    let start = std::time::Instant::now();
    let (end, count, span) = {
        let mut tee_log;
        let inner: &mut dyn Sink = match &mut log {
            Some(m) => {
                tee_log = Tee(m.as_mut(), &mut l2);
                &mut tee_log
            }
            None => &mut l2,
        };
        let mut counting = Counting { inner, bar: &bar, samples: 0, span: None };
        let end = simulate(&plant, controller.as_mut(), reference.as_ref(), &params, &mut counting, Some(super::interrupt::STOP.as_ref()));
        (end, counting.samples, counting.span)
    };
    bar.finish_and_clear();
    let end = end?;
    let elapsed = start.elapsed();
    // summary
    println!("model {} ({} joints: {}), formulation {}", model.name(), n, model.joint_names().join(", "), args.model.formulation.as_str());
    if !effects.is_empty() {
        println!("effects: {}", effects.iter().map(|e| e.name()).collect::<Vec<_>>().join(", "));
    }
    let duration = span.map_or(0.0, |(a, b)| b - a);
    println!("{count} samples over {duration:.4} s in {:.1} ms", elapsed.as_secs_f64() * 1e3);
    if let Ok(l2) = l2.report() {
        let per: Vec<String> = l2.joints.iter().zip(&l2.per_joint).map(|(j, v)| format!("{j} {v:.6}")).collect();
        println!(
            "L2 tracking error [{}]: overall {:.6} ({})",
            simgap::diag::Units::of(&model.joints().iter().map(|j| j.kind).collect::<Vec<_>>()).position,
            l2.overall,
            per.join(", ")
        );
    }
    // the log: the sink finished it (an MCAP log says how the run ended; a CSV log has its name)
    drop(log);
    if let Some(path) = &args.out {
        println!("wrote {}", path.display());
    }
    match end {
        RunEnd::Completed => Ok(()),
        RunEnd::Interrupted { t } => {
            eprintln!("interrupted at t = {t} s{}", if args.out.is_some() { "; the log holds the run so far" } else { "" });
            Err(super::Interrupted.into())
        }
        RunEnd::Diverged { t, joint } => bail!("the simulation diverged at t = {t} s on joint '{joint}'; the log holds the run until then"),
    }
}
