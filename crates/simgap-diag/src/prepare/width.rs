//! The width `w` of the smoothed sign of every dry friction, `sign(q̇) ≈ tanh(q̇ / w)`, per
//! joint from the joint type and the fit runs, in the joint's own units (rad/s, m/s).
//!
//! A width below the velocity noise is one the data cannot resolve (the noise flips the sign
//! back and forth about q̇ = 0); a width of a good share of the speed blurs a dry friction into
//! a steep viscous law. The data allow widths within
//!
//! ```text
//! lo_j = max(NOISE_MULTIPLE · σ_j, MIN_SHARE · v_j),   hi_j = max(MAX_SHARE · v_j, lo_j)
//! ```
//!
//! and the width chosen is the joint type's typical one ([`TYPICAL_REVOLUTE`],
//! [`TYPICAL_PRISMATIC`]) brought within that range: fixed, not fitted (a width fitted to the
//! torque residual trades against the viscous friction and came out 1.4 times a simulated
//! plant's, with b 13 % off), and stated in the report.
//!
//! with `σ_j` the noise of the logged velocity of joint `j` (a robust standard deviation of its
//! second difference, `1.4826 · median |Δ²q̇| / √6`: white noise of variance σ² gives Δ²q̇ of
//! variance 6σ², while a smooth motion adds only `q⃛ Δt²`) and `v_j` the RMS of its smoothed
//! velocity over the fit runs. A joint that never moves has no speed to scale by: its range is
//! [`simgap_sim::DEFAULT_COULOMB_WIDTH`] alone (no dry friction can be seen there anyway).
//!
//! The width a term carries is the column of the fit, the width the corrected model simulates
//! with and the parameter `w` the report states (chosen, so without an interval). A
//! [`DryWidth`] holds the one width as a range of one point, so that the selection's width grid
//! has a single member.

/// Multiple of the velocity noise below which the width is not searched [–].
pub(crate) const NOISE_MULTIPLE: f64 = 3.0;

/// Smallest width as a share of the joint's RMS speed [–].
pub(crate) const MIN_SHARE: f64 = 0.002;

/// Largest width as a share of the joint's RMS speed [–].
pub(crate) const MAX_SHARE: f64 = 0.05;

/// Typical width of the sign of a turning joint's dry friction [rad/s] (0.6 °/s).
pub(crate) const TYPICAL_REVOLUTE: f64 = simgap_sim::DEFAULT_COULOMB_WIDTH;

/// Typical width of the sign of a linear joint's dry friction [m/s] (2 mm/s: linear axes move
/// at a fifth of the speeds, in their units, that arms turn at).
pub(crate) const TYPICAL_PRISMATIC: f64 = 0.002;

/// The widths of a joint's dry friction the data allow [rad/s or m/s] (see `prepare/width.rs`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DryWidth {
    /// Smallest width: a few times the velocity noise, at least a small share of the speed.
    pub lo: f64,
    /// Largest width: 5 % of the joint's RMS speed (at least `lo`).
    pub hi: f64,
}

impl DryWidth {
    /// `count` widths spaced geometrically from `lo` to `hi` (one, `hi`, when they coincide or
    /// `count` is 1).
    pub fn grid(&self, count: usize) -> Vec<f64> {
        if count < 2 || !(self.hi > self.lo) {
            return vec![self.hi];
        }
        let ratio = (self.hi / self.lo).powf(1.0 / (count - 1) as f64);
        (0..count).map(|i| self.lo * ratio.powi(i as i32)).collect()
    }

    /// The geometric middle of the range, for a term that is not searched.
    pub fn mid(&self) -> f64 {
        (self.lo * self.hi).sqrt()
    }

    /// `w` brought into the range.
    pub fn clamp(&self, w: f64) -> f64 {
        w.clamp(self.lo, self.hi)
    }
}

/// The dry-friction width of each joint of types `kinds` (model order), as a one-point range:
/// the type's typical width within the range the fit runs allow (see the module docs).
pub(crate) fn dry_friction_widths(kinds: &[simgap_core::JointKind], runs: &[(Vec<f64>, &[f64])]) -> Vec<DryWidth> {
    dry_friction_ranges(kinds.len(), runs)
        .into_iter()
        .zip(kinds)
        .map(|(range, kind)| {
            let w = range.clamp(if kind.is_rotational() { TYPICAL_REVOLUTE } else { TYPICAL_PRISMATIC });
            DryWidth { lo: w, hi: w }
        })
        .collect()
}

/// The dry-friction width range of each of `n` joints (model order) from the fit runs (see the
/// module docs): per run, its logged velocities and its smoothed velocities, both row-major with
/// `n` columns.
pub(crate) fn dry_friction_ranges(n: usize, runs: &[(Vec<f64>, &[f64])]) -> Vec<DryWidth> {
    (0..n)
        .map(|j| {
            // velocity noise: robust spread of the second difference of the logged velocity
            let mut second: Vec<f64> = Vec::new();
            for (logged, _) in runs {
                let qd: Vec<f64> = logged.iter().skip(j).step_by(n).copied().collect();
                second.extend(qd.windows(3).map(|w| (w[2] - 2.0 * w[1] + w[0]).abs()).filter(|x| x.is_finite()));
            }
            let sigma = if second.is_empty() { 0.0 } else { 1.4826 * median(&mut second) / 6f64.sqrt() };
            // speed: RMS of the smoothed velocity over every run
            let (sum, count) = runs.iter().flat_map(|(_, qd)| qd.iter().skip(j).step_by(n)).fold((0.0, 0usize), |(s, c), v| (s + v * v, c + 1));
            let speed = if count > 0 { (sum / count as f64).sqrt() } else { 0.0 };
            if !(speed.is_finite() && speed > 0.0) {
                return DryWidth { lo: simgap_sim::DEFAULT_COULOMB_WIDTH, hi: simgap_sim::DEFAULT_COULOMB_WIDTH };
            }
            let lo = (NOISE_MULTIPLE * sigma).max(MIN_SHARE * speed);
            DryWidth { lo, hi: (MAX_SHARE * speed).max(lo) }
        })
        .collect()
}

fn median(v: &mut [f64]) -> f64 {
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, f64::total_cmp);
    *m
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One joint moving as `q̇ = cos t` at 400 Hz for 10 s, its logged velocity with white noise
    /// of `sigma` (a fixed pseudo-random sequence), its smoothed velocity exact.
    fn widths(sigma: f64) -> (DryWidth, f64) {
        let mut state = 12345u64;
        let (mut logged, mut smooth) = (Vec::new(), Vec::new());
        for k in 0..4000 {
            let t = k as f64 * 0.0025;
            // uniform noise of standard deviation sigma
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let u = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            logged.push(t.cos() + sigma * u * 12f64.sqrt());
            smooth.push(t.cos());
        }
        let speed = (smooth.iter().map(|x| x * x).sum::<f64>() / smooth.len() as f64).sqrt();
        (dry_friction_ranges(1, &[(logged, &smooth)])[0], speed)
    }

    #[test]
    fn the_width_range_starts_above_the_velocity_noise_within_its_speed_bounds() {
        // RMS speed of cos t over 10 s is about 0.71 rad/s: widths between 0.0014 and 0.035
        let (quiet, speed) = widths(0.0);
        assert!((quiet.lo - MIN_SHARE * speed).abs() < 1e-12 && (quiet.hi - MAX_SHARE * speed).abs() < 1e-12, "quiet {quiet:?}, speed {speed}");
        // a noise above the speed bound: the range is one width, the noise's
        let (loud, _) = widths(1.0);
        assert!(loud.lo > MAX_SHARE * speed && loud.hi == loud.lo, "loud {loud:?}");
        // 3 σ of a 0.005 rad/s noise, within 20 %
        let (noisy, _) = widths(0.005);
        assert!((noisy.lo - 0.015).abs() < 0.003 && (noisy.hi - MAX_SHARE * speed).abs() < 1e-12, "noisy {noisy:?}");
        // the grid spans the range geometrically
        let g = quiet.grid(5);
        assert!((g[0] - quiet.lo).abs() < 1e-15 && (g[4] - quiet.hi).abs() < 1e-12 && (g[2] - quiet.mid()).abs() < 1e-12, "{g:?}");
    }
}
