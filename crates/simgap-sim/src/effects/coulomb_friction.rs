//! Coulomb friction, `τ += −fc tanh(q̇ / w)` (`w = 0`: the exact sign)
//! ([`Effect::CoulombFriction`]).

use super::spelling::Spelling;
use super::{check, dry_included, dry_slope, dry_stiff_band, nonzero, smooth_sign, Effect, Simulated};
use crate::error::Result;
use crate::kind::EffectKind;

/// A Coulomb friction's parameters, per joint: levels `fc` [N·m or N] and widths `w` of the
/// smoothed sign [rad/s or m/s].
pub(super) struct CoulombFriction<'a> {
    /// Coulomb levels.
    pub(super) fc: &'a [f64],
    /// Widths of the smoothed sign, `>= 0`.
    pub(super) w: &'a [f64],
}

impl Simulated for CoulombFriction<'_> {
    fn kind(&self) -> EffectKind {
        EffectKind::CoulombFriction
    }

    fn validate(&self, dof: usize) -> Result<()> {
        let name = self.kind().as_str();
        check(name, "fc", self.fc, dof, true, false)?;
        check(name, "w", self.w, dof, true, false)
    }

    fn joints_acted(&self) -> Vec<usize> {
        nonzero(self.fc)
    }

    fn add_friction_torque(&self, _q: &[f64], qd: &[f64], exact: bool, out: &mut [f64]) {
        let (fc, w) = (self.fc, self.w);
        for i in 0..out.len() {
            if fc[i] != 0.0 && dry_included(exact, w[i]) {
                out[i] -= fc[i] * smooth_sign(qd[i], w[i]);
            }
        }
    }

    fn slope(&self, i: usize, dry: f64, _hump_scale: f64) -> f64 {
        dry_slope(dry, self.fc[i].abs(), self.w[i])
    }

    fn stiff_band(&self, i: usize) -> f64 {
        dry_stiff_band(self.w[i])
    }

    fn exact_dry_levels(&self, i: usize, _qd: f64, _tau_drive: f64) -> (f64, f64) {
        if self.w[i] <= 0.0 {
            (self.fc[i], self.fc[i])
        } else {
            (0.0, 0.0)
        }
    }

    fn has_exact_dry_friction(&self) -> bool {
        self.fc.iter().zip(self.w).any(|(f, w)| *f != 0.0 && *w <= 0.0)
    }
}

/// Reads `fc=...` (per joint) and the width `w` (per joint, or the caller's default).
pub(super) fn parse(s: &Spelling<'_>) -> Result<Effect> {
    Ok(Effect::CoulombFriction { fc: s.per_joint("fc")?, w: s.width("w")? })
}
