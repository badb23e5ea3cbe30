//! Load-dependent friction whose level at rest rises above its level in motion
//! ([`Effect::LoadStribeckFriction`], a gear train's breakaway, as in BAM's load-dependent
//! Stribeck models): `τ += −(fc + mu |τ_drive| + ((fs − fc) + (mus − mu) |τ_drive|)
//! e^{−(q̇/vs)²}) tanh(q̇ / w)`. It needs the drive's torque, which the
//! [`Stepper`](crate::step::Stepper) knows ([`drive_torque`](super::drive_torque)).

use super::load_friction::{add_smooth, exact_levels};
use super::spelling::Spelling;
use super::{check, stribeck_friction, Effect, Simulated};
use crate::error::Result;
use crate::kind::EffectKind;

/// A load Stribeck friction's parameters, per joint: levels `fc`, `fs` [N·m or N], frictions
/// per unit of drive torque `mu`, `mus` [–], Stribeck velocities `vs` and widths `w` [rad/s or
/// m/s].
pub(super) struct LoadStribeckFriction<'a> {
    /// Load-independent levels in motion.
    pub(super) fc: &'a [f64],
    /// Friction per unit of drive torque in motion.
    pub(super) mu: &'a [f64],
    /// Load-independent levels at rest.
    pub(super) fs: &'a [f64],
    /// Friction per unit of drive torque at rest.
    pub(super) mus: &'a [f64],
    /// Stribeck velocities.
    pub(super) vs: &'a [f64],
    /// Widths of the smoothed sign.
    pub(super) w: &'a [f64],
}

impl Simulated for LoadStribeckFriction<'_> {
    fn kind(&self) -> EffectKind {
        EffectKind::LoadStribeckFriction
    }

    fn validate(&self, dof: usize) -> Result<()> {
        let name = self.kind().as_str();
        check(name, "fc", self.fc, dof, true, false)?;
        check(name, "mu", self.mu, dof, true, false)?;
        check(name, "fs", self.fs, dof, true, false)?;
        check(name, "mus", self.mus, dof, true, false)?;
        check(name, "vs", self.vs, dof, true, false)?;
        check(name, "w", self.w, dof, true, false)
    }

    fn joints_acted(&self) -> Vec<usize> {
        (0..self.fc.len()).filter(|&i| [self.fc, self.mu, self.fs, self.mus].iter().any(|v| v.get(i).is_some_and(|x| *x != 0.0))).collect()
    }

    // the load-independent levels as a Stribeck friction's; the load part is bounded by the
    // simulator from the effort limits (it scales with the drive's torque)
    fn slope(&self, i: usize, dry: f64, hump_scale: f64) -> f64 {
        stribeck_friction::slope(self.fc[i], self.fs[i], self.vs[i], self.w[i], dry, hump_scale)
    }

    fn stiff_band(&self, i: usize) -> f64 {
        stribeck_friction::stiff_band(self.vs[i], self.w[i])
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

    fn load_level(&self, i: usize, qd: f64, tau_drive: f64) -> f64 {
        let (fc, mu, fs, mus, vs) = (self.fc, self.mu, self.fs, self.mus, self.vs);
        let load = tau_drive.abs();
        let rise = if vs[i] > 0.0 { (-(qd / vs[i]).powi(2)).exp() } else { 0.0 };
        fc[i] + mu[i] * load + rise * ((fs[i] - fc[i]) + (mus[i] - mu[i]) * load)
    }

    fn add_load_friction(&self, qd: &[f64], drive: &[f64], out: &mut [f64]) {
        add_smooth(self, self.w, qd, drive, out);
    }
}

/// Reads `fc`, `mu`, `fs`, `mus`, `vs` (per joint) and the width `w` (per joint, or the
/// caller's default).
pub(super) fn parse(s: &Spelling<'_>) -> Result<Effect> {
    Ok(Effect::LoadStribeckFriction { fc: s.per_joint("fc")?, mu: s.per_joint("mu")?, fs: s.per_joint("fs")?, mus: s.per_joint("mus")?, vs: s.per_joint("vs")?, w: s.width("w")? })
}
