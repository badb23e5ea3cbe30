//! A torque saturation, `τ_applied = clamp(τ_cmd, ±limit)` [N·m]
//! ([`Effect::TorqueSaturation`]).

use super::spelling::Spelling;
use super::{check, Actuator, Effect, Simulated};
use crate::error::Result;
use crate::kind::EffectKind;

/// A torque saturation's parameters: the limits [N·m or N] per joint (`+∞` for none).
pub(super) struct TorqueSaturation<'a> {
    /// Limits (`+∞` for none).
    pub(super) limit: &'a [f64],
}

impl Simulated for TorqueSaturation<'_> {
    fn kind(&self) -> EffectKind {
        EffectKind::TorqueSaturation
    }

    fn validate(&self, dof: usize) -> Result<()> {
        check(self.kind().as_str(), "limit", self.limit, dof, true, true)
    }

    fn joints_acted(&self) -> Vec<usize> {
        self.limit.iter().enumerate().filter(|(_, x)| x.is_finite()).map(|(i, _)| i).collect()
    }

    fn actuate(&self, i: usize, actuator: &mut Actuator) {
        actuator.limit = actuator.limit.min(self.limit[i]);
    }
}

/// Reads `limit=...` (per joint, `inf` for none).
pub(super) fn parse(s: &Spelling<'_>) -> Result<Effect> {
    Ok(Effect::TorqueSaturation { limit: s.per_joint("limit")? })
}
