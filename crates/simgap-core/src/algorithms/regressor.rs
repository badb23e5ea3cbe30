//! The inverse-dynamics regressor: τ = Y(q, q̇, q̈) π, linear in the inertial parameters.

use nalgebra::{DMatrix, Matrix3, Vector3};

use crate::algorithms::kinematics::{check_len, forward_kinematics, velocities};
use crate::algorithms::workspace::Workspace;
use crate::model::Model;
use crate::spatial::{Motion, SpatialInertia};

/// Number of inertial parameters per link.
pub const PARAMS_PER_LINK: usize = 10;

/// The ten inertial parameters of one link, in the joint frame about its origin:
/// `[m, m cx, m cy, m cz, Ixx, Ixy, Ixz, Iyy, Iyz, Izz]` (rotational inertia about the frame
/// origin, not the centre of mass).
#[must_use]
pub fn inertial_parameters(inertia: &SpatialInertia) -> [f64; PARAMS_PER_LINK] {
    let h = &inertia.first_moment;
    let i = &inertia.rotational;
    [inertia.mass, h.x, h.y, h.z, i[(0, 0)], i[(0, 1)], i[(0, 2)], i[(1, 1)], i[(1, 2)], i[(2, 2)]]
}

/// The inverse of [`inertial_parameters`].
#[must_use]
pub fn inertia_from_parameters(p: &[f64]) -> SpatialInertia {
    assert!(p.len() >= PARAMS_PER_LINK, "expected {PARAMS_PER_LINK} parameters, got {}", p.len());
    SpatialInertia { mass: p[0], first_moment: Vector3::new(p[1], p[2], p[3]), rotational: Matrix3::new(p[4], p[5], p[6], p[5], p[7], p[8], p[6], p[8], p[9]) }
}

/// Inverse-dynamics regressor Y, `dof × 10·dof`, such that
/// `inverse_dynamics(q, q̇, q̈) = Y π` with π the stacked [`inertial_parameters`] of every link
/// in chain order (gravity included).
///
/// Column `10 i + p` is the joint torque produced by link i's parameter p alone: the link's
/// Newton–Euler force `U a_i + v_i ×* (U v_i)` for the unit inertia U of that parameter,
/// projected on the joints that carry link i (Atkeson, An & Hollerbach 1986).
///
/// # Panics
/// If a length, `ws` or `out` does not match the model.
pub fn inverse_dynamics_regressor_into(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64], qdd: &[f64], out: &mut DMatrix<f64>) {
    let n = model.dof();
    check_len(model, "qdd", qdd);
    assert_eq!(out.shape(), (n, PARAMS_PER_LINK * n), "regressor output shape");
    forward_kinematics(model, ws, q);
    velocities(model, ws, qd);
    out.fill(0.0);
    // forward pass: link accelerations, base accelerating at −gravity
    let mut a = Motion::new(Vector3::zeros(), -model.gravity());
    for i in 0..n {
        a = ws.subspace_rates[i].scale_add(qd[i], &a);
        a = ws.subspaces[i].scale_add(qdd[i], &a);
        ws.accelerations[i] = a;
    }
    // per link and parameter: force of the unit inertia, projected on the joints up to i
    for i in 0..n {
        let pose = &ws.poses[i];
        let (v, a) = (ws.velocities[i], ws.accelerations[i]);
        for p in 0..PARAMS_PER_LINK {
            let mut unit = [0.0; PARAMS_PER_LINK];
            unit[p] = 1.0;
            let u = inertia_from_parameters(&unit).transformed(pose);
            let f = u.mul_motion(&a) + v.cross_force(&u.mul_motion(&v));
            for j in 0..=i {
                out[(j, PARAMS_PER_LINK * i + p)] = ws.subspaces[j].dot(&f);
            }
        }
    }
}

/// Allocating [`inverse_dynamics_regressor_into`].
///
/// # Panics
/// If a length or `ws` does not match the model.
#[must_use]
pub fn inverse_dynamics_regressor(model: &Model, ws: &mut Workspace, q: &[f64], qd: &[f64], qdd: &[f64]) -> DMatrix<f64> {
    let mut out = DMatrix::zeros(model.dof(), PARAMS_PER_LINK * model.dof());
    inverse_dynamics_regressor_into(model, ws, q, qd, qdd, &mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::algorithms::rnea::inverse_dynamics;

    #[test]
    fn regressor_times_parameters_equals_inverse_dynamics() {
        let model = Model::from_urdf_str(crate::robots::PAPER_ARM_URDF).unwrap();
        let mut ws = Workspace::new(&model);
        let (q, qd, qdd) = ([0.4, -1.1], [0.7, -0.3], [1.5, 2.0]);
        let y = inverse_dynamics_regressor(&model, &mut ws, &q, &qd, &qdd);
        let pi: Vec<f64> = model.joints().iter().flat_map(|j| inertial_parameters(&j.inertia)).collect();
        let tau = &y * nalgebra::DVector::from_vec(pi);
        let expected = inverse_dynamics(&model, &mut ws, &q, &qd, &qdd);
        assert!((tau - expected).norm() < 1e-10);
    }
}
