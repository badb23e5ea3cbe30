//! Back-EMF, `τ += −kb q̇` while the drive is enabled ([`Effect::BackEmf`]): absent with
//! torque off, which tells it from viscous friction. It is part of the drive's torque, which
//! the [`Stepper`](crate::step::Stepper) evaluates ([`drive_torque`](super::drive_torque)).

use super::spelling::Spelling;
use super::{check, nonzero, Effect, Simulated};
use crate::error::Result;
use crate::kind::EffectKind;

/// A back-EMF's parameters: the coefficients `kb` [N·m·s/rad or N·s/m] per joint.
pub(super) struct BackEmf<'a> {
    /// Back-EMF coefficients.
    pub(super) kb: &'a [f64],
}

impl Simulated for BackEmf<'_> {
    fn kind(&self) -> EffectKind {
        EffectKind::BackEmf
    }

    fn validate(&self, dof: usize) -> Result<()> {
        check(self.kind().as_str(), "kb", self.kb, dof, false, false)
    }

    fn joints_acted(&self) -> Vec<usize> {
        nonzero(self.kb)
    }

    fn slope(&self, i: usize, _dry: f64, _hump_scale: f64) -> f64 {
        self.kb[i].abs()
    }

    fn acts_through_drive(&self) -> bool {
        true
    }

    fn add_drive_torque(&self, qd: &[f64], drive: &mut [f64]) {
        for i in 0..drive.len() {
            drive[i] -= self.kb[i] * qd[i];
        }
    }
}

/// Reads `kb=...` (per joint).
pub(super) fn parse(s: &Spelling<'_>) -> Result<Effect> {
    Ok(Effect::BackEmf { kb: s.per_joint("kb")? })
}
