//! Alternatives: effect sets the data cannot tell apart from the selected one (exact
//! equivalences, and swaps of one selected effect whose prediction ties).

use rayon::prelude::*;

use crate::report::Alternative;
use crate::select::prediction::{swap_candidates, swapped, ADD_GAIN, PRUNE_TOLERANCE, TIE_TOLERANCE};
use crate::select::scorer::Scorer;
use crate::vocabulary::{EffectReport, Param, Term};

/// Effect sets the data cannot tell apart from the selected one: exact equivalences, and swaps
/// of one selected effect for another whose prediction score ties within the tolerance.
pub(crate) fn alternatives(
    scorer: &Scorer<'_>,
    groups: &[(&'static str, Vec<Term>)],
    alone_score: &[f64],
    terms: &[Term],
    current: f64,
    selected: &[EffectReport],
) -> Vec<Alternative> {
    let names: Vec<String> = selected.iter().map(|e| e.effect.clone()).collect();
    let with = |drop: &str, add: &str| -> Vec<String> {
        let mut v: Vec<String> = names.iter().filter(|n| n.as_str() != drop).cloned().collect();
        if !v.iter().any(|n| n == add) {
            v.push(add.to_string());
        }
        v
    };
    let mut out = Vec::new();
    // exact equivalences
    for e in selected {
        match e.effect.as_str() {
            "payload" => out.push(Alternative {
                effects: with("payload", "inertial_error"),
                why: "a point mass on the last link is an inertial error of the last link: the same dynamics".into(),
            }),
            "torque_gain" => {
                if let Some(Param::PerJoint(k)) = e.parameters.get("k") {
                    let mean = k.iter().sum::<f64>() / k.len().max(1) as f64;
                    if e.joints.len() == scorer.model.dof() && k.iter().all(|x| (x - mean).abs() <= 0.02 * mean.abs()) {
                        out.push(Alternative {
                            effects: with("torque_gain", "inertial_error"),
                            why: format!(
                                "a torque gain equal on every joint (k ≈ {mean:.3}) and every link's inertial parameters scaled by 1/k are the same dynamics up to friction"
                            ),
                        });
                    }
                }
            }
            "stribeck_friction" => {
                if let Some(Param::PerJoint(vs)) = e.parameters.get("vs") {
                    if vs.iter().all(|v| *v <= 0.02) {
                        out.push(Alternative {
                            effects: with("stribeck_friction", "coulomb_friction"),
                            why: "the Stribeck velocity is below what these runs resolve: Coulomb friction is the same effect here".into(),
                        });
                    }
                }
            }
            _ => {}
        }
    }
    // ties: swap one selected effect for a candidate of similar prediction on its own
    if current.is_finite() && !terms.is_empty() {
        let mut swaps: Vec<(String, usize)> = Vec::new();
        for name in &names {
            for i in swap_candidates(groups, alone_score, &names, name, 1.0 + 5.0 * TIE_TOLERANCE) {
                swaps.push((name.clone(), i));
            }
        }
        let scored: Vec<(String, usize, f64, bool)> = swaps
            .par_iter()
            .map(|(name, i)| {
                let set = swapped(terms, name, &groups[*i].1);
                let s = scorer.score(&set);
                // a swap better on the whole but not fold by fold is named with that said
                let holds = s < current * (1.0 - TIE_TOLERANCE) && scorer.gain_test(&set, terms).holds(PRUNE_TOLERANCE, ADD_GAIN);
                (name.clone(), *i, s, holds)
            })
            .collect();
        for (name, i, s, holds) in scored {
            if s <= current * (1.0 + TIE_TOLERANCE) {
                let effects = with(&name, groups[i].0);
                if !out.iter().any(|a: &Alternative| a.effects == effects) {
                    let why = if s < current * (1.0 - TIE_TOLERANCE) {
                        format!(
                            "replacing {name} by {} predicts the fit runs better on the whole (cross-validated k-step score {s:.4} against {current:.4}){}",
                            groups[i].0,
                            if holds { "" } else { " but not in every part of them" }
                        )
                    } else {
                        format!(
                            "replacing {name} by {} predicts the fit runs as well (cross-validated k-step score {s:.4} against {current:.4}, within {:.0} %)",
                            groups[i].0,
                            100.0 * TIE_TOLERANCE
                        )
                    };
                    out.push(Alternative { effects, why });
                }
            }
        }
    }
    out
}
