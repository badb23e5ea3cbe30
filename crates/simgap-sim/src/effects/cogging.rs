//! Cogging, `τ += −A sin(N q)` ([`Effect::Cogging`]).

use super::spelling::Spelling;
use super::{check, nonzero, Effect, Simulated};
use crate::error::Result;
use crate::kind::EffectKind;

/// A cogging's parameters, per joint: amplitudes `A` [N·m or N] and periods per revolution
/// `N` [–].
pub(super) struct Cogging<'a> {
    /// Amplitudes A.
    pub(super) amplitude: &'a [f64],
    /// Periods per revolution N.
    pub(super) periods_per_rev: &'a [f64],
}

impl Simulated for Cogging<'_> {
    fn kind(&self) -> EffectKind {
        EffectKind::Cogging
    }

    fn validate(&self, dof: usize) -> Result<()> {
        let name = self.kind().as_str();
        check(name, "amplitude", self.amplitude, dof, false, false)?;
        check(name, "periods_per_rev", self.periods_per_rev, dof, false, false)
    }

    fn joints_acted(&self) -> Vec<usize> {
        nonzero(self.amplitude)
    }

    fn add_friction_torque(&self, q: &[f64], _qd: &[f64], _exact: bool, out: &mut [f64]) {
        for i in 0..out.len() {
            if self.amplitude[i] != 0.0 {
                out[i] -= self.amplitude[i] * (self.periods_per_rev[i] * q[i]).sin();
            }
        }
    }
}

/// Reads `amplitude`, `periods_per_rev` (per joint).
pub(super) fn parse(s: &Spelling<'_>) -> Result<Effect> {
    Ok(Effect::Cogging { amplitude: s.per_joint("amplitude")?, periods_per_rev: s.per_joint("periods_per_rev")? })
}
