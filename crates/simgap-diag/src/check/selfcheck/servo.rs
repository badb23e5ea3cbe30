//! The self-check's servo scenarios: pendulums driven by position-controlled servos of random
//! motor constants, with a torque limit or a load friction rising at rest in some
//! ([`servo_scenario`]).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use simgap_core::Model;
use simgap_sim::{Effect, EffectKind, Run};

use super::scenarios::{double_pendulum, Scenario};

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
/// The servo family is drawn apart from the [`CYCLE`](super::CYCLE) (so that the scenarios of
/// earlier seeds stay what they were): scenario `index` of seed `seed` is
/// [`servo_scenario`]`(seed, index)`, scored by [`run_servo_scenario`](super::run_servo_scenario).
pub fn servo_scenario(seed: u64, index: usize) -> crate::Result<Scenario> {
    let family = servo_family(index);
    draw_servo(seed, index, family == "servo_saturation", family == "servo_breakaway", Extra::None)
}

/// A `servo_encoder_offset` scenario: the `servo` draw of [`servo_scenario`] (its mechanics,
/// motor constants and logs' goals), with, on two indices in three, the measured zero of one
/// joint, or of each of the double pendulum's two with even odds, 1–5° off either way
/// (`encoder_offset`, drawn from a stream of its own); the third (`index % 3 == 2`) is a null,
/// the servo draw alone.
pub fn encoder_offset_scenario(seed: u64, index: usize) -> crate::Result<Scenario> {
    let drawn = draw_servo(seed, index, false, false, if index % 3 != 2 { Extra::Offsets } else { Extra::None })?;
    Ok(Scenario { family: "servo_encoder_offset", ..drawn })
}

/// A `servo_backlash` scenario: the `servo` draw of [`servo_scenario`] with a rotor inertia of
/// 0.2–0.6 times its link's on one joint, or on each of the double pendulum's two with even
/// odds, and, on two indices in three, play of 0.5–2° in those joints' gears (`backlash`, drawn
/// from a stream of its own); the third (`index % 3 == 2`) is a null with the rotor inertias
/// alone.
pub fn backlash_scenario(seed: u64, index: usize) -> crate::Result<Scenario> {
    let drawn = draw_servo(seed, index, false, false, Extra::Rotors { play: index % 3 != 2 })?;
    Ok(Scenario { family: "servo_backlash", ..drawn })
}

/// What a servo draw adds to its effects: nothing, encoder offsets
/// ([`encoder_offset_scenario`]), or rotor inertias with or without play ([`backlash_scenario`]).
#[derive(Clone, Copy, PartialEq)]
enum Extra {
    None,
    Offsets,
    Rotors { play: bool },
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
pub(super) fn servo_family(index: usize) -> &'static str {
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
    draw_servo(seed, index, limited, false, Extra::None)
}

/// [`servo_draw`], or with `breakaway` the same draw with its first effect a load friction
/// rising at rest (its parameters and the logs' goals drawn apart, see [`servo_scenario`]); with
/// `extra`, encoder offsets or rotor inertias and play added.
fn draw_servo(seed: u64, index: usize, limited: bool, breakaway: bool, extra: Extra) -> crate::Result<Scenario> {
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
        let kinds = [EffectKind::Armature, EffectKind::CoulombFriction, EffectKind::ViscousFriction, EffectKind::LoadFriction];
        let first = kinds[rng.random_range(0..kinds.len())];
        let mut names = vec![first];
        if rng.random_bool(0.5) {
            let dry = |k: EffectKind| matches!(k, EffectKind::CoulombFriction | EffectKind::LoadFriction);
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
                EffectKind::Armature => Effect::Armature { ia: v(rng.random_range(0.2..0.6) * h[(joint, joint)]) },
                EffectKind::CoulombFriction => Effect::CoulombFriction { fc: v(rng.random_range(0.03..0.08) * stall[joint]), w: vec![simgap_sim::DEFAULT_COULOMB_WIDTH; n] },
                EffectKind::ViscousFriction => Effect::ViscousFriction { b: v(rng.random_range(0.5..1.5) * back_emf) },
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
        if let Extra::Rotors { play } = extra {
            let mut own = ChaCha8Rng::seed_from_u64(seed.wrapping_mul(7_000_003).wrapping_add(index as u64));
            let first = own.random_range(0..n);
            let both = n > 1 && own.random_bool(0.5);
            let on = |j: usize| j == first || both;
            let ia: Vec<f64> = (0..n).map(|j| if on(j) { own.random_range(0.2..0.6) * h[(j, j)] } else { 0.0 }).collect();
            let width: Vec<f64> = (0..n).map(|j| if on(j) { own.random_range(0.5f64..2.0).to_radians() } else { 0.0 }).collect();
            effects.retain(|e| !matches!(e, Effect::Armature { .. }));
            effects.push(Effect::Armature { ia });
            if play {
                effects.push(Effect::Backlash { width });
            }
        }
        if extra == Extra::Offsets {
            let mut own = ChaCha8Rng::seed_from_u64(seed.wrapping_mul(6_000_047).wrapping_add(index as u64));
            let first = own.random_range(0..n);
            let both = n > 1 && own.random_bool(0.5);
            let offset: Vec<f64> =
                (0..n).map(|j| if j == first || both { own.random_range(1.0f64..5.0).to_radians() * if own.random_bool(0.5) { 1.0 } else { -1.0 } } else { 0.0 }).collect();
            effects.push(Effect::EncoderOffset { offset });
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
