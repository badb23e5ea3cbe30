//! The selected set between the stages by prediction (prune, parsimony, refine, drive swap,
//! intervals), and how a stage that replaces it logs the change.

use crate::select::plausible::Replacement;
use crate::select::refine::Refined;
use crate::select::{Selection, Step};
use crate::vocabulary::Term;

/// The selected set as a stage by prediction leaves it.
pub(crate) struct Chosen {
    /// The selected terms, their torque-residual fit and the selection log.
    pub(crate) selection: Selection,
    /// Richer effects replaced by the simpler ones nested in them (richer, simpler, why).
    pub(crate) replacements: Vec<Replacement>,
    /// The set's cross-validated k-step score on the fit runs (against the nominal model's).
    pub(crate) score: f64,
    /// The set's cross-validated k-step RMS per horizon on the fit runs [rad or m].
    pub(crate) cv: Vec<f64>,
    /// The set fitted by multiple shooting, when that fit replaced the torque-residual one.
    pub(crate) refined: Option<Refined>,
    /// What multiple shooting tried and found, for the report's notes.
    pub(crate) shooting_notes: Vec<String>,
}

/// The selection log's words for a set of terms replacing the selection.
pub(crate) struct LogTexts {
    /// For a selected term the new set drops.
    pub(crate) dropped: String,
    /// For a selected term the new set keeps (not logged when `None`).
    pub(crate) kept: Option<String>,
    /// For a term the new set adds.
    pub(crate) added: String,
}

/// Replaces the selected terms by `terms`, logging each term dropped, kept and added with the
/// words of `texts`.
pub(crate) fn log_replacement(selection: &mut Selection, terms: &[Term], texts: LogTexts) {
    let step = |term: &Term, accepted: bool, reason: &str| Step { term: term.clone(), cv_mse: f64::NAN, accepted, reason: reason.to_string() };
    let before = std::mem::replace(&mut selection.terms, terms.to_vec());
    // the terms the new set drops
    for t in before.iter().filter(|t| !terms.contains(t)) {
        selection.log.push(step(t, false, &texts.dropped));
    }
    // the terms it keeps and adds
    for t in terms {
        match (before.contains(t), &texts.kept) {
            (true, Some(kept)) => selection.log.push(step(t, true, kept)),
            (true, None) => {}
            (false, _) => selection.log.push(step(t, true, &texts.added)),
        }
    }
}
