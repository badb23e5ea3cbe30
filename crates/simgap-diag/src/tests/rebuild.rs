//! Anyone rebuilding the model from the JSON report alone gets the model the tool simulated: the
//! selected effects read back from `selected_effects` (names, joints, parameters, the dry
//! friction's width `w` included) and spelled for [`Effect::parse`] predict the held-out runs
//! exactly as the report's `gap.kstep.after` says.

use crate::check::bench::{demo_effects, demo_specs, generate};
use crate::{diagnose, predict, DiagnoseOptions};
use serde_json::Value;
use simgap_core::{Formulation, Model};
use simgap_sim::{Effect, EffectKind};

/// The simulator effects of a report's `selected_effects`, through their command-line spelling
/// (per-joint values in model order, the neutral value on joints an effect does not act on).
fn effects_from_report(model: &Model, report: &Value) -> Vec<Effect> {
    let names = model.joint_names();
    let mut out = Vec::new();
    for e in report["selected_effects"].as_array().expect("selected_effects is a list") {
        let name = e["effect"].as_str().unwrap();
        let kind: EffectKind = name.parse().unwrap();
        let joints: Vec<usize> = e["joints"].as_array().unwrap().iter().map(|j| names.iter().position(|n| *n == j.as_str().unwrap()).unwrap()).collect();
        let mut parts = Vec::new();
        for (key, value) in e["parameters"].as_object().unwrap() {
            let spec = kind.parameter(key).unwrap_or_else(|| panic!("{name} has no parameter {key}"));
            let number = |v: &Value| if v.is_null() { f64::INFINITY } else { v.as_f64().unwrap() };
            let values: Vec<f64> = match value {
                Value::Array(list) if !kind.whole_robot() => {
                    // aligned with `joints`: model order, neutral elsewhere (a width where no
                    // friction acts is any width)
                    let mut v = vec![spec.neutral.unwrap_or(simgap_sim::DEFAULT_COULOMB_WIDTH); names.len()];
                    for (&j, x) in joints.iter().zip(list) {
                        v[j] = number(x);
                    }
                    v
                }
                Value::Array(list) => list.iter().map(number).collect(),
                other => vec![number(other)],
            };
            let text: Vec<String> = values.iter().map(|x| if x.is_infinite() { "inf".to_string() } else { format!("{x:?}") }).collect();
            parts.push(format!("{key}={}", text.join(",")));
        }
        let spelling = if parts.is_empty() { name.to_string() } else { format!("{name}:{}", parts.join(";")) };
        out.push(Effect::parse(&spelling, names.len()).unwrap_or_else(|err| panic!("{spelling}: {err}")));
    }
    out
}

#[test]
fn the_model_rebuilt_from_the_json_report_predicts_as_the_report_says() {
    let model = Model::paper_arm();
    let (fit_specs, hold_specs) = demo_specs(1);
    let gen = |s| generate(&model, Formulation::EulerLagrange, &demo_effects(), s, 0.0025, 1_024_000.0).unwrap();
    let fit: Vec<_> = fit_specs.iter().map(gen).collect();
    let hold: Vec<_> = hold_specs.iter().map(gen).collect();
    let options = DiagnoseOptions::default();
    let d = diagnose(&model, Formulation::EulerLagrange, &fit, &hold, &options, &mut |_| {}).unwrap();
    let report: Value = serde_json::from_str(&d.report.to_json()).unwrap();

    // the dry friction states the width it simulated with, in the joint's units
    let coulomb = report["selected_effects"].as_array().unwrap().iter().find(|e| e["effect"] == "coulomb_friction").expect("Coulomb friction selected");
    let w = coulomb["parameters"]["w"].as_array().expect("w per joint");
    assert!(w.iter().all(|x| x.as_f64().is_some_and(|x| x > 0.0)), "{coulomb}");
    assert_eq!(coulomb["units"]["w"], "rad/s");
    let candidate = report["candidates"].as_array().unwrap().iter().find(|c| c["effect"] == "coulomb_friction").expect("a Coulomb candidate");
    assert!(candidate.to_string().contains("\"w\""), "{candidate}");

    // rebuilt from the JSON alone, the corrected model predicts the held-out run as reported
    let effects = effects_from_report(&model, &report);
    let horizons: Vec<f64> = report["gap"]["kstep"]["horizons_s"].as_array().unwrap().iter().map(|h| h.as_f64().unwrap()).collect();
    let reported: Vec<f64> = report["gap"]["kstep"]["after"].as_array().unwrap().iter().map(|h| h.as_f64().unwrap()).collect();
    let k = predict(&model, Formulation::EulerLagrange, &effects, &hold, &horizons, options.prepare.window).unwrap();
    for (i, h) in horizons.iter().enumerate() {
        let rel = (k.after[i] - reported[i]).abs() / reported[i];
        assert!(rel < 1e-9, "horizon {h} s: rebuilt {} rad, reported {} rad", k.after[i], reported[i]);
    }
    // and the width is part of the model: another width predicts otherwise
    let defaulted: Vec<Effect> = effects
        .iter()
        .map(|e| match e {
            Effect::CoulombFriction { fc, w } => Effect::CoulombFriction { fc: fc.clone(), w: vec![simgap_sim::DEFAULT_COULOMB_WIDTH * 3.0; w.len()] },
            other => other.clone(),
        })
        .collect();
    let k3 = predict(&model, Formulation::EulerLagrange, &defaulted, &hold, &horizons, options.prepare.window).unwrap();
    assert!(k3.after.iter().zip(&k.after).any(|(a, b)| (a - b).abs() > 1e-3 * b), "{:?} vs {:?}", k3.after, k.after);
}
