//! The corrected MJCF: the model's chain as nested MuJoCo bodies with the selected effects in
//! their inertials, joints and motors.

use std::fmt::Write;

use nalgebra::{DMatrix, Rotation3, UnitQuaternion, Vector3};
use simgap_core::{mass_matrix, JointKind, Model, SpatialInertia, Workspace};

use super::effects::Corrections;
use super::servo::ServoActuators;
use super::sidecar::{Format, Sidecar};
use super::urdf::num;
use super::{ExportError, ExportedFile};
use crate::EffectReport;
use simgap_sim::EffectKind;

/// A revolute joint whose limits span at least this much [rad] is taken as unlimited: a
/// `±π` range states the angle's convention, not a stop, and must not clip a run through π.
pub const FULL_TURN: f64 = 2.0 * std::f64::consts::PI - 1e-3;

/// Options of [`export_mjcf`].
#[derive(Clone, Debug)]
pub struct MjcfOptions {
    /// `<option timestep>` [s]: the logs' sample period, so that one `mj_step` is one sample
    /// (the logged torque held as `ctrl` over it).
    pub timestep: f64,
    /// `<option integrator>`: `RK4` (default; simgap integrates the same sampled dynamics with
    /// RK4), or `Euler`, `implicit`, `implicitfast`.
    pub integrator: String,
    /// Joints that get no motor (passive joints, whose commanded torque is always zero).
    pub passive: Vec<String>,
    /// Position-controlled servos (a diagnosis of servo runs, [`ServoActuators::of`]): their
    /// joints get a `<position>` actuator instead of a motor.
    pub servo: Option<ServoActuators>,
}

impl MjcfOptions {
    /// The options for logs sampled every `timestep` seconds: RK4, every joint driven.
    pub fn new(timestep: f64) -> Self {
        MjcfOptions { timestep, integrator: "RK4".into(), passive: Vec::new(), servo: None }
    }
}

/// An MJCF of the corrected robot that MuJoCo compiles as it is, and its sidecar.
///
/// - One body per movable joint, nested along the chain and named after the link its joint
///   moves, placed at the joint's placement at q = 0 (`pos` [m], `quat` w x y z) with the joint
///   at its origin and its axis in the body frame (the URDF's joint axis in the child frame).
///   Links merged by fixed joints are inside their body; the fixed base is the world body.
/// - `<inertial pos mass quat diaginertia>`: the corrected body (payload and inertial errors
///   applied): centre of mass [m] in the body frame, mass [kg], principal axes and moments of
///   the inertia about the centre of mass [kg·m²] (MuJoCo's own form, taken as written). Masses
///   and moments below 1e-9 of the robot's largest are raised to that (MuJoCo refuses a moving
///   body without mass or with a zero principal moment), and the sidecar says so.
/// - Joints `hinge` (revolute, continuous) or `slide` (prismatic), with `armature` (rotor
///   inertia), `damping` (viscous friction), `frictionloss` with `solreffriction` and
///   `solimpfriction` (Coulomb friction: MuJoCo's dry friction is a constraint, written as the
///   band of simgap's `tanh(q̇/w)`, `−fc·clip(q̇/(2 ln 2·w), ±1)` with no stiction; the rate of
///   the band is `fc/(2 ln 2·w)` over the joint's inertia at q = 0, at most `1/timestep`),
///   `stiffness` and `springref` (joint spring); `limited="true" range` only where the URDF's
///   limits are real (not for a continuous joint, nor for a revolute range of a full turn or
///   more, [`FULL_TURN`]).
/// - One `motor` per driven joint: `gear` = the torque gain, `forcelimited` `forcerange` =
///   the torque saturation of the command, `ctrllimited="false"`: `ctrl` is the commanded
///   torque [N·m or N].
/// - A servo joint ([`MjcfOptions::servo`]) gets a `position` actuator `JOINT_servo` instead:
///   `ctrl` is the goal position [rad or m], `kp = kt/R·V·duty_gain`, `kv = kt²/R` (the
///   back-EMF), `forcerange = ±kt/R·V·max_duty` (the firmware's duty saturation as a force
///   clamp), with the report's effective `kt`, `R` (selected torque gain and back-EMF folded in);
///   the sidecar states what this approximates.
/// - `<option timestep gravity integrator>`: the logs' sample period, the model's gravity
///   [m/s²], RK4 by default.
/// - Geometry: a thin capsule from each body to the next (to its centre of mass for the last),
///   visual only (no contacts, no mass).
///
/// Everything else goes to the sidecar.
///
/// # Errors
/// [`ExportError::Option`] for a time step that is not a positive number or an unknown
/// integrator; [`ExportError::Effect`] for an effect naming an unknown joint or with a
/// parameter of the wrong shape; [`ExportError::Sim`] for a correction that leaves a link
/// non-physical.
pub fn export_mjcf(model: &Model, effects: &[EffectReport], options: &MjcfOptions) -> Result<ExportedFile, ExportError> {
    if !(options.timestep.is_finite() && options.timestep > 0.0) {
        return Err(ExportError::Option(format!("MJCF timestep = {} s; expected a positive number (the logs' sample period)", options.timestep)));
    }
    if !["Euler", "RK4", "implicit", "implicitfast"].contains(&options.integrator.as_str()) {
        return Err(ExportError::Option(format!("MJCF integrator '{}'; expected Euler, RK4, implicit or implicitfast", options.integrator)));
    }
    for p in &options.passive {
        if model.joint_index(p).is_none() {
            return Err(ExportError::Option(format!("passive joint '{p}' is not one of the model's joints {:?}", model.joint_names())));
        }
    }
    if let Some(sv) = &options.servo {
        let m = sv.joints.len();
        if [sv.kt.len(), sv.r.len(), sv.duty_gain.len(), sv.max_duty.len()].iter().any(|&l| l != m) {
            return Err(ExportError::Option(format!(
                "servo actuators: {m} joints with {} kt, {} R, {} duty_gain and {} max_duty; expected one of each per joint",
                sv.kt.len(),
                sv.r.len(),
                sv.duty_gain.len(),
                sv.max_duty.len()
            )));
        }
        if let Some(j) = sv.joints.iter().find(|j| model.joint_index(j).is_none()) {
            return Err(ExportError::Option(format!("servo joint '{j}' is not one of the model's joints {:?}", model.joint_names())));
        }
        let numbers = (0..m).flat_map(|i| [sv.kp(i), sv.kv(i), sv.force_limit(i)]);
        if numbers.chain([sv.voltage]).any(|x| !(x.is_finite() && x > 0.0)) {
            return Err(ExportError::Option(format!(
                "servo actuators: kt {:?}, R {:?}, V {} V, duty_gain {:?}, max_duty {:?}; expected positive numbers",
                sv.kt, sv.r, sv.voltage, sv.duty_gain, sv.max_duty
            )));
        }
    }
    let c = Corrections::read(model, effects)?;
    let n = model.dof();
    let joints = model.joints();
    let g = model.gravity();

    // header: compiler, option, visual defaults
    let mut s = String::new();
    let _ = writeln!(
        s,
        "<!-- {}: the corrected model of a simgap diagnosis (docs/guide/export.md). Selected effects MJCF cannot hold are in the .effects.json beside it. -->",
        xml(model.name())
    );
    let _ = writeln!(s, "<mujoco model=\"{}\">", xml(model.name()));
    let _ = writeln!(s, "  <compiler angle=\"radian\" inertiafromgeom=\"false\" autolimits=\"false\"/>");
    let _ = writeln!(s, "  <option timestep=\"{}\" gravity=\"{} {} {}\" integrator=\"{}\"/>", num(options.timestep), num(g.x), num(g.y), num(g.z), options.integrator);
    let _ = writeln!(s, "  <default>");
    let _ = writeln!(s, "    <geom type=\"capsule\" contype=\"0\" conaffinity=\"0\" group=\"1\" mass=\"0\" rgba=\"0.6 0.6 0.7 1\"/>");
    let _ = writeln!(s, "  </default>");
    let _ = writeln!(s, "  <worldbody>");

    // the chain: one nested body per joint; MuJoCo needs every moving body's mass and
    // principal moments above zero, so those below a floor far under the robot's are raised
    let radius = geom_radius(model);
    let floor = Floor::of(c.bodies());
    let inverse_weights = inverse_weights(&c, &floor);
    let raised: Vec<&str> = joints.iter().zip(c.bodies()).filter(|(_, b)| floor.raises(b)).map(|(j, _)| j.link.as_str()).collect();
    for (i, j) in joints.iter().enumerate() {
        let pad = "  ".repeat(i + 2);
        let p = j.placement.translation;
        let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(j.placement.rotation));
        let _ = writeln!(s, "{pad}<body name=\"{}\" pos=\"{} {} {}\" quat=\"{} {} {} {}\">", xml(&j.link), num(p.x), num(p.y), num(p.z), num(q.w), num(q.i), num(q.j), num(q.k));
        let (pos, mass, quat, moments) = principal_inertial(c.body(i), &floor);
        let _ = writeln!(
            s,
            "{pad}  <inertial pos=\"{} {} {}\" mass=\"{}\" quat=\"{} {} {} {}\" diaginertia=\"{} {} {}\"/>",
            num(pos.x),
            num(pos.y),
            num(pos.z),
            num(mass),
            num(quat.w),
            num(quat.i),
            num(quat.j),
            num(quat.k),
            num(moments[0]),
            num(moments[1]),
            num(moments[2]),
        );
        let kind = if j.kind == JointKind::Prismatic { "slide" } else { "hinge" };
        let mut attrs = format!("name=\"{}\" type=\"{kind}\" pos=\"0 0 0\" axis=\"{} {} {}\"", xml(&j.name), num(j.axis.x), num(j.axis.y), num(j.axis.z));
        let real_range = match j.kind {
            JointKind::Continuous => false,
            JointKind::Revolute => j.limits.lower.is_finite() && j.limits.upper.is_finite() && j.limits.upper - j.limits.lower < FULL_TURN,
            JointKind::Prismatic => j.limits.lower.is_finite() && j.limits.upper.is_finite(),
        };
        // an encoder offset δ: qpos is the measured position, the joint turns by qpos − ref
        // = qpos + δ, and its limits (at the true angle) are δ lower in qpos
        let delta = c.encoder_offset[i];
        if delta != 0.0 {
            let _ = write!(attrs, " ref=\"{}\"", num(-delta));
        }
        if real_range {
            let _ = write!(attrs, " limited=\"true\" range=\"{} {}\"", num(j.limits.lower - delta), num(j.limits.upper - delta));
        } else {
            attrs.push_str(" limited=\"false\"");
        }
        for (name, v) in [("armature", c.armature[i]), ("damping", c.viscous[i]), ("frictionloss", c.coulomb[i]), ("stiffness", c.spring_k[i])] {
            if v != 0.0 {
                let _ = write!(attrs, " {name}=\"{}\"", num(v));
            }
        }
        if c.spring_k[i] != 0.0 {
            let _ = write!(attrs, " springref=\"{}\"", num(c.spring_q0[i]));
        }
        if c.coulomb[i] != 0.0 {
            // the friction constraint whose band is simgap's tanh (FrictionRow)
            let row = FrictionRow::of(c.coulomb_slope[i], inverse_weights[i], options.timestep);
            let (d, rate) = (num(row.impedance), num(row.rate));
            let _ = write!(attrs, " solreffriction=\"0 -{rate}\" solimpfriction=\"{d} {d} 0.001 0.5 2\"");
        }
        let _ = writeln!(s, "{pad}  <joint {attrs}/>");
        // backlash: a second joint of the same body and axis, of range ±w/2, between the drive
        // (the joint above, with the rotor's armature and the actuator) and the link
        if c.backlash[i] > 0.0 {
            let half = 0.5 * c.backlash[i];
            let _ = writeln!(
                s,
                "{pad}  <joint name=\"{}_backlash\" type=\"{kind}\" pos=\"0 0 0\" axis=\"{} {} {}\" limited=\"true\" range=\"{} {}\"/>",
                xml(&j.name),
                num(j.axis.x),
                num(j.axis.y),
                num(j.axis.z),
                num(-half),
                num(half)
            );
        }
        // a visual capsule to the next joint (the last body's to its centre of mass)
        let to: Vector3<f64> = joints.get(i + 1).map_or(c.body(i).com(), |next| next.placement.translation);
        if to.norm() > 1e-6 {
            let _ = writeln!(s, "{pad}  <geom name=\"{}_geom\" fromto=\"0 0 0 {} {} {}\" size=\"{}\"/>", xml(&j.link), num(to.x), num(to.y), num(to.z), num(radius));
        } else {
            let _ = writeln!(s, "{pad}  <geom name=\"{}_geom\" type=\"sphere\" size=\"{}\"/>", xml(&j.link), num(radius));
        }
    }
    for i in (0..n).rev() {
        let _ = writeln!(s, "{}</body>", "  ".repeat(i + 2));
    }
    let _ = writeln!(s, "  </worldbody>");

    // a motor per driven joint: ctrl is the commanded torque; a position actuator per servo
    // joint: ctrl is the goal
    let _ = writeln!(s, "  <actuator>");
    let mut servo_limited = Vec::new();
    for (i, j) in joints.iter().enumerate() {
        if options.passive.contains(&j.name) {
            continue;
        }
        if let Some((sv, k)) = options.servo.as_ref().and_then(|sv| sv.index(&j.name).map(|k| (sv, k))) {
            // a selected saturation of the drive torque (after the gain) lowers the clamp
            let mut force = sv.force_limit(k);
            if c.limit[i].is_finite() && c.gain[i] * c.limit[i] < force {
                force = c.gain[i] * c.limit[i];
                servo_limited.push(j.name.clone());
            }
            let _ = writeln!(
                s,
                "    <position name=\"{}_servo\" joint=\"{}\" kp=\"{}\" kv=\"{}\" ctrllimited=\"false\" forcelimited=\"true\" forcerange=\"{} {}\"/>",
                xml(&j.name),
                xml(&j.name),
                num(sv.kp(k)),
                num(sv.kv(k)),
                num(-force),
                num(force)
            );
            continue;
        }
        let mut attrs = format!("name=\"{}_motor\" joint=\"{}\" gear=\"{}\" ctrllimited=\"false\"", xml(&j.name), xml(&j.name), num(c.gain[i]));
        if c.limit[i].is_finite() {
            let _ = write!(attrs, " forcelimited=\"true\" forcerange=\"{} {}\"", num(-c.limit[i]), num(c.limit[i]));
        } else {
            attrs.push_str(" forcelimited=\"false\"");
        }
        let _ = writeln!(s, "    <motor {attrs}/>");
    }
    let _ = writeln!(s, "  </actuator>");
    let _ = writeln!(s, "</mujoco>");

    // the sidecar
    let mut sidecar = Sidecar::new("mjcf");
    let on_servos = |e: &EffectReport| options.servo.as_ref().is_some_and(|sv| !e.joints.is_empty() && e.joints.iter().all(|j| sv.index(j).is_some()));
    for e in effects {
        match e.effect {
            EffectKind::TorqueGain | EffectKind::BackEmf if on_servos(e) => sidecar.hold(e, "servo position actuator kp, kv and forcerange (folded into the servo's effective kt and R)", ""),
            EffectKind::TorqueSaturation if on_servos(e) => sidecar.hold(
                e,
                "servo position actuator forcerange, where below the servo's own",
                "MuJoCo clamps the actuator's whole force (after the back-EMF term); simgap clamps the drive torque before subtracting the selected back-EMF",
            ),
            EffectKind::InertialError | EffectKind::Payload => sidecar.hold(e, "body <inertial>", ""),
            EffectKind::ViscousFriction => sidecar.hold(e, "joint damping", ""),
            EffectKind::CoulombFriction => sidecar.hold(
                e,
                "joint frictionloss, with solreffriction and solimpfriction of the band",
                "MuJoCo's frictionloss is dry friction solved as a constraint; its solreffriction (damping = the band's rate) and solimpfriction (impedance 1e-4: no stiction) make it −fc·clip(q̇/(2 ln 2·w), ±1), the piecewise-linear sign that takes the momentum of the −fc·tanh(q̇/w) simgap simulated (w in the parameters, or 0.01 rad/s where the report gives none); a band whose rate fc/(2 ln 2·w)·(inverse inertia at q = 0) exceeds 1/timestep gets that rate and the impedance that keeps its creep under a steady load",
            ),
            EffectKind::Armature => sidecar.hold(e, "joint armature", ""),
            EffectKind::TorqueGain => sidecar.hold(e, "motor gear", ""),
            EffectKind::TorqueSaturation => sidecar.hold(e, "motor forcerange (forcelimited), applied to ctrl before the gear as simgap clamps before the gain", ""),
            EffectKind::JointSpring => sidecar.hold(e, "joint stiffness and springref", ""),
            EffectKind::EncoderOffset => sidecar.hold(
                e,
                "joint ref = −offset (qpos is the measured position; the joint turns by qpos − ref) and its range shifted by −offset",
                "a joint spring's springref and the servo's goal stay in measured positions",
            ),
            EffectKind::Backlash => sidecar.hold(
                e,
                "a second joint '<name>_backlash' of the same body and axis, range ±width/2, between the drive (the joint, with the rotor's armature and the actuator) and the link",
                "the link's position is the sum of the two joints' qpos; MuJoCo applies the joint's damping, friction and servo on the drive side, simgap its frictions on the link; MuJoCo's joint limit is a soft contact, simgap's take-up a plastic impact",
            ),
            _ => sidecar.defer(e, Format::Mjcf),
        }
    }
    if !raised.is_empty() {
        sidecar.notes.push(format!(
            "MuJoCo needs every moving body's mass and principal moments above zero: bodies {raised:?} have theirs raised to at least {} kg and {} kg·m² (1e-9 of the robot's largest), a change no figure shows",
            num(floor.mass),
            num(floor.moment)
        ));
    }
    for p in &options.passive {
        sidecar.notes.push(format!("joint '{p}' is passive (commanded torque always zero in the logs): it has no motor"));
    }
    if let Some(sv) = &options.servo {
        let per_joint: Vec<String> = sv
            .joints
            .iter()
            .enumerate()
            .map(|(k, j)| {
                format!(
                    "{j}: kt {}, R {} Ω, duty_gain {}, max_duty {} → kp {}, kv {}, forcerange ±{}",
                    num(sv.kt[k]),
                    num(sv.r[k]),
                    num(sv.duty_gain[k]),
                    num(sv.max_duty[k]),
                    num(sv.kp(k)),
                    num(sv.kv(k)),
                    num(sv.force_limit(k))
                )
            })
            .collect();
        sidecar.notes.push(format!(
            "servo joints are MuJoCo position actuators (JOINT_servo; ctrl = the goal position): force = clip(kp·(ctrl − q) − kv·q̇, ±forcerange), kp = kt/R·V·duty_gain, kv = kt²/R (the back-EMF), forcerange = kt/R·V·max_duty, with the report's effective kt and R (servo.effective) and V = {} V ({}); {}",
            num(sv.voltage),
            sv.voltage_source,
            per_joint.join("; ")
        ));
        sidecar.notes.push(
            "approximated: the firmware saturates the duty, simgap's τ = (kt/R)·(V·clip(duty_gain·(goal − q), ±max_duty) − kt·q̇); MuJoCo clamps the force, τ = clip((kt/R)·V·duty_gain·(goal − q) − (kt²/R)·q̇, ±(kt/R)·V·max_duty). The two are the same while the duty is not saturated, and at rest when it is (duty and torque are proportional at zero speed, so the duty clamp is exactly a force clamp); with the duty saturated and the joint moving they differ by up to (kt²/R)·|q̇|: MuJoCo keeps the full clamp where simgap's torque is the clamped duty's less the back-EMF (less torque moving with the drive, more braking against it)".into(),
        );
        sidecar.notes.push(
            "a servo's torque enable is not in the MJCF: with torque off the servo applies no torque and no back-EMF, so set the actuator's kp and kv to zero (MuJoCo: actuator_gainprm[i][0] = 0, actuator_biasprm[i][1:3] = 0) for those samples".into(),
        );
        if !servo_limited.is_empty() {
            sidecar
                .notes
                .push(format!("on servo joints {servo_limited:?} the selected torque saturation (× gain) is below the servo's stall torque at max_duty and is the forcerange"));
        }
        sidecar.notes.extend(sv.notes.iter().cloned());
    }
    if joints.iter().any(|j| j.kind == JointKind::Revolute && j.limits.upper - j.limits.lower >= FULL_TURN) {
        sidecar.notes.push("revolute joints whose URDF range spans a full turn are unlimited in the MJCF: a ±π range is the angle's convention, not a stop".into());
    }
    sidecar.notes.push(format!(
        "simgap does not simulate joint limits; MuJoCo enforces the MJCF ranges (limited=\"true\"), which matters only for motion that reaches them. Integrator {}, one step per sample of {} s.",
        options.integrator,
        num(options.timestep)
    ));
    Ok(ExportedFile { text: s, sidecar })
}

/// MuJoCo's least constraint impedance (`mjMINIMP`).
const MIN_IMPEDANCE: f64 = 1e-4;

/// MuJoCo's greatest constraint impedance (`mjMAXIMP`).
const MAX_IMPEDANCE: f64 = 0.9999;

/// The friction-loss constraint that makes MuJoCo's `frictionloss` simgap's `−fc·tanh(q̇/w)`,
/// written `solreffriction="0 −rate"` (the direct format: damping `rate`, the stiffness a
/// friction row ignores) and `solimpfriction="d d 0.001 0.5 2"`.
///
/// MuJoCo solves `frictionloss` as a soft constraint (its documentation: Computation,
/// Parameters; Modeling, Solver parameters, Friction): below the level `fc` the force is
/// `f = −(b·q̇ + a_u)/(A + R)`, with `a_u` the joint's acceleration without it, `A` its inverse
/// inertia, `R = (1 − d)/d·Â` (`d` = `solimp[0]`, `Â` = `dof_invweight0`, the same inverse
/// inertia at `qpos0`, [`inverse_weights`]) and `b = rate/solimp[1]`. With `solimp[1] = d`, at
/// `qpos0`
///
/// ```text
/// f = −(rate·q̇ + d·a_u) / Â,   |f| <= fc
/// ```
///
/// a viscous band of slope `rate/Â` that also holds a share `d` of the load. simgap's tanh is a
/// band of the velocity alone. So:
/// - `d` = MuJoCo's least, 1e-4: no stiction, and `R` so far above `A` that the band is the same
///   at every configuration;
/// - `rate = fc/(2 ln 2·w)·Â`: the piecewise-linear sign `−fc·clip(q̇/(2 ln 2·w), ±1)` that takes
///   the tanh's momentum: a joint crossing q̇ = 0 at a steady acceleration loses as much to it
///   as to `−fc·tanh(q̇/w)` (the tanh falls short of the exact sign by `∫(1 − tanh) = ln 2`
///   widths on each side, a clip by half its width). A steady load `τ < fc` creeps at
///   `2 ln 2·w·τ/fc`, where the tanh's creeps at `w·atanh(τ/fc)`.
///
/// One step resolves a band up to `rate = 1/timestep`, the bound MuJoCo's `refsafe` keeps (a
/// time constant of two steps). A narrower band (a large friction on a light joint; `w = 0`, the
/// exact sign) gets that rate and `d = 1 − rate/band`, `band` the rate it asks for: the same
/// creep, `(1 − d)·a_u/rate`, reached within a step instead of a fraction of one.
///
/// MuJoCo's default (a time constant of 0.02 s, `d = 0.9`), and the two-step time constant the
/// export wrote before, hold 90 % of the load: where simgap's joint creeps under a load below
/// `fc`, MuJoCo's sticks; and their band's slope grows with the joint's inertia where the
/// tanh's, `fc/w`, does not. On a 40 kg carriage (`tests/python/test_export_carriage.py`)
/// MuJoCo's k-step error was 22 % and 72 % above simgap's at 0.1 and 0.5 s with two steps, and
/// is within 1 % with this row.
#[derive(Clone, Copy, Debug, PartialEq)]
struct FrictionRow {
    /// The band's rate of velocity decay [1/s]: `solreffriction`'s damping.
    rate: f64,
    /// The impedance `d`, `solimpfriction[0]` and `[1]`: the share of the load the band holds.
    impedance: f64,
}

impl FrictionRow {
    /// The row of a dry friction of slope `slope` = `Σ fc/w` [N·m·s/rad or N·s/m] (`+∞`: the
    /// exact sign) on a dof of inverse weight `inverse_weight` [1/(kg·m²) or 1/kg] (MuJoCo's
    /// `dof_invweight0`), stepped every `timestep` [s].
    fn of(slope: f64, inverse_weight: f64, timestep: f64) -> FrictionRow {
        let band = slope * inverse_weight / (2.0 * std::f64::consts::LN_2);
        let band = if band.is_nan() { f64::INFINITY } else { band };
        let rate = band.min(1.0 / timestep);
        FrictionRow { rate, impedance: (1.0 - rate / band).clamp(MIN_IMPEDANCE, MAX_IMPEDANCE) }
    }
}

/// MuJoCo's `dof_invweight0` of each joint of the chain [1/(kg·m²) or 1/kg], as its compiler
/// sets it (`engine_setconst.c`): the diagonal of the inverse of the MJCF's mass matrix at
/// `qpos0` (the corrected bodies at q = 0 of the true angle, an encoder offset's `ref`
/// included), armature included, a backlash joint being a second dof of its body and axis
/// without armature; except on a "simple" body of slides alone (the only body, its inertial at
/// its origin and aligned with it, each slide along a coordinate axis), where it is
/// `1/mass`, armature left out. Where the mass matrix is singular (a backlash joint without
/// rotor inertia), the chain's own without the backlash dofs.
fn inverse_weights(c: &Corrections, floor: &Floor) -> Vec<f64> {
    let n = c.coulomb.len();
    let joints = c.corrected.joints();
    // a simple body of slides: 1/mass
    if let [joint] = joints {
        let (pos, mass, quat, _) = principal_inertial(c.body(0), floor);
        let aligned = joint.axis.iter().filter(|x| x.abs() > 1e-14).count() == 1;
        let identity = [quat.w.abs() - 1.0, quat.i, quat.j, quat.k].iter().all(|x| x.abs() < 1e-6);
        if joint.kind == JointKind::Prismatic && aligned && identity && pos.iter().all(|x| x.abs() < 1e-6) {
            return vec![1.0 / mass];
        }
    }
    let h = mass_matrix(&c.corrected, &mut Workspace::new(&c.corrected), &vec![0.0; n]);
    // the MJCF's dofs: each joint's, then its backlash joint's (the joint each one turns)
    let mut of_joint = Vec::with_capacity(n);
    let mut turns = Vec::with_capacity(2 * n);
    for i in 0..n {
        of_joint.push(turns.len());
        turns.push(i);
        if c.backlash[i] > 0.0 {
            turns.push(i);
        }
    }
    let with_armature = |mut m: DMatrix<f64>, dofs: &[usize]| {
        for (i, &k) in dofs.iter().enumerate() {
            m[(k, k)] += c.armature[i];
        }
        m.cholesky().map(|l| l.inverse().diagonal())
    };
    let full = DMatrix::from_fn(turns.len(), turns.len(), |a, b| h[(turns[a], turns[b])]);
    let chain: Vec<usize> = (0..n).collect();
    match with_armature(full, &of_joint) {
        Some(inv) => of_joint.iter().map(|&k| inv[k]).collect(),
        None => with_armature(h, &chain).map_or(vec![f64::NAN; n], |inv| inv.iter().copied().collect()),
    }
}

/// The smallest mass [kg] and principal moment [kg·m²] written: 1e-9 of the robot's largest
/// body mass and principal moment.
struct Floor {
    mass: f64,
    moment: f64,
}

impl Floor {
    fn of<'a>(bodies: impl Iterator<Item = &'a SpatialInertia>) -> Floor {
        let (mass, moment) = bodies.fold((0.0f64, 0.0f64), |(m, i), b| (m.max(b.mass), i.max(b.inertia_about_com().symmetric_eigenvalues().max())));
        Floor { mass: (1e-9 * mass).max(1e-12), moment: (1e-9 * moment).max(1e-15) }
    }

    fn raises(&self, b: &SpatialInertia) -> bool {
        b.mass < self.mass || b.inertia_about_com().symmetric_eigenvalues().iter().any(|l| *l < self.moment)
    }
}

/// A body's inertial as MuJoCo takes it exactly: centre of mass [m], mass [kg], the rotation of
/// the principal axes (w x y z) and the principal moments [kg·m²], mass and moments raised to
/// the floor.
fn principal_inertial(body: &SpatialInertia, floor: &Floor) -> (Vector3<f64>, f64, UnitQuaternion<f64>, [f64; 3]) {
    let ic = body.inertia_about_com();
    let eig = ((ic + ic.transpose()) * 0.5).symmetric_eigen();
    let mut axes = eig.eigenvectors;
    if axes.determinant() < 0.0 {
        axes.set_column(2, &(-axes.column(2)));
    }
    let quat = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(axes));
    let m = eig.eigenvalues.map(|l| l.max(floor.moment));
    (body.com(), body.mass.max(floor.mass), quat, [m[0], m[1], m[2]])
}

/// A capsule radius in proportion to the robot: 4 % of its longest joint-to-joint distance,
/// at least 5 mm.
fn geom_radius(model: &Model) -> f64 {
    let longest = model.joints().iter().map(|j| j.placement.translation.norm()).chain(model.joints().iter().map(|j| j.inertia.com().norm())).fold(0.0, f64::max);
    (0.04 * longest).max(0.005)
}

/// Text escaped for an XML attribute.
fn xml(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;").replace('\'', "&apos;")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Param;
    use simgap_core::PAPER_ARM_URDF;
    use std::f64::consts::LN_2;

    /// A 40 kg carriage on a horizontal slide.
    const CARRIAGE_URDF: &str = r#"<robot name="carriage_axis"><link name="base_link"/>
        <joint name="carriage" type="prismatic"><parent link="base_link"/><child link="carriage"/>
          <origin xyz="0 0 0.1"/><axis xyz="1 0 0"/><limit lower="-0.4" upper="0.4" effort="800" velocity="1"/></joint>
        <link name="carriage"><inertial><origin xyz="0 0 0.05"/><mass value="40"/>
          <inertia ixx="0.3333" ixy="0" ixz="0" iyy="0.5667" iyz="0" izz="0.8333"/></inertial></link></robot>"#;

    fn entry(effect: EffectKind, joints: &[&str], params: &[(&str, Vec<f64>)]) -> EffectReport {
        let mut e = EffectReport::new(effect);
        e.joints = joints.iter().map(|j| j.to_string()).collect();
        e.parameters = params.iter().map(|(k, v)| (k.to_string(), Param::PerJoint(v.clone()))).collect();
        e
    }

    /// `solreffriction` and `solimpfriction` of a joint of the exported text, as numbers.
    fn friction_row(text: &str, joint: &str) -> (Vec<f64>, Vec<f64>) {
        let doc = roxmltree::Document::parse(text).unwrap();
        let node = doc.descendants().find(|n| n.has_tag_name("joint") && n.attribute("name") == Some(joint)).unwrap();
        let numbers = |key: &str| node.attribute(key).unwrap_or_else(|| panic!("{key} missing: {text}")).split_whitespace().map(|x| x.parse().unwrap()).collect::<Vec<f64>>();
        (numbers("solreffriction"), numbers("solimpfriction"))
    }

    /// MuJoCo's friction row below its level at `qpos0` (Computation, Parameters): the force
    /// `f = −(b·q̇ + a_u)/(A + R)` with `b = damping/solimp[1]`, `R = (1 − d)/d·Â`, `A = Â` at
    /// `qpos0` on a joint of its own; returns `−∂f/∂q̇` [N·s/m] and the share of the load held,
    /// `−∂f/∂a_u·Â`.
    fn mujoco_band(solref: &[f64], solimp: &[f64], inverse_weight: f64) -> (f64, f64) {
        assert!(solref[0] <= 0.0 && solref[1] < 0.0, "direct format expected: {solref:?}");
        let (d, b) = (solimp[0], -solref[1] / solimp[1]);
        let a_plus_r = inverse_weight + (1.0 - d) / d * inverse_weight;
        (b / a_plus_r, inverse_weight / a_plus_r)
    }

    #[test]
    fn exported_friction_row_is_the_tanh_band_of_equal_momentum_without_stiction_on_a_heavy_slide() {
        // 35 N at w = 2 mm/s on 40 kg: the band's rate fc/(2 ln 2·w)/m = 316/s is within one
        // 2.5 ms step (400/s), so MuJoCo's least impedance and the tanh's slope over 2 ln 2
        let model = Model::from_urdf_str(CARRIAGE_URDF).unwrap();
        let effects = [
            entry(EffectKind::CoulombFriction, &["carriage"], &[("fc", vec![35.0]), ("w", vec![0.002])]),
            entry(EffectKind::ViscousFriction, &["carriage"], &[("b", vec![150.0])]),
        ];
        let out = export_mjcf(&model, &effects, &MjcfOptions::new(0.0025)).unwrap();
        let (solref, solimp) = friction_row(&out.text, "carriage");
        assert_eq!(solimp, [1e-4, 1e-4, 0.001, 0.5, 2.0], "{}", out.text);
        let (slope, held) = mujoco_band(&solref, &solimp, 1.0 / 40.0);
        let tanh_slope = 35.0 / 0.002;
        assert!((slope - tanh_slope / (2.0 * LN_2)).abs() < 1e-9 * tanh_slope, "MuJoCo's band {slope} N·s/m, tanh {tanh_slope}");
        assert!(held < 1.000001e-4, "the band holds {held} of the load");
        // equal momentum: a clip of half-width v1 falls short of the sign by v1/2 on each side,
        // the tanh by w·ln 2
        let v1 = 35.0 / slope;
        assert!((v1 / 2.0 - 0.002 * LN_2).abs() < 1e-15, "{v1}");
    }

    #[test]
    fn a_band_one_step_cannot_resolve_gets_the_step_rate_and_keeps_its_creep() {
        // the paper arm's elbow: 1.734 N·m at w = 0.01 rad/s asks for a rate above 1/timestep
        let model = Model::from_urdf_str(PAPER_ARM_URDF).unwrap();
        let timestep = 0.0025;
        let effects = [entry(EffectKind::CoulombFriction, &["shoulder", "elbow"], &[("fc", vec![7.17, 1.734]), ("w", vec![0.01, 0.01])])];
        let out = export_mjcf(&model, &effects, &MjcfOptions::new(timestep)).unwrap();
        let h = mass_matrix(&model, &mut Workspace::new(&model), &[0.0, 0.0]);
        let inverse_weight = h.try_inverse().unwrap()[(1, 1)];
        let asked = 1.734 / (2.0 * LN_2 * 0.01) * inverse_weight;
        assert!(asked * timestep > 1.0, "{asked}");
        let (solref, solimp) = friction_row(&out.text, "elbow");
        assert_eq!(solref, [0.0, -1.0 / timestep], "{}", out.text);
        // the creep under a steady load τ, (1 − d)·a_u/rate = (1 − d)·τ·Â/rate, is the asked band's
        let d = solimp[0];
        assert!(((1.0 - d) / solref[1].abs() - 1.0 / asked).abs() < 1e-12 / asked, "d = {d}");
        // the exact sign (w = 0): the step's rate and MuJoCo's greatest impedance
        let exact = [entry(EffectKind::CoulombFriction, &["elbow"], &[("fc", vec![1.734]), ("w", vec![0.0])])];
        let (solref, solimp) = friction_row(&export_mjcf(&model, &exact, &MjcfOptions::new(timestep)).unwrap().text, "elbow");
        assert_eq!((solref[1], solimp[0]), (-1.0 / timestep, MAX_IMPEDANCE));
    }

    #[test]
    fn inverse_weight_is_mujocos_diagonal_of_the_inverse_mass_matrix_the_rotor_alone_behind_play_and_the_mass_of_a_simple_slide() {
        // without play, 1/(m + ia); with play the link moves freely of the drive: M = [[m + ia,
        // m], [m, m]] over (drive, play), whose inverse's drive entry is 1/ia
        let model = Model::from_urdf_str(CARRIAGE_URDF).unwrap();
        let rotor = entry(EffectKind::Armature, &["carriage"], &[("ia", vec![8.0])]);
        let weights = |model: &Model, effects: &[EffectReport]| {
            let c = Corrections::read(model, effects).unwrap();
            inverse_weights(&c, &Floor::of(c.bodies()))[0]
        };
        assert!((weights(&model, std::slice::from_ref(&rotor)) - 1.0 / 48.0).abs() < 1e-15);
        let play = entry(EffectKind::Backlash, &["carriage"], &[("width", vec![0.001])]);
        let w = weights(&model, &[rotor.clone(), play]);
        assert!((w - 1.0 / 8.0).abs() < 1e-12, "{w}");
        // MuJoCo's "simple" body (its inertial at its origin, a slide along x): 1/mass, the
        // armature left out (MuJoCo 4.0.1 gives 0.025 for this body with armature 8)
        let simple = Model::from_urdf_str(&CARRIAGE_URDF.replace(r#"<origin xyz="0 0 0.05"/>"#, "")).unwrap();
        assert!((weights(&simple, std::slice::from_ref(&rotor)) - 1.0 / 40.0).abs() < 1e-15);
    }
}
