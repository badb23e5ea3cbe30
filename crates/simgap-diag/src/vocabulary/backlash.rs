//! `backlash`: free play of total width `w` between a drive and its link; the drive's torque
//! reaches the link only while the play is taken up (see `simgap_sim::Effect::Backlash`).
//!
//! Its torque on the link is no column of the residual: when the drive's torque reverses, the
//! link loses it for the time the rotor takes to cross the gap, `√(2 w ia / |τ|)`, which depends
//! on the rotor inertia `ia` being fitted and on the torque the model predicts. The term has no
//! fitted column: its width is searched on [`WIDTH_GRID`] by the k-step prediction of the fit runs
//! through the simulator (the stage `select::backlash`), where the play is integrated with the
//! drive side's own state. A joint without a rotor inertia in the set shows no play: the drive
//! side then crosses the gap at once.

use simgap_sim::Effect;

use crate::prepare::dataset::FitData;

use super::effects::{per_joint as reported, sig3, unit_of};
use super::{EffectReport, TermDesign};

/// The widths of play the search tries on a turning joint [rad]: 0.5° to 4°, doubling (a hobby
/// servo's gear train has about 1°; more than a few degrees is a broken gear, not play).
pub(crate) const WIDTH_GRID: [f64; 4] = [0.008_727, 0.017_453, 0.034_907, 0.069_813];

/// The widths of play tried on a linear axis [m]: 0.1 to 0.8 mm, doubling.
pub(crate) const WIDTH_GRID_LINEAR: [f64; 4] = [1e-4, 2e-4, 4e-4, 8e-4];

/// No fitted column (the width is searched by prediction).
pub(super) fn design() -> TermDesign {
    TermDesign::default()
}

/// The samples of the fit runs `data` (numbered over all runs, in order) during which the play
/// of width `width` on joint `j` is open, its drive side (rotor inertia `ia`) crossing the gap.
///
/// The gap opens when the torque the drive passes to the link, `λ = τ − ia q̈` (`τ` the logs'
/// commanded or servo torque, `q̈` the link's), reverses; the rotor, starting at the link's
/// speed, is then driven by `τ` alone (`ia θ̈ = τ`), and the gap closes when it has moved half
/// the width either way relative to the link, integrated sample by sample. While the gap is
/// open the link moves without the drive's torque, which a torque-residual fit would read as
/// rotor inertia, friction or a drive gain: a set holding the play is fitted without these
/// samples of the joint (see `select::scorer`).
pub(crate) fn open_samples(data: &[FitData], j: usize, width: f64, ia: f64) -> Vec<usize> {
    let mut out = Vec::new();
    if !(width > 0.0 && ia > 0.0 && ia.is_finite()) {
        return out;
    }
    let half = 0.5 * width;
    let mut first = 0;
    for d in data {
        let (n, dof) = (d.t.len(), d.dof);
        if j >= dof || d.tau.len() < n * dof || d.qdd.len() < n * dof {
            first += n;
            continue;
        }
        let lambda = |k: usize| d.tau[k * dof + j] - ia * d.qdd[k * dof + j];
        // engaged on side `side` (rotor minus link at side · w/2), or open (side 0) with the
        // rotor's position and speed relative to the link
        let mut side = if n > 0 { lambda(0).signum() } else { 1.0 };
        let (mut delta, mut rate) = (side * half, 0.0);
        for k in 0..n {
            if side != 0.0 && lambda(k) * side < 0.0 {
                side = 0.0;
                rate = 0.0;
            }
            if side == 0.0 {
                out.push(first + k);
                let dt = if k + 1 < n { d.t[k + 1] - d.t[k] } else { 0.0 };
                rate += (d.tau[k * dof + j] / ia - d.qdd[k * dof + j]) * dt;
                delta += rate * dt;
                if delta.abs() >= half {
                    side = delta.signum();
                    delta = side * half;
                }
            }
        }
        first += n;
    }
    out
}

/// Adds the play of joint `j` to the simulator's.
pub(super) fn apply(j: usize, width: f64, n: usize, out: &mut Vec<Effect>) {
    if let Effect::Backlash { width: w } = super::effects::slot(out, Effect::Backlash { width: vec![0.0; n] }) {
        w[j] = width;
    }
}

/// The play in words, in degrees as well on turning joints.
pub(super) fn describe(e: &EffectReport) -> String {
    let unit = unit_of(e, "width");
    let parts: Vec<String> = reported(e, "width")
        .iter()
        .map(|(j, w)| if unit == "rad" { format!("{} rad ({}°) on {j}", sig3(*w), sig3(w.to_degrees())) } else { format!("{} {unit} on {j}", sig3(*w)) })
        .collect();
    format!("backlash (free play between the drive and the link, its rotor crossing the gap when the torque reverses) of {}", parts.join(", "))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Fit data of the paper arm whose joint 0 has the torque `tau(t)` and the link acceleration
    /// `qdd(t)` at `n` samples of `dt`.
    fn data_with(n: usize, dt: f64, tau: impl Fn(f64) -> f64, qdd: impl Fn(f64) -> f64) -> FitData {
        use crate::check::bench::{demo_specs, generate};
        use crate::prepare::dataset::{align_run, PrepareOptions};
        use simgap_core::{Formulation, Model};
        let model = Model::paper_arm();
        let (fit, _) = demo_specs(1);
        let run = generate(&model, Formulation::EulerLagrange, &[], &fit[0], 0.0025, 1_024_000.0).unwrap();
        let mut d = FitData::new(&model, Formulation::EulerLagrange, align_run(&model, &run).unwrap(), &PrepareOptions::default()).unwrap();
        let dof = d.dof;
        d.t = (0..n).map(|k| k as f64 * dt).collect();
        d.tau = (0..n * dof).map(|i| if i % dof == 0 { tau((i / dof) as f64 * dt) } else { 0.0 }).collect();
        d.qdd = (0..n * dof).map(|i| if i % dof == 0 { qdd((i / dof) as f64 * dt) } else { 0.0 }).collect();
        d
    }

    #[test]
    fn the_gap_stays_open_for_the_time_the_rotor_takes_to_cross_it() {
        // the link at rest, the drive's torque reversing from +2 to −2 N·m at t = 0.5 s: the
        // rotor (ia = 0.01 kg·m²) crosses w = 0.02 rad in √(2 w ia / |τ|) = 14.1 ms
        let (dt, ia, w, tau) = (1e-4, 0.01, 0.02, 2.0);
        let d = data_with(10_000, dt, |t| if t < 0.5 { tau } else { -tau }, |_| 0.0);
        let open = open_samples(std::slice::from_ref(&d), 0, w, ia);
        let expected = (2.0 * w * ia / tau).sqrt();
        let seconds = open.len() as f64 * dt;
        assert!((seconds - expected).abs() < 3.0 * dt, "open {seconds} s, expected {expected} s");
        assert_eq!(open[0], 5_000, "the gap opens at the reversal");
        assert!(open.windows(2).all(|p| p[1] == p[0] + 1), "one opening");
        // no reversal, no play, or no rotor: never open
        let steady = data_with(1_000, dt, |_| tau, |_| 0.0);
        assert!(open_samples(std::slice::from_ref(&steady), 0, w, ia).is_empty());
        assert!(open_samples(std::slice::from_ref(&d), 0, 0.0, ia).is_empty());
        assert!(open_samples(std::slice::from_ref(&d), 0, w, 0.0).is_empty());
        // samples numbered over the runs, in order
        let both = open_samples(&[steady, d], 0, w, ia);
        assert_eq!(both[0], 1_000 + 5_000);
        assert_eq!(both.len(), open.len());
    }
}
