//! The recursive Newton–Euler algorithm: inverse dynamics and its special cases
//! (gravity, Coriolis/centrifugal and bias torques).

use nalgebra::{DVector, Vector3};

use crate::algorithms::kinematics::{check_len, forward_kinematics, velocities, world_inertias};
use crate::algorithms::workspace::Workspace;
use crate::formulation::Formulation;
use crate::model::Model;
use crate::spatial::{Force, Motion};

/// Velocity-product RNEA: `ws.forces[i]` = force transmitted by joint i for `q̈ = qdd`
/// (or 0), base acceleration `-gravity` when `with_gravity`; also subtree momenta into
/// `ws.momenta` when `momenta` is set. Assumes kinematics, inertias and velocities are current.
fn rnea_pass(model: &Model, ws: &mut Workspace, qd: &[f64], qdd: Option<&[f64]>, with_gravity: bool, momenta: bool) {
    let n = model.dof();
    let base = if with_gravity { Motion::new(Vector3::zeros(), -model.gravity()) } else { Motion::ZERO };
    // forward pass: link accelerations a_i = a_{i-1} + Ṡ_i q̇_i + S_i q̈_i and link forces
    let mut a = base;
    for i in 0..n {
        a = ws.subspace_rates[i].scale_add(qd[i], &a);
        if let Some(qdd) = qdd {
            a = ws.subspaces[i].scale_add(qdd[i], &a);
        }
        ws.accelerations[i] = a;
        let inertia = &ws.inertias[i];
        let v = &ws.velocities[i];
        let h = inertia.mul_motion(v);
        ws.forces[i] = inertia.mul_motion(&a) + v.cross_force(&h);
        if momenta {
            ws.momenta[i] = h;
        }
    }
    // backward pass: each joint carries the forces of its whole subtree
    for i in (0..n - 1).rev() {
        let child = ws.forces[i + 1];
        ws.forces[i] += child;
        if momenta {
            let child = ws.momenta[i + 1];
            ws.momenta[i] += child;
        }
    }
}

/// Inverse dynamics τ = H(q) q̈ + C(q, q̇) q̇ + g(q), with the true (Euler–Lagrange)
/// Coriolis/centrifugal torque.
///
/// This is the recursive Newton–Euler algorithm (Featherstone 2008, §5.3), in world coordinates.
///
/// `q`, `qd`, `qdd`: joint positions, velocities and accelerations, each of length `model.dof()`.
///
/// # Panics
/// If a length or `ws` does not match the model.
#[must_use]
pub fn inverse_dynamics(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64], qdd: &[f64]) -> DVector<f64> {
    let mut out = DVector::zeros(model.dof());
    inverse_dynamics_into(model, ws, q, qd, qdd, out.as_mut_slice());
    out
}

/// In-place [`inverse_dynamics`].
///
/// # Panics
/// If a length or `ws` does not match the model.
pub fn inverse_dynamics_into(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64], qdd: &[f64], out: &mut [f64]) {
    check_len(model, "qdd", qdd);
    check_len(model, "out", out);
    forward_kinematics(model, ws, q);
    world_inertias(model, ws);
    velocities(model, ws, qd);
    rnea_pass(model, ws, qd, Some(qdd), true, false);
    for i in 0..model.dof() {
        out[i] = ws.subspaces[i].dot(&ws.forces[i]);
    }
}

/// Generalised gravity torques g(q) = ∂U/∂q (the torque that holds the robot still).
///
/// Equivalent to `inverse_dynamics(q, 0, 0)`.
///
/// `q`: joint positions, length `model.dof()`.
///
/// # Panics
/// If `q` or `ws` do not match the model.
#[must_use]
pub fn gravity_torques(model: &Model, ws: &mut Workspace, q: &[f64]) -> DVector<f64> {
    let mut out = DVector::zeros(model.dof());
    gravity_torques_into(model, ws, q, out.as_mut_slice());
    out
}

/// In-place [`gravity_torques`].
///
/// # Panics
/// If `q`, `ws` or `out` do not match the model.
pub fn gravity_torques_into(model: &Model, ws: &mut Workspace, q: &[f64], out: &mut [f64]) {
    check_len(model, "out", out);
    forward_kinematics(model, ws, q);
    gravity_from_kinematics(model, ws, out);
}

/// g(q) from current poses and subspaces: `g_i = S_i · (−h_i × g, −m_i g)` with `m_i`, `h_i`
/// the mass and first moment of the subtree of link i.
#[inline]
pub(crate) fn gravity_from_kinematics(model: &Model, ws: &Workspace, out: &mut [f64]) {
    let g = model.gravity();
    let mut mass = 0.0;
    let mut first = Vector3::zeros();
    // backward pass: subtree mass and first moment, projected on each joint
    for i in (0..model.dof()).rev() {
        let link = &model.joints()[i].inertia;
        let pose = &ws.poses[i];
        mass += link.mass;
        first += pose.rotation * link.first_moment + pose.translation * link.mass;
        let f = Force { moment: -first.cross(&g), force: -g * mass };
        out[i] = ws.subspaces[i].dot(&f);
    }
}

/// g(q) from current composite inertias (after [`composite_inertias`](crate::algorithms::crba)):
/// the same numbers as [`gravity_from_kinematics`] without transforming the first moments again.
#[inline]
pub(crate) fn gravity_from_composites(model: &Model, ws: &Workspace, out: &mut [f64]) {
    let g = model.gravity();
    for (i, c) in ws.composites.iter().enumerate() {
        let f = Force { moment: -c.first_moment.cross(&g), force: -g * c.mass };
        out[i] = ws.subspaces[i].dot(&f);
    }
}

/// Coriolis and centrifugal torques C(q, q̇) q̇ of the chosen formulation.
///
/// For [`Formulation::EulerLagrange`] this is the true velocity-product torque, equivalent to
/// `inverse_dynamics(q, q̇, 0) − g(q)`. For [`Formulation::Simplified`] it is `½ Ḣ q̇`.
///
/// `q`, `qd`: joint positions and velocities, length `model.dof()`.
///
/// # Panics
/// If a length or `ws` does not match the model.
#[must_use]
pub fn coriolis_torques(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64], formulation: Formulation) -> DVector<f64> {
    let mut out = DVector::zeros(model.dof());
    coriolis_torques_into(model, ws, q, qd, formulation, out.as_mut_slice());
    out
}

/// In-place [`coriolis_torques`].
///
/// # Panics
/// If a length or `ws` does not match the model.
pub fn coriolis_torques_into(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64], formulation: Formulation, out: &mut [f64]) {
    velocity_terms(model, ws, q, qd, formulation, false, out);
}

/// Bias torques C(q, q̇) q̇ + g(q) of the chosen formulation.
///
/// For [`Formulation::EulerLagrange`], equivalent to `inverse_dynamics(q, q̇, 0)`.
///
/// # Panics
/// If a length or `ws` does not match the model.
#[must_use]
pub fn bias_torques(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64], formulation: Formulation) -> DVector<f64> {
    let mut out = DVector::zeros(model.dof());
    bias_torques_into(model, ws, q, qd, formulation, out.as_mut_slice());
    out
}

/// In-place [`bias_torques`].
///
/// # Panics
/// If a length or `ws` does not match the model.
pub fn bias_torques_into(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64], formulation: Formulation, out: &mut [f64]) {
    velocity_terms(model, ws, q, qd, formulation, true, out);
}

/// C q̇ (+ g). The simplified torque uses `Ḣ q̇ = C_EL q̇ + (Ṡ_i · h_i)_i`, where `h_i` is the
/// momentum of the subtree of link i (so `∂T/∂q_i = Ṡ_i · h_i`), hence `½ Ḣ q̇` in O(n).
fn velocity_terms(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64], formulation: Formulation, with_gravity: bool, out: &mut [f64]) {
    check_len(model, "out", out);
    forward_kinematics(model, ws, q);
    world_inertias(model, ws);
    velocities(model, ws, qd);
    let simplified = formulation == Formulation::Simplified;
    rnea_pass(model, ws, qd, None, false, simplified);
    for i in 0..model.dof() {
        let c = ws.subspaces[i].dot(&ws.forces[i]);
        out[i] = if simplified { 0.5 * (c + ws.subspace_rates[i].dot(&ws.momenta[i])) } else { c };
    }
    if with_gravity {
        let mut g = std::mem::take(&mut ws.scratch_vector);
        gravity_from_kinematics(model, ws, g.as_mut_slice());
        for i in 0..model.dof() {
            out[i] += g[i];
        }
        ws.scratch_vector = g;
    }
}
