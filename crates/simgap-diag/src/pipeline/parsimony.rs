//! The parsimony stage: a richer effect that the simpler one nested in it matches becomes the
//! simpler ([`crate::select::plausible::parsimony`]).

use crate::pipeline::chosen::Chosen;
use crate::prepare::Prepared;
use crate::select::plausible;
use crate::select::scorer::Scorer;
use crate::select::Selection;

/// The parsimony stage: the pruned `selection` with richer effects replaced by the simpler ones
/// nested in them where those predict the fit runs as well, and the set's score.
pub(crate) fn parsimony(scorer: &Scorer<'_>, prep: &Prepared, mut selection: Selection) -> Chosen {
    // a richer effect that the simpler one nested in it matches is the simpler
    let mut replacements = Vec::new();
    if prep.moving {
        let current = scorer.score(&selection.terms);
        replacements = plausible::parsimony(scorer, &mut selection.terms, current, &mut selection.log, &prep.joints).1;
    }
    // the set's cross-validated prediction of the fit runs
    let score = scorer.score(&selection.terms);
    let cv = scorer.cv(&selection.terms);
    Chosen { selection, replacements, score, cv, refined: None, shooting_notes: Vec::new() }
}
