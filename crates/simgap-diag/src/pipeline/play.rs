//! The play stage: backlash searched by prediction on the joints whose rotor inertia the set holds
//! ([`crate::select::backlash::search`]).

use crate::error::Result;
use crate::pipeline::chosen::Chosen;
use crate::pipeline::runner::Stages;
use crate::prepare::Prepared;
use crate::select::backlash::search;
use crate::select::scorer::Scorer;

/// The play stage: the set after parsimony with the play of each drive added where it predicts
/// the fit runs better, its score and cross-validated errors updated; what was tried goes to the
/// report's notes.
///
/// # Errors
/// [`crate::Error::Interrupted`] when the diagnosis is stopped.
pub(crate) fn play(scorer: &Scorer<'_>, prep: &Prepared, mut chosen: Chosen, stages: &Stages<'_>) -> Result<Chosen> {
    // play needs motion, and a rotor inertia the effort can show (not on the link side of the gearbox)
    if !prep.moving || !crate::vocabulary::rotor::visible(&prep.data) {
        return Ok(chosen);
    }
    let kinds: Vec<simgap_core::JointKind> = scorer.model.joints().iter().map(|j| j.kind).collect();
    let before = chosen.selection.terms.len();
    let searched = search(scorer, &mut chosen.selection.terms, chosen.score, &mut chosen.selection.log, (&prep.joints, &kinds, &prep.passive), &|| stages.check())?;
    if chosen.selection.terms.len() > before {
        chosen.score = searched.score;
        chosen.cv = scorer.cv(&chosen.selection.terms);
    }
    chosen.shooting_notes.extend(searched.notes);
    Ok(chosen)
}
