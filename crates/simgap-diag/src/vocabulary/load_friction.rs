//! `load_friction`: dry friction that grows with the torque the drive pushes through its
//! gearbox, `−(fc + mu |τ_drive|) tanh(q̇ / w)` (harmonic drives, servo gear trains; Rhoban
//! BAM's load-dependent model). `τ_drive` is the nominal drive torque (for a servo, its motor
//! law with back-EMF; 0 while the drive is disabled).
//!
//! Columns (of the smoothed velocity and the filtered drive torque; see [`design`]):
//! `tanh(q̇_j / w)` (fc ≥ 0) and `|τ_drive,j| tanh(q̇_j / w)` (0 ≤ mu ≤ 1: a gearbox
//! that ate more than the torque it carries would never move). With mu = 0 it is Coulomb
//! friction (the nested, simpler effect, see [`simpler`]); it occupies the dry-friction slot.

use simgap_sim::effects::smooth_sign;
use simgap_sim::Effect;

use super::effects::{per_joint as reported, sig3, unit_of, Entry, FittedTerm};
use super::{per_joint, EffectReport, Nested, Term, TermDesign};
use crate::prepare::dataset::FitData;

/// Largest plausible friction per unit of drive torque.
pub(crate) const MU_MAX: f64 = 1.0;

/// The columns of a load friction on `joint` with width `w`.
pub(super) fn design(joint: usize, w: f64, data: &[FitData]) -> TermDesign {
    // of the smoothed velocity, not filtered like the torque as the other friction columns are:
    // filtered (`|τ_cmd| tanh(q̇/w)` at every sample through the torque's kernel), this column
    // of the unclamped command stood in for a torque saturation on the demo arm's logs (two
    // fit runs of three: a payload, torque gains, a delay and a 28.6 N·m limit for a 15 N·m
    // one), where this one does not
    let cols = vec![per_joint(data, joint, |d, i| smooth_sign(d.qd[i], w)), per_joint(data, joint, |d, i| d.tau[i].abs() * smooth_sign(d.qd[i], w))];
    TermDesign { cols, lo: vec![0.0, 0.0], hi: vec![f64::INFINITY, MU_MAX], ..Default::default() }
}

/// The Coulomb friction nested in it (mu = 0), its extra column mu.
pub(super) fn simpler(joint: usize, w: f64) -> Nested {
    Nested { terms: vec![Term::Coulomb { joint, w }], extra: vec![1], unresolved: None }
}

/// Dissipative: fc, mu ≥ 0.
pub(super) fn physical(theta: &[f64]) -> bool {
    theta.iter().all(|x| *x >= -1e-12)
}

/// Adds the term to the simulator's load frictions.
pub(super) fn apply(f: &FittedTerm, n: usize, out: &mut Vec<Effect>) {
    let Term::LoadFriction { joint, w } = f.term else { return };
    let make = Effect::LoadFriction { fc: vec![0.0; n], mu: vec![0.0; n], w: vec![simgap_sim::DEFAULT_COULOMB_WIDTH; n] };
    if let Effect::LoadFriction { fc, mu, w: width } = super::effects::slot(out, make) {
        fc[joint] = f.theta[0];
        mu[joint] = f.theta[1];
        width[joint] = w;
    }
}

/// The term's parameters in its report entry.
pub(super) fn report(f: &FittedTerm, entry: &mut Entry<'_>) {
    let Term::LoadFriction { w, .. } = f.term else { return };
    entry.push("fc", f.theta[0], 1.96 * f.std[0]);
    entry.push("mu", f.theta[1], 1.96 * f.std[1]);
    entry.push("w", w, f64::NAN);
}

/// The load friction in words.
pub(super) fn describe(e: &EffectReport) -> String {
    let uf = unit_of(e, "fc");
    let parts: Vec<String> =
        reported(e, "fc").iter().zip(reported(e, "mu")).map(|((j, fc), (_, mu))| format!("on {j}: fc = {} {uf} + {} × |drive torque|", sig3(*fc), sig3(mu))).collect();
    format!("load-dependent friction {}", parts.join("; "))
}
