//! `payload`: a point mass rigidly attached to the last link of the chain. Its column is the
//! torque of a unit point mass at the centre of mass `c` (the last link's regressor times the
//! point mass's ten inertial parameters); the mass is the fitted parameter (≥ 0, bounded by the
//! torques the drives delivered), `c` is searched.

use nalgebra::Vector3;
use simgap_core::{Model, PARAMS_PER_LINK};

use super::effects::{sig3, Entry};
use super::{Column, EffectReport, Param, TermDesign};
use crate::prepare::dataset::FitData;

/// The column of a payload at `com`, its mass bounded by `max_mass` and the delivered torques.
pub(super) fn design(com: [f64; 3], max_mass: f64, data: &[FitData]) -> TermDesign {
    let col = payload_column(data, com);
    let col_max = col.values.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let hi = payload_mass_bound(col_max, largest_command(data), max_mass);
    TermDesign { cols: vec![col], lo: vec![0.0], hi: vec![hi], ..Default::default() }
}

/// A payload's mass is not negative.
pub(super) fn physical(theta: &[f64]) -> bool {
    theta[0] >= -1e-12
}

/// The payload's parameters in its report entry.
pub(super) fn report(com: [f64; 3], th: &[f64], sd: &[f64], entry: &mut Entry<'_>) {
    entry.number("mass", th[0], 1.96 * sd[0]);
    entry.vector("com", com.to_vec());
}

/// The payload in words.
pub(super) fn describe(model: &Model, e: &EffectReport) -> String {
    let mass = match e.parameters.get("mass") {
        Some(Param::Number(x)) => *x,
        _ => f64::NAN,
    };
    let com = match e.parameters.get("com") {
        Some(Param::Vector(c)) => c.clone(),
        _ => vec![],
    };
    let link = model.joints().last().map_or("the last link", |j| j.link.as_str());
    let at: Vec<String> = com.iter().map(|c| format!("{:.0}", 1e3 * c)).collect();
    format!("payload of {} kg on {link}, centre of mass at ({}) mm in its frame", sig3(mass), at.join(", "))
}

/// The ten inertial parameters `(1, c, |c|² 1 − c cᵀ)` of a unit point mass at `com` [m],
/// in the regressor's order (mass, first moment, rotational inertia about the joint frame).
pub(crate) fn point_mass_parameters(com: [f64; 3]) -> [f64; PARAMS_PER_LINK] {
    let c = Vector3::from(com);
    [1.0, c.x, c.y, c.z, c.y * c.y + c.z * c.z, -c.x * c.y, -c.x * c.z, c.x * c.x + c.z * c.z, -c.y * c.z, c.x * c.x + c.y * c.y]
}

/// The torque of a unit point mass at `com` on the last link (its ten inertial parameters
/// [`point_mass_parameters`] through the regressor), as a global column.
pub(crate) fn payload_column(data: &[FitData], com: [f64; 3]) -> Column {
    let pi = point_mass_parameters(com);
    let rows = payload_basis_rows(data);
    Column::new(None, rows.chunks_exact(PARAMS_PER_LINK).map(|row| row.iter().zip(&pi).map(|(a, b)| a * b).sum()).collect())
}

/// The last link's ten regressor entries of every row (sample × joint, over runs), row-major:
/// a payload's column is their combination by [`point_mass_parameters`].
pub(crate) fn payload_basis_rows(data: &[FitData]) -> Vec<f64> {
    let dof = data[0].dof;
    let last = dof - 1;
    let width = PARAMS_PER_LINK * dof;
    let mut v = Vec::with_capacity(data.iter().map(|d| d.len() * dof * PARAMS_PER_LINK).sum());
    for d in data {
        for s in 0..d.len() {
            for j in 0..dof {
                v.extend_from_slice(&d.regressor[(s * dof + j) * width + PARAMS_PER_LINK * last..(s * dof + j) * width + PARAMS_PER_LINK * (last + 1)]);
            }
        }
    }
    v
}

/// The largest commanded torque over the fit runs [N·m] (what bounds a payload's mass).
pub(crate) fn largest_command(data: &[FitData]) -> f64 {
    data.iter().flat_map(|d| d.tau.iter()).fold(0.0f64, |m, v| m.max(v.abs()))
}

/// Upper bound of a payload's mass [kg] for a unit-mass column whose largest entry is
/// `col_max` [N·m/kg]: a payload whose torque would exceed three times the largest commanded
/// torque `tau_max` is no payload this robot carried, and none is heavier than `max_mass`.
pub(crate) fn payload_mass_bound(col_max: f64, tau_max: f64, max_mass: f64) -> f64 {
    let hi = if col_max > 0.0 && tau_max > 0.0 { 3.0 * tau_max / col_max } else { f64::INFINITY };
    hi.min(max_mass)
}

/// The linear first guess of a payload: mass and first moment of the last link, as four
/// global columns (rotational part ignored).
pub(crate) fn payload_linear_design(data: &[FitData]) -> TermDesign {
    let dof = data[0].dof;
    let last = dof - 1;
    let width = PARAMS_PER_LINK * dof;
    let cols = (0..4)
        .map(|p| {
            let mut v = Vec::new();
            for d in data {
                for s in 0..d.len() {
                    for j in 0..dof {
                        v.push(d.regressor[(s * dof + j) * width + PARAMS_PER_LINK * last + p]);
                    }
                }
            }
            Column::new(None, v)
        })
        .collect();
    TermDesign::free(cols)
}
