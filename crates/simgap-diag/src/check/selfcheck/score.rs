//! The self-check's scoring: each scenario diagnosed like real logs and scored against its hidden
//! truth by its family's rule ([`run_scenario`], [`run_servo_scenario`], [`run_drive_scenario`]
//! and the mixed cycle `simgap selfcheck` runs, [`run_mixed_scenario`]).

use std::collections::{BTreeMap, BTreeSet};

use simgap_core::Formulation;
use simgap_sim::{Effect, EffectKind};

use super::scenarios::{family_of, scenario, Scenario, CYCLE, GLITCH_VALUE};
use super::servo::{backlash_scenario, encoder_offset_scenario, servo_family, servo_scenario};
use super::truth::{comparisons, contradicted, coverage_of, found_set, implausible, inside, Comparison};
use crate::options::DiagnoseOptions;
use crate::pipeline::diagnose;
use crate::report::Diagnosis;
use crate::vocabulary::effects::EffectReport;

/// The score of one scenario.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ScenarioScore {
    /// Index.
    pub index: usize,
    /// Robot.
    pub robot: String,
    /// Hidden (effect, joint) pairs (for `urdf_inertia_pitfall`, the inertial correction a right
    /// diagnosis finds).
    pub truth: Vec<String>,
    /// Selected pairs.
    pub found: Vec<String>,
    /// Scenario family (one of [`FAMILIES`](super::FAMILIES)).
    pub family: String,
    /// Exactly the hidden set.
    pub exact: bool,
    /// Not exact, but the hidden effects are one of the report's `alternatives` (an effect set
    /// these data cannot tell apart from the selected one).
    pub in_alternatives: bool,
    /// Right by the family's rule (see [`run_scenario`]).
    pub right: bool,
    /// Why a scenario that is not exact counts as right or wrong, where the family's rule is not
    /// "exact or among the alternatives".
    pub rule: String,
    /// Held-out k-step error after / before at 0.5 s (the longest horizon when shorter).
    pub kstep_ratio: f64,
    /// Relative parameter errors of correctly found effects.
    pub parameter_errors: Vec<(String, f64)>,
    /// Found parameters with a reported 95 % interval: (name, truth, found, half-width, inside).
    pub intervals: Vec<(String, f64, f64, f64, bool)>,
    /// Coverage of each interval method on its own (name → (inside, count)), for comparison.
    pub interval_variants: BTreeMap<String, (usize, usize)>,
    /// Each interval method's own half-widths (name → (parameter, truth, found, half-width)),
    /// for studying how they combine.
    pub variant_intervals: BTreeMap<String, Vec<(String, f64, f64, f64)>>,
    /// Held-out L² after / before.
    pub holdout_ratio: f64,
    /// Selected effects outside their physical range or consistent with no effect
    /// ([`implausible`]).
    pub implausible: Vec<String>,
    /// Selected effects the report's own selection log last rejected ([`contradicted`]).
    pub contradicted: Vec<String>,
    /// An error, if the diagnosis failed.
    pub error: Option<String>,
}

impl ScenarioScore {
    /// The score of a scenario that could not be generated or diagnosed.
    fn failed(index: usize, robot: String, family: String, truth: Vec<String>, error: String) -> ScenarioScore {
        ScenarioScore {
            index,
            robot,
            family,
            truth,
            found: vec![],
            exact: false,
            in_alternatives: false,
            right: false,
            rule: String::new(),
            kstep_ratio: f64::NAN,
            parameter_errors: vec![],
            intervals: vec![],
            interval_variants: BTreeMap::new(),
            variant_intervals: BTreeMap::new(),
            holdout_ratio: f64::NAN,
            implausible: vec![],
            contradicted: vec![],
            error: Some(error),
        }
    }
}

fn label(s: &BTreeSet<(String, Option<String>)>) -> Vec<String> {
    s.iter()
        .map(|(e, j)| match j {
            Some(j) => format!("{e}@{j}"),
            None => e.clone(),
        })
        .collect()
}

/// Held-out k-step error after/before at 0.5 s (or the longest horizon below it).
fn kstep_ratio_at_half_second(d: &Diagnosis) -> f64 {
    let k = &d.report.gap.kstep;
    let i = k.horizons_s.iter().position(|h| *h >= 0.5 - 1e-9).unwrap_or(k.horizons_s.len().saturating_sub(1));
    k.after.get(i).zip(k.before.get(i)).map_or(f64::NAN, |(a, b)| a / b)
}

/// Runs one scenario end to end and scores it. A scenario is right when the selected set is
/// exactly the hidden one or the hidden effects are among the report's alternatives, except:
///
/// - `friction_shape` (a friction the vocabulary cannot state exactly): right when the selected
///   set holds Coulomb or Stribeck friction on the true joint, nothing but friction (Coulomb,
///   Stribeck, viscous) on that joint besides, and the held-out k-step error at 0.5 s improves;
/// - `urdf_inertia_pitfall`: right when an inertial correction of every link is selected (or is
///   among the alternatives) and nothing else;
/// - `passive_joint`: right by the general rule and with no actuator effect (gain, offset,
///   saturation) on the passive joint;
/// - `glitch`: right when the diagnosis with the glitch selects the same set as without it (the
///   same clean logs) and a note names the glitch.
pub fn run_scenario(seed: u64, index: usize) -> ScenarioScore {
    score(index, family_of(index), scenario(seed, index))
}

/// Runs servo scenario `index` of seed `seed` ([`servo_scenario`]) and scores it: right when the
/// selected mechanical effects are the hidden ones (a torque gain or back-EMF corrects the
/// fitted motor constants, and is not counted) and the motor constants the corrected model
/// drives with, `kt/R` and `kt²/R`, are within 15 % of the servo's.
pub fn run_servo_scenario(seed: u64, index: usize) -> ScenarioScore {
    score(index, servo_family(index), servo_scenario(seed, index))
}

/// Runs encoder-offset scenario `index` of seed `seed` ([`encoder_offset_scenario`]) and scores
/// it as a servo scenario ([`run_servo_scenario`]).
pub fn run_encoder_offset_scenario(seed: u64, index: usize) -> ScenarioScore {
    score(index, "servo_encoder_offset", encoder_offset_scenario(seed, index))
}

/// Runs backlash scenario `index` of seed `seed` ([`backlash_scenario`]) and scores it as a
/// servo scenario ([`run_servo_scenario`]).
pub fn run_backlash_scenario(seed: u64, index: usize) -> ScenarioScore {
    score(index, "servo_backlash", backlash_scenario(seed, index))
}

/// Runs real-drive scenario `index` of seed `seed` ([`drive_scenario`](crate::check::drives::drive_scenario))
/// and scores it. Right when the selected set is exactly the hidden one or among the
/// alternatives, except:
///
/// - `servo`: as [`run_servo_scenario`];
/// - `coulomb_trap`: exactly the hidden set (a Stribeck friction, richer, is wrong even as the
///   selected set with Coulomb friction among its alternatives);
/// - `directional_friction`: exactly the hidden set, every unit that of a linear axis;
/// - `link_side`: the sensor offsets and the spring found, no rotor inertia selected (the
///   viscous frictions may be missed, and extra effects are listed in the rule).
pub fn run_drive_scenario(seed: u64, index: usize) -> ScenarioScore {
    let family = match crate::check::drives::drive_family_of(index) {
        "servo" => servo_family(index),
        other => other,
    };
    score(index, family, crate::check::drives::drive_scenario(seed, index))
}

/// The largest relative error, over the joints (named `joints`, model order) of a hidden torque
/// limit, of the most torque the selected drive delivers there (its limit times its torque
/// gain; no limit selected is an infinite error); `None` without a hidden limit.
fn most_torque_error(joints: &[&str], hidden: &[Effect], selected: &[EffectReport]) -> Option<f64> {
    let limits = hidden.iter().find_map(|e| if let Effect::TorqueSaturation { limit } = e { Some(limit.clone()) } else { None })?;
    let value = |kind: EffectKind, key: &str, j: usize| selected_value(selected, kind, key, joints[j]).filter(|v| v.is_finite());
    let errors = limits.iter().enumerate().filter(|(_, l)| l.is_finite()).map(|(j, l)| match value(EffectKind::TorqueSaturation, "limit", j) {
        Some(fitted) => (fitted * value(EffectKind::TorqueGain, "k", j).unwrap_or(1.0) / l - 1.0).abs(),
        None => f64::INFINITY,
    });
    Some(errors.fold(0.0, f64::max))
}

/// The value of parameter `key` of the selected `effect` on `joint`, if selected there.
fn selected_value(selected: &[EffectReport], effect: EffectKind, key: &str, joint: &str) -> Option<f64> {
    selected.iter().find(|e| e.effect == effect)?.value(key, joint)
}

/// The effects that, on a servo whose motor constants were fitted from its logs, correct those
/// constants rather than add mechanics: a torque gain scales `kt/R` and `kt²/R` alike, a
/// back-EMF `kt²/R` alone. A servo scenario is scored on the other selected effects.
pub const MOTOR_CONSTANTS: [&str; 2] = [EffectKind::TorqueGain.as_str(), EffectKind::BackEmf.as_str()];

/// Of every [`MIXED_CYCLE`] scenarios `simgap selfcheck` runs, the first [`CYCLE`] are one cycle
/// of [`scenario`] and the rest one of each real-drive family
/// ([`DRIVE_FAMILIES`](crate::check::drives::DRIVE_FAMILIES)).
pub const MIXED_CYCLE: usize = CYCLE + crate::check::drives::DRIVE_FAMILIES.len();

/// Runs scenario `index` of the mixed self-check (see [`MIXED_CYCLE`]): scenario
/// `(index / MIXED_CYCLE) · CYCLE + slot` of [`run_scenario`] for the first [`CYCLE`] slots, else
/// real-drive scenario `(index / MIXED_CYCLE) · 7 + slot − CYCLE` of [`run_drive_scenario`].
pub fn run_mixed_scenario(seed: u64, index: usize) -> ScenarioScore {
    let (block, slot) = (index / MIXED_CYCLE, index % MIXED_CYCLE);
    if slot < CYCLE {
        run_scenario(seed, block * CYCLE + slot)
    } else {
        run_drive_scenario(seed, block * crate::check::drives::DRIVE_FAMILIES.len() + slot - CYCLE)
    }
}

/// Diagnoses a generated scenario and scores it by its family's rule.
pub(crate) fn score(index: usize, family: &str, sc: crate::Result<Scenario>) -> ScenarioScore {
    let sc = match sc {
        Ok(s) => s,
        Err(e) => return ScenarioScore::failed(index, String::new(), family.into(), vec![], e.to_string()),
    };
    let truth = sc.truth.clone();
    let mut fit = sc.fit.clone();
    if let Some((r, k, j)) = sc.glitch {
        let n = fit[r].dof();
        fit[r].q[k * n + j] = GLITCH_VALUE;
    }
    let options = DiagnoseOptions { directional_friction: sc.directional_friction, load_stribeck_friction: sc.load_stribeck_friction, ..DiagnoseOptions::default() };
    let d = match diagnose(&sc.diagnosis_model, Formulation::EulerLagrange, &fit, &sc.holdout, &options, &mut |_| {}) {
        Ok(d) => d,
        Err(e) => return ScenarioScore::failed(index, sc.model.name().into(), sc.family.into(), label(&truth), e.to_string()),
    };
    let found = found_set(&d);
    let truth_names: BTreeSet<String> = truth.iter().map(|t| t.0.clone()).collect();
    let in_alternatives = found != truth && !truth_names.is_empty() && d.report.alternatives.iter().any(|a| a.effects.iter().cloned().collect::<BTreeSet<String>>() == truth_names);
    let exact = found == truth;
    let kstep_ratio = kstep_ratio_at_half_second(&d);
    let names = sc.model.joint_names();
    let (right, rule) = match sc.family {
        "friction_shape" => {
            let joint = sc.effects.iter().flat_map(|e| e.joints_acted()).next().map(|j| names[j].to_string());
            use EffectKind::{CoulombFriction, StribeckFriction, ViscousFriction};
            let on = |k: EffectKind| found.contains(&(k.to_string(), joint.clone()));
            let only_friction = found.iter().all(|(e, j)| *j == joint && [CoulombFriction, StribeckFriction, ViscousFriction].iter().any(|k| k.as_str() == e));
            let ok = (on(CoulombFriction) || on(StribeckFriction)) && only_friction && kstep_ratio < 1.0;
            (ok, format!("nearest in-vocabulary friction on the true joint, only friction there, k-step at 0.5 s after/before {kstep_ratio:.3} (< 1 needed)"))
        }
        "urdf_inertia_pitfall" => {
            let links = d.report.selected_effects.iter().find(|e| e.effect == EffectKind::InertialError).map_or(0, |e| e.joints.len());
            let ok = (exact && links == sc.model.dof()) || in_alternatives;
            (ok, format!("an inertial correction of all {} links (the selected one corrects {links})", sc.model.dof()))
        }
        "passive_joint" => {
            let passive = names[0].to_string();
            let actuator = found.iter().any(|(e, j)| {
                j.as_deref() == Some(passive.as_str()) && [EffectKind::TorqueGain, EffectKind::TorqueOffset, EffectKind::TorqueSaturation].iter().any(|k| k.as_str() == e)
            });
            let flagged = d.report.notes.iter().any(|n| n.contains(&format!("joint {passive} is passive")));
            ((exact || in_alternatives) && !actuator && flagged, format!("no actuator effect on the passive joint {passive} (one found: {actuator}); flagged passive: {flagged}"))
        }
        "servo" | "servo_saturation" | "servo_breakaway" | "servo_encoder_offset" | "servo_backlash" => {
            // the motor constants are fitted: a torque gain or back-EMF corrects them, and the
            // constants the corrected model drives with must be the servo's; a limit must be
            // found on its joint, the most the drive delivers (the limit times the gain) within
            // 15 % of the hidden one
            let mechanical: BTreeSet<(String, Option<String>)> = found.iter().filter(|(e, _)| !MOTOR_CONSTANTS.contains(&e.as_str())).cloned().collect();
            let most_torque = most_torque_error(&names, &sc.effects, &d.report.selected_effects);
            let spec = sc.servo.as_ref();
            // where no fit log moves a joint with its drive off, its back-EMF and viscous
            // friction act alike and only their sum is in the logs: the sum is scored there
            let viscous = |j: usize| -> (f64, f64) {
                let hidden = sc.effects.iter().find_map(|e| if let Effect::ViscousFriction { b } = e { Some(b[j]) } else { None }).unwrap_or(0.0);
                let selected = selected_value(&d.report.selected_effects, EffectKind::ViscousFriction, "b", names[j]).unwrap_or(0.0);
                (hidden, selected)
            };
            let summed: Vec<usize> = (0..names.len()).filter(|&j| !crate::prepare::servo::moves_with_drive_off(&sc.model, &sc.fit, j)).collect();
            let constants = match (spec, &d.report.servo) {
                (Some(spec), Some(rep)) => (0..spec.kt.len())
                    .map(|j| {
                        let (kt, r) = (rep.effective.kt[j], rep.effective.r[j]);
                        let (b, b_true) = (kt * kt / r, spec.kt[j] * spec.kt[j] / spec.r[j]);
                        let damping = if summed.contains(&j) {
                            let (c_true, c) = viscous(j);
                            ((b + c) / (b_true + c_true) - 1.0).abs()
                        } else {
                            (b / b_true - 1.0).abs()
                        };
                        ((kt / r) / (spec.kt[j] / spec.r[j]) - 1.0).abs().max(damping)
                    })
                    .fold(0.0, f64::max),
                _ => f64::INFINITY,
            };
            let ok = (mechanical == truth || in_alternatives) && constants <= 0.15 && most_torque.is_none_or(|e| e <= 0.15);
            let sum = if summed.is_empty() {
                String::new()
            } else {
                let on: Vec<&str> = summed.iter().map(|&j| names[j]).collect();
                format!(" (on {}, which no fit log moves with its drive off, kt²/R plus the viscous friction)", on.join(", "))
            };
            (
                ok,
                format!(
                    "the mechanical effects {} the hidden ones; motor constants kt/R and kt²/R{sum} within {:.1} % (15 % allowed){}",
                    if mechanical == truth { "are" } else { "are not" },
                    100.0 * constants,
                    most_torque.map_or(String::new(), |e| format!("; the most torque the drive delivers within {:.1} % of the hidden limit (15 % allowed)", 100.0 * e))
                ),
            )
        }
        "coulomb_trap" => {
            let richer = found.iter().any(|(e, _)| e == EffectKind::StribeckFriction.as_str());
            (exact, format!("exactly the hidden set, not even among alternatives (a Stribeck friction selected: {richer})"))
        }
        crate::check::drives::DIRECTIONAL => {
            // the axis is linear: its forces in N, its speeds in m/s
            let units_ok = d.report.selected_effects.iter().all(|e| e.units.values().all(|u| !u.contains("N·m") && !u.contains("rad")));
            (exact && units_ok, format!("exactly the hidden set (directional or the symmetric pair); units of a linear axis: {units_ok}"))
        }
        "link_side" => {
            // the offsets and the spring must be found, and no rotor inertia: a link-side torque
            // holds none; the viscous frictions are part of the truth but not required
            let needed: BTreeSet<(String, Option<String>)> = truth.iter().filter(|(e, _)| e != EffectKind::ViscousFriction.as_str()).cloned().collect();
            let armature = found.iter().any(|(e, _)| e == EffectKind::Armature.as_str());
            let extra: Vec<String> = label(&found.difference(&truth).cloned().collect());
            (
                needed.is_subset(&found) && !armature,
                format!("sensor offsets and spring found: {}; rotor inertia selected: {armature}; beyond the truth: {extra:?}", needed.is_subset(&found)),
            )
        }
        "glitch" => {
            let clean = diagnose(&sc.diagnosis_model, Formulation::EulerLagrange, &sc.fit, &sc.holdout, &options, &mut |_| {}).map(|c| found_set(&c));
            let (r, _, _) = sc.glitch.unwrap_or_default();
            let noted = d.report.notes.iter().any(|n| n.starts_with(&format!("{}: glitch", sc.fit[r].source)));
            match clean {
                Ok(c) => (c == found && noted, format!("without the glitch the diagnosis selects {:?}; glitch reported: {noted}", label(&c))),
                Err(e) => (false, format!("the clean diagnosis failed: {e}")),
            }
        }
        _ => (exact || in_alternatives, String::new()),
    };
    // a friction outside the vocabulary has no true value of the vocabulary's parameters
    let truth_params: &[Effect] = if sc.family == "friction_shape" { &[] } else { &sc.effects };
    let reported = comparisons(&sc.model, truth_params, &d.report.selected_effects);
    let variant_intervals: BTreeMap<String, Vec<Comparison>> =
        d.interval_variants.iter().map(|(name, reports)| (name.to_string(), comparisons(&sc.model, truth_params, reports))).collect();
    let interval_variants = variant_intervals.iter().map(|(name, c)| (name.clone(), coverage_of(c))).collect();
    ScenarioScore {
        index,
        robot: sc.model.name().into(),
        family: sc.family.into(),
        exact,
        in_alternatives,
        right,
        rule,
        kstep_ratio,
        parameter_errors: reported.iter().map(|c| (c.0.clone(), ((c.2 - c.1) / c.1).abs())).collect(),
        intervals: reported.iter().filter(|c| c.3.is_finite()).map(|c| (c.0.clone(), c.1, c.2, c.3, inside(c))).collect(),
        interval_variants,
        variant_intervals,
        holdout_ratio: d.report.gap.ratio,
        truth: label(&truth),
        found: label(&found),
        implausible: implausible(&sc.model, &sc.fit, &d.report.selected_effects),
        contradicted: contradicted(&d.report),
        error: None,
    }
}
