//! The articulated-body algorithm: forward dynamics in O(n).

use crate::algorithms::kinematics::check_len;
use crate::algorithms::soa::{self, InertiaLevel};
use crate::algorithms::workspace::Workspace;
use crate::formulation::Formulation;
use crate::lanes::Lanes;
use crate::model::Model;

/// Joint accelerations q̈ = H⁻¹ (τ − C q̇ − g) by the articulated-body algorithm, in place.
///
/// This is the articulated-body algorithm (Featherstone 2008, §7.3) in world coordinates: one
/// forward pass (velocities, bias forces), one backward pass (articulated inertias), one
/// forward pass (accelerations), O(n) where CRBA + Cholesky is O(n³).
/// [`forward_dynamics_into`](crate::forward_dynamics_into) picks it for long chains. For
/// [`Formulation::Simplified`] the torque is first corrected by the difference of the two
/// formulations' `C q̇` (one Newton–Euler pass), since the algorithm itself uses the true one.
///
/// `q`, `qd`, `tau`: positions, velocities and joint torques, length `model.dof()`; `out`: q̈.
///
/// # Panics
/// If a length or `ws` does not match the model, or if H is not positive definite.
pub fn forward_dynamics_aba_into(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64], tau: &[f64], formulation: Formulation, out: &mut [f64]) {
    // a pivot D_i <= 0 is a mass matrix that is not positive definite
    assert!(articulated_body(model, ws, q, qd, tau, &[], formulation, out), "matrix is not positive definite");
}

/// [`forward_dynamics_aba_into`] with rotor inertia `armature` (`ia`, length `model.dof()` or
/// empty for none) on the diagonal of H: `q̈ = (H + diag(ia))⁻¹ (τ − C q̇ − g)`, each joint's
/// pivot `D_i = S_iᵀ IA_i S_i + ia_i` (Featherstone 2008, §7.3, with the motor inertia of
/// §9.6). Returns false, with `out` unspecified, when a pivot is not positive and finite
/// (`H + diag(ia)` is not positive definite).
#[allow(clippy::too_many_arguments)]
pub(crate) fn articulated_body(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64], tau: &[f64], armature: &[f64], formulation: Formulation, out: &mut [f64]) -> bool {
    let n = model.dof();
    check_len(model, "q", q);
    check_len(model, "qd", qd);
    check_len(model, "tau", tau);
    check_len(model, "out", out);
    assert_eq!(ws.dof, n, "workspace made for another model");
    let lanes = &mut ws.lanes;
    for i in 0..n {
        lanes.q[i] = Lanes([q[i]]);
        lanes.qd[i] = Lanes([qd[i]]);
    }
    // kinematics, link inertias and velocities in the world frame
    soa::kinematics(model, lanes, InertiaLevel::Full);
    soa::velocities(lanes);
    if formulation == Formulation::Simplified {
        // τ − (½ Ḣ q̇ − C q̇): the algorithm then subtracts the true C q̇
        soa::rnea(model, lanes, false, false, Formulation::Simplified);
        for i in 0..n {
            lanes.tau[i] = Lanes([tau[i] - (lanes.tau[i].0[0] - lanes.el[i].0[0])]);
        }
    } else {
        for i in 0..n {
            lanes.tau[i] = Lanes([tau[i]]);
        }
    }
    soa::aba(model, lanes, armature);
    for i in 0..n {
        out[i] = lanes.tau[i].0[0];
    }
    lanes.dinv[..n].iter().all(|d| d.0[0] > 0.0 && d.0[0].is_finite())
}
