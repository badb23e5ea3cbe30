//! A torque gain, `τ_applied = k τ_cmd` [–] ([`Effect::TorqueGain`]).

use super::spelling::Spelling;
use super::{check, Actuator, Effect, Simulated};
use crate::error::Result;
use crate::kind::EffectKind;

/// A torque gain's parameters: the gains `k` [–] per joint (1 is neutral).
pub(super) struct TorqueGain<'a> {
    /// Gains.
    pub(super) k: &'a [f64],
}

impl Simulated for TorqueGain<'_> {
    fn kind(&self) -> EffectKind {
        EffectKind::TorqueGain
    }

    fn validate(&self, dof: usize) -> Result<()> {
        check(self.kind().as_str(), "k", self.k, dof, false, false)
    }

    fn joints_acted(&self) -> Vec<usize> {
        self.k.iter().enumerate().filter(|(_, x)| **x != 1.0).map(|(i, _)| i).collect()
    }

    fn actuate(&self, i: usize, actuator: &mut Actuator) {
        actuator.k *= self.k[i];
    }
}

/// Reads `k=...` (per joint).
pub(super) fn parse(s: &Spelling<'_>) -> Result<Effect> {
    Ok(Effect::TorqueGain { k: s.per_joint("k")? })
}
