//! Friction: `viscous_friction` (−b q̇), `coulomb_friction` (−fc sign q̇) and
//! `stribeck_friction` (−(fc + (fs − fc) e^{−(q̇/vs)²}) sign q̇), with sign(q̇) smoothed as
//! tanh(q̇ / w) in fitting as in simulation, `w` the joint's width chosen from the data
//! ([`FitData::dry_width`], `prepare/width.rs`) and carried by the term, so that the column,
//! the simulated effect and the reported parameter `w` are one number.
//!
//! Columns: `b_j q̇_j`; `fc_j tanh(q̇_j / w)`; `fc tanh(q̇/w) + (fs − fc) e^{−(q̇/vs)²} tanh(q̇/w)`,
//! with b, fc ≥ 0 and fs − fc ≥ 0 (friction dissipates; a Stribeck hump rises above fc).
//! The Stribeck velocity vs is searched on a grid. Every column is evaluated at every sample
//! and filtered like the torque ([`FitData::filtered_velocity_map`]): the step of dry friction
//! at each velocity reversal reaches the fit through the same kernel on both sides.

use simgap_sim::effects::smooth_sign;
use simgap_sim::Effect;
use simgap_sim::EffectKind;

use super::effects::{list_per_joint, per_joint as reported, sig3, unit_of, Entry, FittedTerm};
use super::{filtered_per_joint, EffectReport, Term, TermDesign};
use crate::prepare::dataset::FitData;

/// The columns of a friction term.
pub(super) fn design(term: &Term, data: &[FitData]) -> TermDesign {
    match *term {
        Term::Viscous(j) => TermDesign::at_least(vec![filtered_per_joint(data, j, |v| v)], 0.0),
        Term::Coulomb { joint, w } => TermDesign::at_least(vec![filtered_per_joint(data, joint, |v| smooth_sign(v, w))], 0.0),
        Term::Stribeck { joint, vs, w } => {
            // fc tanh + (fs − fc) e tanh, with fc ≥ 0 and fs − fc ≥ 0
            let e = |v: f64| (-(v / vs).powi(2)).exp();
            TermDesign::at_least(vec![filtered_per_joint(data, joint, |v| smooth_sign(v, w)), filtered_per_joint(data, joint, |v| e(v) * smooth_sign(v, w))], 0.0)
        }
        _ => TermDesign::default(),
    }
}

/// Below this share of the fit samples moving slower than a Stribeck velocity, the runs do not
/// resolve the Stribeck hump: it is Coulomb friction seen through a handful of samples.
pub(crate) const RESOLVED_SHARE: f64 = 0.02;

/// Whether a Stribeck hump of velocity `vs` stands apart from the smoothed sign of width `w`:
/// `vs > 2 w`. Within twice the width, the hump only reshapes the smoothed step, and its
/// column (filtered like the torque, a few samples wide at each reversal) takes any
/// coefficient the fit needs, however unphysical: such a Stribeck velocity is neither searched
/// nor reported.
pub(crate) fn resolvable(vs: f64, w: f64) -> bool {
    vs > 2.0 * w
}

/// The Coulomb friction nested in a Stribeck friction (fs = fc), its extra column (fs − fc),
/// and why the runs cannot resolve the hump where they cannot: a Stribeck velocity within
/// twice the smoothing width of the sign (see [`resolvable`]), or slower than all but
/// [`RESOLVED_SHARE`] of the fit samples.
pub(super) fn simpler(term: &Term, data: &[FitData]) -> Option<super::Nested> {
    let Term::Stribeck { joint, vs, w } = *term else { return None };
    let (slower, total) = data.iter().fold((0usize, 0usize), |(s, n), d| (s + (0..d.len()).filter(|&i| d.qd[i * d.dof + joint].abs() < vs).count(), n + d.len()));
    let share = if total > 0 { slower as f64 / total as f64 } else { 0.0 };
    let unresolved = if !resolvable(vs, w) {
        Some(format!(
            "its Stribeck velocity vs is {} times the width w over which the sign of the velocity is smoothed (the runs cannot resolve a hump within twice that width)",
            sig3(vs / w)
        ))
    } else if share < RESOLVED_SHARE {
        Some(format!("only {:.1} % of the fit samples move slower than its Stribeck velocity vs: the runs do not resolve its hump", 100.0 * share))
    } else {
        None
    };
    Some(super::Nested { terms: vec![Term::Coulomb { joint, w }], extra: vec![1], unresolved })
}

/// fc and fs of a Stribeck term from its columns' coefficients (fc, fs − fc).
pub(super) fn contract_stribeck(raw: &[f64]) -> Vec<f64> {
    vec![raw[0], raw[0] + raw[1]]
}

/// Dissipative: b, fc ≥ 0 and fs ≥ fc.
pub(super) fn physical(term: &Term, theta: &[f64]) -> bool {
    let tol = 1e-12;
    match term {
        Term::Stribeck { .. } => theta[1] >= theta[0] - tol && theta[0] >= -tol,
        _ => theta[0] >= -tol,
    }
}

/// Adds the term to the simulator's friction effects.
pub(super) fn apply(f: &FittedTerm, n: usize, out: &mut Vec<Effect>) {
    let th = &f.theta;
    match f.term {
        Term::Viscous(j) => {
            if let Effect::ViscousFriction { b } = super::effects::slot(out, Effect::ViscousFriction { b: vec![0.0; n] }) {
                b[j] = th[0];
            }
        }
        Term::Coulomb { joint, w } => {
            let make = Effect::CoulombFriction { fc: vec![0.0; n], w: vec![simgap_sim::DEFAULT_COULOMB_WIDTH; n] };
            if let Effect::CoulombFriction { fc, w: width } = super::effects::slot(out, make) {
                fc[joint] = th[0];
                width[joint] = w;
            }
        }
        Term::Stribeck { joint, vs, w } => {
            let make = Effect::StribeckFriction { fc: vec![0.0; n], fs: vec![0.0; n], vs: vec![0.0; n], w: vec![simgap_sim::DEFAULT_COULOMB_WIDTH; n] };
            if let Effect::StribeckFriction { fc, fs, vs: v, w: width } = super::effects::slot(out, make) {
                fc[joint] = th[0];
                fs[joint] = th[1];
                v[joint] = vs;
                width[joint] = w;
            }
        }
        _ => {}
    }
}

/// The term's parameters in its report entry.
pub(super) fn report(f: &FittedTerm, entry: &mut Entry<'_>) {
    let ci = |s: f64| 1.96 * s;
    let (th, sd) = (&f.theta, &f.std);
    match f.term {
        Term::Viscous(_) => entry.push("b", th[0], ci(sd[0])),
        Term::Coulomb { w, .. } => {
            entry.push("fc", th[0], ci(sd[0]));
            entry.push("w", w, f64::NAN);
        }
        Term::Stribeck { vs, w, .. } => {
            entry.push("fc", th[0], ci(sd[0]));
            entry.push("fs", th[1], ci(sd[1]));
            entry.push("vs", vs, f64::NAN);
            entry.push("w", w, f64::NAN);
        }
        _ => {}
    }
}

/// The friction in words.
pub(super) fn describe(e: &EffectReport) -> String {
    match e.effect {
        EffectKind::ViscousFriction => format!("viscous friction {}", list_per_joint(e, "b")),
        EffectKind::CoulombFriction => format!("Coulomb friction {}", list_per_joint(e, "fc")),
        _ => {
            let (fc, fs, vs) = (reported(e, "fc"), reported(e, "fs"), reported(e, "vs"));
            let (uf, uv) = (unit_of(e, "fc"), unit_of(e, "vs"));
            let parts: Vec<String> =
                fc.iter().zip(&fs).zip(&vs).map(|((c, s), v)| format!("on {}: fc = {} {uf}, fs = {} {uf} below {} {uv}", c.0, sig3(c.1), sig3(s.1), sig3(v.1))).collect();
            format!("Stribeck friction {}", parts.join("; "))
        }
    }
}
