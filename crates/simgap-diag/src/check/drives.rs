//! The self-check's real-drive families: what real arms, linear axes and servos show that the
//! [`CYCLE`](super::selfcheck) of random scenarios does not (each drawn from a failure seen on
//! hardware): a joint spring, pure Coulomb friction that a richer Stribeck friction must not
//! take, a linear axis whose friction differs by direction (units N and m), friction that grows
//! with the drive torque, a 7-DOF arm with link-side torque sensors, signals low-pass filtered
//! by their recorder, and position-controlled servos ([`servo_scenario`]).
//!
//! They are drawn apart from the cycle of [`scenario`](super::selfcheck::scenario) (whose
//! scenarios earlier seeds and tests pin): scenario `index` of seed `seed` is
//! [`drive_scenario`]`(seed, index)`, of family [`drive_family_of`]`(index)`.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use simgap_core::{Formulation, Model, UrdfOptions};
use simgap_sim::{ControllerKind, Effect, EffectKind, Fourier, Run};

use super::bench::{gains_for, generate, random_fourier, random_setpoints, zero_phase_lowpass, RefSpec, RunSpec};
use super::selfcheck::scenarios::{as_replay, double_pendulum, draw_effects, rms, Scenario};
use super::selfcheck::servo::servo_scenario;

/// The real-drive families, in the order [`drive_scenario`] cycles through them.
pub const DRIVE_FAMILIES: [&str; 7] = ["servo", "joint_spring", "coulomb_trap", DIRECTIONAL, "load_friction", "link_side", "filtered"];

/// The family of a linear axis whose friction differs with the direction of motion, named after
/// its effect.
pub(crate) const DIRECTIONAL: &str = EffectKind::DirectionalFriction.as_str();

/// The family of real-drive scenario `index`.
pub fn drive_family_of(index: usize) -> &'static str {
    DRIVE_FAMILIES[index % DRIVE_FAMILIES.len()]
}

/// A linear axis: one prismatic joint along x carrying a 5 kg carriage (a ball-screw drive).
pub const SLIDER_URDF: &str = r#"<robot name="slider">
  <link name="base"/>
  <link name="carriage">
    <inertial><origin xyz="0 0 0"/><mass value="5"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial>
  </link>
  <joint name="axis" type="prismatic">
    <parent link="base"/><child link="carriage"/><axis xyz="1 0 0"/>
    <limit lower="-0.5" upper="0.5" effort="500" velocity="2"/>
  </joint>
</robot>
"#;

/// `run` as a recorder exports it: positions, velocities and torques low-pass filtered at `hz`
/// without phase, labelled a replay.
pub(crate) fn filtered(mut run: Run, hz: f64, period: f64) -> Run {
    let dof = run.dof();
    zero_phase_lowpass(&mut run.q, dof, hz, period);
    zero_phase_lowpass(&mut run.qd, dof, hz, period);
    zero_phase_lowpass(&mut run.tau, dof, hz, period);
    as_replay(std::slice::from_mut(&mut run));
    run
}

/// A per-joint vector: `value` on `joint`, `neutral` elsewhere.
fn on(n: usize, joint: usize, neutral: f64, value: f64) -> Vec<f64> {
    (0..n).map(|i| if i == joint { value } else { neutral }).collect()
}

/// Generates real-drive scenario `index` of seed `seed`. Its family is
/// [`drive_family_of`]`(index)`:
///
/// - `servo`: [`servo_scenario`];
/// - `joint_spring`: the paper's arm, a pendulum or the double pendulum with a spring
///   `k (q − q0)` on one joint (k sized to 10–30 % of the joint's torque over its motion, q0
///   within ±0.4 rad), alone or beside a viscous friction, under PD or PD + gravity tracking;
/// - `coulomb_trap`: pure Coulomb friction (alone or with viscous friction on the same joint)
///   under set-point tracking, which spends long stretches slow: the richer Stribeck friction
///   nests it and must not be selected;
/// - `directional_friction`: a 5 kg linear axis at 1 kHz ([`SLIDER_URDF`], 1 µm encoder) whose
///   dry and viscous friction differ by direction (two thirds of the draws) or not (a third: the
///   symmetric pair must be kept), diagnosed with the defaults (directional friction is tried on linear axes);
/// - `load_friction`: the paper's arm or a pendulum whose dry friction grows with the drive
///   torque, `fc + mu |τ|`, mu 0.1–0.3;
/// - `link_side`: the 7-DOF arm whose torques are measured on the link side at 200 Hz: sensor
///   offsets on two to four joints, viscous friction on every joint, a cable spring on a wrist
///   joint in two draws of three (an offset on the spring's joint is part of its rest position:
///   [`truth_set`](crate::selfcheck::truth_set)), signals zero-phase filtered at 6–10 Hz, two
///   repeats of one trajectory fitted and a faster run held out (no rotor inertia is there to
///   find);
/// - `filtered`: a one-effect scenario of the paper's arm, a pendulum or the double pendulum,
///   its signals zero-phase filtered at 4–8 Hz by the recorder.
///
/// # Errors
/// Simulator errors (a scenario whose hidden effects make it diverge is redrawn).
pub fn drive_scenario(seed: u64, index: usize) -> crate::Result<Scenario> {
    let family = drive_family_of(index);
    if family == "servo" {
        return servo_scenario(seed, index);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_mul(3_000_017).wrapping_add(index as u64));
    let rng = &mut rng;
    for _attempt in 0..10 {
        if let Some(sc) = draw(family, index, rng)? {
            return Ok(sc);
        }
    }
    Err(crate::Error::Input(format!("real-drive scenario {index}: every draw diverged")))
}

/// One draw of a family; `None` when a run diverged (the caller redraws).
fn draw(family: &'static str, index: usize, rng: &mut ChaCha8Rng) -> crate::Result<Option<Scenario>> {
    let pendulum = || Model::from_urdf_str(simgap_core::PENDULUM_URDF);
    let model = match family {
        "joint_spring" | "filtered" => match rng.random_range(0..3) {
            0 => Model::paper_arm(),
            1 => pendulum()?,
            _ => double_pendulum(),
        },
        "coulomb_trap" => {
            if rng.random_bool(0.5) {
                Model::paper_arm()
            } else {
                double_pendulum()
            }
        }
        "load_friction" => {
            if rng.random_bool(0.6) {
                Model::paper_arm()
            } else {
                pendulum()?
            }
        }
        DIRECTIONAL => Model::from_urdf_str(SLIDER_URDF)?,
        _ => Model::from_urdf_str_with(simgap_core::ARM7_URDF, "arm7.urdf", &UrdfOptions { tip: Some("panda_hand".into()) })?,
    };
    let n = model.dof();
    match family {
        DIRECTIONAL => return directional(model, index, rng),
        "link_side" => return link_side(model, index, rng),
        _ => {}
    }
    let (kp, kv) = gains_for(&model, rng.random_range(2.0..4.0));
    let amp = if n > 2 { 0.5 } else { 1.0 };
    let spec = |name: String, rng: &mut ChaCha8Rng| -> RunSpec {
        let controller = if family == "load_friction" || rng.random_bool(0.7) { ControllerKind::PdGravity } else { ControllerKind::Pd };
        let reference = if family == "coulomb_trap" || rng.random_bool(0.4) {
            random_setpoints(n, amp, 4.0, rng.random_range(0.6..1.2), rng)
        } else {
            RefSpec::Fourier(random_fourier(n, amp, rng))
        };
        RunSpec { name, controller, kp: kp.clone(), kv: kv.clone(), reference, duration: 4.0 }
    };
    let fit_specs: Vec<RunSpec> = (0..3).map(|i| spec(format!("d{index}-fit{i}"), rng)).collect();
    let mut hold_spec = spec(format!("d{index}-holdout"), rng);
    hold_spec.duration = 6.0;
    let nominal = generate(&model, Formulation::EulerLagrange, &[], &fit_specs[0], 0.0025, 1_024_000.0)?;
    let joint = rng.random_range(0..n);
    let tau = rms(&nominal, &nominal.tau, joint).max(1e-6);
    let qd = rms(&nominal, &nominal.qd, joint).max(1e-3);
    let viscous = |rng: &mut ChaCha8Rng| Effect::ViscousFriction { b: on(n, joint, 0.0, rng.random_range(0.08..0.25) * tau / qd) };
    let effects: Vec<Effect> = match family {
        "joint_spring" => {
            // the joint's excursion about the spring's rest position sets its torque
            let q: Vec<f64> = nominal.q.iter().skip(joint).step_by(n).copied().collect();
            let mean = q.iter().sum::<f64>() / q.len().max(1) as f64;
            let spread = (q.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / q.len().max(1) as f64).sqrt().max(0.05);
            let k = rng.random_range(0.1..0.3) * tau / spread;
            let mut e = vec![Effect::JointSpring { k: on(n, joint, 0.0, k), q0: on(n, joint, 0.0, rng.random_range(-0.4..0.4)) }];
            if rng.random_bool(0.5) {
                e.push(viscous(rng));
            }
            e
        }
        "coulomb_trap" => {
            let mut e = vec![Effect::CoulombFriction { fc: on(n, joint, 0.0, rng.random_range(0.1..0.25) * tau), w: vec![simgap_sim::DEFAULT_COULOMB_WIDTH; n] }];
            if rng.random_bool(0.5) {
                e.push(viscous(rng));
            }
            e
        }
        "load_friction" => vec![Effect::LoadFriction {
            fc: on(n, joint, 0.0, rng.random_range(0.03..0.1) * tau),
            mu: on(n, joint, 0.0, rng.random_range(0.1..0.3)),
            w: vec![simgap_sim::DEFAULT_COULOMB_WIDTH; n],
        }],
        _ => draw_effects(&model, &nominal, 1, rng),
    };
    let gen = |s: &RunSpec| generate(&model, Formulation::EulerLagrange, &effects, s, 0.0025, 1_024_000.0);
    let (Ok(mut fit), Ok(hold)) = (fit_specs.iter().map(gen).collect::<crate::Result<Vec<Run>>>(), gen(&hold_spec)) else { return Ok(None) };
    let mut holdout = vec![hold];
    if family == "filtered" {
        let hz = rng.random_range(4.0..8.0);
        fit = fit.into_iter().map(|r| filtered(r, hz, 0.0025)).collect();
        holdout = holdout.into_iter().map(|r| filtered(r, hz, 0.0025)).collect();
    }
    Ok(Some(Scenario::simulated(index, model, effects, fit, holdout, family)))
}

/// A `directional_friction` draw on the linear axis `model`.
fn directional(model: Model, index: usize, rng: &mut ChaCha8Rng) -> crate::Result<Option<Scenario>> {
    // a ball screw tracked by a stiff PD loop at 1 kHz, logged by a 1 µm linear encoder
    let period = 0.001;
    let counts = std::f64::consts::TAU / 1e-6;
    let (kp, kv) = (2000.0 * rng.random_range(0.8..1.25), 100.0 * rng.random_range(0.8..1.25));
    let (fc, b) = (rng.random_range(4.0..10.0), rng.random_range(20.0..40.0));
    let effects = if rng.random_bool(2.0 / 3.0) {
        // one direction 35–80 % stronger than the other, in each of dry and viscous friction
        let ratio = |rng: &mut ChaCha8Rng| {
            let r = rng.random_range(1.35..1.8);
            if rng.random_bool(0.5) {
                r
            } else {
                1.0 / r
            }
        };
        let (rf, rb) = (ratio(rng), ratio(rng));
        vec![Effect::DirectionalFriction { fc_pos: vec![fc], fc_neg: vec![fc * rf], b_pos: vec![b], b_neg: vec![b * rb], w: vec![0.002] }]
    } else {
        vec![Effect::ViscousFriction { b: vec![b] }, Effect::CoulombFriction { fc: vec![fc], w: vec![0.002] }]
    };
    let spec = |name: String, duration: f64, rng: &mut ChaCha8Rng| {
        let mut f = random_fourier(1, rng.random_range(0.08..0.15), rng);
        // a ball screw's strokes are faster than an arm's swings
        for fr in f.frequencies.iter_mut().flatten() {
            *fr *= 2.5;
        }
        RunSpec { name, controller: ControllerKind::Pd, kp: vec![kp], kv: vec![kv], reference: RefSpec::Fourier(f), duration }
    };
    let specs: Vec<RunSpec> = (0..3).map(|i| spec(format!("d{index}-fit{i}"), 6.0, rng)).collect();
    let hold = spec(format!("d{index}-holdout"), 6.0, rng);
    let gen = |s: &RunSpec| generate(&model, Formulation::EulerLagrange, &effects, s, period, counts);
    let (Ok(fit), Ok(hold)) = (specs.iter().map(gen).collect::<crate::Result<Vec<Run>>>(), gen(&hold)) else { return Ok(None) };
    Ok(Some(Scenario::simulated(index, model, effects, fit, vec![hold], DIRECTIONAL)))
}

/// A `link_side` draw on the 7-DOF arm `model`.
fn link_side(model: Model, index: usize, rng: &mut ChaCha8Rng) -> crate::Result<Option<Scenario>> {
    let n = model.dof();
    let period = 0.005;
    // the sensors' biases on two to four joints
    let mut offsets = vec![0.0; n];
    let count = rng.random_range(2..=4);
    while offsets.iter().filter(|o| **o != 0.0).count() < count {
        let j = rng.random_range(0..n);
        offsets[j] = rng.random_range(0.5..1.0) * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
    }
    let mut effects = vec![
        Effect::TorqueOffset { offset: offsets },
        Effect::ViscousFriction { b: (0..n).map(|j| if j < 4 { rng.random_range(0.4..0.8) } else { rng.random_range(0.1..0.3) }).collect() },
    ];
    if rng.random_bool(2.0 / 3.0) {
        // cables along the wrist
        let j = rng.random_range(4..6);
        effects.push(Effect::JointSpring { k: on(n, j, 0.0, rng.random_range(1.5..3.0)), q0: on(n, j, 0.0, rng.random_range(-0.4..0.4)) });
    }
    let (kp, kv) = gains_for(&model, 2.0);
    let trajectory = random_fourier(n, 0.5, rng);
    let mut faster = random_fourier(n, 0.5, rng);
    for f in faster.frequencies.iter_mut().flatten() {
        *f *= 1.5;
    }
    let spec =
        |name: String, f: &Fourier| RunSpec { name, controller: ControllerKind::PdGravity, kp: kp.clone(), kv: kv.clone(), reference: RefSpec::Fourier(f.clone()), duration: 12.0 };
    let hz = rng.random_range(6.0..10.0);
    let gen = |s: RunSpec| generate(&model, Formulation::EulerLagrange, &effects, &s, period, 1_048_576.0).map(|r| filtered(r, hz, period));
    // two repeats of one trajectory to fit, a faster run held out
    let (Ok(a), Ok(b), Ok(hold)) =
        (gen(spec(format!("d{index}-repeat1"), &trajectory)), gen(spec(format!("d{index}-repeat2"), &trajectory)), gen(spec(format!("d{index}-faster"), &faster)))
    else {
        return Ok(None);
    };
    Ok(Some(Scenario::simulated(index, model, effects, vec![a, b], vec![hold], "link_side")))
}
