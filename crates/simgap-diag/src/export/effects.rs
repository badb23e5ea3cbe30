//! The selected effects read back from their report form into per-joint numbers (model order)
//! and the corrected link inertias.

use simgap_core::{Model, SpatialInertia};
use simgap_sim::{Effect, EffectKind, LinkDelta, DEFAULT_COULOMB_WIDTH};

use super::ExportError;
use crate::{EffectReport, Param};

/// The selected effects as numbers, per joint in model order; neutral where nothing acts.
#[derive(Clone, Debug)]
pub(super) struct Corrections {
    /// The corrected model: the input's with payload and inertial errors applied (its bodies,
    /// [`Corrections::body`]).
    pub(super) corrected: Model,
    /// Bodies whose inertia the effects change.
    pub(super) changed: Vec<bool>,
    /// Viscous friction [N·m·s/rad or N·s/m].
    pub(super) viscous: Vec<f64>,
    /// Coulomb friction level [N·m or N].
    pub(super) coulomb: Vec<f64>,
    /// Slope at rest of the smoothed Coulomb friction `fc tanh(q̇/w)`, the sum of `fc/w` over
    /// the entries [N·m·s/rad or N·s/m]; `+∞` where a width is 0 (the exact sign), and
    /// [`DEFAULT_COULOMB_WIDTH`] where an entry states no width.
    pub(super) coulomb_slope: Vec<f64>,
    /// Rotor inertia [kg·m² or kg].
    pub(super) armature: Vec<f64>,
    /// Torque gain [–].
    pub(super) gain: Vec<f64>,
    /// Saturation limit of the commanded torque [N·m or N]; `+∞` for none.
    pub(super) limit: Vec<f64>,
    /// Spring stiffness [N·m/rad or N/m].
    pub(super) spring_k: Vec<f64>,
    /// Spring rest position [rad or m] (the stiffness-weighted rest position where several
    /// springs act on one joint).
    pub(super) spring_q0: Vec<f64>,
    /// Encoder offset [rad or m]: the joint is at its measured position plus it.
    pub(super) encoder_offset: Vec<f64>,
    /// Backlash widths [rad or m] (0: no play).
    pub(super) backlash: Vec<f64>,
}

/// A parameter's values per joint of the effect, as model indices (`PerJoint` aligned with
/// `joints`, or one whole-robot number for every joint of the effect).
pub(super) fn per_joint(model: &Model, e: &EffectReport, key: &str) -> Result<Vec<(usize, f64)>, ExportError> {
    let idx = joint_indices(model, e)?;
    let values: Vec<f64> = match e.parameters.get(key) {
        Some(Param::PerJoint(v)) | Some(Param::Vector(v)) => v.clone(),
        Some(Param::Number(x)) => vec![*x; idx.len()],
        Some(Param::PerLink(_)) => return Err(bad(e, format!("parameter '{key}' is a per-link table; expected one number per joint"))),
        None => return Err(bad(e, format!("has no parameter '{key}'"))),
    };
    if values.len() != idx.len() {
        return Err(bad(e, format!("parameter '{key}' has {} values for {} joints {:?}; expected one per joint", values.len(), idx.len(), e.joints)));
    }
    if let Some(x) = values.iter().find(|x| !(x.is_finite() || (key == "limit" && **x == f64::INFINITY))) {
        return Err(bad(e, format!("parameter '{key}' has value {x}; expected a finite number")));
    }
    Ok(idx.into_iter().zip(values).collect())
}

/// The model indices of an effect's joints.
pub(super) fn joint_indices(model: &Model, e: &EffectReport) -> Result<Vec<usize>, ExportError> {
    e.joints
        .iter()
        .map(|name| model.joint_index(name).ok_or_else(|| bad(e, format!("names joint '{name}'; expected one of the model's joints {:?}", model.joint_names()))))
        .collect()
}

fn bad(e: &EffectReport, message: String) -> ExportError {
    ExportError::Effect { effect: e.effect.to_string(), message }
}

fn number(e: &EffectReport, key: &str) -> Result<f64, ExportError> {
    match e.parameters.get(key) {
        Some(Param::Number(x)) if x.is_finite() => Ok(*x),
        Some(other) => Err(bad(e, format!("parameter '{key}' is {other:?}; expected one finite number"))),
        None => Err(bad(e, format!("has no parameter '{key}'"))),
    }
}

fn triple(e: &EffectReport, key: &str, v: &[f64]) -> Result<[f64; 3], ExportError> {
    let t = <[f64; 3]>::try_from(v).map_err(|_| bad(e, format!("parameter '{key}' has {} numbers; expected 3", v.len())))?;
    if t.iter().any(|x| !x.is_finite()) {
        return Err(bad(e, format!("parameter '{key}' = {t:?}; expected finite numbers")));
    }
    Ok(t)
}

/// The payload and inertial-error entries as simulator effects (the form
/// [`simgap_sim::effects::apply_inertial_effects`] applies).
fn inertial_effect(model: &Model, e: &EffectReport) -> Result<Option<Effect>, ExportError> {
    match e.effect {
        EffectKind::Payload => {
            let com = match e.parameters.get("com") {
                Some(Param::Vector(v)) | Some(Param::PerJoint(v)) => triple(e, "com", v)?,
                _ => return Err(bad(e, "has no parameter 'com' (3 numbers, the last link's frame)".into())),
            };
            Ok(Some(Effect::Payload { mass: number(e, "mass")?, com }))
        }
        EffectKind::InertialError => {
            let idx = joint_indices(model, e)?;
            let rows = |key: &str, width: usize| -> Result<Vec<Vec<f64>>, ExportError> {
                let rows: Vec<Vec<f64>> = match e.parameters.get(key) {
                    Some(Param::PerLink(v)) => v.clone(),
                    Some(Param::PerJoint(v)) | Some(Param::Vector(v)) if width == 1 => v.iter().map(|x| vec![*x]).collect(),
                    None => vec![vec![0.0; width]; idx.len()],
                    Some(other) => return Err(bad(e, format!("parameter '{key}' is {other:?}; expected {width} numbers per link"))),
                };
                if rows.len() != idx.len() || rows.iter().any(|r| r.len() != width || r.iter().any(|x| !x.is_finite())) {
                    return Err(bad(e, format!("parameter '{key}' must hold {width} finite numbers for each of the {} links of joints {:?}", idx.len(), e.joints)));
                }
                Ok(rows)
            };
            let (dm, dc, di) = (rows("delta_mass", 1)?, rows("delta_com", 3)?, rows("delta_inertia", 6)?);
            let deltas = idx
                .iter()
                .enumerate()
                .map(|(k, &joint)| LinkDelta { joint, mass: dm[k][0], com: [dc[k][0], dc[k][1], dc[k][2]], inertia: [di[k][0], di[k][1], di[k][2], di[k][3], di[k][4], di[k][5]] })
                .collect();
            Ok(Some(Effect::InertialError { deltas }))
        }
        _ => Ok(None),
    }
}

impl Corrections {
    /// Reads the effects; the corrected bodies are exactly those of
    /// [`simgap_sim::effects::apply_inertial_effects`] (effects applied in the listed order).
    ///
    /// # Errors
    /// [`ExportError::Effect`] for an unknown joint or a parameter of the wrong shape or sign,
    /// [`ExportError::Sim`] when a corrected link is not physical.
    pub(super) fn read(model: &Model, effects: &[EffectReport]) -> Result<Corrections, ExportError> {
        let n = model.dof();
        let mut c = Corrections {
            corrected: model.clone(),
            changed: vec![false; n],
            viscous: vec![0.0; n],
            coulomb: vec![0.0; n],
            coulomb_slope: vec![0.0; n],
            armature: vec![0.0; n],
            gain: vec![1.0; n],
            limit: vec![f64::INFINITY; n],
            spring_k: vec![0.0; n],
            spring_q0: vec![0.0; n],
            encoder_offset: vec![0.0; n],
            backlash: vec![0.0; n],
        };
        let mut inertial = Vec::new();
        let mut spring_moment = vec![0.0; n];
        for e in effects {
            let nonneg = |key: &str| -> Result<Vec<(usize, f64)>, ExportError> {
                let v = per_joint(model, e, key)?;
                if let Some((_, x)) = v.iter().find(|(_, x)| *x < 0.0) {
                    return Err(bad(e, format!("parameter '{key}' = {x}; expected a number >= 0")));
                }
                Ok(v)
            };
            match e.effect {
                EffectKind::ViscousFriction => nonneg("b")?.into_iter().for_each(|(j, x)| c.viscous[j] += x),
                EffectKind::CoulombFriction => {
                    let fc = nonneg("fc")?;
                    let w = if e.parameters.contains_key("w") { nonneg("w")? } else { fc.iter().map(|&(j, _)| (j, DEFAULT_COULOMB_WIDTH)).collect() };
                    for ((j, fc), (_, w)) in fc.into_iter().zip(w) {
                        c.coulomb[j] += fc;
                        if fc > 0.0 {
                            c.coulomb_slope[j] += if w > 0.0 { fc / w } else { f64::INFINITY };
                        }
                    }
                }
                EffectKind::Armature => nonneg("ia")?.into_iter().for_each(|(j, x)| c.armature[j] += x),
                EffectKind::TorqueGain => per_joint(model, e, "k")?.into_iter().for_each(|(j, x)| c.gain[j] *= x),
                EffectKind::TorqueSaturation => nonneg("limit")?.into_iter().for_each(|(j, x)| c.limit[j] = c.limit[j].min(x)),
                EffectKind::EncoderOffset => per_joint(model, e, "offset")?.into_iter().for_each(|(j, x)| c.encoder_offset[j] += x),
                EffectKind::Backlash => nonneg("width")?.into_iter().for_each(|(j, x)| c.backlash[j] += x),
                EffectKind::JointSpring => {
                    let (k, q0) = (nonneg("k")?, per_joint(model, e, "q0")?);
                    for ((j, k), (_, q0)) in k.into_iter().zip(q0) {
                        c.spring_k[j] += k;
                        spring_moment[j] += k * q0;
                    }
                }
                _ => {
                    if let Some(effect) = inertial_effect(model, e)? {
                        for j in effect.joints_acted() {
                            c.changed[j] = true;
                        }
                        if matches!(effect, Effect::Payload { .. }) {
                            c.changed[n - 1] = true;
                        }
                        inertial.push(effect);
                    }
                }
            }
        }
        for j in 0..n {
            if c.spring_k[j] > 0.0 {
                c.spring_q0[j] = spring_moment[j] / c.spring_k[j];
            }
        }
        c.corrected = simgap_sim::effects::apply_inertial_effects(model, &inertial)?;
        Ok(c)
    }

    /// Body inertia of joint `i`'s link in the corrected model (payload and inertial errors
    /// applied), about the body's frame origin (the frame of the link its joint moves).
    pub(super) fn body(&self, i: usize) -> &SpatialInertia {
        &self.corrected.joints()[i].inertia
    }

    /// Every body inertia of the corrected model, in joint order ([`Corrections::body`]).
    pub(super) fn bodies(&self) -> impl Iterator<Item = &SpatialInertia> {
        self.corrected.joints().iter().map(|j| &j.inertia)
    }
}
