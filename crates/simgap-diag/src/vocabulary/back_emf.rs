//! `back_emf`: the voltage a spinning motor induces, `−kb q̇` while the drive is enabled
//! (absent with torque off: the bridge is open). A servo's own motor law holds `kt²/R` of it;
//! this term is what the logs show beyond (or short of) that.
//!
//! The residual holds `kb en_j q̇_j` (column `en q̇`, `en` the drive's enable, filtered like the
//! torque as viscous friction's column is: [`FitData::enabled_qd`]); with the drive
//! never disabled it is viscous friction's column, so the term is a candidate only on joints
//! whose drive some fit run disables. Physical range: the total back-EMF stays ≥ 0, so `kb ≥
//! −kt²/R` of the servo's nominal law (≥ 0 on another drive).

use simgap_sim::{Effect, EffectKind};

use super::effects::list_per_joint;
use super::{per_joint, EffectReport, TermDesign};
use crate::prepare::dataset::FitData;

/// The column of a back-EMF on joint `j`: `en q̇`, bounded below by minus the nominal back-EMF.
pub(super) fn design(j: usize, data: &[FitData]) -> TermDesign {
    let nominal = data.iter().map(|d| d.back_emf[j]).fold(0.0f64, f64::max);
    TermDesign { cols: vec![per_joint(data, j, |d, i| d.enabled_qd[i])], lo: vec![-nominal], hi: vec![f64::INFINITY], ..Default::default() }
}

/// Whether some fit run disables the drive of joint `j` (back-EMF is then told from viscous
/// friction), and the effort was not measured on the link side of the gearbox (the motor's
/// back-EMF acts before such a sensor).
pub(crate) fn separable(j: usize, data: &[FitData]) -> bool {
    super::rotor::visible(data) && data.iter().any(|d| (0..d.len()).any(|s| d.enabled[s * d.dof + j] < 0.5))
}

/// Adds the back-EMF of joint `j` to the simulator's.
pub(super) fn apply(j: usize, theta: &[f64], n: usize, out: &mut Vec<Effect>) {
    if let Effect::BackEmf { kb } = super::effects::slot(out, Effect::BackEmf { kb: vec![0.0; n] }) {
        kb[j] = theta[0];
    }
}

/// The back-EMF in words.
pub(super) fn describe(e: &EffectReport) -> String {
    format!("back-EMF while the drive is enabled {}", list_per_joint(e, "kb"))
}

/// Marks, in its description, each selected back-EMF correction on a servo joint that no fit
/// run moves with its drive disabled ([`moves_with_drive_off`](crate::prepare::servo::moves_with_drive_off)):
/// there the back-EMF and the viscous friction act alike, so the logs show only their sum and
/// the split between the two is not established.
pub(crate) fn mark_damping_sums(model: &simgap_core::Model, fit_runs: &[simgap_sim::Run], selected: &mut [EffectReport]) {
    if !fit_runs.iter().any(crate::prepare::servo::is_servo) {
        return;
    }
    let names = model.joint_names();
    for e in selected.iter_mut().filter(|e| e.effect == EffectKind::BackEmf) {
        let alike: Vec<String> =
            e.joints.iter().filter(|j| names.iter().position(|n| n == *j).is_some_and(|i| !crate::prepare::servo::moves_with_drive_off(model, fit_runs, i))).cloned().collect();
        if !alike.is_empty() {
            e.description.push_str(&format!(
                "; on {} no fit log moves the joint with its drive disabled, so the logs show this back-EMF only with the viscous friction, as their sum: the split between the two is not established",
                alike.join(", ")
            ));
        }
    }
}
