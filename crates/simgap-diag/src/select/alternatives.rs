//! Alternatives: effect sets the data cannot tell apart from the selected one (exact
//! equivalences, and swaps of one selected effect whose prediction ties).

use rayon::prelude::*;
use simgap_core::{gravity_torques, mass_matrix, JointKind, Model, Workspace};
use simgap_sim::{Effect, EffectKind};

use crate::report::Alternative;
use crate::select::prediction::{swap_candidates, swapped, ADD_GAIN, PRUNE_TOLERANCE, TIE_TOLERANCE};
use crate::select::scorer::Scorer;
use crate::vocabulary::{EffectReport, Param, Term};

/// Effect sets the data cannot tell apart from the selected one: exact equivalences, and swaps
/// of one selected effect for another whose prediction score ties within the tolerance.
/// `effects` are the selected effects as simulated (`selected` as reported).
pub(crate) fn alternatives(
    scorer: &Scorer<'_>,
    groups: &[(&'static str, Vec<Term>)],
    alone_score: &[f64],
    terms: &[Term],
    current: f64,
    selected: &[EffectReport],
    effects: &[Effect],
) -> Vec<Alternative> {
    let names: Vec<String> = selected.iter().map(|e| e.effect.to_string()).collect();
    let with = |drop: &str, add: &str| -> Vec<String> {
        let mut v: Vec<String> = names.iter().filter(|n| n.as_str() != drop).cloned().collect();
        if !v.iter().any(|n| n == add) {
            v.push(add.to_string());
        }
        v
    };
    use EffectKind::{Armature, CoulombFriction, InertialError, Payload, StribeckFriction, TorqueGain};
    let mut out = Vec::new();
    // exact equivalences
    for e in selected {
        match e.effect {
            Payload => out.push(Alternative {
                effects: with(Payload.as_str(), InertialError.as_str()),
                why: "a point mass on the last link is an inertial error of the last link: the same dynamics".into(),
            }),
            TorqueGain => {
                if let Some(Param::PerJoint(k)) = e.parameters.get("k") {
                    let mean = k.iter().sum::<f64>() / k.len().max(1) as f64;
                    if e.joints.len() == scorer.model.dof() && k.iter().all(|x| (x - mean).abs() <= 0.02 * mean.abs()) {
                        out.push(Alternative {
                            effects: with(TorqueGain.as_str(), InertialError.as_str()),
                            why: format!(
                                "a torque gain equal on every joint (k ≈ {mean:.3}) and every link's inertial parameters scaled by 1/k are the same dynamics up to friction"
                            ),
                        });
                    }
                }
            }
            InertialError => {
                if let Some(e) = one_joint_equivalent(scorer.model, effects) {
                    let mut set = with(InertialError.as_str(), TorqueGain.as_str());
                    if !set.iter().any(|n| n == Armature.as_str()) {
                        set.push(Armature.to_string());
                    }
                    let why = format!(
                        "on a one-joint arm an inertial correction changes only the weight's moment about the axis (here ×{:.3}) and the inertia about it (×{:.3}): a torque gain k = {:.3} with a rotor inertia ia = {} kg·m² gives the same dynamics up to friction{}",
                        e.moment_ratio,
                        e.inertia_ratio,
                        e.k,
                        crate::vocabulary::effects::sig3(e.ia),
                        if e.turn.abs() > 1e-3 { format!(" and a turn of the weight's direction by {:.1}° that neither holds", e.turn.to_degrees()) } else { String::new() }
                    );
                    out.push(Alternative { effects: set, why });
                }
            }
            StribeckFriction => {
                if let Some(Param::PerJoint(vs)) = e.parameters.get("vs") {
                    if vs.iter().all(|v| *v <= 0.02) {
                        out.push(Alternative {
                            effects: with(StribeckFriction.as_str(), CoulombFriction.as_str()),
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

/// A torque gain with a rotor inertia that give a one-joint arm the dynamics of an inertial
/// correction ([`one_joint_equivalent`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct GainAndRotor {
    /// The torque gain `k` [–].
    pub k: f64,
    /// The rotor inertia `ia` [kg·m²].
    pub ia: f64,
    /// The corrected weight's moment about the axis over the nominal one's [–].
    pub moment_ratio: f64,
    /// The corrected inertia about the axis over the nominal one [–].
    pub inertia_ratio: f64,
    /// The turn of the weight's direction about the axis that neither holds [rad].
    pub turn: f64,
}

/// On a one-joint arm with a rotating joint, an inertial correction changes two things the
/// dynamics see: the weight's moment about the axis (the amplitude of `g(q) = A sin q + B cos q`)
/// and the inertia about the axis (`H`, constant). A torque gain `k` (`k τ = H q̈ + g`) with a
/// rotor inertia `ia` gives `H' = (H + ia)/k` and `g' = g/k`: the same dynamics, up to friction
/// and the weight's direction, for `k = |g| / |g'|` and `ia = k H' − H` where that is not
/// negative. `None` for another arm, no inertial error among `effects`, no weight to compare, or
/// a rotor inertia that would be negative.
pub(crate) fn one_joint_equivalent(model: &Model, effects: &[Effect]) -> Option<GainAndRotor> {
    if model.dof() != 1 || model.joints()[0].kind == JointKind::Prismatic {
        return None;
    }
    let inertial: Vec<Effect> = effects.iter().filter(|e| matches!(e, Effect::InertialError { .. })).cloned().collect();
    if inertial.is_empty() {
        return None;
    }
    let corrected = simgap_sim::effects::apply_inertial_effects(model, &inertial).ok()?;
    // H, and the weight's moment about the axis as an amplitude and a direction
    let moments = |m: &Model| {
        let mut ws = Workspace::new(m);
        let h = mass_matrix(m, &mut ws, &[0.0])[(0, 0)];
        let (b, a) = (gravity_torques(m, &mut ws, &[0.0])[0], gravity_torques(m, &mut ws, &[std::f64::consts::FRAC_PI_2])[0]);
        (h, a.hypot(b), b.atan2(a))
    };
    let (h, g, phase) = moments(model);
    let (h_c, g_c, phase_c) = moments(&corrected);
    if !(g > 0.0 && g_c > 0.0 && h > 0.0 && h_c.is_finite()) {
        return None;
    }
    let k = g / g_c;
    let ia = k * h_c - h;
    if ia < -1e-3 * h {
        return None;
    }
    let turn = (phase_c - phase + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
    Some(GainAndRotor { k, ia: ia.max(0.0), moment_ratio: g_c / g, inertia_ratio: h_c / h, turn })
}
