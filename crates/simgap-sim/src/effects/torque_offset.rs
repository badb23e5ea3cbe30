//! A torque offset, `τ_applied = τ_cmd + offset` [N·m] ([`Effect::TorqueOffset`]).

use super::spelling::Spelling;
use super::{check, nonzero, Actuator, Effect, Simulated};
use crate::error::Result;
use crate::kind::EffectKind;

/// A torque offset's parameters: the offsets [N·m or N] per joint.
pub(super) struct TorqueOffset<'a> {
    /// Offsets.
    pub(super) offset: &'a [f64],
}

impl Simulated for TorqueOffset<'_> {
    fn kind(&self) -> EffectKind {
        EffectKind::TorqueOffset
    }

    fn validate(&self, dof: usize) -> Result<()> {
        check(self.kind().as_str(), "offset", self.offset, dof, false, false)
    }

    fn joints_acted(&self) -> Vec<usize> {
        nonzero(self.offset)
    }

    fn actuate(&self, i: usize, actuator: &mut Actuator) {
        actuator.offset += self.offset[i];
    }
}

/// Reads `offset=...` (per joint).
pub(super) fn parse(s: &Spelling<'_>) -> Result<Effect> {
    Ok(Effect::TorqueOffset { offset: s.per_joint("offset")? })
}
