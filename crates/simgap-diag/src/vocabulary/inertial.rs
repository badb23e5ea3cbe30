//! `inertial_error`: any other wrong link parameter. The columns are every link's ten inertial
//! parameters through the regressor, in units of the prior's scales; the fit keeps every
//! corrected link physically consistent and regularised toward the URDF (see
//! [`crate::lsq::inertial`]).

use std::sync::Arc;

use nalgebra::{Matrix3, Vector3};
use simgap_core::{inertia_from_parameters, inertial_parameters, Model, SpatialInertia, PARAMS_PER_LINK};
use simgap_sim::{Effect, LinkDelta};

use super::effects::{percent, sig3, Entry, FittedTerm};
use super::{Column, Param, TermDesign};
use crate::lsq::inertial::InertialPrior;
use crate::prepare::dataset::FitData;

/// Every stacked parameter's column, in units of its scale.
pub(super) fn design(prior: &Arc<InertialPrior>, data: &[FitData]) -> TermDesign {
    let dof = data[0].dof;
    // every stacked parameter, in units of its scale
    let width = PARAMS_PER_LINK * dof;
    let mut values: Vec<Vec<f64>> = vec![Vec::new(); width];
    for d in data {
        for s in 0..d.len() {
            for j in 0..dof {
                let row = &d.regressor[(s * dof + j) * width..(s * dof + j + 1) * width];
                for (p, col) in values.iter_mut().enumerate() {
                    col.push(row[p] * prior.scales[p]);
                }
            }
        }
    }
    let cols = values.into_iter().map(|v| Column::new(None, v)).collect();
    TermDesign { cols, inertial: Some(prior.clone()), ..Default::default() }
}

/// The simulator effect of fitted corrections `theta` (in units of the prior's scales):
/// every link that changes by more than rounding.
pub(super) fn apply(model: &Model, prior: &InertialPrior, theta: &[f64]) -> Effect {
    let n = model.dof();
    let dpi: Vec<f64> = prior.scales.iter().zip(theta).map(|(s, t)| s * t).collect();
    let deltas = (0..n).map(|j| delta_of(model, j, &dpi[PARAMS_PER_LINK * j..PARAMS_PER_LINK * (j + 1)])).filter(|d| !negligible(model, d)).collect();
    Effect::InertialError { deltas }
}

/// The corrections' parameters in the report entry: Δmass, Δcom, Δinertia per changed link,
/// and the number of parameter directions the runs identify.
pub(super) fn report(model: &Model, prior: &InertialPrior, f: &FittedTerm, entry: &mut Entry<'_>) {
    let names = model.joint_names();
    if let Effect::InertialError { deltas } = apply(model, prior, &f.theta) {
        let e = &mut *entry.e;
        e.joints = deltas.iter().map(|d| names[d.joint].to_string()).collect();
        e.parameters.insert("delta_mass".into(), Param::PerJoint(deltas.iter().map(|d| d.mass).collect()));
        e.parameters.insert("delta_com".into(), Param::PerLink(deltas.iter().map(|d| d.com.to_vec()).collect()));
        e.parameters.insert("delta_inertia".into(), Param::PerLink(deltas.iter().map(|d| d.inertia.to_vec()).collect()));
        e.parameters.insert("identifiable_directions".into(), Param::Number(prior.identifiable as f64));
        e.description = describe_inertial(model, &deltas);
    }
}

/// The nearest physical rotational inertia: principal moments raised to be non-negative and to
/// obey the triangle inequality (for a planar arm the raised moments are the unobservable ones).
fn physical_inertia(i: &Matrix3<f64>) -> Matrix3<f64> {
    let eig = i.symmetric_eigen();
    let mut l: Vec<(f64, usize)> = eig.eigenvalues.iter().copied().enumerate().map(|(k, v)| (v.max(0.0), k)).collect();
    l.sort_by(|a, b| a.0.total_cmp(&b.0));
    let deficit = l[2].0 - l[0].0 - l[1].0;
    if deficit > 0.0 {
        l[0].0 += deficit / 2.0 + 1e-12;
        l[1].0 += deficit / 2.0 + 1e-12;
    }
    let mut d = Vector3::zeros();
    for (v, k) in l {
        d[k] = v;
    }
    eig.eigenvectors * Matrix3::from_diagonal(&d) * eig.eigenvectors.transpose()
}

fn delta_of(model: &Model, joint: usize, dpi: &[f64]) -> LinkDelta {
    let old = &model.joints()[joint].inertia;
    let mut p = inertial_parameters(old);
    for (a, b) in p.iter_mut().zip(dpi) {
        *a += b;
    }
    let raw: SpatialInertia = inertia_from_parameters(&p);
    // a link keeps a positive mass and a physical rotational inertia
    // a non-positive mass keeps the old centre of mass (the first moment cannot be honoured)
    let (mass, com) = if raw.mass > 0.0 { (raw.mass, raw.first_moment / raw.mass) } else { (1e-3 * old.mass.max(1e-3), old.com()) };
    let inertia_c = if raw.mass > 0.0 { raw.inertia_about_com() } else { old.inertia_about_com() };
    let new = SpatialInertia::from_com(mass, com, physical_inertia(&inertia_c));
    let dc: Vector3<f64> = new.com() - old.com();
    let di: Matrix3<f64> = new.inertia_about_com() - old.inertia_about_com();
    LinkDelta { joint, mass: new.mass - old.mass, com: [dc.x, dc.y, dc.z], inertia: [di[(0, 0)], di[(0, 1)], di[(0, 2)], di[(1, 1)], di[(1, 2)], di[(2, 2)]] }
}

/// Whether a link change is too small to state: mass within 1e-6 of the link's, centre of mass
/// within 1 µm, inertia within 1e-6 of the link's largest moment.
fn negligible(model: &Model, d: &LinkDelta) -> bool {
    let old = &model.joints()[d.joint].inertia;
    let m = old.mass.max(1e-3);
    let i = old.inertia_about_com().abs().max().max(m * 1e-4);
    d.mass.abs() <= 1e-6 * m && d.com.iter().all(|c| c.abs() <= 1e-6) && d.inertia.iter().all(|v| v.abs() <= 1e-6 * i)
}

/// "Link2 (joint Joint2): mass −12 %, COM +3 mm along x, inertia about the COM −48 %" per link.
fn describe_inertial(model: &Model, deltas: &[LinkDelta]) -> String {
    if deltas.is_empty() {
        return "no link differs from the URDF".into();
    }
    let parts: Vec<String> = deltas
        .iter()
        .map(|d| {
            let j = &model.joints()[d.joint];
            let old = &j.inertia;
            let mut words = Vec::new();
            if d.mass.abs() > 1e-4 * old.mass.max(1e-3) {
                let ratio = (old.mass + d.mass) / old.mass;
                let bound = if old.mass > 0.0 && (ratio <= 1.001 / crate::lsq::inertial::MASS_FACTOR || ratio >= 0.999 * crate::lsq::inertial::MASS_FACTOR) {
                    " (at the plausibility bound: the data pull further)"
                } else {
                    ""
                };
                words.push(if old.mass > 0.0 { format!("mass {} ({} kg){bound}", percent(d.mass / old.mass), sig3(d.mass)) } else { format!("mass {} kg", sig3(d.mass)) });
            }
            let com: Vec<String> = ["x", "y", "z"]
                .iter()
                .zip(d.com)
                .filter(|(_, c)| c.abs() >= 5e-4)
                .map(|(a, c)| format!("{}{:.0} mm along {a}", if c < 0.0 { "−" } else { "+" }, 1e3 * c.abs()))
                .collect();
            if !com.is_empty() {
                let reach = crate::lsq::inertial::link_reach(model)[d.joint];
                let at = (old.com() + Vector3::from(d.com)).norm() >= 0.999 * reach;
                words.push(format!("COM {}{}", com.join(", "), if at { format!(" (at its reach, {} m from the joint)", sig3(reach)) } else { String::new() }));
            }
            // the moment about the joint axis through the centre of mass
            let a = j.axis.normalize();
            let di = Matrix3::new(d.inertia[0], d.inertia[1], d.inertia[2], d.inertia[1], d.inertia[3], d.inertia[4], d.inertia[2], d.inertia[4], d.inertia[5]);
            let (i0, di_a) = ((a.transpose() * old.inertia_about_com() * a)[0], (a.transpose() * di * a)[0]);
            if di_a.abs() > 1e-4 * i0.abs().max(1e-9) {
                words.push(if i0 > 1e-12 {
                    format!("inertia about the COM (joint axis) {} ({} kg·m²)", percent(di_a / i0), sig3(di_a))
                } else {
                    format!("inertia about the COM (joint axis) {} kg·m²", sig3(di_a))
                });
            }
            if words.is_empty() {
                words.push("unchanged within rounding".into());
            }
            format!("{} (joint {}): {}", j.link, j.name, words.join(", "))
        })
        .collect();
    format!("inertial parameters differ from the URDF: {}", parts.join("; "))
}
