//! `load_stribeck_friction`: a load-dependent friction whose level at rest rises above its
//! level in motion (a gear train's breakaway; BAM's load-dependent Stribeck models),
//! `−(fc + mu |τ_drive| + ((fs − fc) + (mus − mu) |τ_drive|) e^{−(q̇/vs)²}) tanh(q̇ / w)`,
//! `τ_drive` the nominal drive torque as in [`super::load_friction`]. A servo that stops short
//! of its goal and stays there while its duty rises shows it: once the joint is at rest, the
//! friction that holds it grows with the drive's torque faster than the one that brakes it in
//! motion.
//!
//! Columns (of the smoothed velocity and the filtered drive torque, as the load friction's):
//! `tanh(q̇/w)`, `|τ| tanh(q̇/w)`, `e tanh(q̇/w)`, `e |τ| tanh(q̇/w)` with `e = e^{−(q̇/vs)²}`,
//! their coefficients `fc ≥ 0`, `0 ≤ mu ≤ 1`, `fs − fc ≥ 0`, `0 ≤ mus − mu ≤ 1` (a rise, not a
//! dip; see [`super::load_friction::MU_MAX`]; [`physical`] also asks `mus ≤ 1`); stated as
//! `(fc, mu, fs, mus)`. The Stribeck
//! velocity `vs` is searched ([`VS_GRID`]); with `fs = fc` and `mus = mu` it is the load
//! friction (the nested, simpler effect, see [`simpler`]). It occupies the dry-friction slot.

use simgap_sim::effects::smooth_sign;
use simgap_sim::Effect;

use super::effects::{per_joint as reported, sig3, unit_of, Entry, FittedTerm};
use super::load_friction::MU_MAX;
use super::{per_joint, EffectReport, Nested, Term, TermDesign};
use crate::prepare::dataset::FitData;

/// Stribeck velocities tried [rad/s or m/s] as multiples of the joint's dry-friction width
/// `w`: from 3 w (a rise the smoothed sign does not swallow, see
/// [`super::stribeck_resolvable`]) to 30 w.
pub(crate) const VS_GRID: [f64; 3] = [3.0, 10.0, 30.0];

/// The columns of a load Stribeck friction on `joint`.
pub(super) fn design(joint: usize, vs: f64, w: f64, data: &[FitData]) -> TermDesign {
    let rise = |v: f64| (-(v / vs).powi(2)).exp();
    let cols = vec![
        per_joint(data, joint, |d, i| smooth_sign(d.qd[i], w)),
        per_joint(data, joint, |d, i| d.tau[i].abs() * smooth_sign(d.qd[i], w)),
        per_joint(data, joint, |d, i| rise(d.qd[i]) * smooth_sign(d.qd[i], w)),
        per_joint(data, joint, |d, i| rise(d.qd[i]) * d.tau[i].abs() * smooth_sign(d.qd[i], w)),
    ];
    TermDesign { cols, lo: vec![0.0; 4], hi: vec![f64::INFINITY, MU_MAX, f64::INFINITY, MU_MAX], ..Default::default() }
}

/// The load friction nested in it (fs = fc, mus = mu), its extra columns the two rises.
pub(super) fn simpler(joint: usize, vs: f64, w: f64) -> Nested {
    let unresolved = (!super::stribeck_resolvable(vs, w)).then(|| {
        format!(
            "its Stribeck velocity vs is {} times the width w over which the sign of the velocity is smoothed (the runs cannot resolve a rise within twice that width)",
            sig3(vs / w)
        )
    });
    Nested { terms: vec![Term::LoadFriction { joint, w }], extra: vec![2, 3], unresolved }
}

/// `(fc, mu, fs, mus)` from the columns' coefficients `(fc, mu, fs − fc, mus − mu)`.
pub(super) fn contract(raw: &[f64]) -> Vec<f64> {
    vec![raw[0], raw[1], raw[0] + raw[2], raw[1] + raw[3]]
}

/// Standard deviations of `(fs, mus)` as sums of two coefficients (their covariance ignored).
pub(super) fn contract_std(sd: &mut [f64]) {
    sd[2] = sd[0].hypot(sd[2]);
    sd[3] = sd[1].hypot(sd[3]);
}

/// Dissipative, rising at rest, and a drive that can break the joint loose: fc, mu ≥ 0,
/// fs ≥ fc, mu ≤ mus ≤ [`MU_MAX`] (the columns' box bounds mus − mu alone).
pub(super) fn physical(theta: &[f64]) -> bool {
    let tol = 1e-12;
    theta[0] >= -tol && theta[1] >= -tol && theta[2] >= theta[0] - tol && theta[3] >= theta[1] - tol && theta[3] <= MU_MAX + tol
}

/// Adds the term to the simulator's load Stribeck frictions.
pub(super) fn apply(f: &FittedTerm, n: usize, out: &mut Vec<Effect>) {
    let Term::LoadStribeck { joint, vs, w } = f.term else { return };
    let zero = || vec![0.0; n];
    let make = Effect::LoadStribeckFriction { fc: zero(), mu: zero(), fs: zero(), mus: zero(), vs: zero(), w: vec![simgap_sim::DEFAULT_COULOMB_WIDTH; n] };
    if let Effect::LoadStribeckFriction { fc, mu, fs, mus, vs: v, w: width } = super::effects::slot(out, make) {
        fc[joint] = f.theta[0];
        mu[joint] = f.theta[1];
        fs[joint] = f.theta[2];
        mus[joint] = f.theta[3];
        v[joint] = vs;
        width[joint] = w;
    }
}

/// The term's parameters in its report entry.
pub(super) fn report(f: &FittedTerm, entry: &mut Entry<'_>) {
    let Term::LoadStribeck { vs, w, .. } = f.term else { return };
    for (i, name) in ["fc", "mu", "fs", "mus"].into_iter().enumerate() {
        entry.push(name, f.theta[i], 1.96 * f.std[i]);
    }
    entry.push("vs", vs, f64::NAN);
    entry.push("w", w, f64::NAN);
}

/// The load Stribeck friction in words.
pub(super) fn describe(e: &EffectReport) -> String {
    let (uf, uv) = (unit_of(e, "fc"), unit_of(e, "vs"));
    let (fc, mu, fs, mus, vs) = (reported(e, "fc"), reported(e, "mu"), reported(e, "fs"), reported(e, "mus"), reported(e, "vs"));
    let parts: Vec<String> = (0..fc.len())
        .map(|i| {
            format!(
                "on {}: fc = {} {uf} + {} × |drive torque| moving, rising to fs = {} {uf} + {} × |drive torque| below {} {uv}",
                fc[i].0,
                sig3(fc[i].1),
                sig3(mu[i].1),
                sig3(fs[i].1),
                sig3(mus[i].1),
                sig3(vs[i].1)
            )
        })
        .collect();
    format!("load-dependent friction higher at rest {}", parts.join("; "))
}

#[cfg(test)]
mod tests {
    use super::{contract, physical};

    #[test]
    fn its_parameters_are_the_columns_levels_plus_their_rises() {
        // (fc, mu, fs − fc, mus − mu) → (fc, mu, fs, mus)
        assert_eq!(contract(&[0.25, 0.375, 0.5, 0.25]), vec![0.25, 0.375, 0.75, 0.625]);
    }

    #[test]
    fn it_is_physical_when_it_dissipates_rises_at_rest_and_lets_the_drive_break_loose() {
        assert!(physical(&[0.1, 0.3, 0.15, 0.5]));
        assert!(physical(&[0.0, 0.0, 0.0, 0.0]));
        assert!(!physical(&[0.1, 0.3, 0.05, 0.5]), "fs below fc");
        assert!(!physical(&[0.1, 0.3, 0.15, 0.2]), "mus below mu");
        assert!(!physical(&[0.1, 0.6, 0.15, 1.2]), "mus above 1: no drive torque breaks it loose");
    }
}
