//! A joint spring, `τ += −k (q − q0)` ([`Effect::JointSpring`]).

use super::spelling::Spelling;
use super::{check, nonzero, Effect, Simulated};
use crate::error::Result;
use crate::kind::EffectKind;

/// A joint spring's parameters, per joint: stiffnesses `k` [N·m/rad or N/m] and rest
/// positions `q0` [rad or m].
pub(super) struct JointSpring<'a> {
    /// Stiffnesses.
    pub(super) k: &'a [f64],
    /// Rest positions.
    pub(super) q0: &'a [f64],
}

impl Simulated for JointSpring<'_> {
    fn kind(&self) -> EffectKind {
        EffectKind::JointSpring
    }

    fn validate(&self, dof: usize) -> Result<()> {
        let name = self.kind().as_str();
        check(name, "k", self.k, dof, true, false)?;
        check(name, "q0", self.q0, dof, false, false)
    }

    fn joints_acted(&self) -> Vec<usize> {
        nonzero(self.k)
    }

    fn add_friction_torque(&self, q: &[f64], _qd: &[f64], _exact: bool, out: &mut [f64]) {
        for i in 0..out.len() {
            out[i] -= self.k[i] * (q[i] - self.q0[i]);
        }
    }
}

/// Reads `k`, `q0` (per joint).
pub(super) fn parse(s: &Spelling<'_>) -> Result<Effect> {
    Ok(Effect::JointSpring { k: s.per_joint("k")?, q0: s.per_joint("q0")? })
}
