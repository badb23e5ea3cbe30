//! The drive swap stage: on a one-joint servo arm, the drive's gain and rotor inertia in place of
//! an inertial correction that is the same dynamics
//! ([`crate::select::refine::drive_in_place_of_inertia`]).

use crate::error::Result;
use crate::pipeline::chosen::{log_replacement, Chosen, LogTexts};
use crate::pipeline::runner::Stages;
use crate::select::refine::drive_in_place_of_inertia;
use crate::select::scorer::Scorer;

/// The drive swap stage: where the drive's constants predict the fit runs as well as the
/// inertial correction of a set refined by multiple shooting, they replace it.
///
/// # Errors
/// [`crate::Error::Interrupted`] when the diagnosis is stopped.
pub(crate) fn drive_swap(scorer: &Scorer<'_>, mut chosen: Chosen, stages: &Stages<'_>) -> Result<Chosen> {
    let Some(r) = chosen.refined.as_ref() else { return Ok(chosen) };
    // the drive's gain and rotor inertia tried in place of the inertial correction
    let (swapped, notes) = drive_in_place_of_inertia(scorer, r, stages.options)?;
    chosen.shooting_notes.extend(notes);
    // kept where they predict the fit runs as well
    if let Some(s) = swapped {
        let texts = LogTexts {
            dropped: format!("replaced by {} (cross-validated k-step score {:.4} against {:.4}): on one turning joint the same dynamics up to friction", s.name, s.score, r.score),
            kept: None,
            added: format!("added as part of {}: the fit runs' cross-validated k-step error is {:.4} of the nominal model's", s.name, s.score),
        };
        log_replacement(&mut chosen.selection, &s.terms, texts);
        chosen.score = s.score;
        chosen.cv = s.cv.clone();
        chosen.refined = Some(s);
    }
    Ok(chosen)
}
