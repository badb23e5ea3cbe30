//! Wrong link parameters ([`Effect::InertialError`]): each link listed becomes `old + delta`,
//! mass `m + Δm`, centre of mass `c + Δc`, rotational inertia about the new centre of mass
//! `I_c + ΔI`.

use nalgebra::{Matrix3, Vector3};
use simgap_core::{Model, SpatialInertia};

use super::spelling::Spelling;
use super::{invalid, Effect, Simulated};
use crate::error::Result;
use crate::kind::EffectKind;

/// The parameters the command line spells an inertial error with: the link by its joint, and
/// its deltas as `mass`, `com`, `inertia` (the spellings of one link's change).
pub(super) const SPELLED: &[&str] = &["joint", "mass", "com", "inertia"];

/// A change to one link's inertia: `new = old + delta` (see [`Effect::InertialError`]).
#[derive(Clone, Debug, PartialEq)]
pub struct LinkDelta {
    /// Index of the joint whose child link changes (model order).
    pub joint: usize,
    /// Added mass [kg].
    pub mass: f64,
    /// Displacement of the centre of mass, in the link frame [m].
    pub com: [f64; 3],
    /// Added rotational inertia about the (new) centre of mass, `ixx ixy ixz iyy iyz izz`
    /// [kg·m²], in the link frame.
    pub inertia: [f64; 6],
}

/// An inertial error's parameters: one delta per changed link.
pub(super) struct InertialError<'a> {
    /// One entry per changed link.
    pub(super) deltas: &'a [LinkDelta],
}

impl Simulated for InertialError<'_> {
    fn kind(&self) -> EffectKind {
        EffectKind::InertialError
    }

    fn validate(&self, dof: usize) -> Result<()> {
        let name = self.kind().as_str();
        for d in self.deltas {
            if d.joint >= dof {
                return Err(invalid(name, format!("link delta for joint {}; the model has {dof} joints", d.joint)));
            }
            if !d.mass.is_finite() || d.com.iter().chain(d.inertia.iter()).any(|x| !x.is_finite()) {
                return Err(invalid(name, format!("link delta for joint {} has a non-finite number", d.joint)));
            }
        }
        Ok(())
    }

    fn joints_acted(&self) -> Vec<usize> {
        let mut j: Vec<usize> = self.deltas.iter().map(|d| d.joint).collect();
        j.sort_unstable();
        j.dedup();
        j
    }

    fn apply_to_model(&self, m: &mut Model) -> Result<()> {
        for d in self.deltas {
            let old = m.joints()[d.joint].inertia;
            let [ixx, ixy, ixz, iyy, iyz, izz] = d.inertia;
            let di = Matrix3::new(ixx, ixy, ixz, ixy, iyy, iyz, ixz, iyz, izz);
            let new_mass = old.mass + d.mass;
            let new_com = old.com() + Vector3::from(d.com);
            let new = SpatialInertia::from_com(new_mass, new_com, old.inertia_about_com() + di);
            m.set_link_inertia(d.joint, new)?;
        }
        Ok(())
    }
}

/// Reads one link's change: `joint` (an index), and `mass`, `com`, `inertia` (6 numbers),
/// each 0 when left out.
pub(super) fn parse(s: &Spelling<'_>) -> Result<Effect> {
    let joint = s.scalar("joint")?;
    if joint < 0.0 || joint.fract() != 0.0 {
        return Err(invalid(s.name(), format!("joint = {joint}; expected a joint index")));
    }
    let inertia = match s.get("inertia") {
        Ok(v) => <[f64; 6]>::try_from(v.as_slice()).map_err(|_| invalid(s.name(), format!("parameter 'inertia' takes 6 numbers, got {}", v.len())))?,
        Err(_) => [0.0; 6],
    };
    let delta = LinkDelta { joint: joint as usize, mass: s.scalar("mass").unwrap_or(0.0), com: s.triple("com").unwrap_or([0.0; 3]), inertia };
    Ok(Effect::InertialError { deltas: vec![delta] })
}
