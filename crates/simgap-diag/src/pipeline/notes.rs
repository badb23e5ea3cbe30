//! The notes stage: the alternatives to the selected set ([`crate::select::alternatives`],
//! [`crate::select::plausible::richer_alternatives`]), the effects dropped as no finding with
//! what each would have done on the held-out runs, and the report's notes: the logs', multiple
//! shooting's, a servo's by phase and temperature, the URDF's pitfalls
//! ([`crate::report::pitfalls`]), the actuator and mechanics parts of the gap, and what the
//! held-out prediction leaves ([`crate::report::verdict::residual_notes`]).

use rayon::prelude::*;
use simgap_sim::EffectKind;

use crate::pipeline::candidates::Candidates;
use crate::pipeline::how_far::HowFar;
use crate::pipeline::intervals::Intervals;
use crate::pipeline::locate::Located;
use crate::prediction::kstep;
use crate::prepare::Prepared;
use crate::report::residual::ResidualTest;
use crate::report::units::Units;
use crate::report::verdict::residual_notes;
use crate::report::{pitfalls, Alternative, DroppedEffect};
use crate::select::alternatives::alternatives;
use crate::select::plausible;
use crate::select::prediction::{fits_in, ADD_GAIN};
use crate::select::scorer::Scorer;
use crate::vocabulary::effects;

/// The alternatives, dropped effects and notes of the report.
pub(crate) struct Notes {
    /// The effects that left as no finding, with what each would have done on the held-out runs.
    pub(crate) dropped: Vec<DroppedEffect>,
    /// Sets that predict the fit runs about as well as the selected one.
    pub(crate) alternatives: Vec<Alternative>,
    /// The report's notes, in the order they are stated.
    pub(crate) notes: Vec<String>,
    /// The torque residual left by the selected set, tested joint by joint (by the what-is-left
    /// stage; empty before it).
    pub(crate) residual: Vec<ResidualTest>,
}

/// The notes stage: alternatives and notes (see the module documentation).
pub(crate) fn notes(
    scorer: &Scorer<'_>,
    prep: &Prepared,
    located: &Located,
    candidates: &Candidates,
    intervals: &Intervals,
    how_far: &HowFar,
    options: &crate::DiagnoseOptions,
) -> Notes {
    let (model, data, joints, horizons) = (scorer.model, &prep.data, &prep.joints, &prep.horizons);
    let (groups, alone_score) = (&candidates.groups, &candidates.alone_score);
    let (selection, final_score) = (&intervals.chosen.selection, intervals.chosen.score);
    let kinds: Vec<simgap_core::JointKind> = model.joints().iter().map(|j| j.kind).collect();
    let units = Units::of(&kinds);
    // alternatives: exchanges that predict as well, and the richer effects parsimony replaced
    let mut alternatives = if prep.moving { alternatives(scorer, groups, alone_score, &selection.terms, final_score, &intervals.selected, &intervals.effects) } else { Vec::new() };
    for a in plausible::richer_alternatives(&selection.terms, &intervals.chosen.replacements) {
        if !alternatives.iter().any(|b| b.effects == a.effects) {
            alternatives.push(a);
        }
    }
    // the logs' notes, the families not tried, and multiple shooting's
    let mut notes = prep.notes.clone();
    notes.extend(crate::select::families::not_tried(&kinds, joints, prep.servo.is_some(), options));
    notes.extend(intervals.chosen.shooting_notes.iter().cloned());
    // servo runs: the gap by phase, and what their temperatures confound
    let h_last = horizons.len() - 1;
    notes.extend(crate::report::servo::phase_note(&prep.hold_pred, &how_far.before_runs_k, &how_far.after_runs_k, &how_far.floor_runs, h_last, horizons[h_last], &units.position));
    notes.extend(crate::report::servo::temperature_note(prep.fit_runs.iter().chain(&prep.hold_runs)));
    if prep.moving {
        // a pitfall is named with what prediction says of the matching correction; a rotor
        // inertia that does not improve prediction is not named at all
        let alone = |effect: &str| groups.iter().position(|g| g.0 == effect).map(|i| alone_score[i]);
        for note in pitfalls::urdf_pitfalls(model, data) {
            let effect = if note.contains("rotor inertia") {
                Some(EffectKind::Armature.as_str())
            } else if note.contains("inertia about") {
                Some(EffectKind::InertialError.as_str())
            } else {
                None
            };
            // a correction that the selected set already makes needless (its data explained
            // otherwise) is not named: it must improve the selected set's prediction too
            let needless = |e: &str| {
                if selection.terms.iter().any(|t| t.effect_name() == e) {
                    return false;
                }
                let Some(g) = groups.iter().find(|g| g.0 == e) else { return false };
                let mut with = selection.terms.clone();
                with.extend(g.1.iter().filter(|t| fits_in(&selection.terms, t)).cloned());
                scorer.score(&with) >= final_score * (1.0 - ADD_GAIN)
            };
            let selected_it = |e: &str| selection.terms.iter().any(|t| t.effect_name() == e);
            match effect.and_then(|e| alone(e).map(|a| (e, a))) {
                Some((e, _)) if selected_it(e) => notes.push(format!("{note}; the selected {e} corrects it")),
                Some((e, a)) if e == EffectKind::Armature.as_str() && a >= 1.0 - ADD_GAIN => {}
                Some((e, _)) if !selection.terms.is_empty() && needless(e) => {}
                Some((e, a)) => notes.push(format!("{note}; fitted alone, {e} predicts the fit runs at {a:.2} of the nominal model's cross-validated k-step error")),
                None => notes.push(note),
            }
        }
    }
    // with a measured torque: the actuator's and the mechanics' parts of the gap
    for j in &located.location.per_joint {
        if let (Some(a), Some(m)) = (j.actuator_residual_l2, j.mechanics_residual_l2) {
            let (part, other) =
                if a > m { ("the actuator (commanded → delivered torque)", "the mechanics") } else { ("the mechanics (delivered torque → motion)", "the actuator") };
            notes.push(format!(
                "{}: with the measured torque the gap splits into actuator {a:.3e} {e} and mechanics {m:.3e} {e} (RMS): most of it lies in {part}, less in {other}",
                j.joint,
                e = joints.iter().position(|n| *n == j.joint).map_or("N·m", |i| simgap_sim::Quantity::Effort.unit(kinds[i]))
            ));
        }
    }
    // what the held-out prediction leaves
    notes.extend(residual_notes(&how_far.kstep, &intervals.chosen.cv, &scorer.nominal, horizons, &units.position));
    let dropped = dropped_effects(scorer, prep, intervals);
    Notes { alternatives, dropped, notes, residual: Vec::new() }
}

/// The effects that left as no finding, each as it was judged, with the held-out k-step error of
/// the selected effects with it added: what it would have done, measured after every decision
/// (as the screen stage measures every candidate alone), so that a user sees what was dropped
/// and why, not "nothing significant".
fn dropped_effects(scorer: &Scorer<'_>, prep: &Prepared, intervals: &Intervals) -> Vec<DroppedEffect> {
    let (model, formulation, horizons) = (scorer.model, scorer.formulation, &prep.horizons);
    intervals
        .dropped
        .par_iter()
        .filter_map(|d| {
            let fitted = effects::to_reports(model, std::slice::from_ref(&d.fitted)).into_iter().next()?;
            let mut with = intervals.effects.clone();
            with.extend(effects::to_effects(model, std::slice::from_ref(&d.fitted)));
            let holdout_kstep_with = kstep::predict_all(model, formulation, &with, &prep.hold_pred, horizons).map(|e| e.0.rms()).unwrap_or_else(|_| vec![f64::NAN; horizons.len()]);
            Some(DroppedEffect {
                fitted,
                rule: d.rule.as_str().to_string(),
                why: d.why.clone(),
                fit_score_with: d.scores.map(|s| s.0),
                fit_score_without: d.scores.map(|s| s.1),
                holdout_kstep_with,
            })
        })
        .collect()
}
