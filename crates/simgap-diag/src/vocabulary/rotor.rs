//! `armature`: rotor inertia reflected through the gearbox, `ia_j` on the diagonal of H
//! (column `ia_j q̈_j`).
//!
//! Physical range: `0 ≤ ia_j ≤ ARMATURE_MAX_RATIO · max H_jj`, the largest link inertia the
//! joint moves over the fit runs. Reflected rotor inertias of geared arms reach tens of times
//! the wrist's link inertia (a rotor of 1e-5 kg·m² through a 100:1 gearbox is 0.1 kg·m²); an
//! armature a hundred times the link inertia freezes the joint rather than explaining it, and
//! one fitted at that edge is no finding (see [`crate::select::plausible`]). Where the effort is
//! measured on the link side of the gearbox ([`crate::PrepareOptions::link_side_torque`]) the
//! range is empty: the rotor is driven before the sensor, and no rotor inertia is tried.

use simgap_sim::Effect;

use super::effects::list_per_joint;
use super::{per_joint, EffectReport, TermDesign};
use crate::prepare::dataset::FitData;

/// Largest plausible rotor inertia as a multiple of the link inertia its joint moves.
pub(crate) const ARMATURE_MAX_RATIO: f64 = 100.0;

/// Whether the fit runs `data` can show a rotor inertia: not where their effort was measured on
/// the link side of the gearbox, after the rotor.
pub(crate) fn visible(data: &[FitData]) -> bool {
    !data.iter().any(|d| d.link_side_torque)
}

/// The rotor inertia on joint `j` [kg·m² or kg] of the set `terms` (with their `designs`)
/// fitted at coefficients `theta`; `None` where the set holds no rotor inertia there.
pub(crate) fn fitted(terms: &[super::Term], designs: &[TermDesign], theta: &nalgebra::DVector<f64>, j: usize) -> Option<f64> {
    let i = terms.iter().position(|t| *t == super::Term::Armature(j))?;
    theta.get(TermDesign::first_column(designs, i)).copied()
}

/// The column of a rotor inertia on joint `j`, bounded by its physical range.
pub(super) fn design(j: usize, data: &[FitData]) -> TermDesign {
    let h_max = data.iter().map(|d| d.h_max[j]).fold(0.0f64, f64::max);
    let hi = if h_max > 0.0 { ARMATURE_MAX_RATIO * h_max } else { f64::INFINITY };
    TermDesign { cols: vec![per_joint(data, j, |d, i| d.qdd[i])], lo: vec![0.0], hi: vec![hi], ..Default::default() }
}

/// A rotor inertia is not negative.
pub(super) fn physical(theta: &[f64]) -> bool {
    theta[0] >= -1e-12
}

/// Adds the rotor inertia of joint `j` to the simulator's armature.
pub(super) fn apply(j: usize, theta: &[f64], n: usize, out: &mut Vec<Effect>) {
    if let Effect::Armature { ia } = super::effects::slot(out, Effect::Armature { ia: vec![0.0; n] }) {
        ia[j] = theta[0];
    }
}

/// The rotor inertia in words.
pub(super) fn describe(e: &EffectReport) -> String {
    format!("rotor inertia (armature) {}", list_per_joint(e, "ia"))
}
