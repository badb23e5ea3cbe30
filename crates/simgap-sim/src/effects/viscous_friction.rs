//! Viscous friction, `τ += −b q̇` ([`Effect::ViscousFriction`]).

use super::spelling::Spelling;
use super::{check, nonzero, Effect, Simulated};
use crate::error::Result;
use crate::kind::EffectKind;

/// A viscous friction's parameters: `b` [N·m·s/rad or N·s/m] per joint.
pub(super) struct ViscousFriction<'a> {
    /// Viscous coefficients.
    pub(super) b: &'a [f64],
}

impl Simulated for ViscousFriction<'_> {
    fn kind(&self) -> EffectKind {
        EffectKind::ViscousFriction
    }

    fn validate(&self, dof: usize) -> Result<()> {
        check(self.kind().as_str(), "b", self.b, dof, true, false)
    }

    fn joints_acted(&self) -> Vec<usize> {
        nonzero(self.b)
    }

    fn add_friction_torque(&self, _q: &[f64], qd: &[f64], _exact: bool, out: &mut [f64]) {
        for i in 0..out.len() {
            out[i] -= self.b[i] * qd[i];
        }
    }

    fn slope(&self, i: usize, _dry: f64, _hump_scale: f64) -> f64 {
        self.b[i].abs()
    }
}

/// Reads `b=...` (per joint).
pub(super) fn parse(s: &Spelling<'_>) -> Result<Effect> {
    Ok(Effect::ViscousFriction { b: s.per_joint("b")? })
}
