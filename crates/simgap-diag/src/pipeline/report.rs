//! The report stage: the headline, the verdict ([`crate::report::verdict`]) and the report with
//! everything the stages found, handed over with the runs and simulations as a [`Diagnosis`].

use crate::pipeline::how_far::HowFar;
use crate::pipeline::intervals::Intervals;
use crate::pipeline::locate::Located;
use crate::pipeline::notes::Notes;
use crate::prepare::Prepared;
use crate::report::export_basis::ExportBasis;
use crate::report::units::Units;
use crate::report::verdict::{headline, verdict};
use crate::report::{Candidate, Decision, Diagnosis, Gap, Report, ServoReport};
use crate::select::scorer::Scorer;
use simgap_core::Model;

/// The report stage: the headline and verdict, the selection log in words, and the report of
/// every stage's findings (`candidates` from the screen, `notes` from the notes and what-is-left
/// stages).
pub(crate) fn report(scorer: &Scorer<'_>, prep: &Prepared, located: Located, candidates: Vec<Candidate>, intervals: &Intervals, how_far: &HowFar, notes: Notes) -> Report {
    let (model, formulation, joints) = (scorer.model, scorer.formulation, &prep.joints);
    let (selection, h) = (&intervals.chosen.selection, how_far);
    let kinds: Vec<simgap_core::JointKind> = model.joints().iter().map(|j| j.kind).collect();
    let units = Units::of(&kinds);
    // headline: the held-out figure that holds for these runs
    let (headline, headline_reason) = headline(&prep.hold_runs, &h.before_runs, &h.after_runs, h.before, &units.position);
    let Notes { alternatives, dropped, notes, residual } = notes;
    // one verdict
    let verdict = verdict(prep.moving, &intervals.selected, &headline, &h.kstep, (h.before, h.after), &h.before_runs, &units);
    // the selection log in words
    let selection_log = selection
        .log
        .iter()
        .map(|s| Decision { effect: s.term.kind(), joint: s.term.joint().map(|j| joints[j].clone()), cv_mse: s.cv_mse, accepted: s.accepted, reason: s.reason.clone() })
        .collect();
    // the report
    Report {
        simgap_version: env!("CARGO_PKG_VERSION").into(),
        model: model.name().into(),
        formulation: formulation.as_str().into(),
        joints: joints.clone(),
        joint_types: kinds.iter().map(|k| k.as_str().to_string()).collect(),
        fit_logs: prep.fit_runs.iter().map(|r| r.source.clone()).collect(),
        holdout_logs: prep.hold_runs.iter().map(|r| r.source.clone()).collect(),
        verdict,
        selected_effects: intervals.selected.clone(),
        dropped_effects: dropped,
        candidates,
        alternatives,
        notes,
        residual,
        sensors: prep.sensors.clone(),
        gap: Gap {
            headline,
            headline_reason,
            kstep: h.kstep.clone(),
            fit_kstep_cv_before: scorer.nominal.clone(),
            fit_kstep_cv_after: intervals.chosen.cv.clone(),
            holdout_l2_before: h.before,
            holdout_l2_after: h.after,
            ratio: if h.before > 0.0 { h.after / h.before } else { f64::NAN },
            per_joint_before: h.before_joint.clone(),
            per_joint_after: h.after_joint.clone(),
            runs_before: h.before_runs.clone(),
            runs_after: h.after_runs.clone(),
            fit_l2_before: h.fit_before,
            fit_l2_after: h.fit_after,
        },
        location: located.location,
        selection_log,
        nominal_cv_mse: selection.nominal_cv_mse,
        servo: prep.servo.as_ref().map(|c| ServoReport::new(joints, &c.kt, &c.r, c.source, &intervals.effects)),
    }
}

/// The diagnosis handed to the caller: `report`, the selected effects, the held-out runs with
/// their nominal and corrected simulations and the fit data, for plots, and what the export
/// takes from the logs ([`ExportBasis`]), decided here once from the prepared runs (fit, then
/// held out) so that every front end exports the same files.
pub(crate) fn diagnosis(model: &Model, report: Report, prep: Prepared, intervals: Intervals, how_far: HowFar) -> Diagnosis {
    // the export's time step, passive joints and servo firmware, from every prepared run
    let export = ExportBasis::of(model, prep.fit_runs.iter().chain(&prep.hold_runs));
    // the runs behind the figures
    let Prepared { hold_runs, data, .. } = prep;
    Diagnosis {
        report,
        effects: intervals.effects,
        holdout: hold_runs,
        holdout_nominal: how_far.holdout_nominal,
        holdout_corrected: how_far.holdout_corrected,
        fit_data: data,
        interval_variants: intervals.variants,
        export,
    }
}
