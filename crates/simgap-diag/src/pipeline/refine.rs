//! The refine stage: parameters fitted to k-step prediction by multiple shooting, on open-loop
//! fit runs ([`crate::select::refine::refine_by_shooting`]).

use crate::error::Result;
use crate::pipeline::chosen::{log_replacement, Chosen, LogTexts};
use crate::pipeline::runner::Stages;
use crate::prepare::Prepared;
use crate::select::refine::refine_by_shooting;
use crate::select::scorer::Scorer;

/// The refine stage: the set fitted by multiple shooting replaces the torque-residual fit when
/// the cross-validated prediction of the fit runs says so (the selection log says what changed).
///
/// # Errors
/// [`crate::Error::Interrupted`] when the diagnosis is stopped.
pub(crate) fn refine(scorer: &Scorer<'_>, prep: &Prepared, mut chosen: Chosen, stages: &mut Stages<'_>) -> Result<Chosen> {
    // parameters fitted to k-step prediction by multiple shooting
    let options = stages.options;
    let (refined, notes) = if prep.moving { refine_by_shooting(scorer, &chosen.selection.terms, chosen.score, stages.progress(), options)? } else { (None, Vec::new()) };
    // kept when the cross-validated prediction of the fit runs says so
    if let Some(r) = &refined {
        let before = chosen.score;
        let why = |how: &str| {
            format!(
                "{how} as part of {}: the fit runs' cross-validated k-step error is {:.4} of the nominal model's (torque-residual fit of the set before: {before:.4})",
                r.name, r.score
            )
        };
        let texts = LogTexts {
            dropped: format!("replaced by {}, fitted by multiple shooting (cross-validated k-step score {:.4} against {before:.4})", r.name, r.score),
            kept: Some(why("parameters refitted by multiple shooting")),
            added: why("added by multiple shooting"),
        };
        log_replacement(&mut chosen.selection, &r.terms, texts);
        chosen.score = r.score;
        chosen.cv = r.cv.clone();
    }
    chosen.refined = refined;
    chosen.shooting_notes.extend(notes);
    Ok(chosen)
}
