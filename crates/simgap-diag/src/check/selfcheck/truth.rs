//! The self-check's truth against what a diagnosis found: the (effect, joint) pairs hidden
//! ([`truth_set`]) and selected ([`found_set`]), found parameters against their true values and
//! 95 % intervals, and selected effects outside their physical range ([`implausible`]) or
//! contradicted by the report's own selection log ([`contradicted`]).

use std::collections::{BTreeMap, BTreeSet};

use simgap_core::{mass_matrix, Model, Workspace};
use simgap_sim::{Effect, EffectKind, Run};

use crate::report::Diagnosis;
use crate::vocabulary::effects::{EffectReport, Param};

/// The whole-robot effects: their (effect, joint) pairs have joint `None`.
pub(super) const WHOLE: [EffectKind; 4] = [EffectKind::Payload, EffectKind::InertialError, EffectKind::TimeDelay, EffectKind::CoriolisStructure];

/// The (effect, joint) pairs of a set of effects; whole-robot effects have joint `None`.
///
/// A torque offset on a joint that also carries a spring is not a pair of its own: the spring's
/// torque `−k (q − q0)` holds a constant `k q0`, so `−k (q − q0) + o` is one spring about
/// `q0 + o / k`, and no data tell the two apart (the diagnosis reports the spring, whose rest
/// position holds the offset).
pub fn truth_set(model: &Model, effects: &[Effect]) -> BTreeSet<(String, Option<String>)> {
    let names = model.joint_names();
    let sprung: BTreeSet<usize> = effects.iter().filter(|e| matches!(e, Effect::JointSpring { .. })).flat_map(|e| e.joints_acted()).collect();
    let mut s = BTreeSet::new();
    for e in effects {
        if WHOLE.contains(&e.kind()) {
            s.insert((e.name().to_string(), None));
        } else {
            for j in e.joints_acted() {
                if matches!(e, Effect::TorqueOffset { .. }) && sprung.contains(&j) {
                    continue;
                }
                s.insert((e.name().to_string(), Some(names[j].to_string())));
            }
        }
    }
    s
}

/// The (effect, joint) pairs the diagnosis selected.
pub fn found_set(d: &Diagnosis) -> BTreeSet<(String, Option<String>)> {
    let mut s = BTreeSet::new();
    for e in &d.report.selected_effects {
        if WHOLE.contains(&e.effect) {
            s.insert((e.effect.to_string(), None));
        } else {
            for j in &e.joints {
                s.insert((e.effect.to_string(), Some(j.clone())));
            }
        }
    }
    s
}

/// One found parameter against its true value: `(effect.parameter, truth, found, 95 %
/// half-width)` (the half-width `NaN` where the report gives none: grid-searched values).
pub(super) type Comparison = (String, f64, f64, f64);

/// The found parameters of `reports` (selected effects) against the truth, for the true effects
/// found on their true joints.
pub(super) fn comparisons(model: &Model, truth: &[Effect], reports: &[EffectReport]) -> Vec<Comparison> {
    let names = model.joint_names();
    let mut out = Vec::new();
    for e in truth {
        let Some(rep) = reports.iter().find(|r| r.effect == e.kind()) else { continue };
        let per_joint = |key: &str, values: &[f64]| -> Vec<Comparison> {
            let mut v = Vec::new();
            if let (Some(Param::PerJoint(found)), unc) = (rep.parameters.get(key), rep.uncertainty.get(key)) {
                for j in e.joints_acted() {
                    if let Some(pos) = rep.joints.iter().position(|n| n == names[j]) {
                        let t = values[j];
                        let hw = match unc {
                            Some(Param::PerJoint(u)) => u.get(pos).copied().unwrap_or(f64::NAN),
                            _ => f64::NAN,
                        };
                        if t.is_finite() && t != 0.0 {
                            v.push((format!("{}.{key}", e.name()), t, found[pos], hw));
                        }
                    }
                }
            }
            v
        };
        match e {
            Effect::ViscousFriction { b } => out.extend(per_joint("b", b)),
            Effect::CoulombFriction { fc, .. } => out.extend(per_joint("fc", fc)),
            Effect::StribeckFriction { fc, fs, .. } => {
                out.extend(per_joint("fc", fc));
                out.extend(per_joint("fs", fs));
            }
            Effect::Armature { ia } => out.extend(per_joint("ia", ia)),
            Effect::TorqueGain { k } => out.extend(per_joint("k", k)),
            Effect::TorqueOffset { offset } => out.extend(per_joint("offset", offset)),
            Effect::EncoderOffset { offset } => out.extend(per_joint("offset", offset)),
            Effect::Backlash { width } => out.extend(per_joint("width", width)),
            Effect::TorqueSaturation { limit } => out.extend(per_joint("limit", limit)),
            Effect::Cogging { amplitude, .. } => out.extend(per_joint("amplitude", amplitude)),
            Effect::JointSpring { k, .. } => out.extend(per_joint("k", k)),
            Effect::LoadFriction { fc, mu, .. } => {
                out.extend(per_joint("fc", fc));
                out.extend(per_joint("mu", mu));
            }
            Effect::LoadStribeckFriction { fc, mu, fs, mus, .. } => {
                for (key, v) in [("fc", fc), ("mu", mu), ("fs", fs), ("mus", mus)] {
                    out.extend(per_joint(key, v));
                }
            }
            Effect::DirectionalFriction { fc_pos, fc_neg, b_pos, b_neg, .. } => {
                for (key, v) in [("fc_pos", fc_pos), ("fc_neg", fc_neg), ("b_pos", b_pos), ("b_neg", b_neg)] {
                    out.extend(per_joint(key, v));
                }
            }
            Effect::TimeDelay { delay } => {
                if let Some(Param::Number(f)) = rep.parameters.get("delay") {
                    out.push((format!("{}.delay", EffectKind::TimeDelay), *delay, *f, f64::NAN));
                }
            }
            Effect::Payload { mass, .. } => {
                if let Some(Param::Number(f)) = rep.parameters.get("mass") {
                    let hw = match rep.uncertainty.get("mass") {
                        Some(Param::Number(u)) => *u,
                        _ => f64::NAN,
                    };
                    out.push((format!("{}.mass", EffectKind::Payload), *mass, *f, hw));
                }
            }
            _ => {}
        }
    }
    out
}

/// Whether the found value lies within its 95 % half-width of the truth.
pub(super) fn inside(c: &Comparison) -> bool {
    (c.2 - c.1).abs() <= c.3
}

/// Of the comparisons with a reported interval: (truth inside found ± half-width, count).
pub(super) fn coverage_of(c: &[Comparison]) -> (usize, usize) {
    let with: Vec<&Comparison> = c.iter().filter(|x| x.3.is_finite()).collect();
    (with.iter().filter(|x| inside(x)).count(), with.len())
}

/// The selected effects of `reports` outside their physical range on `model` and the fit runs
/// `fit`, or whose reported 95 % intervals hold their neutral value in every parameter (no
/// finding): the self-check's own statement of the ranges, apart from the pipeline's.
///
/// Ranges: a rotor inertia positive and at most a hundred times the largest `H_jj` its joint
/// moves over the fit runs; a torque offset at most the largest torque logged on its joint; a
/// torque gain within 0.2–5; frictions, springs and load-friction coefficients non-negative,
/// mu at most 1; a payload's mass positive.
pub fn implausible(model: &Model, fit: &[Run], reports: &[EffectReport]) -> Vec<String> {
    let names = model.joint_names();
    let n = model.dof();
    let mut ws = Workspace::new(model);
    // the largest H_jj and |τ_j| over the fit runs (every 20th sample)
    let (mut h_max, mut tau_max) = (vec![0.0f64; n], vec![0.0f64; n]);
    for r in fit.iter().filter(|r| r.dof() == n) {
        for k in (0..r.len()).step_by(20) {
            let h = mass_matrix(model, &mut ws, &r.q[k * n..(k + 1) * n]);
            for j in 0..n {
                h_max[j] = h_max[j].max(h[(j, j)]);
            }
        }
        for (i, t) in r.tau.iter().enumerate() {
            tau_max[i % n] = tau_max[i % n].max(t.abs());
        }
    }
    let mut out = Vec::new();
    for e in reports {
        // a per-joint entry of `map` at position `pos` (NaN where absent)
        let at = |map: &BTreeMap<String, Param>, key: &str, pos: usize| match map.get(key) {
            Some(Param::PerJoint(v)) => v.get(pos).copied().unwrap_or(f64::NAN),
            _ => f64::NAN,
        };
        for (pos, joint) in e.joints.iter().enumerate() {
            let Some(j) = names.iter().position(|x| x == joint) else { continue };
            let value = |key: &str| at(&e.parameters, key, pos);
            let hw = |key: &str| at(&e.uncertainty, key, pos);
            let nonneg = |keys: &[&str]| keys.iter().all(|k| !(value(k) < -1e-9));
            let (in_range, neutral): (bool, Vec<(&str, f64)>) = match e.effect {
                EffectKind::Armature => (value("ia") > 0.0 && value("ia") <= 100.0 * h_max[j], vec![("ia", 0.0)]),
                EffectKind::TorqueOffset => (tau_max[j] == 0.0 || value("offset").abs() <= tau_max[j], vec![("offset", 0.0)]),
                EffectKind::TorqueGain => ((0.2..=5.0).contains(&value("k")), vec![("k", 1.0)]),
                EffectKind::EncoderOffset => (value("offset").abs() <= crate::vocabulary::OFFSET_MAX, vec![("offset", 0.0)]),
                EffectKind::Backlash => (value("width") > 0.0 && value("width") <= 5f64.to_radians(), vec![]),
                EffectKind::ViscousFriction => (nonneg(&["b"]), vec![("b", 0.0)]),
                EffectKind::CoulombFriction => (nonneg(&["fc"]), vec![("fc", 0.0)]),
                EffectKind::StribeckFriction => (nonneg(&["fc", "fs"]), vec![("fc", 0.0), ("fs", 0.0)]),
                EffectKind::JointSpring => (nonneg(&["k"]), vec![("k", 0.0)]),
                EffectKind::LoadFriction => (nonneg(&["fc", "mu"]) && !(value("mu") > 1.0), vec![("fc", 0.0), ("mu", 0.0)]),
                EffectKind::LoadStribeckFriction => (
                    nonneg(&["fc", "mu"]) && !(value("fs") < value("fc") - 1e-9) && !(value("mus") < value("mu") - 1e-9) && !(value("mus") > 1.0),
                    vec![("fc", 0.0), ("mu", 0.0), ("fs", 0.0), ("mus", 0.0)],
                ),
                EffectKind::DirectionalFriction => (nonneg(&["fc_pos", "fc_neg", "b_pos", "b_neg"]), vec![("fc_pos", 0.0), ("fc_neg", 0.0), ("b_pos", 0.0), ("b_neg", 0.0)]),
                _ => (true, vec![]),
            };
            // no finding: every neutral-valued parameter's interval (where given) holds it
            let given: Vec<&(&str, f64)> = neutral.iter().filter(|(k, _)| hw(k).is_finite()).collect();
            let no_finding = !given.is_empty() && given.iter().all(|(k, v)| (value(k) - v).abs() <= hw(k));
            if !in_range || no_finding {
                out.push(format!("{}@{joint}{}", e.effect, if in_range { " (its interval holds no effect)" } else { " (outside its physical range)" }));
            }
        }
        if e.effect == EffectKind::Payload && !matches!(e.parameters.get("mass"), Some(Param::Number(m)) if *m > 0.0) {
            out.push(format!("{} (mass not positive)", EffectKind::Payload));
        }
    }
    out
}

/// The selected effects of `report` (`effect@joint`) whose last decision in the report's
/// selection log is a rejection: a report that states an effect its own log says left.
pub fn contradicted(report: &crate::Report) -> Vec<String> {
    let mut out = Vec::new();
    for e in &report.selected_effects {
        let joints: Vec<Option<&String>> = if e.joints.is_empty() { vec![None] } else { e.joints.iter().map(Some).collect() };
        for j in joints {
            let last = report.selection_log.iter().rev().find(|d| d.effect == e.effect && (j.is_none() || d.joint.as_ref() == j));
            if last.is_some_and(|d| !d.accepted) {
                out.push(j.map_or(e.effect.to_string(), |j| format!("{}@{j}", e.effect)));
            }
        }
    }
    out
}
