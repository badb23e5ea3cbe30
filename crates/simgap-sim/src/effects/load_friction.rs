//! Dry friction that grows with the torque the drive applies through its gearbox
//! ([`Effect::LoadFriction`]): `τ += −(fc + mu |τ_drive|) tanh(q̇ / w)` (`w = 0`: the exact
//! sign, integrated as stick–slip). It needs the drive's torque, which the
//! [`Stepper`](crate::step::Stepper) knows ([`drive_torque`](super::drive_torque)).

use super::spelling::Spelling;
use super::{check, dry_slope, dry_stiff_band, smooth_sign, Effect, Simulated};
use crate::error::Result;
use crate::kind::EffectKind;

/// A load friction's parameters, per joint: levels `fc` [N·m or N], friction per unit of
/// drive torque `mu` [–] and widths `w` [rad/s or m/s].
pub(super) struct LoadFriction<'a> {
    /// Load-independent levels.
    pub(super) fc: &'a [f64],
    /// Friction per unit of drive torque.
    pub(super) mu: &'a [f64],
    /// Widths of the smoothed sign.
    pub(super) w: &'a [f64],
}

/// The levels forward and back on joint `i` of a load-dependent friction `e` of widths `w`
/// where the width is 0 (the exact sign), `e`'s [`Simulated::load_level`] [N·m or N].
pub(super) fn exact_levels(e: &impl Simulated, w: &[f64], i: usize, qd: f64, tau_drive: f64) -> (f64, f64) {
    if w[i] <= 0.0 {
        let level = e.load_level(i, qd, tau_drive);
        (level, level)
    } else {
        (0.0, 0.0)
    }
}

/// Adds the smooth (`w > 0`) part of a load-dependent friction `e` of widths `w` to `out`:
/// `−level tanh(q̇/w)` with `e`'s [`Simulated::load_level`] at the drive torque `drive` [N·m or N].
pub(super) fn add_smooth(e: &impl Simulated, w: &[f64], qd: &[f64], drive: &[f64], out: &mut [f64]) {
    for i in 0..out.len() {
        if w[i] > 0.0 {
            let level = e.load_level(i, qd[i], drive[i]);
            if level != 0.0 {
                out[i] -= level * smooth_sign(qd[i], w[i]);
            }
        }
    }
}

impl Simulated for LoadFriction<'_> {
    fn kind(&self) -> EffectKind {
        EffectKind::LoadFriction
    }

    fn validate(&self, dof: usize) -> Result<()> {
        let name = self.kind().as_str();
        check(name, "fc", self.fc, dof, true, false)?;
        check(name, "mu", self.mu, dof, true, false)?;
        check(name, "w", self.w, dof, true, false)
    }

    fn joints_acted(&self) -> Vec<usize> {
        (0..self.fc.len()).filter(|&i| self.fc[i] != 0.0 || self.mu.get(i).is_some_and(|x| *x != 0.0)).collect()
    }

    // the load-independent level; the load part is bounded by the simulator from the effort
    // limits (it scales with the drive's torque)
    fn slope(&self, i: usize, dry: f64, _hump_scale: f64) -> f64 {
        dry_slope(dry, self.fc[i].abs(), self.w[i])
    }

    fn stiff_band(&self, i: usize) -> f64 {
        dry_stiff_band(self.w[i])
    }

    fn exact_dry_levels(&self, i: usize, qd: f64, tau_drive: f64) -> (f64, f64) {
        exact_levels(self, self.w, i, qd, tau_drive)
    }

    fn has_exact_dry_friction(&self) -> bool {
        self.joints_acted().iter().any(|&i| self.w[i] <= 0.0)
    }

    fn acts_through_drive(&self) -> bool {
        true
    }

    fn load_level(&self, i: usize, _qd: f64, tau_drive: f64) -> f64 {
        self.fc[i] + self.mu[i] * tau_drive.abs()
    }

    fn add_load_friction(&self, qd: &[f64], drive: &[f64], out: &mut [f64]) {
        add_smooth(self, self.w, qd, drive, out);
    }
}

/// Reads `fc`, `mu` (per joint) and the width `w` (per joint, or the caller's default).
pub(super) fn parse(s: &Spelling<'_>) -> Result<Effect> {
    Ok(Effect::LoadFriction { fc: s.per_joint("fc")?, mu: s.per_joint("mu")?, w: s.width("w")? })
}
