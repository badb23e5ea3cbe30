//! The prune stage: the torque-residual selection pruned, completed with whole effects and
//! exchanged by cross-validated k-step prediction of the fit runs
//! ([`crate::select::prediction`]).

use crate::error::Result;
use crate::pipeline::candidates::Candidates;
use crate::pipeline::runner::Stages;
use crate::prepare::Prepared;
use crate::select::prediction::prune_and_complete;
use crate::select::scorer::Scorer;
use crate::select::Selection;

/// The prune stage: `selection` pruned and completed by prediction (unchanged when the fit runs
/// do not move).
///
/// # Errors
/// [`crate::Error::Interrupted`] when the diagnosis is stopped.
pub(crate) fn prune(scorer: &Scorer<'_>, candidates: &Candidates, mut selection: Selection, prep: &Prepared, stages: &mut Stages<'_>) -> Result<Selection> {
    // cross-validated k-step error on the fit runs
    if prep.moving {
        let options = stages.options;
        prune_and_complete(scorer, &candidates.groups, &candidates.alone_score, &mut selection, stages.progress(), options)?;
    }
    Ok(selection)
}
