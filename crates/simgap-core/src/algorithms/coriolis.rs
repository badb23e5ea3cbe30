//! The Coriolis matrix C(q, q̇) in both formulations, and Ḣ(q, q̇).
//!
//! With `A = ∂(H q̇)/∂q` (q̇ held fixed), the Christoffel symbols of the first kind give
//! `C = ½ Ḣ + ½ (A − Aᵀ)`: the Euler–Lagrange C is the seed paper's simplified C = ½ Ḣ plus a
//! skew-symmetric part. Since `(H q̇)_i = S_iᵀ h_i`, with `h_i` the spatial momentum of the
//! subtree of link i, every entry is a dot product of world-frame spatial vectors
//! (cf. Echeandia & Wensing 2021), for O(n²) work after O(n) passes:
//!
//! ```text
//! f1_j = Ic_j S_j,   f2_j = İc_j S_j + Ic_j Ṡ_j,   f3_j = S_j ×* h_j + Ic_j Ṡ_j
//! H_ij = S_i·f1_j,   Ḣ_ij = Ṡ_i·f1_j + S_i·f2_j                       (i ≤ j)
//! C_ij = ½ S_i·(f2_j + f3_j),   C_ji = Ṡ_i·f1_j + ½ S_i·(f2_j − f3_j)   (i ≤ j)
//! ```

use nalgebra::DMatrix;

use crate::algorithms::crba::composite_inertias;
use crate::algorithms::kinematics::{forward_kinematics, velocities, world_inertias};
use crate::algorithms::workspace::Workspace;
use crate::model::Model;
use crate::spatial::InertiaRate;

/// Re-exported where it was first defined, so that `algorithms::coriolis::Formulation` still names it.
pub use crate::formulation::Formulation;

/// Kinematics, velocities, composite inertias, subtree momenta and composite inertia rates.
///
/// This pass, [`fill_second_order`] and the per-link steps they take (velocities, world and
/// composite inertias, inertia rates) are always inlined: left to the inliner, whether they
/// were depended on how the crate fell into codegen units, and `dynamics_terms` of a 7-joint
/// arm took 1.13–1.28× as long where they were calls (`examples/timings.rs`).
#[inline(always)]
pub(crate) fn second_order_pass(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64]) {
    forward_kinematics(model, ws, q);
    world_inertias(model, ws);
    velocities(model, ws, qd);
    composite_inertias(model, ws);
    let n = model.dof();
    // backward pass: subtree momenta h_i = Σ I_l v_l and composite rates İc_i = Σ İ_l
    let mut momentum = crate::spatial::Force::ZERO;
    let mut rate = InertiaRate::default();
    for i in (0..n).rev() {
        let inertia = &ws.inertias[i];
        let v = &ws.velocities[i];
        momentum += inertia.mul_motion(v);
        rate += inertia.rate(v);
        ws.momenta[i] = momentum;
        ws.composite_rates[i] = rate;
    }
}

/// Which outputs [`fill_second_order`] writes.
pub(crate) struct SecondOrderOut<'a> {
    pub(crate) h: Option<&'a mut DMatrix<f64>>,
    pub(crate) c: Option<(&'a mut DMatrix<f64>, Formulation)>,
    pub(crate) hdot: Option<&'a mut DMatrix<f64>>,
}

/// Fills H, C and Ḣ from a [`second_order_pass`] (formulas in the module docs).
#[inline(always)]
pub(crate) fn fill_second_order(model: &Model, ws: &Workspace, mut out: SecondOrderOut<'_>) {
    let n = model.dof();
    for j in 0..n {
        let s_j = &ws.subspaces[j];
        let sd_j = &ws.subspace_rates[j];
        let ic = &ws.composites[j];
        let f1 = ic.mul_motion(s_j);
        let ic_sd = ic.mul_motion(sd_j);
        let f2 = ws.composite_rates[j].mul_motion(s_j) + ic_sd;
        let f3 = s_j.cross_force(&ws.momenta[j]) + ic_sd;
        let plus = (f2 + f3) * 0.5;
        let minus = (f2 - f3) * 0.5;
        for i in 0..=j {
            let s_i = &ws.subspaces[i];
            let sd_i = &ws.subspace_rates[i];
            let sd_f1 = sd_i.dot(&f1);
            let s_f2 = s_i.dot(&f2);
            if let Some(h) = out.h.as_deref_mut() {
                let hij = s_i.dot(&f1);
                h[(i, j)] = hij;
                h[(j, i)] = hij;
            }
            if let Some(hd) = out.hdot.as_deref_mut() {
                let v = sd_f1 + s_f2;
                hd[(i, j)] = v;
                hd[(j, i)] = v;
            }
            if let Some((c, formulation)) = out.c.as_mut() {
                match formulation {
                    Formulation::EulerLagrange => {
                        c[(i, j)] = s_i.dot(&plus);
                        if i < j {
                            c[(j, i)] = sd_f1 + s_i.dot(&minus);
                        }
                    }
                    Formulation::Simplified => {
                        let v = 0.5 * (sd_f1 + s_f2);
                        c[(i, j)] = v;
                        c[(j, i)] = v;
                    }
                }
            }
        }
    }
}

/// Coriolis matrix C(q, q̇), `dof × dof`, of the chosen formulation.
///
/// Euler–Lagrange: `C_ij = Σ_k Γ_ijk q̇_k` with Christoffel symbols of the first kind, so
/// `Ḣ − 2C` is skew-symmetric and `C q̇` equals [`coriolis_torques`](crate::coriolis_torques).
/// Simplified: `C = Ḣ / 2`. See the crate root and Echeandia & Wensing (2021).
///
/// `q`, `qd`: joint positions and velocities, length `model.dof()`.
///
/// # Panics
/// If a length or `ws` does not match the model.
#[must_use]
pub fn coriolis_matrix(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64], formulation: Formulation) -> DMatrix<f64> {
    let mut out = DMatrix::zeros(model.dof(), model.dof());
    coriolis_matrix_into(model, ws, q, qd, formulation, &mut out);
    out
}

/// In-place [`coriolis_matrix`].
///
/// # Panics
/// If a length, `ws` or `out` does not match the model.
pub fn coriolis_matrix_into(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64], formulation: Formulation, out: &mut DMatrix<f64>) {
    assert_eq!(out.shape(), (model.dof(), model.dof()), "coriolis matrix output shape");
    second_order_pass(model, ws, q, qd);
    fill_second_order(model, ws, SecondOrderOut { h: None, c: Some((out, formulation)), hdot: None });
}

/// Time derivative of the mass matrix Ḣ(q, q̇) = Σ_k ∂H/∂q_k q̇_k, symmetric, `dof × dof`.
///
/// Equals `C + Cᵀ` for the Euler–Lagrange C and `2C` for the simplified C.
///
/// # Panics
/// If a length or `ws` does not match the model.
#[must_use]
pub fn mass_matrix_derivative(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64]) -> DMatrix<f64> {
    let mut out = DMatrix::zeros(model.dof(), model.dof());
    mass_matrix_derivative_into(model, ws, q, qd, &mut out);
    out
}

/// In-place [`mass_matrix_derivative`].
///
/// # Panics
/// If a length, `ws` or `out` does not match the model.
pub fn mass_matrix_derivative_into(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64], out: &mut DMatrix<f64>) {
    assert_eq!(out.shape(), (model.dof(), model.dof()), "mass matrix derivative output shape");
    second_order_pass(model, ws, q, qd);
    fill_second_order(model, ws, SecondOrderOut { h: None, c: None, hdot: Some(out) });
}
