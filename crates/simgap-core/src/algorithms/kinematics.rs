//! Forward kinematics: world poses, world-frame joint subspaces, link velocities.

use crate::algorithms::workspace::Workspace;
use crate::model::Model;
use crate::spatial::Motion;

/// Asserts that a joint-space vector has `model.dof()` entries.
#[inline]
pub(crate) fn check_len(model: &Model, what: &str, v: &[f64]) {
    assert!(v.len() == model.dof(), "{what}: expected length {}, got {}", model.dof(), v.len());
}

/// Computes the world pose of every joint frame and the world-frame motion subspace
/// `S_i = (a_i, p_i × a_i)` (revolute) or `(0, a_i)` (prismatic), into `ws.poses` and
/// `ws.subspaces`.
///
/// `q`: joint positions, length `model.dof()`.
///
/// # Panics
/// If `q` or `ws` do not match the model.
pub fn forward_kinematics(model: &Model, ws: &mut Workspace, q: &[f64]) {
    check_len(model, "q", q);
    assert_eq!(ws.dof, model.dof(), "workspace made for another model");
    // forward pass: compose joint transforms from the root
    for (i, joint) in model.joints().iter().enumerate() {
        let local = model.joint_transform(i, q[i]);
        let pose = if i == 0 { local } else { ws.poses[i - 1].compose(&local) };
        let axis = pose.rotation * joint.axis;
        ws.subspaces[i] = if joint.kind.is_rotational() { Motion::new(axis, pose.translation.cross(&axis)) } else { Motion::new(nalgebra::Vector3::zeros(), axis) };
        ws.poses[i] = pose;
    }
}

/// Link inertias in world coordinates into `ws.inertias` (after [`forward_kinematics`]).
#[inline(always)]
pub(crate) fn world_inertias(model: &Model, ws: &mut Workspace) {
    for (i, joint) in model.joints().iter().enumerate() {
        ws.inertias[i] = joint.inertia.transformed(&ws.poses[i]);
    }
}

/// Link velocities `v_i = v_{i-1} + S_i q̇_i` and subspace rates `Ṡ_i = v_i × S_i` into
/// `ws.velocities` and `ws.subspace_rates` (after [`forward_kinematics`]).
#[inline(always)]
pub(crate) fn velocities(model: &Model, ws: &mut Workspace, qd: &[f64]) {
    check_len(model, "qd", qd);
    // forward pass: accumulate joint velocities from the root
    let mut v = Motion::ZERO;
    for i in 0..model.dof() {
        v = ws.subspaces[i].scale_add(qd[i], &v);
        ws.velocities[i] = v;
        ws.subspace_rates[i] = v.cross_motion(&ws.subspaces[i]);
    }
}
