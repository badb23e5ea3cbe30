//! The self-check: random blind scenarios (robot, hidden effects, references, controllers),
//! diagnosed like real logs and scored against the hidden truth.

use std::collections::{BTreeMap, BTreeSet};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use simgap_core::{mass_matrix, Formulation, Model, UrdfOptions, Workspace};
use simgap_sim::{ControllerKind, Effect, LinkDelta, Run};

use crate::bench::{gains_for, generate, random_fourier, random_setpoints, RefSpec, RunSpec};
use crate::effects::Param;
use crate::{diagnose, DiagnoseOptions, Diagnosis};

/// The robots the self-check draws from.
pub fn robots() -> Vec<Model> {
    let pendulum = Model::from_urdf_str(simgap_core::PENDULUM_URDF).expect("pendulum fixture");
    let arm7 = Model::from_urdf_str_with(simgap_core::ARM7_URDF, "arm7.urdf", &UrdfOptions { tip: Some("panda_hand".into()) }).expect("arm7 fixture");
    vec![Model::paper_arm(), pendulum, arm7]
}

/// One scenario: a robot, hidden effects and the logs they produce.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// Index.
    pub index: usize,
    /// The robot.
    pub model: Model,
    /// The hidden effects.
    pub effects: Vec<Effect>,
    /// Fit logs.
    pub fit: Vec<Run>,
    /// Held-out logs.
    pub holdout: Vec<Run>,
    /// `closed_loop` (PD or PD + gravity tracking) or `open_loop` (the same motions replayed
    /// open loop from the commanded torque, as a sys-id experiment without feedback).
    pub family: &'static str,
}

/// Relabels runs as open-loop replays of their commanded torque.
fn as_replay(runs: &mut [Run]) {
    for r in runs {
        if let Some(e) = r.experiment.as_mut() {
            e.controller = ControllerKind::Replay;
            e.kp = vec![0.0; e.joints.len()];
            e.kv = vec![0.0; e.joints.len()];
        }
    }
}

fn rms(run: &Run, m: &[f64], j: usize) -> f64 {
    let n = run.dof();
    let v: Vec<f64> = m.iter().skip(j).step_by(n).copied().collect();
    (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
}

fn max_abs(run: &Run, m: &[f64], j: usize) -> f64 {
    m.iter().skip(j).step_by(run.dof()).fold(0.0f64, |a, x| a.max(x.abs()))
}

const PER_JOINT: [&str; 8] = ["viscous_friction", "coulomb_friction", "stribeck_friction", "armature", "torque_gain", "torque_offset", "torque_saturation", "cogging"];
const WHOLE: [&str; 4] = ["payload", "inertial_error", "time_delay", "coriolis_structure"];

/// Draws an effect of kind `name` sized against a nominal run.
fn draw_effect(name: &str, model: &Model, nominal: &Run, joint: usize, rng: &mut ChaCha8Rng) -> Effect {
    let n = model.dof();
    let tau = rms(nominal, &nominal.tau, joint).max(1e-6);
    let qd = rms(nominal, &nominal.qd, joint).max(1e-3);
    let v = |neutral: f64, x: f64| {
        let mut out = vec![neutral; n];
        out[joint] = x;
        out
    };
    match name {
        "viscous_friction" => Effect::ViscousFriction { b: v(0.0, rng.random_range(0.08..0.25) * tau / qd) },
        "coulomb_friction" => Effect::CoulombFriction { fc: v(0.0, rng.random_range(0.08..0.25) * tau) },
        "stribeck_friction" => {
            let fc = rng.random_range(0.08..0.2) * tau;
            Effect::StribeckFriction { fc: v(0.0, fc), fs: v(0.0, fc * rng.random_range(1.8..3.0)), vs: v(0.0, rng.random_range(0.1..0.3) * qd) }
        }
        "armature" => {
            let mut ws = Workspace::new(model);
            let h = mass_matrix(model, &mut ws, &vec![0.0; n]);
            Effect::Armature { ia: v(0.0, rng.random_range(0.2..0.6) * h[(joint, joint)]) }
        }
        "torque_gain" => Effect::TorqueGain { k: v(1.0, if rng.random_bool(0.5) { rng.random_range(0.6..0.85) } else { rng.random_range(1.15..1.4) }) },
        "torque_offset" => Effect::TorqueOffset { offset: v(0.0, rng.random_range(0.08..0.25) * tau * if rng.random_bool(0.5) { 1.0 } else { -1.0 }) },
        "torque_saturation" => Effect::TorqueSaturation { limit: v(f64::INFINITY, rng.random_range(0.45..0.75) * max_abs(nominal, &nominal.tau, joint)) },
        "cogging" => Effect::Cogging { amplitude: v(0.0, rng.random_range(0.08..0.2) * tau), periods_per_rev: v(1.0, rng.random_range(4..30) as f64) },
        "payload" => {
            let last = model.joints()[n - 1].inertia.mass.max(0.5);
            Effect::Payload { mass: rng.random_range(0.3..1.0) * last, com: [rng.random_range(-0.05..0.05), rng.random_range(-0.05..0.05), rng.random_range(-0.1..0.1)] }
        }
        "inertial_error" => {
            // a mass change of the last link is a payload; draw another link (robots with one
            // link never draw this effect)
            let link = rng.random_range(0..n.saturating_sub(1).max(1));
            let m = model.joints()[link].inertia.mass;
            Effect::InertialError {
                deltas: vec![LinkDelta { joint: link, mass: m * rng.random_range(0.15..0.35) * if rng.random_bool(0.5) { 1.0 } else { -1.0 }, com: [0.0; 3], inertia: [0.0; 6] }],
            }
        }
        "time_delay" => Effect::TimeDelay { delay: rng.random_range(1..=3) as f64 * 0.0025 },
        _ => Effect::CoriolisStructure,
    }
}

/// Generates scenario `index` of a self-check seeded with `seed`: 20 % effect-free, 50 % one
/// effect, 30 % two effects of different kinds; a quarter of the scenarios are open-loop
/// replays (the logs of the closed-loop runs relabelled `replay`: the robot driven by the
/// recorded torque, no feedback).
///
/// # Errors
/// Simulator errors (a scenario whose hidden effects make it diverge is redrawn).
pub fn scenario(seed: u64, index: usize) -> crate::Result<Scenario> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_mul(1_000_003).wrapping_add(index as u64));
    let robots = robots();
    for _attempt in 0..10 {
        let model = robots[[0, 0, 0, 1, 2][rng.random_range(0..5)]].clone();
        let n = model.dof();
        let (kp, kv) = gains_for(&model, rng.random_range(2.0..4.0));
        let amp = if n > 2 { 0.5 } else { 1.0 };
        let spec = |name: String, duration: f64, rng: &mut ChaCha8Rng| -> RunSpec {
            let controller = if rng.random_bool(0.7) { ControllerKind::PdGravity } else { ControllerKind::Pd };
            let reference = if rng.random_bool(0.6) { RefSpec::Fourier(random_fourier(n, amp, rng)) } else { random_setpoints(n, amp, duration, rng.random_range(0.6..1.2), rng) };
            RunSpec { name, controller, kp: kp.clone(), kv: kv.clone(), reference, duration }
        };
        let fit_specs: Vec<RunSpec> = (0..3).map(|i| spec(format!("s{index}-fit{i}"), 4.0, &mut rng)).collect();
        let hold_specs = [spec(format!("s{index}-holdout"), 6.0, &mut rng)];
        let nominal = generate(&model, Formulation::EulerLagrange, &[], &fit_specs[0], 0.0025, 1_024_000.0)?;
        let count = [0, 1, 1, 1, 1, 1, 2, 2, 2, 0][rng.random_range(0..10)];
        let mut effects: Vec<Effect> = Vec::new();
        while effects.len() < count {
            let all: Vec<&str> = PER_JOINT.iter().chain(WHOLE.iter()).copied().collect();
            let name = all[rng.random_range(0..all.len())];
            // on a one-joint robot a torque gain is exactly a scaling of its inertial parameters,
            // and an inertial error of its only link is a payload: not identifiable apart
            // a one-joint robot has no Coriolis terms at all, so neither formulation differs
            if n == 1 && matches!(name, "torque_gain" | "inertial_error" | "payload" | "coriolis_structure") {
                continue;
            }
            // Coulomb plus Stribeck on one joint is a single Stribeck friction
            let dry = |e: &Effect| matches!(e.name(), "coulomb_friction" | "stribeck_friction");
            if matches!(name, "coulomb_friction" | "stribeck_friction") && effects.iter().any(dry) {
                continue;
            }
            if effects.iter().any(|e| e.name() == name)
                || (name == "payload" && effects.iter().any(|e| e.name() == "inertial_error"))
                || (name == "inertial_error" && effects.iter().any(|e| e.name() == "payload"))
            {
                continue;
            }
            let joint = rng.random_range(0..n);
            effects.push(draw_effect(name, &model, &nominal, joint, &mut rng));
        }
        let gen = |s: &RunSpec| generate(&model, Formulation::EulerLagrange, &effects, s, 0.0025, 1_024_000.0);
        let fit: crate::Result<Vec<Run>> = fit_specs.iter().map(gen).collect();
        let hold: crate::Result<Vec<Run>> = hold_specs.iter().map(gen).collect();
        let open_loop = rng.random_bool(0.25);
        if let (Ok(mut fit), Ok(mut holdout)) = (fit, hold) {
            if open_loop {
                as_replay(&mut fit);
                as_replay(&mut holdout);
            }
            return Ok(Scenario { index, model, effects, fit, holdout, family: if open_loop { "open_loop" } else { "closed_loop" } });
        }
    }
    Err(crate::Error::Input(format!("scenario {index}: every draw diverged")))
}

/// The (effect, joint) pairs of a set of effects; whole-robot effects have joint `None`.
pub fn truth_set(model: &Model, effects: &[Effect]) -> BTreeSet<(String, Option<String>)> {
    let names = model.joint_names();
    let mut s = BTreeSet::new();
    for e in effects {
        if WHOLE.contains(&e.name()) {
            s.insert((e.name().to_string(), None));
        } else {
            for j in e.joints_acted() {
                s.insert((e.name().to_string(), Some(names[j].to_string())));
            }
        }
    }
    s
}

/// The (effect, joint) pairs the diagnosis selected.
pub fn found_set(d: &Diagnosis) -> BTreeSet<(String, Option<String>)> {
    let mut s = BTreeSet::new();
    for e in &d.report.selected_effects {
        if WHOLE.contains(&e.effect.as_str()) {
            s.insert((e.effect.clone(), None));
        } else {
            for j in &e.joints {
                s.insert((e.effect.clone(), Some(j.clone())));
            }
        }
    }
    s
}

/// Relative errors of the found parameters against the truth, for correctly found effects.
fn parameter_errors(model: &Model, truth: &[Effect], d: &Diagnosis) -> Vec<(String, f64)> {
    let names = model.joint_names();
    let mut out = Vec::new();
    for e in truth {
        let Some(rep) = d.report.selected_effects.iter().find(|r| r.effect == e.name()) else { continue };
        let per_joint = |key: &str, values: &[f64]| -> Vec<(String, f64)> {
            let mut v = Vec::new();
            if let Some(Param::PerJoint(found)) = rep.parameters.get(key) {
                for j in e.joints_acted() {
                    if let Some(pos) = rep.joints.iter().position(|n| n == names[j]) {
                        let t = values[j];
                        if t.is_finite() && t != 0.0 {
                            v.push((format!("{}.{key}", e.name()), ((found[pos] - t) / t).abs()));
                        }
                    }
                }
            }
            v
        };
        match e {
            Effect::ViscousFriction { b } => out.extend(per_joint("b", b)),
            Effect::CoulombFriction { fc } => out.extend(per_joint("fc", fc)),
            Effect::StribeckFriction { fc, fs, .. } => {
                out.extend(per_joint("fc", fc));
                out.extend(per_joint("fs", fs));
            }
            Effect::Armature { ia } => out.extend(per_joint("ia", ia)),
            Effect::TorqueGain { k } => out.extend(per_joint("k", k)),
            Effect::TorqueOffset { offset } => out.extend(per_joint("offset", offset)),
            Effect::TorqueSaturation { limit } => out.extend(per_joint("limit", limit)),
            Effect::Cogging { amplitude, .. } => out.extend(per_joint("amplitude", amplitude)),
            Effect::TimeDelay { delay } => {
                if let Some(Param::Number(f)) = rep.parameters.get("delay") {
                    out.push(("time_delay.delay".into(), ((f - delay) / delay).abs()));
                }
            }
            Effect::Payload { mass, .. } => {
                if let Some(Param::Number(f)) = rep.parameters.get("mass") {
                    out.push(("payload.mass".into(), ((f - mass) / mass).abs()));
                }
            }
            _ => {}
        }
    }
    out
}

/// The score of one scenario.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ScenarioScore {
    /// Index.
    pub index: usize,
    /// Robot.
    pub robot: String,
    /// Hidden (effect, joint) pairs.
    pub truth: Vec<String>,
    /// Selected pairs.
    pub found: Vec<String>,
    /// Scenario family (`closed_loop` or `open_loop`).
    pub family: String,
    /// Exactly the hidden set.
    pub exact: bool,
    /// Not exact, but the hidden effects are one of the report's `alternatives` (an effect set
    /// these data cannot tell apart from the selected one).
    pub in_alternatives: bool,
    /// Held-out k-step error after / before at the longest horizon.
    pub kstep_ratio: f64,
    /// Relative parameter errors of correctly found effects.
    pub parameter_errors: Vec<(String, f64)>,
    /// Held-out L² after / before.
    pub holdout_ratio: f64,
    /// An error, if the diagnosis failed.
    pub error: Option<String>,
}

impl ScenarioScore {
    /// The score of a scenario that could not be generated or diagnosed.
    fn failed(index: usize, robot: String, family: String, truth: Vec<String>, error: String) -> ScenarioScore {
        ScenarioScore {
            index,
            robot,
            family,
            truth,
            found: vec![],
            exact: false,
            in_alternatives: false,
            kstep_ratio: f64::NAN,
            parameter_errors: vec![],
            holdout_ratio: f64::NAN,
            error: Some(error),
        }
    }
}

fn label(s: &BTreeSet<(String, Option<String>)>) -> Vec<String> {
    s.iter()
        .map(|(e, j)| match j {
            Some(j) => format!("{e}@{j}"),
            None => e.clone(),
        })
        .collect()
}

/// Runs one scenario end to end.
pub fn run_scenario(seed: u64, index: usize) -> ScenarioScore {
    let sc = match scenario(seed, index) {
        Ok(s) => s,
        Err(e) => return ScenarioScore::failed(index, String::new(), String::new(), vec![], e.to_string()),
    };
    let truth = truth_set(&sc.model, &sc.effects);
    match diagnose(&sc.model, Formulation::EulerLagrange, &sc.fit, &sc.holdout, &DiagnoseOptions::default(), &mut |_| {}) {
        Ok(d) => {
            let found = found_set(&d);
            let truth_names: BTreeSet<String> = truth.iter().map(|t| t.0.clone()).collect();
            let in_alternatives =
                found != truth && !truth_names.is_empty() && d.report.alternatives.iter().any(|a| a.effects.iter().cloned().collect::<BTreeSet<String>>() == truth_names);
            let k = &d.report.gap.kstep;
            let last = k.horizons_s.len().saturating_sub(1);
            ScenarioScore {
                index,
                robot: sc.model.name().into(),
                family: sc.family.into(),
                exact: found == truth,
                in_alternatives,
                kstep_ratio: k.after.get(last).zip(k.before.get(last)).map_or(f64::NAN, |(a, b)| a / b),
                parameter_errors: parameter_errors(&sc.model, &sc.effects, &d),
                holdout_ratio: d.report.gap.ratio,
                truth: label(&truth),
                found: label(&found),
                error: None,
            }
        }
        Err(e) => ScenarioScore::failed(index, sc.model.name().into(), sc.family.into(), label(&truth), e.to_string()),
    }
}

/// Aggregate of a self-check.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Summary {
    /// Scenarios per number of hidden effects: (count, exactly right, right up to an
    /// alternative the data cannot tell apart).
    pub by_count: BTreeMap<usize, (usize, usize, usize)>,
    /// Per family: (scenarios, right up to alternatives, median held-out k-step after/before at
    /// the longest horizon over scenarios with hidden effects).
    pub by_family: BTreeMap<String, (usize, usize, f64)>,
    /// Confusion counts: true effect (or `none`) → selected effect (or `nothing`) → count.
    pub confusion: BTreeMap<String, BTreeMap<String, usize>>,
    /// Median relative parameter error over correctly found effects.
    pub median_parameter_error: f64,
    /// Median held-out L² after/before where the true effects were found.
    pub median_holdout_ratio: f64,
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
    let mut perr = Vec::new();
    let mut ratios = Vec::new();
    let mut failures = 0;
    let base = |s: &str| s.split('@').next().unwrap_or(s).to_string();
    for s in scores {
        if s.error.is_some() {
            failures += 1;
            continue;
        }
        let true_effects: BTreeSet<String> = s.truth.iter().map(|x| base(x)).collect();
        let found_effects: BTreeSet<String> = s.found.iter().map(|x| base(x)).collect();
        let e = by_count.entry(true_effects.len()).or_insert((0, 0, 0));
        e.0 += 1;
        if s.exact {
            e.1 += 1;
        }
        if s.exact || s.in_alternatives {
            e.2 += 1;
        }
        let f = by_family.entry(s.family.clone()).or_insert((0, 0, Vec::new()));
        f.0 += 1;
        if s.exact || s.in_alternatives {
            f.1 += 1;
        }
        if !true_effects.is_empty() {
            f.2.push(s.kstep_ratio);
        }
        let rows: Vec<String> = if true_effects.is_empty() { vec!["none".into()] } else { true_effects.iter().cloned().collect() };
        let cols: Vec<String> = if found_effects.is_empty() { vec!["nothing".into()] } else { found_effects.iter().cloned().collect() };
        for r in &rows {
            for c in &cols {
                *confusion.entry(r.clone()).or_default().entry(c.clone()).or_default() += 1;
            }
        }
        perr.extend(s.parameter_errors.iter().map(|p| p.1));
        if s.exact && !true_effects.is_empty() {
            ratios.push(s.holdout_ratio);
        }
    }
    let by_family = by_family.into_iter().map(|(k, (n, right, r))| (k, (n, right, median(r)))).collect();
    Summary { by_count, by_family, confusion, median_parameter_error: median(perr), median_holdout_ratio: median(ratios), failures }
}
