//! The parser of an effect's command-line spelling, `name[:param=v1,v2,...[;param=...]]`
//! ([`Effect::parse`]): the name read as its [`EffectKind`], then each effect's file reads its
//! own parameters.

use simgap_core::Model;

use super::spelling::Spelling;
use super::{
    armature, back_emf, backlash, cogging, coriolis_structure, coulomb_friction, directional_friction, encoder_offset, inertial_error, joint_spring, load_friction,
    load_stribeck_friction, payload, stribeck_friction, time_delay, torque_gain, torque_offset, torque_saturation, typical_width, viscous_friction, Effect, DEFAULT_COULOMB_WIDTH,
};
use crate::error::Result;
use crate::kind::EffectKind;

impl Effect {
    /// Parses the command-line spelling `name[:param=v1,v2,...[;param=...]]`, e.g.
    /// `viscous_friction:b=2.288,0.175`, `stribeck_friction:fc=1,1;fs=2,2;vs=0.1,0.1`,
    /// `payload:mass=0.5;com=0,0,-0.1`, `time_delay:delay=0.005`, `coriolis_structure`,
    /// `inertial_error:joint=1;mass=0.2;com=0,0,0.01;inertia=0,0,0,0,0,0`.
    /// Per-joint parameters take one value per joint (`dof` values), or a single value used for
    /// every joint. A dry friction's width `w` [rad/s or m/s] may be given
    /// (`coulomb_friction:fc=7.17,1.734;w=0.01,0.02`); left out, it is
    /// [`DEFAULT_COULOMB_WIDTH`] on every joint (with the model known, use
    /// [`Effect::parse_for_model`]: the joint type's typical width).
    ///
    /// # Errors
    /// [`Error::Invalid`] for an unknown name, a missing or unknown parameter, or a bad number.
    pub fn parse(spec: &str, dof: usize) -> Result<Effect> {
        Effect::parse_with_width(spec, dof, DEFAULT_COULOMB_WIDTH)
    }

    /// [`Effect::parse`], with `default_w` [rad/s or m/s] the width `w` of a dry friction whose
    /// spelling leaves it out (e.g. the Python `simulate(..., coulomb_width=...)`).
    ///
    /// # Errors
    /// As [`Effect::parse`]; also [`Error::Invalid`] for a `default_w` that is needed and is not
    /// a finite number `>= 0`.
    pub fn parse_with_width(spec: &str, dof: usize, default_w: f64) -> Result<Effect> {
        if !(default_w.is_finite() && default_w >= 0.0) {
            // refused only where a dry friction needs it (below)
            return Effect::parse_with_widths(spec, dof, &[default_w]);
        }
        Effect::parse_with_widths(spec, dof, &vec![default_w; dof])
    }

    /// [`Effect::parse`] for `model`'s joints: a dry friction whose spelling leaves `w` out
    /// gets each joint type's typical width ([`typical_width`]: 0.01 rad/s on a revolute
    /// joint, 0.002 m/s on a prismatic one), the width the diagnosis starts from. This is how
    /// `simgap simulate --effect` and `simgap predict --effect` read their effects.
    ///
    /// # Errors
    /// As [`Effect::parse`].
    pub fn parse_for_model(spec: &str, model: &Model) -> Result<Effect> {
        let widths: Vec<f64> = model.joints().iter().map(|j| typical_width(j.kind)).collect();
        Effect::parse_with_widths(spec, model.dof(), &widths)
    }

    /// The parser: `default_w` the widths of a dry friction whose spelling leaves `w` out, one
    /// per joint (or a single value, refused as not a width where one is needed).
    fn parse_with_widths(spec: &str, dof: usize, default_w: &[f64]) -> Result<Effect> {
        let (name, rest) = match spec.split_once(':') {
            Some((n, r)) => (n.trim(), r.trim()),
            None => (spec.trim(), ""),
        };
        let kind: EffectKind = name.parse()?;
        let s = Spelling::read(name, rest, dof, default_w)?;
        // the command line names the inertial error's link by its joint, and its deltas as
        // `mass`, `com`, `inertia`: the spellings of one link's change
        let known: Vec<&str> = match kind {
            EffectKind::InertialError => inertial_error::SPELLED.to_vec(),
            k => k.parameters().iter().map(|p| p.name).collect(),
        };
        s.only(&known)?;
        // each effect's file reads its own parameters
        let effect = match kind {
            EffectKind::ViscousFriction => viscous_friction::parse(&s)?,
            EffectKind::CoulombFriction => coulomb_friction::parse(&s)?,
            EffectKind::StribeckFriction => stribeck_friction::parse(&s)?,
            EffectKind::Armature => armature::parse(&s)?,
            EffectKind::Payload => payload::parse(&s)?,
            EffectKind::InertialError => inertial_error::parse(&s)?,
            EffectKind::TorqueGain => torque_gain::parse(&s)?,
            EffectKind::TorqueOffset => torque_offset::parse(&s)?,
            EffectKind::TorqueSaturation => torque_saturation::parse(&s)?,
            EffectKind::TimeDelay => time_delay::parse(&s)?,
            EffectKind::Cogging => cogging::parse(&s)?,
            EffectKind::CoriolisStructure => coriolis_structure::parse(&s)?,
            EffectKind::JointSpring => joint_spring::parse(&s)?,
            EffectKind::DirectionalFriction => directional_friction::parse(&s)?,
            EffectKind::LoadFriction => load_friction::parse(&s)?,
            EffectKind::LoadStribeckFriction => load_stribeck_friction::parse(&s)?,
            EffectKind::BackEmf => back_emf::parse(&s)?,
            EffectKind::EncoderOffset => encoder_offset::parse(&s)?,
            EffectKind::Backlash => backlash::parse(&s)?,
        };
        effect.validate(dof)?;
        Ok(effect)
    }
}
