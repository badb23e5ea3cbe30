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
