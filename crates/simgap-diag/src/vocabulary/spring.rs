//! `joint_spring`: a torque −k (q − q0) pulling a joint back to a rest position (cables, hoses,
//! a counterbalance spring).
//!
//! The residual holds `k q_j − k q0_j`: the columns `q_j` (k ≥ 0) and `−1` (its coefficient
//! `k q0`, free). The constant is the one a torque offset has, so the spring occupies the offset's
//! slot on its joint as well as its own (a spring and an offset on one joint would be one
//! constant fitted twice); the report states `q0 = (k q0) / k`.

use simgap_sim::Effect;

use super::effects::{per_joint as reported, sig3, unit_of, Entry};
use super::{per_joint, EffectReport, Nested, Term, TermDesign};
use crate::prepare::dataset::FitData;

/// The columns of a spring on joint `j`: `q_j` with k ≥ 0, and the constant `−1` of `k q0`.
pub(super) fn design(j: usize, data: &[FitData]) -> TermDesign {
    let cols = vec![per_joint(data, j, |d, i| d.q[i]), per_joint(data, j, |_, _| -1.0)];
    TermDesign { cols, lo: vec![0.0, f64::NEG_INFINITY], hi: vec![f64::INFINITY; 2], ..Default::default() }
}

/// The torque offset nested in it: with k = 0 its constant `k q0` alone is left, an offset of
/// `−k q0` on the joint; its extra column is `q_j` (a spring whose stiffness the runs cannot tell
/// from 0, about a rest position far outside the motion, is a constant torque).
pub(super) fn simpler(j: usize) -> Nested {
    Nested { terms: vec![Term::Offset(j)], extra: vec![0], unresolved: None }
}

/// `(k, q0)` from the columns' coefficients `(k, k q0)` (q0 = 0 for no spring).
pub(super) fn contract(raw: &[f64]) -> Vec<f64> {
    let q0 = if raw[0] > 0.0 { raw[1] / raw[0] } else { 0.0 };
    vec![raw[0], q0]
}

/// The standard deviations of `(k, q0)` from those of `(k, k q0)` (first order, covariance
/// ignored).
pub(super) fn contract_std(theta: &[f64], sd: &mut [f64]) {
    if theta[0] > 0.0 {
        sd[1] = sd[1].hypot(theta[1] * sd[0]) / theta[0];
    }
}

/// A spring stores energy, it does not feed it: k ≥ 0.
pub(super) fn physical(theta: &[f64]) -> bool {
    theta[0] >= -1e-12
}

/// Adds the spring of joint `j` to the simulator's.
pub(super) fn apply(j: usize, theta: &[f64], n: usize, out: &mut Vec<Effect>) {
    if let Effect::JointSpring { k, q0 } = super::effects::slot(out, Effect::JointSpring { k: vec![0.0; n], q0: vec![0.0; n] }) {
        k[j] = theta[0];
        q0[j] = theta[1];
    }
}

/// The spring's parameters in its report entry.
pub(super) fn report(th: &[f64], sd: &[f64], entry: &mut Entry<'_>) {
    entry.push("k", th[0], 1.96 * sd[0]);
    entry.push("q0", th[1], 1.96 * sd[1]);
}

/// The spring in words.
pub(super) fn describe(e: &EffectReport) -> String {
    let (uk, uq) = (unit_of(e, "k"), unit_of(e, "q0"));
    let parts: Vec<String> = reported(e, "k").iter().zip(reported(e, "q0")).map(|((j, k), (_, q0))| format!("k = {} {uk} about q0 = {} {uq} on {j}", sig3(*k), sig3(q0))).collect();
    // −k (q − q0) + o is a spring about q0 + o/k: an offset on its joint is in its rest position
    format!("joint spring {} (a constant torque on its joint, such as a sensor offset, is part of its rest position)", parts.join(", "))
}
