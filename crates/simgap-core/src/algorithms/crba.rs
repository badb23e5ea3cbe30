//! The composite rigid body algorithm: the joint-space mass matrix H(q).

use nalgebra::DMatrix;

use crate::algorithms::kinematics::{forward_kinematics, world_inertias};
use crate::algorithms::workspace::Workspace;
use crate::model::Model;

/// Accumulates composite inertias `Ic_i = Σ_{l ≥ i} I_l` into `ws.composites`.
#[inline(always)]
pub(crate) fn composite_inertias(model: &Model, ws: &mut Workspace) {
    let n = model.dof();
    // backward pass: add each subtree's inertia to its parent
    ws.composites[n - 1] = ws.inertias[n - 1];
    for i in (0..n - 1).rev() {
        ws.composites[i] = ws.inertias[i] + ws.composites[i + 1];
    }
}

/// Fills the upper triangle and mirrors it: `H_ij = S_iᵀ Ic_j S_j` for `i ≤ j`.
#[inline]
pub(crate) fn fill_mass_matrix(model: &Model, ws: &Workspace, out: &mut DMatrix<f64>) {
    let n = model.dof();
    for j in 0..n {
        let f = ws.composites[j].mul_motion(&ws.subspaces[j]);
        for i in 0..=j {
            let hij = ws.subspaces[i].dot(&f);
            out[(i, j)] = hij;
            out[(j, i)] = hij;
        }
    }
}

/// Joint-space mass matrix H(q), symmetric positive definite, `dof × dof`.
///
/// This is the composite rigid body algorithm (Featherstone 2008, §6.2), in world coordinates.
/// H is the same in both formulations; see the crate root for conventions.
///
/// `q`: joint positions, length `model.dof()`.
///
/// # Panics
/// If `q` or `ws` do not match the model.
#[must_use]
pub fn mass_matrix(model: &Model, ws: &mut Workspace, q: &[f64]) -> DMatrix<f64> {
    let mut out = DMatrix::zeros(model.dof(), model.dof());
    mass_matrix_into(model, ws, q, &mut out);
    out
}

/// In-place [`mass_matrix`]: writes H(q) into `out` (`dof × dof`) without allocating.
///
/// # Panics
/// If `q`, `ws` or `out` do not match the model.
pub fn mass_matrix_into(model: &Model, ws: &mut Workspace, q: &[f64], out: &mut DMatrix<f64>) {
    assert_eq!(out.shape(), (model.dof(), model.dof()), "mass matrix output shape");
    forward_kinematics(model, ws, q);
    world_inertias(model, ws);
    composite_inertias(model, ws);
    fill_mass_matrix(model, ws, out);
}
