//! An encoder offset: the joint's measured zero is not the model's, the joint is at
//! `q_measured + offset` [rad or m] ([`Effect::EncoderOffset`]).
//!
//! The simulator's state, its controller and its log are in measured positions (what the
//! encoder reads); the plant evaluates the rigid-body terms `H`, `C q̇` and `g` at the true
//! position `q + offset` ([`Plant`](crate::plant::Plant)). The other effects that depend on the
//! position (a spring's rest position, cogging's phase) are stated in measured positions.

use super::spelling::Spelling;
use super::{check, nonzero, Effect, Simulated};
use crate::error::Result;
use crate::kind::EffectKind;

/// An encoder offset's parameters: the offsets [rad or m] per joint.
pub(super) struct EncoderOffset<'a> {
    /// Offsets: true position minus measured position.
    pub(super) offset: &'a [f64],
}

impl Simulated for EncoderOffset<'_> {
    fn kind(&self) -> EffectKind {
        EffectKind::EncoderOffset
    }

    fn validate(&self, dof: usize) -> Result<()> {
        check(self.kind().as_str(), "offset", self.offset, dof, false, false)
    }

    fn joints_acted(&self) -> Vec<usize> {
        nonzero(self.offset)
    }

    fn add_encoder_offset(&self, out: &mut [f64]) {
        for (o, x) in out.iter_mut().zip(self.offset) {
            *o += x;
        }
    }
}

/// Reads `offset=...` (per joint).
pub(super) fn parse(s: &Spelling<'_>) -> Result<Effect> {
    Ok(Effect::EncoderOffset { offset: s.per_joint("offset")? })
}
