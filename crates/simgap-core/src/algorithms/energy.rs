//! Kinetic and potential energy.

use crate::algorithms::kinematics::{check_len, forward_kinematics, velocities, world_inertias};
use crate::algorithms::workspace::Workspace;
use crate::model::Model;

/// Kinetic energy T = ½ q̇ᵀ H(q) q̇ = ½ Σ v_iᵀ I_i v_i [J].
///
/// # Panics
/// If a length or `ws` does not match the model.
pub fn kinetic_energy(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64]) -> f64 {
    forward_kinematics(model, ws, q);
    world_inertias(model, ws);
    velocities(model, ws, qd);
    // sum over links of ½ vᵀ I v
    (0..model.dof()).map(|i| 0.5 * ws.velocities[i].dot(&ws.inertias[i].mul_motion(&ws.velocities[i]))).sum()
}

/// Potential energy of gravity U(q) = −Σ m_i gᵀ c_i [J], zero when every centre of mass is at
/// the base origin's height; `g(q) = ∂U/∂q`.
///
/// # Panics
/// If `q` or `ws` do not match the model.
pub fn potential_energy(model: &Model, ws: &mut Workspace, q: &[f64]) -> f64 {
    check_len(model, "q", q);
    forward_kinematics(model, ws, q);
    let g = model.gravity();
    // sum over links of −m gᵀ c, with m c the world first moment
    model
        .joints()
        .iter()
        .enumerate()
        .map(|(i, j)| {
            let pose = &ws.poses[i];
            let h = pose.rotation * j.inertia.first_moment + pose.translation * j.inertia.mass;
            -g.dot(&h)
        })
        .sum()
}
