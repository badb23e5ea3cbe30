//! The self-check: blind scenarios (robot, hidden effects, references, controllers; random ones
//! and named families, [`scenario`]), diagnosed like real logs and scored against the hidden
//! truth by each family's rule ([`run_scenario`]); for found effects whose truth is known, whether
//! the true parameter lies within the reported 95 % interval ([`Summary::coverage`]).

use std::collections::{BTreeMap, BTreeSet};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use simgap_core::{mass_matrix, Formulation, Model, UrdfOptions, Workspace};
use simgap_sim::{ControllerKind, Effect, LinkDelta, Run};

use crate::check::bench::{gains_for, generate, random_fourier, random_setpoints, RefSpec, RunSpec};
use crate::options::DiagnoseOptions;
use crate::pipeline::diagnose;
use crate::report::Diagnosis;
use crate::vocabulary::effects::{EffectReport, Param};

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
    /// The family (one of [`FAMILIES`]).
    pub family: &'static str,
    /// The model the diagnosis is given (the robot's own, except in `urdf_inertia_pitfall`).
    pub diagnosis_model: Model,
    /// The (effect, joint) pairs a right diagnosis selects ([`truth_set`] of the effects, or an
    /// inertial correction for a wrong URDF).
    pub truth: BTreeSet<(String, Option<String>)>,
    /// A `glitch` scenario's glitch: (fit log, sample, joint) set to [`GLITCH_VALUE`] when
    /// diagnosed; the logs in `fit` are clean.
    pub glitch: Option<(usize, usize, usize)>,
    /// A `servo` scenario's servos (their motor constants are the truth the diagnosis fits).
    pub servo: Option<crate::check::bench::ServoSpec>,
    /// The diagnosis is asked to try friction that differs by direction (as
    /// `--directional-friction`).
    pub directional_friction: bool,
    /// The diagnosis is asked to try a servo's load friction rising at rest (as
    /// `--load-stribeck-friction`).
    pub load_stribeck_friction: bool,
}

impl Scenario {
    /// A scenario whose logs were simulated on `model` itself with the hidden `effects` (the
    /// diagnosis gets the robot's own model; the truth is [`truth_set`] of the effects; no glitch,
    /// no servo, directional friction not tried).
    pub(crate) fn simulated(index: usize, model: Model, effects: Vec<Effect>, fit: Vec<Run>, holdout: Vec<Run>, family: &'static str) -> Scenario {
        let truth = truth_set(&model, &effects);
        Scenario {
            index,
            diagnosis_model: model.clone(),
            model,
            effects,
            truth,
            fit,
            holdout,
            family,
            glitch: None,
            servo: None,
            directional_friction: false,
            load_stribeck_friction: false,
        }
    }
}

/// Relabels runs as open-loop replays of their commanded torque.
pub(crate) fn as_replay(runs: &mut [Run]) {
    for r in runs {
        if let Some(e) = r.experiment.as_mut() {
            e.controller = ControllerKind::Replay;
            e.kp = vec![0.0; e.joints.len()];
            e.kv = vec![0.0; e.joints.len()];
        }
    }
}

pub(crate) fn rms(run: &Run, m: &[f64], j: usize) -> f64 {
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
    // a passive joint is commanded no torque: its effects are sized against the largest joint's
    let tau = rms(nominal, &nominal.tau, joint);
    let tau = if tau > 1e-9 { tau } else { (0..n).map(|j| rms(nominal, &nominal.tau, j)).fold(0.0, f64::max) }.max(1e-6);
    let qd = rms(nominal, &nominal.qd, joint).max(1e-3);
    let v = |neutral: f64, x: f64| {
        let mut out = vec![neutral; n];
        out[joint] = x;
        out
    };
    match name {
        "viscous_friction" => Effect::ViscousFriction { b: v(0.0, rng.random_range(0.08..0.25) * tau / qd) },
        "coulomb_friction" => Effect::CoulombFriction { fc: v(0.0, rng.random_range(0.08..0.25) * tau), w: vec![simgap_sim::DEFAULT_COULOMB_WIDTH; n] },
        "stribeck_friction" => {
            let fc = rng.random_range(0.08..0.2) * tau;
            Effect::StribeckFriction {
                fc: v(0.0, fc),
                fs: v(0.0, fc * rng.random_range(1.8..3.0)),
                vs: v(0.0, rng.random_range(0.1..0.3) * qd),
                w: vec![simgap_sim::DEFAULT_COULOMB_WIDTH; n],
            }
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

/// The scenario families, in the order the self-check cycles through them (see [`scenario`]).
pub const FAMILIES: [&str; 11] = [
    "closed_loop",
    "open_loop",
    "double_pendulum_replay",
    "urdf_inertia_pitfall",
    "passive_joint",
    "feed_forward",
    "friction_shape",
    "per_joint_gains",
    "delay",
    "glitch",
    "equivalence",
];

/// Of every [`CYCLE`] consecutive scenarios, the first [`RANDOM_SLOTS`] are random
/// (`closed_loop` or `open_loop`); the others are the named families from
/// `double_pendulum_replay` on, one each.
pub const CYCLE: usize = 13;
const RANDOM_SLOTS: usize = 4;

/// The family of scenario `index`.
pub fn family_of(index: usize) -> &'static str {
    let slot = index % CYCLE;
    if slot < RANDOM_SLOTS {
        "random"
    } else {
        FAMILIES[2 + slot - RANDOM_SLOTS]
    }
}

/// A double pendulum shaped like DFKI's (two 0.6 kg links, 0.3 m and 0.2 m, nearly point
/// masses at their ends), hanging at q = 0; joints `shoulder` and `elbow` about y.
pub fn double_pendulum() -> Model {
    use nalgebra::{Matrix3, Vector3};
    use simgap_core::{Joint, JointKind, JointLimits, SpatialInertia, Transform};
    let link = |m: f64, r: f64, i: f64| SpatialInertia::from_com(m, Vector3::new(0.0, 0.0, -r), Matrix3::from_diagonal(&Vector3::new(i, i, 0.2 * i)));
    let limits = JointLimits { lower: -std::f64::consts::PI, upper: std::f64::consts::PI, effort: 6.0, velocity: 20.0 };
    let mut shoulder = Joint::new("shoulder", JointKind::Revolute, Vector3::y(), Transform::IDENTITY, "upper_link", link(0.6, 0.3, 0.004));
    shoulder.limits = limits;
    let placement = Transform { rotation: Matrix3::identity(), translation: Vector3::new(0.0, 0.0, -0.3) };
    let mut elbow = Joint::new("elbow", JointKind::Revolute, Vector3::y(), placement, "lower_link", link(0.6, 0.2, 0.002));
    elbow.limits = limits;
    let mut model = Model::new("double_pendulum", "base_link", vec![shoulder, elbow]).expect("the double pendulum is a valid model");
    model.set_gravity(Vector3::new(0.0, 0.0, -9.81));
    model
}

/// `model` with every link's inertia about its joint axis written as its inertia about the
/// centre of mass (`I_c' = I_c + m (|c|² 1 − c cᵀ)`, the URDF pitfall of DFKI's published
/// double pendulum).
pub fn inertia_about_axis_as_com(model: &Model) -> Model {
    let mut wrong = model.clone();
    for (i, j) in model.joints().iter().enumerate() {
        let (m, c) = (j.inertia.mass, j.inertia.com());
        let shifted = j.inertia.inertia_about_com() + (nalgebra::Matrix3::identity() * c.norm_squared() - c * c.transpose()) * m;
        // the result is a valid inertia (a sum of two), so this cannot fail
        let _ = wrong.set_link_inertia(i, simgap_core::SpatialInertia::from_com(m, c, shifted));
    }
    wrong
}

/// Draws `count` effects of different kinds for `model` (sized against `nominal`), keeping out
/// pairs the data cannot tell apart (see the comments).
pub(crate) fn draw_effects(model: &Model, nominal: &Run, count: usize, rng: &mut ChaCha8Rng) -> Vec<Effect> {
    let n = model.dof();
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
        effects.push(draw_effect(name, model, nominal, joint, rng));
    }
    effects
}

/// Position [rad] written into one fit sample of a `glitch` scenario.
pub const GLITCH_VALUE: f64 = 10.0;

/// Generates scenario `index` of a self-check seeded with `seed`. Its family is
/// [`family_of`]`(index)`:
///
/// - `random` slots: the robot (the paper's arm, a pendulum, a 7-joint arm) and 0 effects
///   (20 %), one (50 %) or two of different kinds (30 %), PD or PD + gravity tracking of sums of
///   sinusoids or set-points; a quarter of them are relabelled `open_loop` (the logs replayed
///   from their commanded torque, no feedback), the rest are `closed_loop`;
/// - `double_pendulum_replay`: a DFKI-like [`double_pendulum`], one effect, open-loop replays;
/// - `urdf_inertia_pitfall`: logs of the double pendulum or the paper's arm, diagnosed with a
///   model whose links' inertias about the joint axes are written as about the COM
///   ([`inertia_about_axis_as_com`]); the truth is an inertial correction of every link;
/// - `passive_joint`: the double pendulum or the paper's arm with its shoulder unactuated
///   (gains 0, commanded torque exactly 0, as an acrobot), one effect that a passive joint can
///   have (friction, armature on either joint; an actuator effect only on the elbow);
/// - `feed_forward`: PD tracking with the nominal computed torque as feed-forward, one effect;
/// - `friction_shape`: a dry friction `fc tanh(q̇ / w)` with `w` 0.1–0.3 rad/s, ten to thirty
///   times softer than the vocabulary's Coulomb and Stribeck shapes, on one joint;
/// - `per_joint_gains`: a torque gain on every joint of a multi-joint robot, different per joint;
/// - `delay`: an actuation delay of 1, 2 or 3 samples alone;
/// - `glitch`: a random one-effect scenario with one sample of one fit log at
///   [`GLITCH_VALUE`] rad;
/// - `equivalence`: an effect with an exact equivalent (a payload, or a torque gain equal on
///   every joint).
///
/// # Errors
/// Simulator errors (a scenario whose hidden effects make it diverge is redrawn).
pub fn scenario(seed: u64, index: usize) -> crate::Result<Scenario> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_mul(1_000_003).wrapping_add(index as u64));
    let robots = robots();
    let family = family_of(index);
    for _attempt in 0..10 {
        let model = match family {
            "random" | "feed_forward" | "friction_shape" | "delay" | "glitch" => robots[[0, 0, 0, 1, 2][rng.random_range(0..5)]].clone(),
            "per_joint_gains" | "equivalence" => robots[[0, 0, 2][rng.random_range(0..3)]].clone(),
            "double_pendulum_replay" => double_pendulum(),
            _ => {
                if rng.random_bool(0.5) {
                    double_pendulum()
                } else {
                    robots[0].clone()
                }
            }
        };
        let n = model.dof();
        let (mut kp, mut kv) = gains_for(&model, rng.random_range(2.0..4.0));
        if family == "passive_joint" {
            kp[0] = 0.0;
            kv[0] = 0.0;
        }
        let amp = if n > 2 { 0.5 } else { 1.0 };
        let spec = |name: String, duration: f64, rng: &mut ChaCha8Rng| -> RunSpec {
            let mut controller = if rng.random_bool(0.7) { ControllerKind::PdGravity } else { ControllerKind::Pd };
            let mut reference =
                if rng.random_bool(0.6) { RefSpec::Fourier(random_fourier(n, amp, rng)) } else { random_setpoints(n, amp, duration, rng.random_range(0.6..1.2), rng) };
            match family {
                // gravity compensation would drive the passive joint
                "passive_joint" => controller = ControllerKind::Pd,
                "feed_forward" => {
                    controller = ControllerKind::Pd;
                    reference = RefSpec::FeedForward(random_fourier(n, amp, rng));
                }
                _ => {}
            }
            RunSpec { name, controller, kp: kp.clone(), kv: kv.clone(), reference, duration }
        };
        let fit_specs: Vec<RunSpec> = (0..3).map(|i| spec(format!("s{index}-fit{i}"), 4.0, &mut rng)).collect();
        let hold_specs = [spec(format!("s{index}-holdout"), 6.0, &mut rng)];
        let nominal = generate(&model, Formulation::EulerLagrange, &[], &fit_specs[0], 0.0025, 1_024_000.0)?;
        let effects: Vec<Effect> = match family {
            "random" => {
                let count = [0, 1, 1, 1, 1, 1, 2, 2, 2, 0][rng.random_range(0..10)];
                draw_effects(&model, &nominal, count, &mut rng)
            }
            "double_pendulum_replay" | "feed_forward" | "glitch" => draw_effects(&model, &nominal, 1, &mut rng),
            "urdf_inertia_pitfall" => vec![],
            "passive_joint" => {
                let joint = rng.random_range(0..n);
                let kinds: &[&str] = if joint == 0 {
                    &["viscous_friction", "coulomb_friction", "armature"]
                } else {
                    &["viscous_friction", "coulomb_friction", "armature", "torque_gain", "torque_offset"]
                };
                let name = kinds[rng.random_range(0..kinds.len())];
                vec![draw_effect(name, &model, &nominal, joint, &mut rng)]
            }
            "friction_shape" => {
                let width = rng.random_range(0.1..0.3);
                let joint = rng.random_range(0..n);
                let tau = rms(&nominal, &nominal.tau, joint).max(1e-6);
                let mut fc = vec![0.0; n];
                fc[joint] = rng.random_range(0.1..0.25) * tau;
                vec![Effect::CoulombFriction { fc, w: vec![width; n] }]
            }
            "per_joint_gains" => {
                // distinct gains from a grid of twelve (0.60–0.85 and 1.15–1.40 in steps of 0.05),
                // drawn without replacement and jittered by at most ±0.01, so any two are at
                // least 0.03 apart even on the seven-joint arm (equal gains are the
                // `equivalence` family)
                let mut grid: Vec<f64> = (0..6).map(|i| 0.6 + 0.05 * i as f64).chain((0..6).map(|i| 1.15 + 0.05 * i as f64)).collect();
                let k: Vec<f64> = (0..n)
                    .map(|_| {
                        let g = grid.swap_remove(rng.random_range(0..grid.len()));
                        g + rng.random_range(-0.01..0.01)
                    })
                    .collect();
                vec![Effect::TorqueGain { k }]
            }
            "delay" => vec![Effect::TimeDelay { delay: rng.random_range(1..=3) as f64 * 0.0025 }],
            _ => {
                if rng.random_bool(0.5) {
                    vec![draw_effect("payload", &model, &nominal, n - 1, &mut rng)]
                } else {
                    let k = if rng.random_bool(0.5) { rng.random_range(0.6..0.85) } else { rng.random_range(1.15..1.4) };
                    vec![Effect::TorqueGain { k: vec![k; n] }]
                }
            }
        };
        let gen = |s: &RunSpec| generate(&model, Formulation::EulerLagrange, &effects, s, 0.0025, 1_024_000.0);
        let fit: crate::Result<Vec<Run>> = fit_specs.iter().map(gen).collect();
        let hold: crate::Result<Vec<Run>> = hold_specs.iter().map(gen).collect();
        let open_loop = match family {
            "random" => rng.random_bool(0.25),
            "double_pendulum_replay" => true,
            _ => false,
        };
        if let (Ok(mut fit), Ok(mut holdout)) = (fit, hold) {
            if open_loop {
                as_replay(&mut fit);
                as_replay(&mut holdout);
            }
            let mut truth = truth_set(&model, &effects);
            let mut diagnosis_model = model.clone();
            let mut glitch = None;
            match family {
                "urdf_inertia_pitfall" => {
                    diagnosis_model = inertia_about_axis_as_com(&model);
                    truth = BTreeSet::from([("inertial_error".to_string(), None)]);
                }
                "glitch" => {
                    let (r, j) = (rng.random_range(0..fit.len()), rng.random_range(0..n));
                    let k = rng.random_range(fit[r].len() / 10..fit[r].len() * 9 / 10);
                    glitch = Some((r, k, j));
                }
                _ => {}
            }
            let family = match family {
                "random" if open_loop => "open_loop",
                "random" => "closed_loop",
                f => f,
            };
            return Ok(Scenario {
                index,
                model,
                diagnosis_model,
                effects,
                truth,
                fit,
                holdout,
                family,
                glitch,
                servo: None,
                directional_friction: false,
                load_stribeck_friction: false,
            });
        }
    }
    Err(crate::Error::Input(format!("scenario {index}: every draw diverged")))
}

/// A `servo` scenario: a pendulum or the double pendulum driven by position-controlled servos
/// of random motor constants (stall torque 2–4 times the largest gravity torque, a 2 Hz P loop),
/// one or two hidden mechanical effects (rotor inertia, Coulomb, viscous or load-dependent
/// friction), three 8 s fit logs (two dropped with torque off at 5 s, as a servo
/// identification drops the arm to tell friction from the drive) and one held-out log,
/// logged as servos log (goal, duty, torque enable; no torque, no motor-constant priors).
///
/// One index in [`SATURATION_EVERY`] (`index % 4 == 1`) draws a `servo_saturation` scenario
/// instead: the same servo and mechanics, its first joint's drive limited to 45–75 % of that
/// joint's gravity torque at the horizontal (a current limit well below the stall torque, drawn
/// apart so that the rest of the draw stays what it was), and goals of 0.9 rad (two joints) or
/// 1.2 rad (one), large enough to reach it. Another (`index % 4 == 3`) draws a
/// `servo_breakaway` scenario: its first hidden effect is a load friction rising at rest
/// (`load_stribeck_friction`: moving `fc` 1–3 % of the stall torque and `mu` 0.15–0.35, at rest
/// `fs` 1–3 % of the stall torque higher and `mus` 0.2–0.4 higher, `vs` 0.05–0.3 rad/s), and the
/// diagnosis is asked to try it (`--load-stribeck-friction`).
///
/// The servo family is drawn apart from the [`CYCLE`] (so that the scenarios of earlier seeds
/// stay what they were): scenario `index` of seed `seed` is [`servo_scenario`]`(seed, index)`,
/// scored by [`run_servo_scenario`].
pub fn servo_scenario(seed: u64, index: usize) -> crate::Result<Scenario> {
    let family = servo_family(index);
    draw_servo(seed, index, family == "servo_saturation", family == "servo_breakaway")
}

/// `effects` (of a `dof`-joint robot) with their first a load friction rising at rest on
/// `joint` (of stall torque `stall`), drawn from `rng` (see [`servo_scenario`]), and without a
/// second dry friction.
fn rising_at_rest(effects: &[Effect], dof: usize, joint: usize, stall: f64, rng: &mut ChaCha8Rng) -> Vec<Effect> {
    let v = |value: f64| -> Vec<f64> { (0..dof).map(|i| if i == joint { value } else { 0.0 }).collect() };
    let (fc, mu) = (rng.random_range(0.01..0.03) * stall, rng.random_range(0.15..0.35));
    let rise = Effect::LoadStribeckFriction {
        fc: v(fc),
        mu: v(mu),
        fs: v(fc + rng.random_range(0.01..0.03) * stall),
        mus: v(mu + rng.random_range(0.2..0.4)),
        vs: v(rng.random_range(0.05..0.3)),
        w: vec![simgap_sim::DEFAULT_COULOMB_WIDTH; dof],
    };
    let dry = |e: &Effect| matches!(e, Effect::CoulombFriction { .. } | Effect::LoadFriction { .. });
    std::iter::once(rise).chain(effects.iter().skip(1).filter(|e| !dry(e)).cloned()).collect()
}

/// The family of servo scenario `index`: `servo_saturation` for one in [`SATURATION_EVERY`],
/// `servo_breakaway` for another, else `servo`.
fn servo_family(index: usize) -> &'static str {
    match index % SATURATION_EVERY {
        1 => "servo_saturation",
        3 => "servo_breakaway",
        _ => "servo",
    }
}

/// Of every this many servo scenarios, one (`index % SATURATION_EVERY == 1`) has a torque
/// limit ([`servo_scenario`]).
pub const SATURATION_EVERY: usize = 4;

/// Servo scenario `index` of seed `seed` ([`servo_scenario`]), with its torque limit or without
/// (`limited`).
///
/// # Errors
/// [`crate::Error::Input`] when every draw diverged.
pub fn servo_draw(seed: u64, index: usize, limited: bool) -> crate::Result<Scenario> {
    draw_servo(seed, index, limited, false)
}

/// [`servo_draw`], or with `breakaway` the same draw with its first effect a load friction
/// rising at rest (its parameters and the logs' goals drawn apart, see [`servo_scenario`]).
fn draw_servo(seed: u64, index: usize, limited: bool, breakaway: bool) -> crate::Result<Scenario> {
    use crate::check::bench::{generate_servo, random_fourier, ServoSpec};
    // the limit's share of the gravity torque, drawn apart from the rest
    let limit_share = ChaCha8Rng::seed_from_u64(seed.wrapping_mul(4_000_037).wrapping_add(index as u64)).random_range(0.45..0.75);
    let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_mul(2_000_029).wrapping_add(index as u64));
    let rng = &mut rng;
    for _attempt in 0..10 {
        let model = if rng.random_bool(0.5) { Model::from_urdf_str(simgap_core::PENDULUM_URDF)? } else { double_pendulum() };
        let n = model.dof();
        let h = simgap_core::mass_matrix(&model, &mut simgap_core::Workspace::new(&model), &vec![0.0; n]);
        let gravity: Vec<f64> = (0..n).map(|j| (j..n).map(|i| model.joints()[i].inertia.mass).sum::<f64>() * 9.81 * 0.5).collect();
        let volts = rng.random_range(6.0..14.0);
        let kt: Vec<f64> = (0..n).map(|_| rng.random_range(0.3..1.5)).collect();
        let stall: Vec<f64> = (0..n).map(|j| rng.random_range(2.0..4.0) * gravity[j].max(1.0)).collect();
        let r: Vec<f64> = (0..n).map(|j| kt[j] * volts / stall[j]).collect();
        let w = std::f64::consts::TAU * 2.0;
        let duty_gain: Vec<f64> = (0..n).map(|j| w * w * h[(j, j)] / stall[j]).collect();
        let servo = ServoSpec { duty_gain, volts, kt: kt.clone(), r: r.clone() };
        // one or two effects, not two dry frictions
        let joint = rng.random_range(0..n);
        let kinds = ["armature", "coulomb_friction", "viscous_friction", "load_friction"];
        let first = kinds[rng.random_range(0..kinds.len())];
        let mut names = vec![first];
        if rng.random_bool(0.5) {
            let dry = |k: &str| matches!(k, "coulomb_friction" | "load_friction");
            let second = kinds[rng.random_range(0..kinds.len())];
            if second != first && !(dry(first) && dry(second)) {
                names.push(second);
            }
        }
        let v = |value: f64| -> Vec<f64> { (0..n).map(|i| if i == joint { value } else { 0.0 }).collect() };
        let back_emf = kt[joint] * kt[joint] / r[joint];
        let mut effects: Vec<Effect> = names
            .iter()
            .map(|k| match *k {
                "armature" => Effect::Armature { ia: v(rng.random_range(0.2..0.6) * h[(joint, joint)]) },
                "coulomb_friction" => Effect::CoulombFriction { fc: v(rng.random_range(0.03..0.08) * stall[joint]), w: vec![simgap_sim::DEFAULT_COULOMB_WIDTH; n] },
                "viscous_friction" => Effect::ViscousFriction { b: v(rng.random_range(0.5..1.5) * back_emf) },
                _ => {
                    Effect::LoadFriction { fc: v(rng.random_range(0.01..0.03) * stall[joint]), mu: v(rng.random_range(0.15..0.35)), w: vec![simgap_sim::DEFAULT_COULOMB_WIDTH; n] }
                }
            })
            .collect();
        let amp = match (limited, n > 1) {
            (false, true) => 0.5,
            (false, false) => 0.7,
            (true, true) => 0.9,
            (true, false) => 1.2,
        };
        if limited {
            effects.push(Effect::TorqueSaturation { limit: (0..n).map(|j| if j == 0 { limit_share * gravity[0].max(1.0) } else { f64::INFINITY }).collect() });
        }
        let family = match (limited, breakaway) {
            (true, _) => "servo_saturation",
            (false, true) => "servo_breakaway",
            (false, false) => "servo",
        };
        // a breakaway draw's friction and goals come from a stream of their own
        let mut apart = ChaCha8Rng::seed_from_u64(seed.wrapping_mul(5_000_011).wrapping_add(index as u64));
        if breakaway {
            effects = rising_at_rest(&effects, n, joint, kt[joint] / r[joint] * volts, &mut apart);
        }
        let logs: &mut ChaCha8Rng = if breakaway { &mut apart } else { &mut *rng };
        let goal = |rng: &mut ChaCha8Rng| random_fourier(n, amp, rng);
        let gen =
            |i: usize, off: f64, rng: &mut ChaCha8Rng, name: String| generate_servo(&model, &effects, &servo, &goal(rng), 8.0, off, 0.005, 1_024_000.0, &name).map_err(|e| (i, e));
        let fit: std::result::Result<Vec<Run>, _> = (0..3).map(|i| gen(i, if i < 2 { 5.0 } else { f64::INFINITY }, logs, format!("s{index}-fit{i}"))).collect();
        let hold = gen(3, f64::INFINITY, logs, format!("s{index}-holdout"));
        if let (Ok(fit), Ok(hold)) = (fit, hold) {
            return Ok(Scenario { servo: Some(servo), load_stribeck_friction: breakaway, ..Scenario::simulated(index, model, effects, fit, vec![hold], family) });
        }
    }
    Err(crate::Error::Input(format!("scenario {index}: every servo draw diverged")))
}

/// The (effect, joint) pairs of a set of effects; whole-robot effects have joint `None`.
///
/// A torque offset on a joint that also carries a spring is not a pair of its own: the spring's
/// torque `−k (q − q0)` holds a constant `k q0`, so `−k (q − q0) + o` is one spring about
/// `q0 + o / k`, and no data tell the two apart (the diagnosis reports the spring, whose rest
/// position holds the offset).
pub fn truth_set(model: &Model, effects: &[Effect]) -> BTreeSet<(String, Option<String>)> {
    let names = model.joint_names();
    let sprung: BTreeSet<usize> = effects.iter().filter(|e| matches!(e, Effect::JointSpring { .. })).flat_map(|e| e.joints_acted()).collect();
    let mut s = BTreeSet::new();
    for e in effects {
        if WHOLE.contains(&e.name()) {
            s.insert((e.name().to_string(), None));
        } else {
            for j in e.joints_acted() {
                if matches!(e, Effect::TorqueOffset { .. }) && sprung.contains(&j) {
                    continue;
                }
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

/// One found parameter against its true value: `(effect.parameter, truth, found, 95 %
/// half-width)` (the half-width `NaN` where the report gives none: grid-searched values).
type Comparison = (String, f64, f64, f64);

/// The found parameters of `reports` (selected effects) against the truth, for the true effects
/// found on their true joints.
fn comparisons(model: &Model, truth: &[Effect], reports: &[EffectReport]) -> Vec<Comparison> {
    let names = model.joint_names();
    let mut out = Vec::new();
    for e in truth {
        let Some(rep) = reports.iter().find(|r| r.effect == e.name()) else { continue };
        let per_joint = |key: &str, values: &[f64]| -> Vec<Comparison> {
            let mut v = Vec::new();
            if let (Some(Param::PerJoint(found)), unc) = (rep.parameters.get(key), rep.uncertainty.get(key)) {
                for j in e.joints_acted() {
                    if let Some(pos) = rep.joints.iter().position(|n| n == names[j]) {
                        let t = values[j];
                        let hw = match unc {
                            Some(Param::PerJoint(u)) => u.get(pos).copied().unwrap_or(f64::NAN),
                            _ => f64::NAN,
                        };
                        if t.is_finite() && t != 0.0 {
                            v.push((format!("{}.{key}", e.name()), t, found[pos], hw));
                        }
                    }
                }
            }
            v
        };
        match e {
            Effect::ViscousFriction { b } => out.extend(per_joint("b", b)),
            Effect::CoulombFriction { fc, .. } => out.extend(per_joint("fc", fc)),
            Effect::StribeckFriction { fc, fs, .. } => {
                out.extend(per_joint("fc", fc));
                out.extend(per_joint("fs", fs));
            }
            Effect::Armature { ia } => out.extend(per_joint("ia", ia)),
            Effect::TorqueGain { k } => out.extend(per_joint("k", k)),
            Effect::TorqueOffset { offset } => out.extend(per_joint("offset", offset)),
            Effect::TorqueSaturation { limit } => out.extend(per_joint("limit", limit)),
            Effect::Cogging { amplitude, .. } => out.extend(per_joint("amplitude", amplitude)),
            Effect::JointSpring { k, .. } => out.extend(per_joint("k", k)),
            Effect::LoadFriction { fc, mu, .. } => {
                out.extend(per_joint("fc", fc));
                out.extend(per_joint("mu", mu));
            }
            Effect::LoadStribeckFriction { fc, mu, fs, mus, .. } => {
                for (key, v) in [("fc", fc), ("mu", mu), ("fs", fs), ("mus", mus)] {
                    out.extend(per_joint(key, v));
                }
            }
            Effect::DirectionalFriction { fc_pos, fc_neg, b_pos, b_neg, .. } => {
                for (key, v) in [("fc_pos", fc_pos), ("fc_neg", fc_neg), ("b_pos", b_pos), ("b_neg", b_neg)] {
                    out.extend(per_joint(key, v));
                }
            }
            Effect::TimeDelay { delay } => {
                if let Some(Param::Number(f)) = rep.parameters.get("delay") {
                    out.push(("time_delay.delay".into(), *delay, *f, f64::NAN));
                }
            }
            Effect::Payload { mass, .. } => {
                if let Some(Param::Number(f)) = rep.parameters.get("mass") {
                    let hw = match rep.uncertainty.get("mass") {
                        Some(Param::Number(u)) => *u,
                        _ => f64::NAN,
                    };
                    out.push(("payload.mass".into(), *mass, *f, hw));
                }
            }
            _ => {}
        }
    }
    out
}

/// Whether the found value lies within its 95 % half-width of the truth.
fn inside(c: &Comparison) -> bool {
    (c.2 - c.1).abs() <= c.3
}

/// Of the comparisons with a reported interval: (truth inside found ± half-width, count).
fn coverage_of(c: &[Comparison]) -> (usize, usize) {
    let with: Vec<&Comparison> = c.iter().filter(|x| x.3.is_finite()).collect();
    (with.iter().filter(|x| inside(x)).count(), with.len())
}

/// The selected effects of `reports` outside their physical range on `model` and the fit runs
/// `fit`, or whose reported 95 % intervals hold their neutral value in every parameter (no
/// finding): the self-check's own statement of the ranges, apart from the pipeline's.
///
/// Ranges: a rotor inertia positive and at most a hundred times the largest `H_jj` its joint
/// moves over the fit runs; a torque offset at most the largest torque logged on its joint; a
/// torque gain within 0.2–5; frictions, springs and load-friction coefficients non-negative,
/// mu at most 1; a payload's mass positive.
pub fn implausible(model: &Model, fit: &[Run], reports: &[EffectReport]) -> Vec<String> {
    let names = model.joint_names();
    let n = model.dof();
    let mut ws = Workspace::new(model);
    // the largest H_jj and |τ_j| over the fit runs (every 20th sample)
    let (mut h_max, mut tau_max) = (vec![0.0f64; n], vec![0.0f64; n]);
    for r in fit.iter().filter(|r| r.dof() == n) {
        for k in (0..r.len()).step_by(20) {
            let h = mass_matrix(model, &mut ws, &r.q[k * n..(k + 1) * n]);
            for j in 0..n {
                h_max[j] = h_max[j].max(h[(j, j)]);
            }
        }
        for (i, t) in r.tau.iter().enumerate() {
            tau_max[i % n] = tau_max[i % n].max(t.abs());
        }
    }
    let mut out = Vec::new();
    for e in reports {
        // a per-joint entry of `map` at position `pos` (NaN where absent)
        let at = |map: &BTreeMap<String, Param>, key: &str, pos: usize| match map.get(key) {
            Some(Param::PerJoint(v)) => v.get(pos).copied().unwrap_or(f64::NAN),
            _ => f64::NAN,
        };
        for (pos, joint) in e.joints.iter().enumerate() {
            let Some(j) = names.iter().position(|x| x == joint) else { continue };
            let value = |key: &str| at(&e.parameters, key, pos);
            let hw = |key: &str| at(&e.uncertainty, key, pos);
            let nonneg = |keys: &[&str]| keys.iter().all(|k| !(value(k) < -1e-9));
            let (in_range, neutral): (bool, Vec<(&str, f64)>) = match e.effect.as_str() {
                "armature" => (value("ia") > 0.0 && value("ia") <= 100.0 * h_max[j], vec![("ia", 0.0)]),
                "torque_offset" => (tau_max[j] == 0.0 || value("offset").abs() <= tau_max[j], vec![("offset", 0.0)]),
                "torque_gain" => ((0.2..=5.0).contains(&value("k")), vec![("k", 1.0)]),
                "viscous_friction" => (nonneg(&["b"]), vec![("b", 0.0)]),
                "coulomb_friction" => (nonneg(&["fc"]), vec![("fc", 0.0)]),
                "stribeck_friction" => (nonneg(&["fc", "fs"]), vec![("fc", 0.0), ("fs", 0.0)]),
                "joint_spring" => (nonneg(&["k"]), vec![("k", 0.0)]),
                "load_friction" => (nonneg(&["fc", "mu"]) && !(value("mu") > 1.0), vec![("fc", 0.0), ("mu", 0.0)]),
                "load_stribeck_friction" => (
                    nonneg(&["fc", "mu"]) && !(value("fs") < value("fc") - 1e-9) && !(value("mus") < value("mu") - 1e-9) && !(value("mus") > 1.0),
                    vec![("fc", 0.0), ("mu", 0.0), ("fs", 0.0), ("mus", 0.0)],
                ),
                "directional_friction" => (nonneg(&["fc_pos", "fc_neg", "b_pos", "b_neg"]), vec![("fc_pos", 0.0), ("fc_neg", 0.0), ("b_pos", 0.0), ("b_neg", 0.0)]),
                _ => (true, vec![]),
            };
            // no finding: every neutral-valued parameter's interval (where given) holds it
            let given: Vec<&(&str, f64)> = neutral.iter().filter(|(k, _)| hw(k).is_finite()).collect();
            let no_finding = !given.is_empty() && given.iter().all(|(k, v)| (value(k) - v).abs() <= hw(k));
            if !in_range || no_finding {
                out.push(format!("{}@{joint}{}", e.effect, if in_range { " (its interval holds no effect)" } else { " (outside its physical range)" }));
            }
        }
        if e.effect == "payload" && !matches!(e.parameters.get("mass"), Some(Param::Number(m)) if *m > 0.0) {
            out.push("payload (mass not positive)".into());
        }
    }
    out
}

/// The selected effects of `report` (`effect@joint`) whose last decision in the report's
/// selection log is a rejection: a report that states an effect its own log says left.
pub fn contradicted(report: &crate::Report) -> Vec<String> {
    let mut out = Vec::new();
    for e in &report.selected_effects {
        let joints: Vec<Option<&String>> = if e.joints.is_empty() { vec![None] } else { e.joints.iter().map(Some).collect() };
        for j in joints {
            let last = report.selection_log.iter().rev().find(|d| d.effect == e.effect && (j.is_none() || d.joint.as_ref() == j));
            if last.is_some_and(|d| !d.accepted) {
                out.push(j.map_or(e.effect.clone(), |j| format!("{}@{j}", e.effect)));
            }
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
    /// Hidden (effect, joint) pairs (for `urdf_inertia_pitfall`, the inertial correction a right
    /// diagnosis finds).
    pub truth: Vec<String>,
    /// Selected pairs.
    pub found: Vec<String>,
    /// Scenario family (one of [`FAMILIES`]).
    pub family: String,
    /// Exactly the hidden set.
    pub exact: bool,
    /// Not exact, but the hidden effects are one of the report's `alternatives` (an effect set
    /// these data cannot tell apart from the selected one).
    pub in_alternatives: bool,
    /// Right by the family's rule (see [`run_scenario`]).
    pub right: bool,
    /// Why a scenario that is not exact counts as right or wrong, where the family's rule is not
    /// "exact or among the alternatives".
    pub rule: String,
    /// Held-out k-step error after / before at 0.5 s (the longest horizon when shorter).
    pub kstep_ratio: f64,
    /// Relative parameter errors of correctly found effects.
    pub parameter_errors: Vec<(String, f64)>,
    /// Found parameters with a reported 95 % interval: (name, truth, found, half-width, inside).
    pub intervals: Vec<(String, f64, f64, f64, bool)>,
    /// Coverage of each interval method on its own (name → (inside, count)), for comparison.
    pub interval_variants: BTreeMap<String, (usize, usize)>,
    /// Each interval method's own half-widths (name → (parameter, truth, found, half-width)),
    /// for studying how they combine.
    pub variant_intervals: BTreeMap<String, Vec<(String, f64, f64, f64)>>,
    /// Held-out L² after / before.
    pub holdout_ratio: f64,
    /// Selected effects outside their physical range or consistent with no effect
    /// ([`implausible`]).
    pub implausible: Vec<String>,
    /// Selected effects the report's own selection log last rejected ([`contradicted`]).
    pub contradicted: Vec<String>,
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
            right: false,
            rule: String::new(),
            kstep_ratio: f64::NAN,
            parameter_errors: vec![],
            intervals: vec![],
            interval_variants: BTreeMap::new(),
            variant_intervals: BTreeMap::new(),
            holdout_ratio: f64::NAN,
            implausible: vec![],
            contradicted: vec![],
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

/// Held-out k-step error after/before at 0.5 s (or the longest horizon below it).
fn kstep_ratio_at_half_second(d: &Diagnosis) -> f64 {
    let k = &d.report.gap.kstep;
    let i = k.horizons_s.iter().position(|h| *h >= 0.5 - 1e-9).unwrap_or(k.horizons_s.len().saturating_sub(1));
    k.after.get(i).zip(k.before.get(i)).map_or(f64::NAN, |(a, b)| a / b)
}

/// Runs one scenario end to end and scores it. A scenario is right when the selected set is
/// exactly the hidden one or the hidden effects are among the report's alternatives, except:
///
/// - `friction_shape` (a friction the vocabulary cannot state exactly): right when the selected
///   set holds Coulomb or Stribeck friction on the true joint, nothing but friction (Coulomb,
///   Stribeck, viscous) on that joint besides, and the held-out k-step error at 0.5 s improves;
/// - `urdf_inertia_pitfall`: right when an inertial correction of every link is selected (or is
///   among the alternatives) and nothing else;
/// - `passive_joint`: right by the general rule and with no actuator effect (gain, offset,
///   saturation) on the passive joint;
/// - `glitch`: right when the diagnosis with the glitch selects the same set as without it (the
///   same clean logs) and a note names the glitch.
pub fn run_scenario(seed: u64, index: usize) -> ScenarioScore {
    score(index, family_of(index), scenario(seed, index))
}

/// Runs servo scenario `index` of seed `seed` ([`servo_scenario`]) and scores it: right when the
/// selected mechanical effects are the hidden ones (a torque gain or back-EMF corrects the
/// fitted motor constants, and is not counted) and the motor constants the corrected model
/// drives with, `kt/R` and `kt²/R`, are within 15 % of the servo's.
pub fn run_servo_scenario(seed: u64, index: usize) -> ScenarioScore {
    score(index, servo_family(index), servo_scenario(seed, index))
}

/// Runs real-drive scenario `index` of seed `seed` ([`drive_scenario`](crate::check::drives::drive_scenario))
/// and scores it. Right when the selected set is exactly the hidden one or among the
/// alternatives, except:
///
/// - `servo`: as [`run_servo_scenario`];
/// - `coulomb_trap`: exactly the hidden set (a Stribeck friction, richer, is wrong even as the
///   selected set with Coulomb friction among its alternatives);
/// - `directional_friction`: exactly the hidden set, every unit that of a linear axis;
/// - `link_side`: the sensor offsets and the spring found, no rotor inertia selected (the
///   viscous frictions may be missed, and extra effects are listed in the rule).
pub fn run_drive_scenario(seed: u64, index: usize) -> ScenarioScore {
    let family = match crate::check::drives::drive_family_of(index) {
        "servo" => servo_family(index),
        other => other,
    };
    score(index, family, crate::check::drives::drive_scenario(seed, index))
}

/// The largest relative error, over the joints (named `joints`, model order) of a hidden torque
/// limit, of the most torque the selected drive delivers there (its limit times its torque
/// gain; no limit selected is an infinite error); `None` without a hidden limit.
fn most_torque_error(joints: &[&str], hidden: &[Effect], selected: &[EffectReport]) -> Option<f64> {
    let limits = hidden.iter().find_map(|e| if let Effect::TorqueSaturation { limit } = e { Some(limit.clone()) } else { None })?;
    let value = |name: &str, key: &str, j: usize| selected_value(selected, name, key, joints[j]).filter(|v| v.is_finite());
    let errors = limits.iter().enumerate().filter(|(_, l)| l.is_finite()).map(|(j, l)| match value("torque_saturation", "limit", j) {
        Some(fitted) => (fitted * value("torque_gain", "k", j).unwrap_or(1.0) / l - 1.0).abs(),
        None => f64::INFINITY,
    });
    Some(errors.fold(0.0, f64::max))
}

/// The value of parameter `key` of the selected `effect` on `joint`, if selected there.
fn selected_value(selected: &[EffectReport], effect: &str, key: &str, joint: &str) -> Option<f64> {
    let e = selected.iter().find(|e| e.effect == effect)?;
    crate::vocabulary::effects::per_joint(e, key).into_iter().find(|(at, _)| *at == joint).map(|(_, v)| v)
}

/// The effects that, on a servo whose motor constants were fitted from its logs, correct those
/// constants rather than add mechanics: a torque gain scales `kt/R` and `kt²/R` alike, a
/// back-EMF `kt²/R` alone. A servo scenario is scored on the other selected effects.
pub const MOTOR_CONSTANTS: [&str; 2] = ["torque_gain", "back_emf"];

/// Of every [`MIXED_CYCLE`] scenarios `simgap selfcheck` runs, the first [`CYCLE`] are one cycle
/// of [`scenario`] and the rest one of each real-drive family
/// ([`DRIVE_FAMILIES`](crate::check::drives::DRIVE_FAMILIES)).
pub const MIXED_CYCLE: usize = CYCLE + crate::check::drives::DRIVE_FAMILIES.len();

/// Runs scenario `index` of the mixed self-check (see [`MIXED_CYCLE`]): scenario
/// `(index / MIXED_CYCLE) · CYCLE + slot` of [`run_scenario`] for the first [`CYCLE`] slots, else
/// real-drive scenario `(index / MIXED_CYCLE) · 7 + slot − CYCLE` of [`run_drive_scenario`].
pub fn run_mixed_scenario(seed: u64, index: usize) -> ScenarioScore {
    let (block, slot) = (index / MIXED_CYCLE, index % MIXED_CYCLE);
    if slot < CYCLE {
        run_scenario(seed, block * CYCLE + slot)
    } else {
        run_drive_scenario(seed, block * crate::check::drives::DRIVE_FAMILIES.len() + slot - CYCLE)
    }
}

/// Diagnoses a generated scenario and scores it by its family's rule.
pub(crate) fn score(index: usize, family: &str, sc: crate::Result<Scenario>) -> ScenarioScore {
    let sc = match sc {
        Ok(s) => s,
        Err(e) => return ScenarioScore::failed(index, String::new(), family.into(), vec![], e.to_string()),
    };
    let truth = sc.truth.clone();
    let mut fit = sc.fit.clone();
    if let Some((r, k, j)) = sc.glitch {
        let n = fit[r].dof();
        fit[r].q[k * n + j] = GLITCH_VALUE;
    }
    let options = DiagnoseOptions { directional_friction: sc.directional_friction, load_stribeck_friction: sc.load_stribeck_friction, ..DiagnoseOptions::default() };
    let d = match diagnose(&sc.diagnosis_model, Formulation::EulerLagrange, &fit, &sc.holdout, &options, &mut |_| {}) {
        Ok(d) => d,
        Err(e) => return ScenarioScore::failed(index, sc.model.name().into(), sc.family.into(), label(&truth), e.to_string()),
    };
    let found = found_set(&d);
    let truth_names: BTreeSet<String> = truth.iter().map(|t| t.0.clone()).collect();
    let in_alternatives = found != truth && !truth_names.is_empty() && d.report.alternatives.iter().any(|a| a.effects.iter().cloned().collect::<BTreeSet<String>>() == truth_names);
    let exact = found == truth;
    let kstep_ratio = kstep_ratio_at_half_second(&d);
    let names = sc.model.joint_names();
    let (right, rule) = match sc.family {
        "friction_shape" => {
            let joint = sc.effects.iter().flat_map(|e| e.joints_acted()).next().map(|j| names[j].to_string());
            let on = |e: &str| found.contains(&(e.to_string(), joint.clone()));
            let only_friction = found.iter().all(|(e, j)| *j == joint && matches!(e.as_str(), "coulomb_friction" | "stribeck_friction" | "viscous_friction"));
            let ok = (on("coulomb_friction") || on("stribeck_friction")) && only_friction && kstep_ratio < 1.0;
            (ok, format!("nearest in-vocabulary friction on the true joint, only friction there, k-step at 0.5 s after/before {kstep_ratio:.3} (< 1 needed)"))
        }
        "urdf_inertia_pitfall" => {
            let links = d.report.selected_effects.iter().find(|e| e.effect == "inertial_error").map_or(0, |e| e.joints.len());
            let ok = (exact && links == sc.model.dof()) || in_alternatives;
            (ok, format!("an inertial correction of all {} links (the selected one corrects {links})", sc.model.dof()))
        }
        "passive_joint" => {
            let passive = names[0].to_string();
            let actuator = found.iter().any(|(e, j)| j.as_deref() == Some(passive.as_str()) && matches!(e.as_str(), "torque_gain" | "torque_offset" | "torque_saturation"));
            let flagged = d.report.notes.iter().any(|n| n.contains(&format!("joint {passive} is passive")));
            ((exact || in_alternatives) && !actuator && flagged, format!("no actuator effect on the passive joint {passive} (one found: {actuator}); flagged passive: {flagged}"))
        }
        "servo" | "servo_saturation" | "servo_breakaway" => {
            // the motor constants are fitted: a torque gain or back-EMF corrects them, and the
            // constants the corrected model drives with must be the servo's; a limit must be
            // found on its joint, the most the drive delivers (the limit times the gain) within
            // 15 % of the hidden one
            let mechanical: BTreeSet<(String, Option<String>)> = found.iter().filter(|(e, _)| !MOTOR_CONSTANTS.contains(&e.as_str())).cloned().collect();
            let most_torque = most_torque_error(&names, &sc.effects, &d.report.selected_effects);
            let spec = sc.servo.as_ref();
            // where no fit log moves a joint with its drive off, its back-EMF and viscous
            // friction act alike and only their sum is in the logs: the sum is scored there
            let viscous = |j: usize| -> (f64, f64) {
                let hidden = sc.effects.iter().find_map(|e| if let Effect::ViscousFriction { b } = e { Some(b[j]) } else { None }).unwrap_or(0.0);
                let selected = selected_value(&d.report.selected_effects, "viscous_friction", "b", names[j]).unwrap_or(0.0);
                (hidden, selected)
            };
            let summed: Vec<usize> = (0..names.len()).filter(|&j| !crate::prepare::servo::moves_with_drive_off(&sc.model, &sc.fit, j)).collect();
            let constants = match (spec, &d.report.servo) {
                (Some(spec), Some(rep)) => (0..spec.kt.len())
                    .map(|j| {
                        let (kt, r) = (rep.effective.kt[j], rep.effective.r[j]);
                        let (b, b_true) = (kt * kt / r, spec.kt[j] * spec.kt[j] / spec.r[j]);
                        let damping = if summed.contains(&j) {
                            let (c_true, c) = viscous(j);
                            ((b + c) / (b_true + c_true) - 1.0).abs()
                        } else {
                            (b / b_true - 1.0).abs()
                        };
                        ((kt / r) / (spec.kt[j] / spec.r[j]) - 1.0).abs().max(damping)
                    })
                    .fold(0.0, f64::max),
                _ => f64::INFINITY,
            };
            let ok = (mechanical == truth || in_alternatives) && constants <= 0.15 && most_torque.is_none_or(|e| e <= 0.15);
            let sum = if summed.is_empty() {
                String::new()
            } else {
                let on: Vec<&str> = summed.iter().map(|&j| names[j]).collect();
                format!(" (on {}, which no fit log moves with its drive off, kt²/R plus the viscous friction)", on.join(", "))
            };
            (
                ok,
                format!(
                    "the mechanical effects {} the hidden ones; motor constants kt/R and kt²/R{sum} within {:.1} % (15 % allowed){}",
                    if mechanical == truth { "are" } else { "are not" },
                    100.0 * constants,
                    most_torque.map_or(String::new(), |e| format!("; the most torque the drive delivers within {:.1} % of the hidden limit (15 % allowed)", 100.0 * e))
                ),
            )
        }
        "coulomb_trap" => {
            let richer = found.iter().any(|(e, _)| e == "stribeck_friction");
            (exact, format!("exactly the hidden set, not even among alternatives (a Stribeck friction selected: {richer})"))
        }
        "directional_friction" => {
            // the axis is linear: its forces in N, its speeds in m/s
            let units_ok = d.report.selected_effects.iter().all(|e| e.units.values().all(|u| !u.contains("N·m") && !u.contains("rad")));
            (exact && units_ok, format!("exactly the hidden set (directional or the symmetric pair); units of a linear axis: {units_ok}"))
        }
        "link_side" => {
            // the offsets and the spring must be found, and no rotor inertia: a link-side torque
            // holds none; the viscous frictions are part of the truth but not required
            let needed: BTreeSet<(String, Option<String>)> = truth.iter().filter(|(e, _)| e != "viscous_friction").cloned().collect();
            let armature = found.iter().any(|(e, _)| e == "armature");
            let extra: Vec<String> = label(&found.difference(&truth).cloned().collect());
            (
                needed.is_subset(&found) && !armature,
                format!("sensor offsets and spring found: {}; rotor inertia selected: {armature}; beyond the truth: {extra:?}", needed.is_subset(&found)),
            )
        }
        "glitch" => {
            let clean = diagnose(&sc.diagnosis_model, Formulation::EulerLagrange, &sc.fit, &sc.holdout, &options, &mut |_| {}).map(|c| found_set(&c));
            let (r, _, _) = sc.glitch.unwrap_or_default();
            let noted = d.report.notes.iter().any(|n| n.starts_with(&format!("{}: glitch", sc.fit[r].source)));
            match clean {
                Ok(c) => (c == found && noted, format!("without the glitch the diagnosis selects {:?}; glitch reported: {noted}", label(&c))),
                Err(e) => (false, format!("the clean diagnosis failed: {e}")),
            }
        }
        _ => (exact || in_alternatives, String::new()),
    };
    // a friction outside the vocabulary has no true value of the vocabulary's parameters
    let truth_params: &[Effect] = if sc.family == "friction_shape" { &[] } else { &sc.effects };
    let reported = comparisons(&sc.model, truth_params, &d.report.selected_effects);
    let variant_intervals: BTreeMap<String, Vec<Comparison>> =
        d.interval_variants.iter().map(|(name, reports)| (name.to_string(), comparisons(&sc.model, truth_params, reports))).collect();
    let interval_variants = variant_intervals.iter().map(|(name, c)| (name.clone(), coverage_of(c))).collect();
    ScenarioScore {
        index,
        robot: sc.model.name().into(),
        family: sc.family.into(),
        exact,
        in_alternatives,
        right,
        rule,
        kstep_ratio,
        parameter_errors: reported.iter().map(|c| (c.0.clone(), ((c.2 - c.1) / c.1).abs())).collect(),
        intervals: reported.iter().filter(|c| c.3.is_finite()).map(|c| (c.0.clone(), c.1, c.2, c.3, inside(c))).collect(),
        interval_variants,
        variant_intervals,
        holdout_ratio: d.report.gap.ratio,
        truth: label(&truth),
        found: label(&found),
        implausible: implausible(&sc.model, &sc.fit, &d.report.selected_effects),
        contradicted: contradicted(&d.report),
        error: None,
    }
}

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
    /// Selected effects the report's selection log last rejected ([`contradicted`]): (count,
    /// selected).
    pub contradicted: (usize, usize),
    /// Selected effects ([`implausible`]): (outside their physical range or consistent with no
    /// effect, selected in all).
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
        if true_effects.contains("time_delay") {
            delays_found.0 += 1;
            if found_effects.contains("time_delay") {
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
