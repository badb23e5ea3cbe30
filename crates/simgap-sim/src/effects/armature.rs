//! Armature, the rotor inertia `ia` [kg·m²] added to the diagonal of H ([`Effect::Armature`]).

use super::spelling::Spelling;
use super::{check, nonzero, Effect, Simulated};
use crate::error::Result;
use crate::kind::EffectKind;

/// An armature's parameters: the reflected rotor inertias `ia` [kg·m² or kg] per joint.
pub(super) struct Armature<'a> {
    /// Reflected rotor inertias.
    pub(super) ia: &'a [f64],
}

impl Simulated for Armature<'_> {
    fn kind(&self) -> EffectKind {
        EffectKind::Armature
    }

    fn validate(&self, dof: usize) -> Result<()> {
        check(self.kind().as_str(), "ia", self.ia, dof, false, false)
    }

    fn joints_acted(&self) -> Vec<usize> {
        nonzero(self.ia)
    }

    fn add_armature(&self, out: &mut [f64]) {
        for i in 0..out.len() {
            out[i] += self.ia[i];
        }
    }
}

/// Reads `ia=...` (per joint).
pub(super) fn parse(s: &Spelling<'_>) -> Result<Effect> {
    Ok(Effect::Armature { ia: s.per_joint("ia")? })
}
