//! The self-check's scenario cycle: the robots, the hidden effects drawn for them and the logs
//! they produce, random ones and named families ([`scenario`], of family [`family_of`]).

use std::collections::BTreeSet;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use simgap_core::{mass_matrix, Formulation, Model, UrdfOptions, Workspace};
use simgap_sim::{ControllerKind, Effect, EffectKind, LinkDelta, Run};

use super::truth::{truth_set, WHOLE};
use crate::check::bench::{gains_for, generate, random_fourier, random_setpoints, RefSpec, RunSpec};

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

const PER_JOINT: [EffectKind; 8] = [
    EffectKind::ViscousFriction,
    EffectKind::CoulombFriction,
    EffectKind::StribeckFriction,
    EffectKind::Armature,
    EffectKind::TorqueGain,
    EffectKind::TorqueOffset,
    EffectKind::TorqueSaturation,
    EffectKind::Cogging,
];

/// Draws an effect of kind `kind` sized against a nominal run.
fn draw_effect(kind: EffectKind, model: &Model, nominal: &Run, joint: usize, rng: &mut ChaCha8Rng) -> Effect {
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
    match kind {
        EffectKind::ViscousFriction => Effect::ViscousFriction { b: v(0.0, rng.random_range(0.08..0.25) * tau / qd) },
        EffectKind::CoulombFriction => Effect::CoulombFriction { fc: v(0.0, rng.random_range(0.08..0.25) * tau), w: vec![simgap_sim::DEFAULT_COULOMB_WIDTH; n] },
        EffectKind::StribeckFriction => {
            let fc = rng.random_range(0.08..0.2) * tau;
            Effect::StribeckFriction {
                fc: v(0.0, fc),
                fs: v(0.0, fc * rng.random_range(1.8..3.0)),
                vs: v(0.0, rng.random_range(0.1..0.3) * qd),
                w: vec![simgap_sim::DEFAULT_COULOMB_WIDTH; n],
            }
        }
        EffectKind::Armature => {
            let mut ws = Workspace::new(model);
            let h = mass_matrix(model, &mut ws, &vec![0.0; n]);
            Effect::Armature { ia: v(0.0, rng.random_range(0.2..0.6) * h[(joint, joint)]) }
        }
        EffectKind::TorqueGain => Effect::TorqueGain { k: v(1.0, if rng.random_bool(0.5) { rng.random_range(0.6..0.85) } else { rng.random_range(1.15..1.4) }) },
        EffectKind::TorqueOffset => Effect::TorqueOffset { offset: v(0.0, rng.random_range(0.08..0.25) * tau * if rng.random_bool(0.5) { 1.0 } else { -1.0 }) },
        EffectKind::TorqueSaturation => Effect::TorqueSaturation { limit: v(f64::INFINITY, rng.random_range(0.45..0.75) * max_abs(nominal, &nominal.tau, joint)) },
        EffectKind::Cogging => Effect::Cogging { amplitude: v(0.0, rng.random_range(0.08..0.2) * tau), periods_per_rev: v(1.0, rng.random_range(4..30) as f64) },
        EffectKind::Payload => {
            let last = model.joints()[n - 1].inertia.mass.max(0.5);
            Effect::Payload { mass: rng.random_range(0.3..1.0) * last, com: [rng.random_range(-0.05..0.05), rng.random_range(-0.05..0.05), rng.random_range(-0.1..0.1)] }
        }
        EffectKind::InertialError => {
            // a mass change of the last link is a payload; draw another link (robots with one
            // link never draw this effect)
            let link = rng.random_range(0..n.saturating_sub(1).max(1));
            let m = model.joints()[link].inertia.mass;
            Effect::InertialError {
                deltas: vec![LinkDelta { joint: link, mass: m * rng.random_range(0.15..0.35) * if rng.random_bool(0.5) { 1.0 } else { -1.0 }, com: [0.0; 3], inertia: [0.0; 6] }],
            }
        }
        EffectKind::TimeDelay => Effect::TimeDelay { delay: rng.random_range(1..=3) as f64 * 0.0025 },
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
        let all: Vec<EffectKind> = PER_JOINT.iter().chain(WHOLE.iter()).copied().collect();
        let kind = all[rng.random_range(0..all.len())];
        // on a one-joint robot a torque gain is exactly a scaling of its inertial parameters,
        // and an inertial error of its only link is a payload: not identifiable apart
        // a one-joint robot has no Coriolis terms at all, so neither formulation differs
        if n == 1 && matches!(kind, EffectKind::TorqueGain | EffectKind::InertialError | EffectKind::Payload | EffectKind::CoriolisStructure) {
            continue;
        }
        // Coulomb plus Stribeck on one joint is a single Stribeck friction
        let is_dry = |k: EffectKind| matches!(k, EffectKind::CoulombFriction | EffectKind::StribeckFriction);
        if is_dry(kind) && effects.iter().any(|e| is_dry(e.kind())) {
            continue;
        }
        if effects.iter().any(|e| e.kind() == kind)
            || (kind == EffectKind::Payload && effects.iter().any(|e| e.kind() == EffectKind::InertialError))
            || (kind == EffectKind::InertialError && effects.iter().any(|e| e.kind() == EffectKind::Payload))
        {
            continue;
        }
        let joint = rng.random_range(0..n);
        effects.push(draw_effect(kind, model, nominal, joint, rng));
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
                use EffectKind::{Armature, CoulombFriction, TorqueGain, TorqueOffset, ViscousFriction};
                let kinds: &[EffectKind] =
                    if joint == 0 { &[ViscousFriction, CoulombFriction, Armature] } else { &[ViscousFriction, CoulombFriction, Armature, TorqueGain, TorqueOffset] };
                let kind = kinds[rng.random_range(0..kinds.len())];
                vec![draw_effect(kind, &model, &nominal, joint, &mut rng)]
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
                    vec![draw_effect(EffectKind::Payload, &model, &nominal, n - 1, &mut rng)]
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
                    truth = BTreeSet::from([(EffectKind::InertialError.to_string(), None)]);
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
