//! Stribeck friction, `τ += −(fc + (fs − fc) e^{−(q̇/vs)²}) tanh(q̇ / w)` (`vs ≤ 0` drops the
//! Stribeck term; `w = 0`: the exact sign) ([`Effect::StribeckFriction`]).

use super::spelling::Spelling;
use super::{check, dry_included, dry_slope, smooth_sign, Effect, Simulated, STIFF_STRIBECK_VELOCITIES, STIFF_WIDTHS};
use crate::error::Result;
use crate::kind::EffectKind;

/// A Stribeck friction's parameters, per joint: levels `fc`, `fs` [N·m or N], Stribeck
/// velocities `vs` and widths `w` of the smoothed sign [rad/s or m/s].
pub(super) struct StribeckFriction<'a> {
    /// Coulomb levels.
    pub(super) fc: &'a [f64],
    /// Static (breakaway) levels.
    pub(super) fs: &'a [f64],
    /// Stribeck velocities.
    pub(super) vs: &'a [f64],
    /// Widths of the smoothed sign, `>= 0`.
    pub(super) w: &'a [f64],
}

/// The level `fc + (fs − fc) e^{−(q̇/vs)²}` at velocity `qd` [N·m or N] (`fc` for `vs ≤ 0`).
fn level(fc: f64, fs: f64, vs: f64, qd: f64) -> f64 {
    fc + if vs > 0.0 { (fs - fc) * (-(qd / vs).powi(2)).exp() } else { 0.0 }
}

/// Bound of the slope of a Stribeck law of levels `fc`, `fs`, velocity `vs` and width `w`, its
/// dry step's slope scaled by `dry` and its hump's (`2 |fs − fc| / vs`) by `hump_scale`
/// [N·m·s/rad or N·s/m]; also the load-independent part of a load Stribeck friction's.
pub(super) fn slope(fc: f64, fs: f64, vs: f64, w: f64, dry: f64, hump_scale: f64) -> f64 {
    let hump = if vs > 0.0 { hump_scale * 2.0 * (fs - fc).abs() / vs } else { 0.0 };
    dry_slope(dry, fc.abs().max(fs.abs()), w) + hump
}

/// The speed below which a Stribeck law of velocity `vs` and width `w` is stiff [rad/s or
/// m/s]: the larger of [`STIFF_WIDTHS`] `· w` and [`STIFF_STRIBECK_VELOCITIES`] `· vs` (0 for
/// the exact sign, `w = 0`).
pub(super) fn stiff_band(vs: f64, w: f64) -> f64 {
    if w > 0.0 {
        (STIFF_WIDTHS * w).max(STIFF_STRIBECK_VELOCITIES * vs.max(0.0))
    } else {
        0.0
    }
}

impl Simulated for StribeckFriction<'_> {
    fn kind(&self) -> EffectKind {
        EffectKind::StribeckFriction
    }

    fn validate(&self, dof: usize) -> Result<()> {
        let name = self.kind().as_str();
        check(name, "fc", self.fc, dof, true, false)?;
        check(name, "fs", self.fs, dof, true, false)?;
        check(name, "vs", self.vs, dof, true, false)?;
        check(name, "w", self.w, dof, true, false)
    }

    fn joints_acted(&self) -> Vec<usize> {
        (0..self.fc.len()).filter(|&i| self.fc[i] != 0.0 || self.fs.get(i).is_some_and(|x| *x != 0.0)).collect()
    }

    fn add_friction_torque(&self, _q: &[f64], qd: &[f64], exact: bool, out: &mut [f64]) {
        let (fc, fs, vs, w) = (self.fc, self.fs, self.vs, self.w);
        for i in 0..out.len() {
            if (fc[i] == 0.0 && fs[i] == 0.0) || !dry_included(exact, w[i]) {
                continue;
            }
            out[i] -= level(fc[i], fs[i], vs[i], qd[i]) * smooth_sign(qd[i], w[i]);
        }
    }

    fn slope(&self, i: usize, dry: f64, hump_scale: f64) -> f64 {
        slope(self.fc[i], self.fs[i], self.vs[i], self.w[i], dry, hump_scale)
    }

    fn stiff_band(&self, i: usize) -> f64 {
        stiff_band(self.vs[i], self.w[i])
    }

    fn exact_dry_levels(&self, i: usize, qd: f64, _tau_drive: f64) -> (f64, f64) {
        if self.w[i] <= 0.0 {
            let level = level(self.fc[i], self.fs[i], self.vs[i], qd);
            (level, level)
        } else {
            (0.0, 0.0)
        }
    }

    fn has_exact_dry_friction(&self) -> bool {
        (0..self.fc.len()).any(|i| (self.fc[i] != 0.0 || self.fs[i] != 0.0) && self.w[i] <= 0.0)
    }
}

/// Reads `fc`, `fs`, `vs` (per joint) and the width `w` (per joint, or the caller's default).
pub(super) fn parse(s: &Spelling<'_>) -> Result<Effect> {
    Ok(Effect::StribeckFriction { fc: s.per_joint("fc")?, fs: s.per_joint("fs")?, vs: s.per_joint("vs")?, w: s.width("w")? })
}
