//! Forward dynamics: q̈ = H(q)⁻¹ (τ − C(q, q̇) q̇ − g(q)).

use nalgebra::DVector;

use crate::algorithms::closed_forms;
use crate::algorithms::crba::{composite_inertias, fill_mass_matrix};
use crate::algorithms::kinematics::check_len;
use crate::algorithms::rnea::bias_torques_into;
use crate::algorithms::workspace::Workspace;
use crate::formulation::Formulation;
use crate::model::Model;

/// Joint accelerations q̈ = H⁻¹ (τ − C q̇ − g) with the chosen formulation's C.
///
/// The algorithm is picked by the model: for an arm of one joint or of two rotational joints, a
/// closed form generated from the model into `ws` on the first call with it; from [`ABA_MIN_DOF`] joints on, the
/// articulated-body algorithm ([`forward_dynamics_aba_into`](crate::forward_dynamics_aba_into)),
/// O(n); below, the bias torques (Newton–Euler), the mass matrix (composite rigid body
/// algorithm) and an in-place Cholesky solve ([`forward_dynamics_crba_into`]), O(n³). All
/// give the same q̈ to rounding.
///
/// `q`, `qd`, `tau`: positions, velocities and joint torques, length `model.dof()`.
///
/// # Panics
/// If a length or `ws` does not match the model, or if H is not positive definite (a
/// model with a massless tail link whose joint carries no inertia).
#[must_use]
pub fn forward_dynamics(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64], tau: &[f64], formulation: Formulation) -> DVector<f64> {
    let mut out = DVector::zeros(model.dof());
    forward_dynamics_into(model, ws, q, qd, tau, formulation, out.as_mut_slice());
    out
}

/// Chains of at least this many joints take the articulated-body algorithm in
/// [`forward_dynamics`]: measured side by side (`cargo bench --bench dynamics --
/// forward_dynamics_`), it is faster than CRBA + Cholesky from two joints on.
pub const ABA_MIN_DOF: usize = 2;

/// In-place [`forward_dynamics`].
///
/// # Panics
/// As [`forward_dynamics`].
pub fn forward_dynamics_into(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64], tau: &[f64], formulation: Formulation, out: &mut [f64]) {
    assert!(try_forward_dynamics_into(model, ws, q, qd, tau, formulation, out), "matrix is not positive definite");
}

/// [`forward_dynamics_into`] that returns false instead of panicking when H is not positive
/// definite (a model whose inertial parameters are not physical, such as a link corrected to a
/// negative mass); `out` is then unspecified.
///
/// # Panics
/// If a length or `ws` does not match the model.
pub fn try_forward_dynamics_into(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64], tau: &[f64], formulation: Formulation, out: &mut [f64]) -> bool {
    let n = model.dof();
    if let Some(solved) = closed_forms::forward_dynamics(model, ws, q, qd, tau, &[], formulation, out) {
        solved
    } else if n >= ABA_MIN_DOF {
        check_len(model, "tau", tau);
        crate::algorithms::aba::articulated_body(model, ws, q, qd, tau, &[], formulation, out)
    } else {
        check_len(model, "tau", tau);
        crba_solve(model, ws, q, qd, tau, &[], formulation, out)
    }
}

/// [`forward_dynamics`] by bias torques, CRBA and Cholesky, whatever the number of joints.
///
/// # Panics
/// As [`forward_dynamics`].
pub fn forward_dynamics_crba_into(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64], tau: &[f64], formulation: Formulation, out: &mut [f64]) {
    check_len(model, "tau", tau);
    assert!(crba_solve(model, ws, q, qd, tau, &[], formulation, out), "matrix is not positive definite");
}

/// `q̈ = (H + diag(ia))⁻¹ (τ − C q̇ − g)` by bias torques, the mass matrix (sharing one
/// kinematics pass) and a Cholesky solve; `armature` empty for none. False when the matrix is
/// not positive definite.
#[allow(clippy::too_many_arguments)]
fn crba_solve(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64], tau: &[f64], armature: &[f64], formulation: Formulation, out: &mut [f64]) -> bool {
    let n = model.dof();
    // bias torques; kinematics and world inertias stay in the workspace for H
    bias_torques_into(model, ws, q, qd, formulation, out);
    for i in 0..n {
        out[i] = tau[i] - out[i];
    }
    composite_inertias(model, ws);
    let mut h = std::mem::take(&mut ws.scratch_matrix);
    fill_mass_matrix(model, ws, &mut h);
    for (i, ia) in armature.iter().enumerate() {
        h[(i, i)] += ia;
    }
    let ok = try_solve_spd_in_place(&mut h, out);
    ws.scratch_matrix = h;
    ok
}

/// Joint accelerations with rotor inertia: `q̈ = (H + diag(ia))⁻¹ (τ − C q̇ − g)`. Returns
/// false, with `out` unspecified, when `H + diag(ia)` is not positive definite (a negative
/// rotor inertia).
///
/// An arm of one joint, or of two rotational joints, uses its closed form (as
/// [`try_forward_dynamics_into`] does) with `ia` added to the diagonal of H. Otherwise, from
/// [`ABA_MIN_DOF`] joints on, the articulated-body algorithm with the rotor inertia in each
/// joint's pivot (`D_i = S_iᵀ IA_i S_i + ia_i`, Featherstone 2008, §7.3), O(n); below, bias
/// torques, the mass matrix plus `diag(ia)` (sharing one kinematics pass) and a Cholesky solve.
/// Equivalent to [`bias_torques_into`](crate::bias_torques_into), then
/// [`mass_matrix_into`](crate::mass_matrix_into) plus `diag(ia)` and
/// [`try_solve_spd_in_place`], to rounding.
///
/// `q`, `qd`, `tau`, `armature`: positions, velocities, joint torques [N·m or N] and rotor
/// inertias `ia` [kg·m² or kg], length `model.dof()`; `out`: q̈, length `model.dof()`.
///
/// # Panics
/// If a length or `ws` does not match the model.
#[allow(clippy::too_many_arguments)]
pub fn forward_dynamics_armature_into(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64], tau: &[f64], armature: &[f64], formulation: Formulation, out: &mut [f64]) -> bool {
    check_len(model, "tau", tau);
    check_len(model, "rotor inertias ia", armature);
    let n = model.dof();
    if let Some(solved) = closed_forms::forward_dynamics(model, ws, q, qd, tau, armature, formulation, out) {
        return solved;
    }
    if n >= ABA_MIN_DOF {
        return crate::algorithms::aba::articulated_body(model, ws, q, qd, tau, armature, formulation, out);
    }
    crba_solve(model, ws, q, qd, tau, armature, formulation, out)
}

/// Solves `A x = b` for symmetric positive definite `A` by Cholesky, overwriting `A` with its
/// factor and `b` with `x`.
///
/// # Panics
/// If `A` is not positive definite (see [`try_solve_spd_in_place`]).
pub fn solve_spd_in_place(a: &mut nalgebra::DMatrix<f64>, b: &mut [f64]) {
    assert!(try_solve_spd_in_place(a, b), "matrix is not positive definite");
}

/// [`solve_spd_in_place`] that reports a matrix that is not positive definite by returning
/// false (`b` is then unspecified) instead of panicking.
pub fn try_solve_spd_in_place(a: &mut nalgebra::DMatrix<f64>, b: &mut [f64]) -> bool {
    let n = b.len();
    // factorise A = L Lᵀ (lower triangle)
    for j in 0..n {
        let mut d = a[(j, j)];
        for k in 0..j {
            d -= a[(j, k)] * a[(j, k)];
        }
        if !(d > 0.0) {
            return false;
        }
        let d = d.sqrt();
        a[(j, j)] = d;
        for i in j + 1..n {
            let mut s = a[(i, j)];
            for k in 0..j {
                s -= a[(i, k)] * a[(j, k)];
            }
            a[(i, j)] = s / d;
        }
    }
    // forward substitution L y = b
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= a[(i, k)] * b[k];
        }
        b[i] = s / a[(i, i)];
    }
    // back substitution Lᵀ x = y
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= a[(k, i)] * b[k];
        }
        b[i] = s / a[(i, i)];
    }
    true
}
