//! Backlash: free play of total width `width` [rad or m] between the drive and the link
//! ([`Effect::Backlash`]). The hidden state of the drive's side and its impacts are integrated by
//! the stepper (see [`crate::backlash`]); this file holds the parameters.

use super::spelling::Spelling;
use super::{check, nonzero, Effect, Simulated};
use crate::error::Result;
use crate::kind::EffectKind;

/// A backlash's parameters: the total widths of the play [rad or m] per joint.
pub(super) struct Backlash<'a> {
    /// Total widths, `>= 0`.
    pub(super) width: &'a [f64],
}

impl Simulated for Backlash<'_> {
    fn kind(&self) -> EffectKind {
        EffectKind::Backlash
    }

    fn validate(&self, dof: usize) -> Result<()> {
        check(self.kind().as_str(), "width", self.width, dof, true, false)
    }

    fn joints_acted(&self) -> Vec<usize> {
        nonzero(self.width)
    }

    fn add_backlash(&self, out: &mut [f64]) {
        for (o, x) in out.iter_mut().zip(self.width) {
            *o += x;
        }
    }
}

/// Reads `width=...` (per joint).
pub(super) fn parse(s: &Spelling<'_>) -> Result<Effect> {
    Ok(Effect::Backlash { width: s.per_joint("width")? })
}
