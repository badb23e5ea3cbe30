//! `armature`: rotor inertia reflected through the gearbox, `ia_j` on the diagonal of H
//! (column `ia_j q̈_j`, ia ≥ 0).

use simgap_sim::Effect;

use super::effects::list_per_joint;
use super::{per_joint, EffectReport, TermDesign};
use crate::prepare::dataset::FitData;

/// The column of a rotor inertia on joint `j`.
pub(super) fn design(j: usize, data: &[FitData]) -> TermDesign {
    TermDesign::at_least(vec![per_joint(data, j, |d, i| d.qdd[i])], 0.0)
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
