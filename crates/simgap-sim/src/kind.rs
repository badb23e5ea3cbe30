//! The vocabulary of unmodelled effects by name: the one list every crate, the CLI, Python and
//! the fleet use to spell an effect, its parameters, their units and their neutral values.
//!
//! The names are a public contract (they appear in reports and in other people's scripts).
//! Units follow the joint type: a parameter whose quantity is a joint torque is `N·m` on a
//! revolute joint and `N` on a prismatic one (see [`Quantity::unit`]).

use std::fmt;
use std::str::FromStr;

use simgap_core::JointKind;

use crate::error::Error;

/// One effect of the vocabulary, by name (the data it carries is [`crate::Effect`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum EffectKind {
    /// `viscous_friction`: −b q̇.
    ViscousFriction,
    /// `coulomb_friction`: −fc sign(q̇).
    CoulombFriction,
    /// `stribeck_friction`: −(fc + (fs − fc) e^{−(q̇/vs)²}) sign(q̇).
    StribeckFriction,
    /// `armature`: rotor inertia on the diagonal of H.
    Armature,
    /// `payload`: a point mass on the last link.
    Payload,
    /// `inertial_error`: wrong link parameters.
    InertialError,
    /// `torque_gain`: τ_applied = k τ_cmd.
    TorqueGain,
    /// `torque_offset`: τ_applied = τ_cmd + offset.
    TorqueOffset,
    /// `torque_saturation`: τ_applied = clamp(τ_cmd, ±limit).
    TorqueSaturation,
    /// `time_delay`: τ_applied(t) = τ_cmd(t − delay).
    TimeDelay,
    /// `cogging`: −A sin(N q).
    Cogging,
    /// `coriolis_structure`: the model's C misses (or wrongly has) its skew-symmetric part.
    CoriolisStructure,
    /// `joint_spring`: −k (q − q0) (cables, hoses, a counterbalance spring).
    JointSpring,
    /// `directional_friction`: −(fc_pos + b_pos q̇) for q̇ > 0, fc_neg − b_neg q̇ for q̇ < 0.
    DirectionalFriction,
    /// `load_friction`: dry friction growing with the drive's torque through the gearbox.
    LoadFriction,
    /// `load_stribeck_friction`: a load-dependent friction whose level at rest (breakaway,
    /// `fs + mus |τ_drive|`) rises above its level in motion (`fc + mu |τ_drive|`) below a
    /// Stribeck velocity.
    LoadStribeckFriction,
    /// `back_emf`: `−kb q̇` while the drive is enabled.
    BackEmf,
    /// `encoder_offset`: the joint's measured zero is not the model's; the joint is at
    /// `q_measured + offset`.
    EncoderOffset,
    /// `backlash`: free play of total width `width` between the drive and the link; the drive's
    /// torque reaches the link only while the play is taken up.
    Backlash,
}

/// The physical quantity of a parameter, which gives its unit on a joint of either type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Quantity {
    /// A generalised force: N·m (revolute), N (prismatic).
    Effort,
    /// Effort per velocity: N·m·s/rad, N·s/m.
    Damping,
    /// Effort per displacement: N·m/rad, N/m.
    Stiffness,
    /// A joint velocity: rad/s, m/s.
    Velocity,
    /// A joint position: rad, m.
    Position,
    /// Reflected inertia on a joint: kg·m² (revolute), kg (prismatic).
    JointInertia,
    /// A mass [kg], whatever the joint.
    Mass,
    /// A length in a link frame [m].
    Length,
    /// A rotational inertia of a link [kg·m²].
    LinkInertia,
    /// A time [s].
    Time,
    /// A dimensionless ratio [-].
    Ratio,
    /// The width of a smoothed sign, tanh(q̇ / w), in joint velocity units (rad/s, m/s): how
    /// the effect is simulated, not a property of the robot.
    Width,
    /// A count (periods per revolution, identifiable directions): reported, never a physical
    /// parameter to test [-].
    Count,
}

impl Quantity {
    /// The SI unit of the quantity on a joint of type `joint` (`-` for a ratio).
    pub fn unit(self, joint: JointKind) -> &'static str {
        let linear = matches!(joint, JointKind::Prismatic);
        match (self, linear) {
            (Quantity::Effort, false) => "N·m",
            (Quantity::Effort, true) => "N",
            (Quantity::Damping, false) => "N·m·s/rad",
            (Quantity::Damping, true) => "N·s/m",
            (Quantity::Stiffness, false) => "N·m/rad",
            (Quantity::Stiffness, true) => "N/m",
            (Quantity::Velocity | Quantity::Width, false) => "rad/s",
            (Quantity::Velocity | Quantity::Width, true) => "m/s",
            (Quantity::Position, false) => "rad",
            (Quantity::Position, true) => "m",
            (Quantity::JointInertia, false) => "kg·m²",
            (Quantity::JointInertia, true) => "kg",
            (Quantity::Mass, _) => "kg",
            (Quantity::Length, _) => "m",
            (Quantity::LinkInertia, _) => "kg·m²",
            (Quantity::Time, _) => "s",
            (Quantity::Ratio | Quantity::Count, _) => "-",
        }
    }

    /// The quantity's name (`effort`, `damping`, …, `count`), as other languages read it.
    pub const fn name(self) -> &'static str {
        match self {
            Quantity::Effort => "effort",
            Quantity::Damping => "damping",
            Quantity::Stiffness => "stiffness",
            Quantity::Velocity => "velocity",
            Quantity::Position => "position",
            Quantity::JointInertia => "joint_inertia",
            Quantity::Mass => "mass",
            Quantity::Length => "length",
            Quantity::LinkInertia => "link_inertia",
            Quantity::Time => "time",
            Quantity::Ratio => "ratio",
            Quantity::Width => "width",
            Quantity::Count => "count",
        }
    }
}

/// A parameter of an effect as the report states it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamSpec {
    /// Its name in reports and on the command line.
    pub name: &'static str,
    /// Its quantity (and so its unit).
    pub quantity: Quantity,
    /// The value at which the effect is absent (`None`: no such value, e.g. a period count
    /// or a position the effect is centred on).
    pub neutral: Option<f64>,
    /// Whether the report gives it an interval: `false` for values searched on a grid or
    /// fixed by choice, and for counts that are no parameter at all.
    pub estimated: bool,
}

const fn p(name: &'static str, quantity: Quantity, neutral: Option<f64>, estimated: bool) -> ParamSpec {
    ParamSpec { name, quantity, neutral, estimated }
}

use Quantity::{Count, Damping, Effort, JointInertia, Length, LinkInertia, Mass, Position, Ratio, Stiffness, Time, Velocity, Width};
const VISCOUS: &[ParamSpec] = &[p("b", Damping, Some(0.0), true)];
const COULOMB: &[ParamSpec] = &[p("fc", Effort, Some(0.0), true), p("w", Width, None, false)];
const STRIBECK: &[ParamSpec] = &[p("fc", Effort, Some(0.0), true), p("fs", Effort, Some(0.0), true), p("vs", Velocity, None, false), p("w", Width, None, false)];
const ARMATURE: &[ParamSpec] = &[p("ia", JointInertia, Some(0.0), true)];
const PAYLOAD: &[ParamSpec] = &[p("mass", Mass, Some(0.0), true), p("com", Length, None, false)];
const INERTIAL: &[ParamSpec] = &[
    p("delta_mass", Mass, Some(0.0), false),
    p("delta_com", Length, Some(0.0), false),
    p("delta_inertia", LinkInertia, Some(0.0), false),
    p("identifiable_directions", Count, None, false),
];
const GAIN: &[ParamSpec] = &[p("k", Ratio, Some(1.0), true)];
const OFFSET: &[ParamSpec] = &[p("offset", Effort, Some(0.0), true)];
const SATURATION: &[ParamSpec] = &[p("limit", Effort, Some(f64::INFINITY), false)];
const DELAY: &[ParamSpec] = &[p("delay", Time, Some(0.0), false)];
const SPRING: &[ParamSpec] = &[p("k", Stiffness, Some(0.0), true), p("q0", Position, None, true)];
const DIRECTIONAL: &[ParamSpec] = &[
    p("fc_pos", Effort, Some(0.0), true),
    p("fc_neg", Effort, Some(0.0), true),
    p("b_pos", Damping, Some(0.0), true),
    p("b_neg", Damping, Some(0.0), true),
    p("w", Width, None, false),
];
const LOAD: &[ParamSpec] = &[p("fc", Effort, Some(0.0), true), p("mu", Ratio, Some(0.0), true), p("w", Width, None, false)];
const LOAD_STRIBECK: &[ParamSpec] = &[
    p("fc", Effort, Some(0.0), true),
    p("mu", Ratio, Some(0.0), true),
    p("fs", Effort, Some(0.0), true),
    p("mus", Ratio, Some(0.0), true),
    p("vs", Velocity, None, false),
    p("w", Width, None, false),
];
const BACK_EMF: &[ParamSpec] = &[p("kb", Damping, Some(0.0), true)];
const ENCODER_OFFSET: &[ParamSpec] = &[p("offset", Position, Some(0.0), true)];
const BACKLASH: &[ParamSpec] = &[p("width", Position, Some(0.0), false)];
const COGGING: &[ParamSpec] = &[p("amplitude", Effort, Some(0.0), true), p("periods_per_rev", Count, None, false)];

impl EffectKind {
    /// Every effect, in the documented order.
    pub const ALL: [EffectKind; 19] = [
        EffectKind::ViscousFriction,
        EffectKind::CoulombFriction,
        EffectKind::StribeckFriction,
        EffectKind::Armature,
        EffectKind::Payload,
        EffectKind::InertialError,
        EffectKind::TorqueGain,
        EffectKind::TorqueOffset,
        EffectKind::TorqueSaturation,
        EffectKind::TimeDelay,
        EffectKind::Cogging,
        EffectKind::CoriolisStructure,
        EffectKind::JointSpring,
        EffectKind::DirectionalFriction,
        EffectKind::LoadFriction,
        EffectKind::LoadStribeckFriction,
        EffectKind::BackEmf,
        EffectKind::EncoderOffset,
        EffectKind::Backlash,
    ];

    /// The contract name (`viscous_friction`, …, `coriolis_structure`).
    pub const fn as_str(self) -> &'static str {
        match self {
            EffectKind::ViscousFriction => "viscous_friction",
            EffectKind::CoulombFriction => "coulomb_friction",
            EffectKind::StribeckFriction => "stribeck_friction",
            EffectKind::Armature => "armature",
            EffectKind::Payload => "payload",
            EffectKind::InertialError => "inertial_error",
            EffectKind::TorqueGain => "torque_gain",
            EffectKind::TorqueOffset => "torque_offset",
            EffectKind::TorqueSaturation => "torque_saturation",
            EffectKind::TimeDelay => "time_delay",
            EffectKind::Cogging => "cogging",
            EffectKind::CoriolisStructure => "coriolis_structure",
            EffectKind::JointSpring => "joint_spring",
            EffectKind::DirectionalFriction => "directional_friction",
            EffectKind::LoadFriction => "load_friction",
            EffectKind::LoadStribeckFriction => "load_stribeck_friction",
            EffectKind::BackEmf => "back_emf",
            EffectKind::EncoderOffset => "encoder_offset",
            EffectKind::Backlash => "backlash",
        }
    }

    /// The parameters the report states, with their quantities and neutral values.
    pub const fn parameters(self) -> &'static [ParamSpec] {
        match self {
            EffectKind::ViscousFriction => VISCOUS,
            EffectKind::CoulombFriction => COULOMB,
            EffectKind::StribeckFriction => STRIBECK,
            EffectKind::Armature => ARMATURE,
            EffectKind::Payload => PAYLOAD,
            EffectKind::InertialError => INERTIAL,
            EffectKind::TorqueGain => GAIN,
            EffectKind::TorqueOffset => OFFSET,
            EffectKind::TorqueSaturation => SATURATION,
            EffectKind::TimeDelay => DELAY,
            EffectKind::Cogging => COGGING,
            EffectKind::CoriolisStructure => &[],
            EffectKind::JointSpring => SPRING,
            EffectKind::DirectionalFriction => DIRECTIONAL,
            EffectKind::LoadFriction => LOAD,
            EffectKind::LoadStribeckFriction => LOAD_STRIBECK,
            EffectKind::BackEmf => BACK_EMF,
            EffectKind::EncoderOffset => ENCODER_OFFSET,
            EffectKind::Backlash => BACKLASH,
        }
    }

    /// The specification of parameter `param`, if the effect has one of that name.
    pub fn parameter(self, param: &str) -> Option<&'static ParamSpec> {
        self.parameters().iter().find(|s| s.name == param)
    }

    /// The unit of parameter `param` on a joint of type `joint` (`None` for an unknown name).
    pub fn unit(self, param: &str, joint: JointKind) -> Option<&'static str> {
        self.parameter(param).map(|s| s.quantity.unit(joint))
    }

    /// The value of parameter `param` at which the effect is absent.
    pub fn neutral(self, param: &str) -> Option<f64> {
        self.parameter(param).and_then(|s| s.neutral)
    }

    /// Whether the effect acts on the whole robot (its parameters are numbers, not per-joint
    /// lists).
    pub const fn whole_robot(self) -> bool {
        matches!(self, EffectKind::Payload | EffectKind::TimeDelay | EffectKind::CoriolisStructure)
    }

    /// The names of every effect, comma-separated (for error messages).
    pub fn known() -> String {
        EffectKind::ALL.iter().map(|k| k.as_str()).collect::<Vec<_>>().join(", ")
    }
}

impl fmt::Display for EffectKind {
    /// The contract name, padded to a width where one is given (`{:<18}`).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.pad(self.as_str())
    }
}

impl FromStr for EffectKind {
    type Err = Error;

    /// The effect of a contract name.
    ///
    /// # Errors
    /// [`Error::Invalid`] naming the unknown name and every known one.
    fn from_str(s: &str) -> Result<Self, Error> {
        EffectKind::ALL
            .into_iter()
            .find(|k| k.as_str() == s)
            .ok_or_else(|| Error::Invalid { what: "effect".into(), message: format!("unknown effect '{s}'; expected one of {}", EffectKind::known()) })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_name_parses_back_to_its_kind() {
        for k in EffectKind::ALL {
            assert_eq!(k.as_str().parse::<EffectKind>().unwrap(), k);
        }
    }

    #[test]
    fn an_unknown_name_is_refused_naming_the_known_ones() {
        let err = "gear_wear".parse::<EffectKind>().unwrap_err().to_string();
        assert!(err.contains("gear_wear") && err.contains("viscous_friction") && err.contains("coriolis_structure"), "{err}");
    }

    #[test]
    fn units_follow_the_joint_type() {
        assert_eq!(EffectKind::ViscousFriction.unit("b", JointKind::Revolute), Some("N·m·s/rad"));
        assert_eq!(EffectKind::ViscousFriction.unit("b", JointKind::Prismatic), Some("N·s/m"));
        assert_eq!(EffectKind::CoulombFriction.unit("fc", JointKind::Prismatic), Some("N"));
        assert_eq!(EffectKind::Armature.unit("ia", JointKind::Prismatic), Some("kg"));
        assert_eq!(EffectKind::Payload.unit("mass", JointKind::Prismatic), Some("kg"));
        assert_eq!(EffectKind::TorqueGain.unit("k", JointKind::Prismatic), Some("-"));
        assert_eq!(EffectKind::TorqueGain.unit("nope", JointKind::Revolute), None);
    }
}
