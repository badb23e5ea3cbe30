//! From fitted terms to simulator effects and to the report's parameter maps.

use std::collections::BTreeMap;

use nalgebra::{Matrix3, Vector3};
use simgap_core::{inertia_from_parameters, inertial_parameters, Model, SpatialInertia, PARAMS_PER_LINK};
use simgap_sim::{Effect, LinkDelta};

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
    /// Contract name.
    pub effect: String,
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

/// The SI unit of a parameter of an effect of the vocabulary (`-` for dimensionless values).
/// Torques are written for revolute joints (`N·m`); a prismatic joint's are in `N`.
pub(crate) fn param_unit(effect: &str, param: &str) -> &'static str {
    match (effect, param) {
        ("viscous_friction", "b") => "N·m·s/rad",
        ("coulomb_friction" | "stribeck_friction", "fc" | "fs") => "N·m",
        ("stribeck_friction", "vs") => "rad/s",
        ("armature", "ia") => "kg·m²",
        ("payload", "mass") | ("inertial_error", "delta_mass") => "kg",
        ("payload", "com") | ("inertial_error", "delta_com") => "m",
        ("inertial_error", "delta_inertia") => "kg·m²",
        ("torque_offset", "offset") | ("torque_saturation", "limit") | ("cogging", "amplitude") => "N·m",
        ("time_delay", "delay") => "s",
        _ => "-",
    }
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

/// Converts fitted terms into simulator effects, merging per-joint terms of one effect.
pub(crate) fn to_effects(model: &Model, fitted: &[FittedTerm]) -> Vec<Effect> {
    let n = model.dof();
    let mut out: Vec<Effect> = Vec::new();
    fn slot(out: &mut Vec<Effect>, name: &str, make: &dyn Fn() -> Effect) -> usize {
        if let Some(i) = out.iter().position(|e| e.name() == name) {
            i
        } else {
            out.push(make());
            out.len() - 1
        }
    }
    for f in fitted {
        let th = &f.theta;
        match f.term {
            Term::Viscous(j) => {
                let i = slot(&mut out, "viscous_friction", &|| Effect::ViscousFriction { b: vec![0.0; n] });
                if let Effect::ViscousFriction { b } = &mut out[i] {
                    b[j] = th[0];
                }
            }
            Term::Coulomb(j) => {
                let i = slot(&mut out, "coulomb_friction", &|| Effect::CoulombFriction { fc: vec![0.0; n] });
                if let Effect::CoulombFriction { fc } = &mut out[i] {
                    fc[j] = th[0];
                }
            }
            Term::Stribeck { joint, vs } => {
                let i = slot(&mut out, "stribeck_friction", &|| Effect::StribeckFriction { fc: vec![0.0; n], fs: vec![0.0; n], vs: vec![0.0; n] });
                if let Effect::StribeckFriction { fc, fs, vs: v } = &mut out[i] {
                    fc[joint] = th[0];
                    fs[joint] = th[1];
                    v[joint] = vs;
                }
            }
            Term::Armature(j) => {
                let i = slot(&mut out, "armature", &|| Effect::Armature { ia: vec![0.0; n] });
                if let Effect::Armature { ia } = &mut out[i] {
                    ia[j] = th[0];
                }
            }
            Term::Gain(j) => {
                let i = slot(&mut out, "torque_gain", &|| Effect::TorqueGain { k: vec![1.0; n] });
                if let Effect::TorqueGain { k } = &mut out[i] {
                    k[j] = 1.0 - th[0];
                }
            }
            Term::Offset(j) => {
                let i = slot(&mut out, "torque_offset", &|| Effect::TorqueOffset { offset: vec![0.0; n] });
                if let Effect::TorqueOffset { offset } = &mut out[i] {
                    offset[j] = th[0];
                }
            }
            Term::Saturation { joint, limit } => {
                let i = slot(&mut out, "torque_saturation", &|| Effect::TorqueSaturation { limit: vec![f64::INFINITY; n] });
                if let Effect::TorqueSaturation { limit: l } = &mut out[i] {
                    l[joint] = limit;
                }
            }
            Term::Cogging { joint, periods } => {
                let i = slot(&mut out, "cogging", &|| Effect::Cogging { amplitude: vec![0.0; n], periods_per_rev: vec![1.0; n] });
                if let Effect::Cogging { amplitude, periods_per_rev } = &mut out[i] {
                    amplitude[joint] = th[0];
                    periods_per_rev[joint] = periods;
                }
            }
            Term::Delay { delay } => out.push(Effect::TimeDelay { delay }),
            Term::CoriolisStructure => out.push(Effect::CoriolisStructure),
            Term::Payload { com, .. } => out.push(Effect::Payload { mass: th[0], com }),
            Term::InertialError { ref prior } => {
                let dpi: Vec<f64> = prior.scales.iter().zip(th).map(|(s, t)| s * t).collect();
                let deltas = (0..n).map(|j| delta_of(model, j, &dpi[PARAMS_PER_LINK * j..PARAMS_PER_LINK * (j + 1)])).filter(|d| !negligible(model, d)).collect();
                out.push(Effect::InertialError { deltas });
            }
        }
    }
    out
}

/// The report entries of fitted terms (merged per effect, joints named).
pub(crate) fn to_reports(model: &Model, fitted: &[FittedTerm]) -> Vec<EffectReport> {
    let names: Vec<String> = model.joint_names().iter().map(|s| s.to_string()).collect();
    let mut out: Vec<EffectReport> = Vec::new();
    for f in fitted {
        let effect = f.term.effect_name();
        let idx = match out.iter().position(|e| e.effect == effect) {
            Some(i) => i,
            None => {
                out.push(EffectReport {
                    effect: effect.into(),
                    joints: vec![],
                    parameters: BTreeMap::new(),
                    uncertainty: BTreeMap::new(),
                    units: BTreeMap::new(),
                    description: String::new(),
                });
                out.len() - 1
            }
        };
        let e = &mut out[idx];
        let ci = |s: f64| 1.96 * s;
        let mut push = |key: &str, v: f64, u: f64| {
            for (map, x) in [(&mut e.parameters, v), (&mut e.uncertainty, u)] {
                match map.entry(key.to_string()).or_insert_with(|| Param::PerJoint(vec![])) {
                    Param::PerJoint(list) => list.push(x),
                    other => *other = Param::Number(x),
                }
            }
        };
        if let Some(j) = f.term.joint() {
            e.joints.push(names[j].clone());
        }
        let (th, sd) = (&f.theta, &f.std);
        match f.term {
            Term::Viscous(_) => push("b", th[0], ci(sd[0])),
            Term::Coulomb(_) => push("fc", th[0], ci(sd[0])),
            Term::Stribeck { vs, .. } => {
                push("fc", th[0], ci(sd[0]));
                push("fs", th[1], ci(sd[1]));
                push("vs", vs, f64::NAN);
            }
            Term::Armature(_) => push("ia", th[0], ci(sd[0])),
            Term::Gain(_) => push("k", 1.0 - th[0], ci(sd[0])),
            Term::Offset(_) => push("offset", th[0], ci(sd[0])),
            Term::Saturation { limit, .. } => push("limit", limit, f64::NAN),
            Term::Cogging { periods, .. } => {
                push("amplitude", th[0], ci(sd[0]));
                push("periods_per_rev", periods, f64::NAN);
            }
            Term::Delay { delay } => {
                e.parameters.insert("delay".into(), Param::Number(delay));
                e.uncertainty.insert("delay".into(), Param::Number(f64::NAN));
            }
            Term::CoriolisStructure => {}
            Term::Payload { com, .. } => {
                e.parameters.insert("mass".into(), Param::Number(th[0]));
                e.uncertainty.insert("mass".into(), Param::Number(ci(sd[0])));
                e.parameters.insert("com".into(), Param::Vector(com.to_vec()));
            }
            Term::InertialError { .. } => {
                let effects = to_effects(model, std::slice::from_ref(f));
                if let Some(Effect::InertialError { deltas }) = effects.first() {
                    e.joints = deltas.iter().map(|d| names[d.joint].clone()).collect();
                    e.parameters.insert("delta_mass".into(), Param::PerJoint(deltas.iter().map(|d| d.mass).collect()));
                    e.parameters.insert("delta_com".into(), Param::PerLink(deltas.iter().map(|d| d.com.to_vec()).collect()));
                    e.parameters.insert("delta_inertia".into(), Param::PerLink(deltas.iter().map(|d| d.inertia.to_vec()).collect()));
                    let identifiable = if let Term::InertialError { prior } = &f.term { prior.identifiable } else { 0 };
                    e.parameters.insert("identifiable_directions".into(), Param::Number(identifiable as f64));
                    e.description = describe_inertial(model, deltas);
                }
            }
        }
    }
    for e in &mut out {
        e.units = e.parameters.keys().map(|k| (k.clone(), param_unit(&e.effect, k).to_string())).collect();
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
            e.description = describe(model, e);
        }
    }
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
fn percent(x: f64) -> String {
    let v = 100.0 * x;
    let s = if v.abs() >= 10.0 { format!("{:.0}", v.abs()) } else { format!("{:.1}", v.abs()) };
    format!("{}{s} %", if v < 0.0 { "−" } else { "+" })
}

/// The per-joint values of parameter `key` of a report entry, with their joints.
fn per_joint<'a>(e: &'a EffectReport, key: &str) -> Vec<(&'a str, f64)> {
    match e.parameters.get(key) {
        Some(Param::PerJoint(v)) => e.joints.iter().map(String::as_str).zip(v.iter().copied()).collect(),
        _ => vec![],
    }
}

/// "b = 0.17 N·m·s/rad on elbow, 0 on shoulder (at its bound: none)".
fn list_per_joint(e: &EffectReport, key: &str, unit: &str) -> String {
    per_joint(e, key)
        .iter()
        .map(|(j, v)| if *v == 0.0 { format!("{key} = 0 on {j} (at its bound: none there)") } else { format!("{key} = {} {unit} on {j}", sig3(*v)) })
        .collect::<Vec<_>>()
        .join(", ")
}

/// The effect in words (the `description` of [`EffectReport`]).
fn describe(model: &Model, e: &EffectReport) -> String {
    let num = |k: &str| match e.parameters.get(k) {
        Some(Param::Number(x)) => *x,
        _ => f64::NAN,
    };
    match e.effect.as_str() {
        "viscous_friction" => format!("viscous friction {}", list_per_joint(e, "b", "N·m·s/rad")),
        "coulomb_friction" => format!("Coulomb friction {}", list_per_joint(e, "fc", "N·m")),
        "stribeck_friction" => {
            let (fc, fs, vs) = (per_joint(e, "fc"), per_joint(e, "fs"), per_joint(e, "vs"));
            let parts: Vec<String> =
                fc.iter().zip(&fs).zip(&vs).map(|((c, s), v)| format!("on {}: fc = {} N·m, fs = {} N·m below {} rad/s", c.0, sig3(c.1), sig3(s.1), sig3(v.1))).collect();
            format!("Stribeck friction {}", parts.join("; "))
        }
        "armature" => format!("rotor inertia (armature) {}", list_per_joint(e, "ia", "kg·m²")),
        "torque_gain" => {
            let parts: Vec<String> = per_joint(e, "k").iter().map(|(j, k)| format!("k = {} on {j} (the drive delivers {:.0} % of the command)", sig3(*k), 100.0 * k)).collect();
            format!("torque gain {}", parts.join(", "))
        }
        "torque_offset" => format!("torque offset {}", list_per_joint(e, "offset", "N·m")),
        "torque_saturation" => {
            let parts: Vec<String> = per_joint(e, "limit").iter().map(|(j, l)| format!("±{} N·m on {j}", sig3(*l))).collect();
            format!("torque saturation at {}", parts.join(", "))
        }
        "cogging" => {
            let parts: Vec<String> = per_joint(e, "amplitude")
                .iter()
                .zip(per_joint(e, "periods_per_rev"))
                .map(|((j, a), (_, n))| format!("{} N·m, {n:.0} periods per revolution on {j}", sig3(a.abs())))
                .collect();
            format!("cogging torque {}", parts.join(", "))
        }
        "time_delay" => format!("actuation delay of {} ms (whole robot)", sig3(1e3 * num("delay"))),
        "coriolis_structure" => "the model's Coriolis matrix C misses (or wrongly has) its skew-symmetric part: the other formulation fits better".into(),
        "payload" => {
            let com = match e.parameters.get("com") {
                Some(Param::Vector(c)) => c.clone(),
                _ => vec![],
            };
            let link = model.joints().last().map_or("the last link", |j| j.link.as_str());
            let at: Vec<String> = com.iter().map(|c| format!("{:.0}", 1e3 * c)).collect();
            format!("payload of {} kg on {link}, centre of mass at ({}) mm in its frame", sig3(num("mass")), at.join(", "))
        }
        _ => String::new(),
    }
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
