//! URDF pitfalls the data reveal, in words: an inertia written about the joint axis as if it
//! were about the centre of mass, a missing rotor inertia, a wrong gravity direction, a joint
//! whose sign in the log is opposite to the URDF's axis.
//!
//! Each is a small dedicated fit on the nominal torque residual `r = τ − (H q̈ + C q̇ + g)` of
//! the fit runs (with Coulomb and viscous friction fitted alongside, bounded, so that friction is
//! not mistaken for them), judged by cross-validation like the selection:
//!
//! - **Inertia about the joint axis written as about the COM.** For link i with mass m, centre of
//!   mass at distance d from its joint axis and URDF moment `I` about the axis through the COM,
//!   the column of the correction `ΔI_c = −κ m d²` (along the axis). A fitted κ near 1 that removes
//!   a clear part of the residual says the URDF's number is the moment about the joint axis
//!   (parallel-axis theorem: `I_axis = I_c + m d²`).
//! - **Missing rotor inertia.** A fitted armature `ia ≥ 0` large against the link inertia the
//!   joint moves (mean `H_jj`), while the URDF has none.
//! - **Gravity direction.** The residual ≈ β g(q) with β near −2: the model's gravity torque has
//!   the wrong sign (the direction of gravity, or the zero of q, is flipped).
//! - **Joint sign.** The commanded torque opposed to the torque the model needs for the logged
//!   motion (correlation below −0.5): the joint's axis or its sign in the log is flipped.

use simgap_core::{gravity_torques_into, mass_matrix_into, Model, Workspace, PARAMS_PER_LINK};

use crate::lsq::{fit, grams, Fit, Problem};
use crate::prepare::dataset::FitData;
use crate::vocabulary::effects::sig3;
use crate::vocabulary::{design, Column, Term, TermDesign};

/// Smallest relative decrease of the cross-validated residual for a pitfall to be named.
const MIN_GAIN: f64 = 0.1;

/// Plain-language notes on URDF pitfalls the fit data reveal (empty when none is seen).
///
/// `data` are the prepared fit runs of `model` (with the regressor, see
/// [`crate::PrepareOptions::regressor`]).
pub(crate) fn urdf_pitfalls(model: &Model, data: &[FitData]) -> Vec<String> {
    let mut notes = Vec::new();
    if data.is_empty() || data.iter().all(|d| d.is_empty()) {
        return notes;
    }
    let n = model.dof();
    let p = Problem::new(data);
    let friction: Vec<TermDesign> = (0..n).flat_map(|j| [design(&Term::Coulomb { joint: j, w: data[0].dry_width[j].mid() }, data), design(&Term::Viscous(j), data)]).collect();
    let fit_with = |extra: &[TermDesign]| -> Fit {
        let mut ds: Vec<&TermDesign> = friction.iter().collect();
        ds.extend(extra.iter());
        fit(&p, &grams(&p, &ds))
    };
    let base = fit_with(&[]);
    let k0: usize = friction.iter().map(|d| d.cols.len()).sum();
    let gain = |f: &Fit| if base.cv_mse > 0.0 { (base.cv_mse - f.cv_mse) / base.cv_mse } else { 0.0 };
    let names = model.joint_names();

    // inertia about the joint axis written as if about the centre of mass
    if data.iter().all(|d| !d.regressor.is_empty()) {
        for (i, j) in model.joints().iter().enumerate() {
            let s = &j.inertia;
            let a = j.axis.normalize();
            let c = s.com();
            let d2 = (c.norm_squared() - a.dot(&c).powi(2)).max(0.0);
            let md2 = s.mass * d2;
            let i_axis_c = (a.transpose() * s.inertia_about_com() * a)[0];
            if s.mass <= 0.0 || md2 < 0.2 * i_axis_c.abs().max(1e-12) {
                continue;
            }
            // ΔĪ = −m d² a aᵀ (about the joint origin; the same shift about the COM)
            let v = [0.0, 0.0, 0.0, 0.0, -md2 * a.x * a.x, -md2 * a.x * a.y, -md2 * a.x * a.z, -md2 * a.y * a.y, -md2 * a.y * a.z, -md2 * a.z * a.z];
            let col = regressor_column(data, i, &v);
            let f = fit_with(&[TermDesign::free(vec![col])]);
            let kappa = f.theta[k0];
            if (0.5..=1.5).contains(&kappa) && gain(&f) >= MIN_GAIN {
                let fixed = i_axis_c - md2;
                let advice = if fixed > 0.0 {
                    format!("about the COM it would be I − m d² = {} kg·m²", sig3(fixed))
                } else {
                    format!("I − m d² = {} kg·m² is negative, so the link is close to a point mass there (its inertia about the COM ≈ 0)", sig3(fixed))
                };
                notes.push(format!(
                    "{} (joint {}): the URDF inertia about the joint axis through the COM ({} kg·m²) looks like the inertia about the joint axis itself: the data fit a correction of {} × m d² = {} kg·m² (m = {} kg, d = {} m from the axis), removing {:.0} % of the cross-validated residual; {advice}",
                    j.link,
                    names[i],
                    sig3(i_axis_c),
                    sig3(kappa),
                    sig3(-kappa * md2),
                    sig3(s.mass),
                    sig3(d2.sqrt()),
                    100.0 * gain(&f)
                ));
            }
        }
    }

    // missing rotor inertia (none where the effort was measured on the link side of the gearbox,
    // after the rotor)
    let h_mean = mean_mass_diagonal(model, data);
    let rotor = crate::vocabulary::rotor::visible(data);
    for j in (0..n).filter(|_| rotor) {
        let f = fit_with(&[design(&Term::Armature(j), data)]);
        let ia = f.theta[k0];
        if ia > 0.1 * h_mean[j] && gain(&f) >= MIN_GAIN {
            let unit = simgap_sim::Quantity::JointInertia.unit(model.joints()[j].kind);
            notes.push(format!(
                "joint {}: the data show a rotor inertia (armature) of {} {unit}, {:.0} % of the link inertia the joint moves (mean H_jj = {} {unit}), which the URDF lacks; add the motor's rotor inertia × gear ratio² (removes {:.0} % of the cross-validated residual)",
                names[j],
                sig3(ia),
                100.0 * ia / h_mean[j],
                sig3(h_mean[j]),
                100.0 * gain(&f)
            ));
        }
    }

    // gravity direction: r ≈ β g(q), β near −2
    let gcol = gravity_column(model, data);
    let mut gravity_flipped = false;
    if gcol.values.iter().any(|v| *v != 0.0) {
        let f = fit_with(&[TermDesign::free(vec![gcol])]);
        let beta = f.theta[k0];
        if (-2.5..=-1.5).contains(&beta) && gain(&f) >= 0.3 {
            gravity_flipped = true;
            notes.push(format!(
                "the torque residual is {} × the model's gravity torque g(q) (removing {:.0} % of it): the model's gravity has the wrong sign; check the direction of gravity and which way q = 0 points",
                sig3(beta),
                100.0 * gain(&f)
            ));
        }
    }

    // joint sign: commanded torque against the torque the model needs (a flipped gravity
    // explains that already)
    for (j, name) in names.iter().enumerate().filter(|_| !gravity_flipped) {
        // centred: an offset (a torque sensor's bias) is no sign
        let (mut count, mut mean_tau, mut mean_model) = (0.0f64, 0.0, 0.0);
        for d in data {
            for s in 0..d.len() {
                mean_tau += d.tau[s * n + j];
                mean_model += d.tau[s * n + j] - d.residual[s * n + j];
                count += 1.0;
            }
        }
        mean_tau /= count.max(1.0);
        mean_model /= count.max(1.0);
        let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
        for d in data {
            for s in 0..d.len() {
                let tau = d.tau[s * n + j] - mean_tau;
                let model_tau = d.tau[s * n + j] - d.residual[s * n + j] - mean_model;
                sxy += tau * model_tau;
                sxx += tau * tau;
                syy += model_tau * model_tau;
            }
        }
        let corr = sxy / (sxx * syy).sqrt().max(1e-300);
        // only where the model's own torque is most of what was measured: a small model torque
        // against friction, an offset or a spring says nothing of the axis
        let dominates = syy >= SIGN_MODEL_SHARE * SIGN_MODEL_SHARE * sxx;
        if corr < -0.5 && dominates {
            notes.push(format!(
                "joint {name}: the commanded torque is opposed to the torque the model needs for the logged motion (correlation {corr:.2}, the model's torque {:.0} % of the commanded one, RMS): the joint's axis in the URDF, or its sign in the log, seems flipped",
                100.0 * (syy / sxx.max(1e-300)).sqrt()
            ));
        }
    }
    notes
}

/// The joint-sign note needs the model's torque (RMS, centred) to be at least this share of the
/// commanded torque's.
const SIGN_MODEL_SHARE: f64 = 0.5;

/// The residual column of a change `v` of link `link`'s ten inertial parameters.
fn regressor_column(data: &[FitData], link: usize, v: &[f64; PARAMS_PER_LINK]) -> Column {
    let dof = data[0].dof;
    let width = PARAMS_PER_LINK * dof;
    let mut values = Vec::new();
    for d in data {
        for s in 0..d.len() {
            for j in 0..dof {
                let row = &d.regressor[(s * dof + j) * width + PARAMS_PER_LINK * link..(s * dof + j) * width + PARAMS_PER_LINK * (link + 1)];
                values.push(row.iter().zip(v).map(|(a, b)| a * b).sum());
            }
        }
    }
    Column::new(None, values)
}

/// The model's gravity torque g(q) at the fit samples, as a global column.
fn gravity_column(model: &Model, data: &[FitData]) -> Column {
    let n = model.dof();
    let mut ws = Workspace::new(model);
    let mut g = vec![0.0; n];
    let mut values = Vec::new();
    for d in data {
        for s in 0..d.len() {
            gravity_torques_into(model, &mut ws, &d.q[s * n..(s + 1) * n], &mut g);
            values.extend_from_slice(&g);
        }
    }
    Column::new(None, values)
}

/// Mean of the diagonal of H(q) over the fit samples, per joint.
pub(crate) fn mean_mass_diagonal(model: &Model, data: &[FitData]) -> Vec<f64> {
    let n = model.dof();
    let mut ws = Workspace::new(model);
    let mut h = nalgebra::DMatrix::zeros(n, n);
    let mut acc = vec![0.0; n];
    let mut count = 0usize;
    for d in data {
        for s in (0..d.len()).step_by(10) {
            mass_matrix_into(model, &mut ws, &d.q[s * n..(s + 1) * n], &mut h);
            for (j, a) in acc.iter_mut().enumerate() {
                *a += h[(j, j)];
            }
            count += 1;
        }
    }
    acc.iter().map(|a| a / count.max(1) as f64).collect()
}
