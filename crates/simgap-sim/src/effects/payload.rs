//! A payload, a point mass rigidly attached to the last link of the chain
//! ([`Effect::Payload`]): it changes the last link's inertia.

use nalgebra::{Matrix3, Vector3};
use simgap_core::{Model, SpatialInertia};

use super::spelling::Spelling;
use super::{invalid, Effect, Simulated};
use crate::error::Result;
use crate::kind::EffectKind;

/// A payload's parameters: its mass and its position in the last link's frame.
pub(super) struct Payload {
    /// Mass [kg].
    pub(super) mass: f64,
    /// Position in the last link's frame [m].
    pub(super) com: [f64; 3],
}

impl Simulated for Payload {
    fn kind(&self) -> EffectKind {
        EffectKind::Payload
    }

    fn validate(&self, _dof: usize) -> Result<()> {
        if !self.mass.is_finite() || self.com.iter().any(|c| !c.is_finite()) {
            return Err(invalid(self.kind().as_str(), "mass and com must be finite".into()));
        }
        Ok(())
    }

    fn joints_acted(&self) -> Vec<usize> {
        Vec::new()
    }

    fn apply_to_model(&self, m: &mut Model) -> Result<()> {
        let last = m.dof() - 1;
        let point = SpatialInertia::from_com(self.mass, Vector3::from(self.com), Matrix3::zeros());
        let old = m.joints()[last].inertia;
        let new = SpatialInertia { mass: old.mass + point.mass, first_moment: old.first_moment + point.first_moment, rotational: old.rotational + point.rotational };
        m.set_link_inertia(last, new)?;
        Ok(())
    }
}

/// Reads `mass` (one number) and `com` (three).
pub(super) fn parse(s: &Spelling<'_>) -> Result<Effect> {
    Ok(Effect::Payload { mass: s.scalar("mass")?, com: s.triple("com")? })
}
