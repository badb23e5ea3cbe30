//! The width `w` of the smoothed sign of every dry friction, `sign(q̇) ≈ tanh(q̇ / w)`, per
//! joint from the joint type and the fit runs, in the joint's own units (rad/s, m/s).
//!
//! A width of a good share of the speed blurs a dry friction into a steep viscous law; one far
//! below the speeds the runs hold is a sign the smoothed velocities cannot resolve. The width
//! chosen is the joint type's typical one ([`TYPICAL_REVOLUTE`], [`TYPICAL_PRISMATIC`]) brought
//! within
//!
//! ```text
//! lo_j = MIN_SHARE · v_j,   hi_j = MAX_SHARE · v_j
//! ```
//!
//! with `v_j` the RMS of the joint's smoothed velocity over the fit runs. It is fixed, not
//! fitted: a width fitted to the torque residual trades against the viscous friction (on the
//! demo's arm it came out 1.4 times the simulated plant's, with b 13 % off and the held-out
//! k-step error 2.7 times larger), and a floor of a few times the logged velocity's noise
//! reached 0.35 rad/s on DFKI's jittered stamps, where the fit's velocity is the smoothed one.
//! A joint that never moves has no speed to scale by: it takes the typical width.
//!
//! The width a term carries is the column of the fit, the width the corrected model simulates
//! with and the parameter `w` the report states (chosen, so without an interval). A
//! [`DryWidth`] holds the one width as a range of one point, so that the selection's width grid
//! has a single member.

/// Smallest width as a share of the joint's RMS speed [–].
pub(crate) const MIN_SHARE: f64 = 0.002;

/// Largest width as a share of the joint's RMS speed [–].
pub(crate) const MAX_SHARE: f64 = 0.05;

/// Typical width of the sign of a turning joint's dry friction [rad/s] (0.6 °/s): the
/// simulator's, so that `simgap simulate --effect` without `w` simulates the same width.
pub(crate) const TYPICAL_REVOLUTE: f64 = simgap_sim::TYPICAL_WIDTH_REVOLUTE;

/// Typical width of the sign of a linear joint's dry friction [m/s] (2 mm/s: linear axes move
/// at a fifth of the speeds, in their units, that arms turn at): the simulator's.
pub(crate) const TYPICAL_PRISMATIC: f64 = simgap_sim::TYPICAL_WIDTH_PRISMATIC;

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
/// the type's typical width within the range the fit runs' speeds allow (see the module docs).
/// `runs`: per run, its smoothed velocities, row-major with one column per joint.
pub(crate) fn dry_friction_widths(kinds: &[simgap_core::JointKind], runs: &[&[f64]]) -> Vec<DryWidth> {
    let n = kinds.len();
    kinds
        .iter()
        .enumerate()
        .map(|(j, kind)| {
            let typical = typical(*kind);
            let w = speed_range(n, j, runs).map_or(typical, |r| r.clamp(typical));
            DryWidth { lo: w, hi: w }
        })
        .collect()
}

/// The typical width of a joint of type `kind` [rad/s or m/s]: [`TYPICAL_REVOLUTE`] for a
/// turning joint, [`TYPICAL_PRISMATIC`] for a linear one.
pub(crate) fn typical(kind: simgap_core::JointKind) -> f64 {
    if kind.is_rotational() {
        TYPICAL_REVOLUTE
    } else {
        TYPICAL_PRISMATIC
    }
}

/// The widths joint `j`'s speeds allow, `[MIN_SHARE · v, MAX_SHARE · v]` with `v` the RMS of its
/// smoothed velocity over `runs` (row-major, `n` columns); none for a joint that never moves.
pub(crate) fn speed_range(n: usize, j: usize, runs: &[&[f64]]) -> Option<DryWidth> {
    let (sum, count) = runs.iter().flat_map(|qd| qd.iter().skip(j).step_by(n)).fold((0.0, 0usize), |(s, c), v| (s + v * v, c + 1));
    let speed = if count > 0 { (sum / count as f64).sqrt() } else { 0.0 };
    (speed.is_finite() && speed > 0.0).then_some(DryWidth { lo: MIN_SHARE * speed, hi: MAX_SHARE * speed })
}

#[cfg(test)]
mod tests {
    use super::*;
    use simgap_core::JointKind;

    #[test]
    fn the_width_is_the_joint_types_within_its_speed_bounds() {
        // q̇ = s cos t at 400 Hz for 10 s: RMS speed s/√2
        let run = |s: f64| -> Vec<f64> { (0..4000).map(|k| s * (k as f64 * 0.0025).cos()).collect() };
        let (slow, normal, fast) = (run(0.1), run(1.0), run(10.0));
        let w = |kind: JointKind, qd: &[f64]| dry_friction_widths(&[kind], &[qd])[0];
        // a turning joint at about 0.7 rad/s: the typical 0.01 rad/s, within [0.0014, 0.035]
        assert_eq!(w(JointKind::Revolute, &normal).lo, TYPICAL_REVOLUTE);
        // slow: at most 5 % of the speed; fast: at least 0.2 % of it
        let s = w(JointKind::Revolute, &slow);
        assert!((s.lo - MAX_SHARE * 0.1 / 2f64.sqrt()).abs() < 1e-4 && s.hi == s.lo, "{s:?}");
        let f = w(JointKind::Revolute, &fast);
        assert!((f.lo - MIN_SHARE * 10.0 / 2f64.sqrt()).abs() < 1e-3, "{f:?}");
        // a linear axis takes its own typical width; a joint at rest the typical one
        assert_eq!(w(JointKind::Prismatic, &normal).lo, TYPICAL_PRISMATIC);
        assert_eq!(w(JointKind::Revolute, &vec![0.0; 100]).lo, TYPICAL_REVOLUTE);
        // the grid of a one-point range is that point
        assert_eq!(w(JointKind::Revolute, &normal).grid(5), vec![TYPICAL_REVOLUTE]);
    }
}
