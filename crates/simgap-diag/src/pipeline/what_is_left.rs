//! The what-is-left stage: the torque residual after the selected effects, tested joint by joint
//! ([`crate::report::residual`]).

use crate::pipeline::intervals::Intervals;
use crate::pipeline::notes::Notes;
use crate::prepare::Prepared;
use crate::report::residual;
use crate::select::residual_after;
use crate::select::scorer::Scorer;

/// The what-is-left stage: the torque residual after the selected effects (their
/// torque-residual fit on all fit data), tested joint by joint (no test when the fit runs do not
/// move); what is not negligible closes the notes.
pub(crate) fn what_is_left(scorer: &Scorer<'_>, prep: &Prepared, intervals: &Intervals, mut notes: Notes) -> Notes {
    if !prep.moving {
        return notes;
    }
    let (p, selection) = (&scorer.ctx.problem, &intervals.chosen.selection);
    let kinds: Vec<simgap_core::JointKind> = scorer.model.joints().iter().map(|j| j.kind).collect();
    // the residual left by the selected set, tested joint by joint
    let left = residual_after(p, &selection.designs, &selection.fit.theta);
    notes.residual = residual::test(p, &prep.data, &left, &prep.joints, &kinds);
    // what is not negligible closes the notes
    notes.notes.extend(notes.residual.iter().filter(|t| t.kind != "negligible").map(|t| t.sentence()));
    notes
}
