//! From fitted terms to simulator effects and to the report's parameter maps.

use std::collections::BTreeMap;

use simgap_core::{JointKind, Model};
use simgap_sim::{Effect, EffectKind};

use crate::vocabulary::Term;

/// A parameter value: per joint (aligned with the effect's joints) or whole robot.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
#[serde(untagged)]
pub enum Param {
    /// Per-joint values.
    PerJoint(Vec<f64>),
    /// A whole-robot number.
    Number(f64),
    /// A vector (e.g. a centre of mass).
    Vector(Vec<f64>),
    /// Per-link values (inertial error).
    PerLink(Vec<Vec<f64>>),
}

/// One effect as the report states it.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct EffectReport {
    /// The effect (its contract name in the JSON report: `viscous_friction`, …).
    #[serde(serialize_with = "contract_name")]
    pub effect: EffectKind,
    /// Joints it acts on (names); empty for whole-robot effects.
    pub joints: Vec<String>,
    /// Parameters.
    pub parameters: BTreeMap<String, Param>,
    /// Half-widths of 95 % intervals, same layout as `parameters` (resampling spread and the
    /// pipeline's shared error, [`crate::select::uncertainty`]; `NaN` for values searched on a grid).
    pub uncertainty: BTreeMap<String, Param>,
    /// The unit of each parameter (`N·m·s/rad`, `kg`, `-`, …).
    pub units: BTreeMap<String, String>,
    /// The effect in words, for people (e.g. "link 2: mass −12 %, inertia about the COM −48 %").
    pub description: String,
}

impl EffectReport {
    /// An entry of `effect` with no joint, parameter or description yet.
    pub fn new(effect: EffectKind) -> Self {
        EffectReport { effect, joints: Vec::new(), parameters: BTreeMap::new(), uncertainty: BTreeMap::new(), units: BTreeMap::new(), description: String::new() }
    }

    /// The value of parameter `key` on joint `joint` (its per-joint value, or the entry's
    /// whole-robot number), when the entry acts on that joint and has that parameter: the one
    /// reader of a report entry's numbers.
    pub fn value(&self, key: &str, joint: &str) -> Option<f64> {
        let at = self.joints.iter().position(|j| j == joint)?;
        match self.parameters.get(key)? {
            Param::PerJoint(v) => v.get(at).copied(),
            Param::Number(x) => Some(*x),
            _ => None,
        }
    }
}

/// Writes an effect as its contract name.
pub(crate) fn contract_name<S: serde::Serializer>(kind: &EffectKind, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(kind.as_str())
}

/// The unit of parameter `param` of `effect` on joints of types `kinds` (units follow the joint
/// type: N·m on a revolute joint, N on a prismatic one; `-` for an unknown parameter). An
/// effect on joints of both types states both: `N·m (revolute), N (prismatic)`.
pub(crate) fn unit_on(kind: EffectKind, param: &str, kinds: &[JointKind]) -> String {
    let of = |k: JointKind| kind.unit(param, k).unwrap_or("-");
    let rotational = kinds.iter().any(|k| k.is_rotational());
    let linear = kinds.iter().any(|k| !k.is_rotational());
    match (rotational, linear) {
        (true, true) if of(JointKind::Revolute) != of(JointKind::Prismatic) => format!("{} (revolute), {} (prismatic)", of(JointKind::Revolute), of(JointKind::Prismatic)),
        (false, true) => of(JointKind::Prismatic).into(),
        _ => of(JointKind::Revolute).into(),
    }
}

/// The unit of a parameter of a report entry, as the entry states it (`-` when it has none).
pub(crate) fn unit_of<'a>(e: &'a EffectReport, param: &str) -> &'a str {
    e.units.get(param).map_or("-", String::as_str)
}

/// A fitted term with its parameter values and standard deviations.
#[derive(Clone, Debug)]
pub(crate) struct FittedTerm {
    /// The term.
    pub term: Term,
    /// Its free parameters.
    pub theta: Vec<f64>,
    /// Standard deviations: ±1.96 of them is the parameter's 95 % interval (see
    /// [`crate::select::uncertainty`]).
    pub std: Vec<f64>,
}

/// A report entry being filled: per-joint parameters are pushed joint by joint, with their
/// 95 % half-widths beside them.
pub(crate) struct Entry<'a> {
    /// The entry.
    pub(crate) e: &'a mut EffectReport,
}

impl Entry<'_> {
    /// Appends a per-joint value `v` of parameter `key` and its half-width `u`.
    pub(crate) fn push(&mut self, key: &str, v: f64, u: f64) {
        for (map, x) in [(&mut self.e.parameters, v), (&mut self.e.uncertainty, u)] {
            match map.entry(key.to_string()).or_insert_with(|| Param::PerJoint(vec![])) {
                Param::PerJoint(list) => list.push(x),
                other => *other = Param::Number(x),
            }
        }
    }

    /// Sets a whole-robot number `v` of parameter `key` and its half-width `u`.
    pub(crate) fn number(&mut self, key: &str, v: f64, u: f64) {
        self.e.parameters.insert(key.into(), Param::Number(v));
        self.e.uncertainty.insert(key.into(), Param::Number(u));
    }

    /// Sets a vector `v` of parameter `key` (searched: no interval).
    pub(crate) fn vector(&mut self, key: &str, v: Vec<f64>) {
        self.e.parameters.insert(key.into(), Param::Vector(v));
    }
}

/// The effect of `out` of the kind of `make`, added (as `make`) when there is none yet.
pub(super) fn slot(out: &mut Vec<Effect>, make: Effect) -> &mut Effect {
    let i = match out.iter().position(|e| e.kind() == make.kind()) {
        Some(i) => i,
        None => {
            out.push(make);
            out.len() - 1
        }
    };
    &mut out[i]
}

/// Converts fitted terms into simulator effects, merging per-joint terms of one effect.
pub(crate) fn to_effects(model: &Model, fitted: &[FittedTerm]) -> Vec<Effect> {
    let mut out: Vec<Effect> = Vec::new();
    for f in fitted {
        super::apply(model, f, &mut out);
    }
    out
}

/// The report entries of fitted terms (merged per effect, joints named).
pub(crate) fn to_reports(model: &Model, fitted: &[FittedTerm]) -> Vec<EffectReport> {
    let names: Vec<String> = model.joint_names().iter().map(|s| s.to_string()).collect();
    let mut out: Vec<EffectReport> = Vec::new();
    for f in fitted {
        let effect = f.term.kind();
        let idx = match out.iter().position(|e| e.effect == effect) {
            Some(i) => i,
            None => {
                out.push(EffectReport::new(effect));
                out.len() - 1
            }
        };
        let e = &mut out[idx];
        if let Some(j) = f.term.joint() {
            e.joints.push(names[j].clone());
        }
        super::report(model, f, &mut Entry { e });
    }
    for e in &mut out {
        // units by the type of the joints the effect acts on (the whole robot's for a
        // whole-robot effect)
        let kinds: Vec<JointKind> = if e.joints.is_empty() {
            model.joints().iter().map(|j| j.kind).collect()
        } else {
            e.joints.iter().filter_map(|n| model.joints().iter().find(|j| j.name == *n)).map(|j| j.kind).collect()
        };
        e.units = e.parameters.keys().map(|k| (k.clone(), unit_on(e.effect, k, &kinds))).collect();
        // joints in model order, per-joint parameters along with them
        let mut order: Vec<usize> = (0..e.joints.len()).collect();
        order.sort_by_key(|&i| names.iter().position(|n| *n == e.joints[i]).unwrap_or(usize::MAX));
        let per_link = e.parameters.values().any(|v| matches!(v, Param::PerLink(_)));
        if !per_link && order.iter().enumerate().any(|(k, &i)| k != i) {
            e.joints = order.iter().map(|&i| e.joints[i].clone()).collect();
            for map in [&mut e.parameters, &mut e.uncertainty] {
                for v in map.values_mut() {
                    if let Param::PerJoint(list) = v {
                        if list.len() == order.len() {
                            *list = order.iter().map(|&i| list[i]).collect();
                        }
                    }
                }
            }
        }
        if e.description.is_empty() {
            e.description = super::describe(model, e);
        }
    }
    super::describe_together(&mut out);
    out
}

/// A number with three significant digits (no exponent between 1e-3 and 1e4).
pub(crate) fn sig3(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let a = x.abs();
    if !(1e-3..1e4).contains(&a) {
        return format!("{x:.2e}");
    }
    let decimals = (2 - a.log10().floor() as i32).max(0) as usize;
    format!("{x:.decimals$}")
}

/// A signed percentage ("+12 %", "−48 %").
pub(super) fn percent(x: f64) -> String {
    let v = 100.0 * x;
    let s = if v.abs() >= 10.0 { format!("{:.0}", v.abs()) } else { format!("{:.1}", v.abs()) };
    format!("{}{s} %", if v < 0.0 { "−" } else { "+" })
}

/// The per-joint values of parameter `key` of a report entry, with their joints.
pub(crate) fn per_joint<'a>(e: &'a EffectReport, key: &str) -> Vec<(&'a str, f64)> {
    match e.parameters.get(key) {
        Some(Param::PerJoint(v)) => e.joints.iter().map(String::as_str).zip(v.iter().copied()).collect(),
        _ => vec![],
    }
}

/// "b = 0.17 N·m·s/rad on elbow, 0 on shoulder (at its bound: none)".
pub(super) fn list_per_joint(e: &EffectReport, key: &str) -> String {
    let unit = unit_of(e, key);
    per_joint(e, key)
        .iter()
        .map(|(j, v)| if *v == 0.0 { format!("{key} = 0 on {j} (at its bound: none there)") } else { format!("{key} = {} {unit} on {j}", sig3(*v)) })
        .collect::<Vec<_>>()
        .join(", ")
}

#[cfg(test)]
mod tests {
    use super::unit_on;
    use simgap_core::JointKind::{Continuous, Prismatic, Revolute};
    use simgap_sim::EffectKind;

    #[test]
    fn units_follow_the_type_of_the_joints_an_effect_acts_on() {
        assert_eq!(unit_on(EffectKind::ViscousFriction, "b", &[Prismatic]), "N·s/m");
        assert_eq!(unit_on(EffectKind::CoulombFriction, "fc", &[Prismatic]), "N");
        assert_eq!(unit_on(EffectKind::CoulombFriction, "fc", &[Revolute, Continuous]), "N·m");
        assert_eq!(unit_on(EffectKind::Armature, "ia", &[Prismatic]), "kg");
        assert_eq!(unit_on(EffectKind::TorqueOffset, "offset", &[Revolute, Prismatic]), "N·m (revolute), N (prismatic)");
        assert_eq!(unit_on(EffectKind::Payload, "mass", &[Prismatic]), "kg");
        assert_eq!(unit_on(EffectKind::ViscousFriction, "no_such_parameter", &[Revolute]), "-");
    }

    #[test]
    fn a_limit_selected_with_a_gain_states_the_most_the_drive_delivers() {
        use super::{to_reports, FittedTerm};
        use crate::vocabulary::Term;
        let model = simgap_core::Model::from_urdf_str(simgap_core::PENDULUM_URDF).unwrap();
        let limit = FittedTerm { term: Term::Saturation { joint: 0, limit: 0.2 }, theta: vec![], std: vec![] };
        // the gain's column coefficient is 1 − k: k = 2.5
        let gain = FittedTerm { term: Term::Gain(0), theta: vec![-1.5], std: vec![0.0] };
        let both = to_reports(&model, &[limit.clone(), gain]);
        let saturation = both.iter().find(|e| e.effect == EffectKind::TorqueSaturation).unwrap();
        assert!(saturation.description.contains("±0.200 N·m") && saturation.description.contains("at most ±0.500 N·m on hinge"), "{}", saturation.description);
        // alone, the limit is the most the drive delivers
        let alone = to_reports(&model, &[limit]);
        assert!(!alone[0].description.contains("at most"), "{}", alone[0].description);
    }
}
