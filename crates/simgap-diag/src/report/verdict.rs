//! The verdict and the headline: which figure answers "how far", and the one-sentence
//! conclusion drawn from the figures.

use simgap_sim::{ControllerKind, EffectKind, Run};

use crate::prediction::resim;
use crate::report::units::Units;
use crate::report::{KStep, Report};
use crate::vocabulary::{EffectReport, Param};

/// The verdict says "explained" only when the selected effects leave at most this fraction of
/// the held-out gap (and no horizon gets worse); above it, "partly explained".
pub(crate) const EXPLAINED_BELOW: f64 = 0.5;

/// Above this fraction of the held-out gap left, the verdict says "barely explained" (the HTML
/// banner's "barely change" uses the same figure).
pub(crate) const BARELY_ABOVE: f64 = 0.9;

/// Which figure answers "how far", and why.
pub(crate) fn headline(hold_runs: &[Run], before_runs: &[resim::RunGap], after_runs: &[resim::RunGap], before: f64, u: &str) -> (String, String) {
    let open_loop: Vec<&str> = hold_runs.iter().filter(|r| r.experiment.as_ref().is_none_or(|e| e.controller == ControllerKind::Replay)).map(|r| r.source.as_str()).collect();
    if !open_loop.is_empty() {
        return (
            "k_step".into(),
            format!("held-out run(s) {} are open-loop replays: a whole-run simulation of an open loop measures how fast trajectories diverge, not the model", open_loop.join(", ")),
        );
    }
    if let Some(g) = before_runs.iter().chain(after_runs).find(|g| g.status != "completed") {
        return ("k_step".into(), format!("the closed-loop simulation of {} did not complete ({}): its whole-run figure measures divergence", g.log, g.status));
    }
    // the closed loop must stay near the measured run: within a fifth of the motion's spread
    let spread = {
        let (mut s, mut c) = (0.0, 0usize);
        for r in hold_runs {
            let n = r.dof();
            for j in 0..n {
                let col: Vec<f64> = r.q.iter().skip(j).step_by(n).copied().collect();
                let m = col.iter().sum::<f64>() / col.len().max(1) as f64;
                s += col.iter().map(|v| (v - m).powi(2)).sum::<f64>();
                c += col.len();
            }
        }
        (s / c.max(1) as f64 * hold_runs.first().map_or(1, Run::dof) as f64).sqrt()
    };
    if before > 0.2 * spread {
        return ("k_step".into(), format!("the nominal closed-loop simulation strays {before:.3e} {u} (L²) from the measured runs, more than a fifth of the motion's spread ({spread:.3e} {u}): the whole-run figure would measure divergence"));
    }
    ("closed_loop".into(), "every held-out run is a feedback loop and its closed-loop simulation stays near the measured run: the whole-run L² (eq. 127) is meaningful; k-step figures are given beside it".into())
}

/// What is left after the selected effects, in words.
pub(crate) fn residual_notes(k: &KStep, fit_cv: &[f64], fit_nominal: &[f64], horizons: &[f64], u: &str) -> Vec<String> {
    let mut notes = Vec::new();
    for (i, h) in horizons.iter().enumerate() {
        let (a, f) = (k.after.get(i).copied().unwrap_or(f64::NAN), k.floor.get(i).copied().unwrap_or(f64::NAN));
        if a.is_finite() && f.is_finite() && a >= f {
            notes.push(format!("at {h} s the corrected model predicts the held-out runs no better than constant-velocity extrapolation ({a:.3e} vs {f:.3e} {u}): at this horizon the figures say nothing about physics"));
        }
    }
    if let (Some(a), Some(b)) = (fit_cv.first(), fit_nominal.first()) {
        if a.is_finite() && b.is_finite() && *b > 0.0 && a / b > 0.5 {
            notes.push(format!("after the selected effects the fit runs' cross-validated k-step error at {} s is still {:.0} % of the nominal model's: much of the gap is left (the residual test of each joint, in these notes, says whether it is noise or structure)", horizons[0], 100.0 * a / b));
        }
    }
    notes
}

/// The one-sentence conclusion; never says "explained" when the held-out figure got worse or
/// the nominal simulation diverged.
pub(crate) fn verdict(moving: bool, selected: &[EffectReport], headline: &str, k: &KStep, (before, after): (f64, f64), before_runs: &[resim::RunGap], units: &Units) -> String {
    let (u, v) = (units.position.as_str(), units.velocity.as_str());
    if !moving {
        return format!("cannot tell: the fit logs show no motion (all velocities below 1e-3 {v}), so no effect can be told apart");
    }
    let names: Vec<String> = selected.iter().map(|e| if e.joints.is_empty() { e.effect.to_string() } else { format!("{} on {}", e.effect, e.joints.join(", ")) }).collect();
    let (figure, b, a) = if headline == "closed_loop" {
        ("closed-loop L²".to_string(), before, after)
    } else {
        let i = k.horizons_s.len().saturating_sub(1).min(k.horizons_s.iter().position(|h| *h >= 0.5).unwrap_or(usize::MAX));
        (
            format!("k-step error at {} s", k.horizons_s.get(i).copied().unwrap_or(f64::NAN)),
            k.before.get(i).copied().unwrap_or(f64::NAN),
            k.after.get(i).copied().unwrap_or(f64::NAN),
        )
    };
    let diverged = before_runs.iter().any(|g| g.status != "completed");
    let diverged_note = if diverged && headline != "closed_loop" { " (the nominal closed-loop simulation diverged, so the closed-loop figure is not used)" } else { "" };
    if selected.is_empty() {
        return format!("nothing significant: no effect improves the cross-validated prediction of the fit runs; held-out {figure} {b:.3e} {u}{diverged_note}");
    }
    if !(a < b) {
        return format!(
            "not explained: the effects the fit runs support ({}) do not improve the held-out {figure}: {b:.3e} → {a:.3e} {u} (worse or equal){diverged_note}",
            names.join("; ")
        );
    }
    // every horizon must improve for the gap to be called explained
    let worse: Vec<String> =
        k.horizons_s.iter().zip(k.before.iter().zip(&k.after)).filter(|(_, (b, a))| !(a < b)).map(|(h, (b, a))| format!("{h} s ({b:.3e} → {a:.3e} {u})")).collect();
    if !worse.is_empty() {
        return format!(
            "partly explained: with {} the held-out {figure} goes {b:.3e} → {a:.3e} {u}, but the k-step error is worse or equal at {}{diverged_note}",
            names.join("; "),
            worse.join(", ")
        );
    }
    // how much of the gap is gone decides the word: a small improvement is no explanation
    let ratio = a / b;
    if ratio > BARELY_ABOVE {
        return format!(
            "barely explained: with {} the held-out {figure} goes {b:.3e} → {a:.3e} {u} ({:.1} % of before), a change of the size noise and small unmodelled effects make{diverged_note}",
            names.join("; "),
            100.0 * ratio
        );
    }
    if ratio > EXPLAINED_BELOW {
        return format!(
            "partly explained: {} shrink the held-out {figure} {b:.3e} → {a:.3e} {u} ({:.1} % of before); more than half of the gap remains{diverged_note}",
            names.join("; "),
            100.0 * ratio
        );
    }
    // "explained" needs at most half of the gap left at every k-step horizon of a k-step
    // headline, and a corrected model that beats constant-velocity extrapolation clearly
    let (half_left, not_beaten) = against_floor(k, headline == "k_step", u);
    if !half_left.is_empty() {
        return format!(
            "partly explained: {} shrink the held-out {figure} {b:.3e} → {a:.3e} {u} ({:.1} % of before), but more than half of the k-step error remains at {}{diverged_note}",
            names.join("; "),
            100.0 * ratio,
            half_left.join(", ")
        );
    }
    if !not_beaten.is_empty() {
        return format!(
            "partly explained: {} shrink the held-out {figure} {b:.3e} → {a:.3e} {u} ({:.1} % of before), but the corrected model does not beat constant-velocity extrapolation by {:.0} % at {}: at those horizons these data cannot show that the effects are the robot's physics (heavily filtered signals or a repeated trajectory, for example, leave inertia and position-dependent torques inseparable){diverged_note}",
            names.join("; "),
            100.0 * ratio,
            100.0 * (1.0 - FLOOR_MARGIN),
            not_beaten.join(", ")
        );
    }
    format!("the gap is explained by {}; held-out {figure} {b:.3e} → {a:.3e} {u} ({:.1} % of before){diverged_note}", names.join("; "), 100.0 * ratio)
}

/// A corrected model beats constant-velocity extrapolation clearly when its k-step error is at
/// most this fraction of the extrapolation's.
pub(crate) const FLOOR_MARGIN: f64 = 0.8;

/// The horizons where more than half of the k-step error is left (checked when `every_horizon`:
/// a k-step headline) and where the corrected model does not beat constant-velocity
/// extrapolation by [`FLOOR_MARGIN`], as "h s (a vs b rad)" in the position unit `u`.
pub(crate) fn against_floor(k: &KStep, every_horizon: bool, u: &str) -> (Vec<String>, Vec<String>) {
    let mut half_left = Vec::new();
    let mut not_beaten = Vec::new();
    for (i, h) in k.horizons_s.iter().enumerate() {
        let (b, a) = (k.before.get(i).copied().unwrap_or(f64::NAN), k.after.get(i).copied().unwrap_or(f64::NAN));
        let f = k.floor.get(i).copied().unwrap_or(f64::NAN);
        if every_horizon && !(a <= EXPLAINED_BELOW * b) {
            half_left.push(format!("{h} s ({b:.3e} → {a:.3e} {u})"));
        }
        if f.is_finite() && !(a <= FLOOR_MARGIN * f) {
            not_beaten.push(format!("{h} s ({a:.3e} vs {f:.3e} {u})"));
        }
    }
    (half_left, not_beaten)
}

/// How the page sums up the answer: a class (`good`, `warn`, `bad`, `none`) and a sentence,
/// both from the report's numbers (never from the verdict text, so the banner cannot
/// contradict the figures below it).
#[derive(Clone, Debug, PartialEq)]
pub struct Assessment {
    /// `good`, `warn`, `bad` or `none`.
    pub class: &'static str,
    /// One or two sentences.
    pub text: String,
}

/// The runs whose simulation did not complete, as `log (status)`.
fn not_completed(runs: &[crate::prediction::resim::RunGap]) -> Vec<String> {
    runs.iter().filter(|g| g.status != "completed").map(|g| format!("{} ({})", g.log, g.status)).collect()
}

/// Sums up the report from its numbers (see [`Assessment`]).
pub fn assess(r: &Report) -> Assessment {
    let units = Units::of_types(&r.joint_types);
    let u = units.position.as_str();
    let g = &r.gap;
    let names: Vec<String> =
        ranked_selection(r).iter().map(|e| if e.joints.is_empty() { e.effect.to_string() } else { format!("{} on {}", e.effect, e.joints.join(", ")) }).collect();
    let nominal_bad = not_completed(&g.runs_before);
    let corrected_bad = if r.selected_effects.is_empty() { vec![] } else { not_completed(&g.runs_after) };
    let k = &g.kstep;
    let use_kstep = g.headline == "k_step" && !k.before.is_empty() && k.before.len() == k.after.len() && k.before.len() == k.horizons_s.len();
    let mut notes = Vec::new();
    if !nominal_bad.is_empty() {
        notes.push(format!("The nominal simulation diverges on {}: its closed-loop L² measures divergence, not the model.", nominal_bad.join(", ")));
    }
    if r.selected_effects.is_empty() {
        let text = format!("No effect selected: {}. {}", lowercase_first(&r.verdict), notes.join(" "));
        return Assessment { class: "none", text: text.trim().to_string() };
    }
    let selected = names.join("; ");
    if !corrected_bad.is_empty() {
        notes.insert(0, format!("With the selected effects ({selected}) the simulation still diverges on {}: they do not close the gap.", corrected_bad.join(", ")));
        return Assessment { class: "bad", text: notes.join(" ") };
    }
    if use_kstep {
        // the longest horizon decides; the constant-velocity floor says whether physics helps
        let i = k.horizons_s.len() - 1;
        let (h, b, a) = (k.horizons_s[i], k.before[i], k.after[i]);
        let floor = k.floor.get(i).copied().unwrap_or(f64::NAN);
        let ratio = a / b;
        let beat = if floor.is_finite() && !(a <= FLOOR_MARGIN * floor) {
            format!(" It does not beat constant-velocity extrapolation ({floor:.3e} {u}) by {:.0} %, so it says little about the physics.", 100.0 * (1.0 - FLOOR_MARGIN))
        } else {
            String::new()
        };
        let (class, what) = if !ratio.is_finite() {
            ("warn", format!("the {h} s prediction error cannot be compared ({b:.3e} → {a:.3e} {u})"))
        } else if ratio > 1.0 {
            ("bad", format!("they make the {h} s prediction of held-out runs worse: {b:.3e} → {a:.3e} {u} (×{ratio:.2})"))
        } else if ratio > BARELY_ABOVE {
            ("warn", format!("they barely change the {h} s prediction of held-out runs: {b:.3e} → {a:.3e} {u} ({:.0} % of before)", 100.0 * ratio))
        } else {
            ("good", format!("they shrink the {h} s prediction error on held-out runs: {b:.3e} → {a:.3e} {u} ({:.0} % of before)", 100.0 * ratio))
        };
        let class = if class == "good" && !beat.is_empty() { "warn" } else { class };
        let text = format!("Selected: {selected}; {what}.{beat} {}", notes.join(" "));
        return Assessment { class, text: text.trim().to_string() };
    }
    let (b, a) = (g.holdout_l2_before, g.holdout_l2_after);
    if !nominal_bad.is_empty() || !b.is_finite() {
        let text = format!("Selected: {selected}. {} With them the held-out runs complete with closed-loop L² {a:.3e} {u}; compare the plots below.", notes.join(" "));
        return Assessment { class: "warn", text: text.trim().to_string() };
    }
    let ratio = a / b;
    let (class, what) = if !ratio.is_finite() {
        ("warn", format!("held-out L² {b:.3e} → {a:.3e} {u} cannot be compared"))
    } else if ratio > 1.0 {
        ("bad", format!("they make held-out runs worse: closed-loop L² {b:.3e} → {a:.3e} {u} (×{ratio:.2})"))
    } else if ratio > BARELY_ABOVE {
        ("warn", format!("they barely change held-out runs: closed-loop L² {b:.3e} → {a:.3e} {u} ({:.0} % of before)", 100.0 * ratio))
    } else {
        ("good", format!("they shrink the gap on held-out runs: closed-loop L² {b:.3e} → {a:.3e} {u} ({:.1} % of before)", 100.0 * ratio))
    };
    Assessment { class, text: format!("Selected: {selected}; {what}.") }
}

fn lowercase_first(s: &str) -> String {
    let mut c = s.chars();
    match c.next() {
        Some(f) => f.to_lowercase().chain(c).collect(),
        None => String::new(),
    }
}

/// The selected effects in candidate rank order, each with its joints (and per-joint
/// parameters) in model order.
pub(crate) fn ranked_selection(r: &Report) -> Vec<EffectReport> {
    let rank = |effect: EffectKind| r.candidates.iter().find(|c| c.effect == effect).map_or(usize::MAX, |c| c.rank);
    let mut out: Vec<EffectReport> = r.selected_effects.iter().map(|e| in_model_order(e, &r.joints)).collect();
    out.sort_by_key(|e| rank(e.effect));
    out
}

/// `e` with its joints in the order of `joints` (a model's), per-joint values moved with them.
fn in_model_order(e: &EffectReport, joints: &[String]) -> EffectReport {
    let pos = |name: &String| joints.iter().position(|j| j == name).unwrap_or(usize::MAX);
    let mut order: Vec<usize> = (0..e.joints.len()).collect();
    order.sort_by_key(|&i| pos(&e.joints[i]));
    if order.iter().enumerate().all(|(k, &i)| k == i) {
        return e.clone();
    }
    let n = e.joints.len();
    let reorder = |m: &std::collections::BTreeMap<String, Param>| -> std::collections::BTreeMap<String, Param> {
        m.iter()
            .map(|(k, v)| {
                let v = match v {
                    Param::PerJoint(x) if x.len() == n => Param::PerJoint(order.iter().map(|&i| x[i]).collect()),
                    Param::PerLink(x) if x.len() == n => Param::PerLink(order.iter().map(|&i| x[i].clone()).collect()),
                    other => other.clone(),
                };
                (k.clone(), v)
            })
            .collect()
    };
    let mut out = e.clone();
    out.joints = order.iter().map(|&i| e.joints[i].clone()).collect();
    out.parameters = reorder(&e.parameters);
    out.uncertainty = reorder(&e.uncertainty);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kstep(before: [f64; 2], after: [f64; 2], floor: [f64; 2]) -> KStep {
        KStep { horizons_s: vec![0.1, 0.5], before: before.to_vec(), after: after.to_vec(), floor: floor.to_vec(), per_joint_before: vec![], per_joint_after: vec![], runs: vec![] }
    }

    fn one_effect() -> Vec<EffectReport> {
        vec![EffectReport { joints: vec!["j1".into()], ..EffectReport::new(EffectKind::Armature) }]
    }

    #[test]
    fn a_corrected_model_that_beats_the_floor_clearly_explains_the_gap() {
        let k = kstep([1.0, 2.0], [0.1, 0.2], [0.5, 1.0]);
        let v = verdict(true, &one_effect(), "k_step", &k, (f64::NAN, f64::NAN), &[], &Units::of(&[]));
        assert!(v.starts_with("the gap is explained"), "{v}");
    }

    #[test]
    fn a_corrected_model_no_better_than_constant_velocity_explains_nothing() {
        // the 7-DOF arm's case: 6 % of the gap left, but only 8–9 % better than the floor
        let k = kstep([1.0, 2.0], [0.06, 0.12], [0.066, 0.13]);
        let v = verdict(true, &one_effect(), "k_step", &k, (f64::NAN, f64::NAN), &[], &Units::of(&[]));
        assert!(v.starts_with("partly explained") && v.contains("constant-velocity"), "{v}");
    }

    #[test]
    fn more_than_half_left_at_one_horizon_is_not_explained() {
        let k = kstep([1.0, 2.0], [0.6, 0.2], [5.0, 10.0]);
        let v = verdict(true, &one_effect(), "k_step", &k, (f64::NAN, f64::NAN), &[], &Units::of(&[]));
        assert!(v.starts_with("partly explained") && v.contains("0.1 s"), "{v}");
    }
}
