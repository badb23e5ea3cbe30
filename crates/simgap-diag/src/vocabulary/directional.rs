//! `directional_friction`: friction that differs with the direction of motion (worn ball screws,
//! asymmetric seals): `−(fc_pos + b_pos q̇)` moving forward, `fc_neg − b_neg q̇` moving back,
//! switched by `s± = (1 ± tanh(q̇ / w)) / 2`.
//!
//! The residual holds `s⁺ fc_pos − s⁻ fc_neg + s⁺ q̇ b_pos + s⁻ q̇ b_neg`: four columns, every
//! coefficient ≥ 0. With equal levels and slopes it is Coulomb plus viscous friction, which it
//! replaces on its joint (it occupies the dry-friction and the viscous slots); it is tried only
//! as an exchange for them, kept when it predicts the fit runs better in every part of them
//! ([`crate::select::prediction`]), so symmetric friction stays the simpler pair.

use simgap_sim::effects::smooth_sign;
use simgap_sim::Effect;

use super::effects::{per_joint as reported, sig3, unit_of, Entry, FittedTerm};
use super::{filtered_per_joint, EffectReport, Term, TermDesign};
use crate::prepare::dataset::FitData;

/// The columns of a directional friction on `joint` with width `w`.
pub(super) fn design(joint: usize, w: f64, data: &[FitData]) -> TermDesign {
    // each column filtered like the torque (see `friction.rs`); the filter is linear and keeps
    // constants, so equal levels and slopes give exactly the Coulomb and viscous columns
    let pos = move |v: f64| 0.5 * (1.0 + smooth_sign(v, w));
    let neg = move |v: f64| 0.5 * (1.0 - smooth_sign(v, w));
    let cols = vec![
        filtered_per_joint(data, joint, pos),
        filtered_per_joint(data, joint, |v| -neg(v)),
        filtered_per_joint(data, joint, |v| pos(v) * v),
        filtered_per_joint(data, joint, |v| neg(v) * v),
    ];
    TermDesign::at_least(cols, 0.0)
}

/// Dissipative: every level and slope ≥ 0.
pub(super) fn physical(theta: &[f64]) -> bool {
    theta.iter().all(|x| *x >= -1e-12)
}

/// Adds the term to the simulator's directional frictions.
pub(super) fn apply(f: &FittedTerm, n: usize, out: &mut Vec<Effect>) {
    let Term::Directional { joint, w } = f.term else { return };
    let z = vec![0.0; n];
    let make = Effect::DirectionalFriction { fc_pos: z.clone(), fc_neg: z.clone(), b_pos: z.clone(), b_neg: z, w: vec![simgap_sim::DEFAULT_COULOMB_WIDTH; n] };
    if let Effect::DirectionalFriction { fc_pos, fc_neg, b_pos, b_neg, w: width } = super::effects::slot(out, make) {
        fc_pos[joint] = f.theta[0];
        fc_neg[joint] = f.theta[1];
        b_pos[joint] = f.theta[2];
        b_neg[joint] = f.theta[3];
        width[joint] = w;
    }
}

/// The term's parameters in its report entry.
pub(super) fn report(f: &FittedTerm, entry: &mut Entry<'_>) {
    let Term::Directional { w, .. } = f.term else { return };
    for (i, key) in ["fc_pos", "fc_neg", "b_pos", "b_neg"].iter().enumerate() {
        entry.push(key, f.theta[i], 1.96 * f.std[i]);
    }
    entry.push("w", w, f64::NAN);
}

/// The directional friction in words.
pub(super) fn describe(e: &EffectReport) -> String {
    let (uf, ub) = (unit_of(e, "fc_pos"), unit_of(e, "b_pos"));
    let get = |k: &str| reported(e, k);
    let (fp, fnn, bp, bn) = (get("fc_pos"), get("fc_neg"), get("b_pos"), get("b_neg"));
    let parts: Vec<String> = (0..fp.len())
        .map(|i| {
            format!(
                "on {}: forward fc = {} {uf}, b = {} {ub}; back fc = {} {uf}, b = {} {ub}",
                fp[i].0,
                sig3(fp[i].1),
                sig3(bp.get(i).map_or(f64::NAN, |x| x.1)),
                sig3(fnn.get(i).map_or(f64::NAN, |x| x.1)),
                sig3(bn.get(i).map_or(f64::NAN, |x| x.1))
            )
        })
        .collect();
    format!("friction that differs with the direction of motion {}", parts.join("; "))
}
