//! Friction that differs with the direction of motion ([`Effect::DirectionalFriction`]):
//! `τ += −s⁺ (fc_pos + b_pos q̇) + s⁻ (fc_neg − b_neg q̇)` with `s± = (1 ± tanh(q̇ / w)) / 2`
//! (`w = 0`: the exact sign).

use super::spelling::Spelling;
use super::{check, dry_included, dry_slope, dry_stiff_band, smooth_sign, Effect, Simulated};
use crate::error::Result;
use crate::kind::EffectKind;

/// A directional friction's parameters, per joint: dry levels `fc_pos`, `fc_neg` [N·m or N],
/// viscous coefficients `b_pos`, `b_neg` [N·m·s/rad or N·s/m] and widths `w` [rad/s or m/s].
pub(super) struct DirectionalFriction<'a> {
    /// Dry friction levels moving forward (q̇ > 0).
    pub(super) fc_pos: &'a [f64],
    /// Dry friction levels moving back (q̇ < 0).
    pub(super) fc_neg: &'a [f64],
    /// Viscous coefficients moving forward.
    pub(super) b_pos: &'a [f64],
    /// Viscous coefficients moving back.
    pub(super) b_neg: &'a [f64],
    /// Widths of the smoothed sign.
    pub(super) w: &'a [f64],
}

impl Simulated for DirectionalFriction<'_> {
    fn kind(&self) -> EffectKind {
        EffectKind::DirectionalFriction
    }

    fn validate(&self, dof: usize) -> Result<()> {
        let name = self.kind().as_str();
        check(name, "fc_pos", self.fc_pos, dof, true, false)?;
        check(name, "fc_neg", self.fc_neg, dof, true, false)?;
        check(name, "b_pos", self.b_pos, dof, true, false)?;
        check(name, "b_neg", self.b_neg, dof, true, false)?;
        check(name, "w", self.w, dof, true, false)
    }

    fn joints_acted(&self) -> Vec<usize> {
        (0..self.fc_pos.len()).filter(|&i| [self.fc_pos, self.fc_neg, self.b_pos, self.b_neg].iter().any(|v| v.get(i).is_some_and(|x| *x != 0.0))).collect()
    }

    fn add_friction_torque(&self, _q: &[f64], qd: &[f64], exact: bool, out: &mut [f64]) {
        for i in 0..out.len() {
            let s = smooth_sign(qd[i], self.w[i]);
            let (pos, neg) = (0.5 * (1.0 + s), 0.5 * (1.0 - s));
            // at w = 0 without `exact` only the viscous parts (continuous at rest)
            let (fp, fn_) = if dry_included(exact, self.w[i]) { (self.fc_pos[i], self.fc_neg[i]) } else { (0.0, 0.0) };
            out[i] += -pos * (fp + self.b_pos[i] * qd[i]) + neg * (fn_ - self.b_neg[i] * qd[i]);
        }
    }

    // the viscous parts, the dry step (fc_pos + fc_neg) / 2 over w, and the switch between the
    // viscous slopes (|Δb| q̇ sech²(q̇/w) / 2w ≤ 0.23 |Δb|)
    fn slope(&self, i: usize, dry: f64, _hump_scale: f64) -> f64 {
        let (b_pos, b_neg) = (self.b_pos[i], self.b_neg[i]);
        b_pos.abs().max(b_neg.abs()) + dry_slope(dry, 0.5 * (self.fc_pos[i].abs() + self.fc_neg[i].abs()), self.w[i]) + 0.25 * (b_pos - b_neg).abs()
    }

    fn stiff_band(&self, i: usize) -> f64 {
        dry_stiff_band(self.w[i])
    }

    fn exact_dry_levels(&self, i: usize, _qd: f64, _tau_drive: f64) -> (f64, f64) {
        if self.w[i] <= 0.0 {
            (self.fc_pos[i], self.fc_neg[i])
        } else {
            (0.0, 0.0)
        }
    }

    fn has_exact_dry_friction(&self) -> bool {
        (0..self.w.len()).any(|i| (self.fc_pos[i] != 0.0 || self.fc_neg[i] != 0.0) && self.w[i] <= 0.0)
    }
}

/// Reads `fc_pos`, `fc_neg`, `b_pos`, `b_neg` (per joint) and the width `w` (per joint, or the
/// caller's default).
pub(super) fn parse(s: &Spelling<'_>) -> Result<Effect> {
    Ok(Effect::DirectionalFriction { fc_pos: s.per_joint("fc_pos")?, fc_neg: s.per_joint("fc_neg")?, b_pos: s.per_joint("b_pos")?, b_neg: s.per_joint("b_neg")?, w: s.width("w")? })
}
