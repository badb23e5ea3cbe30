//! H, C and g together, sharing one set of passes.

use nalgebra::{DMatrix, DVector};

use crate::algorithms::closed_forms;
use crate::algorithms::coriolis::{fill_second_order, second_order_pass, SecondOrderOut};
use crate::algorithms::kinematics::check_len;
use crate::algorithms::rnea::gravity_from_composites;
use crate::algorithms::workspace::Workspace;
use crate::formulation::Formulation;
use crate::model::Model;

/// The terms of H(q) q̈ + C(q, q̇) q̇ + g(q) = τ at one state.
#[derive(Clone, Debug, PartialEq)]
pub struct DynamicsTerms {
    /// Mass matrix H, `dof × dof`.
    pub mass_matrix: DMatrix<f64>,
    /// Coriolis matrix C of the requested formulation, `dof × dof`.
    pub coriolis_matrix: DMatrix<f64>,
    /// Gravity torques g, length `dof`.
    pub gravity_torques: DVector<f64>,
}

impl DynamicsTerms {
    /// Zeroed terms sized for `model`.
    #[must_use]
    pub fn new(model: &Model) -> Self {
        let n = model.dof();
        DynamicsTerms { mass_matrix: DMatrix::zeros(n, n), coriolis_matrix: DMatrix::zeros(n, n), gravity_torques: DVector::zeros(n) }
    }
}

/// H(q), C(q, q̇) and g(q) in one call, cheaper than three: the kinematics, composite
/// inertias and momenta are computed once. An arm of two rotational joints uses its closed
/// form, generated into `ws` on the first call with the model (the general algorithms give the
/// same numbers to rounding).
///
/// # Panics
/// If a length or `ws` does not match the model.
#[must_use]
pub fn dynamics_terms(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64], formulation: Formulation) -> DynamicsTerms {
    let mut out = DynamicsTerms::new(model);
    dynamics_terms_into(model, ws, q, qd, formulation, &mut out);
    out
}

/// In-place [`dynamics_terms`].
///
/// # Panics
/// If a length, `ws` or `out` does not match the model.
pub fn dynamics_terms_into(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64], formulation: Formulation, out: &mut DynamicsTerms) {
    let n = model.dof();
    assert!(out.mass_matrix.shape() == (n, n) && out.coriolis_matrix.shape() == (n, n) && out.gravity_torques.len() == n, "dynamics terms output shape");
    if let Some(arm) = closed_forms::two_joint(model, ws) {
        check_len(model, "q", q);
        check_len(model, "qd", qd);
        arm.terms_into(q, qd, formulation, &mut out.mass_matrix, &mut out.coriolis_matrix, &mut out.gravity_torques);
        return;
    }
    second_order_pass(model, ws, q, qd);
    fill_second_order(model, ws, SecondOrderOut { h: Some(&mut out.mass_matrix), c: Some((&mut out.coriolis_matrix, formulation)), hdot: None });
    gravity_from_composites(model, ws, out.gravity_torques.as_mut_slice());
}
