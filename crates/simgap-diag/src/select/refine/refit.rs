//! A shooting-refined set fitted again ([`refit`]) or scored with a term more or less
//! ([`shooting_errors`]), each half started from the set's own answer on that half.

use crate::error::Result;
use crate::options::DiagnoseOptions;
use crate::prediction::kstep;
use crate::select::scorer::Scorer;
use crate::select::shooting;
use crate::vocabulary::{Term, TermDesign};

use super::cross_validation::{shooting_options, transfer, try_set, Tried};
use super::final_fit::{finish, Refined};

/// The set of `r` fitted again by multiple shooting after a term left it with a value the others
/// were fitted beside (a partner it traded with, or a term at the edge of its range): its
/// two-fold cross-validation and its fit on all fit runs, each half started from the
/// torque-residual fit and from `r`'s answer on that half.
/// `None` when nothing is left to fit.
///
/// # Errors
/// As [`refine_by_shooting`](super::refine_by_shooting).
pub(crate) fn refit(scorer: &Scorer<'_>, r: &Refined, options: &DiagnoseOptions) -> Result<Option<(Refined, Vec<String>)>> {
    if r.terms.is_empty() {
        return Ok(None);
    }
    let sopts = shooting_options(scorer);
    let tried = try_from(scorer, &sopts, r, &r.terms, options)?;
    let what = "after a term that is no finding left the set, the parameters of the others are fitted again";
    finish(scorer, &r.runs, &sopts, tried, what, options).map(Some)
}

/// The two-fold cross-validated errors of every fit window of `terms` fitted by multiple
/// shooting as the shooting stage fits its sets, each half started from the torque-residual fit
/// and from `r`'s answer on the same half (shared terms; never from an answer that saw the held
/// half): what the fit runs say of `r`'s set with a term more or less, on the same footing as
/// the model the report states (its score is [`kstep::score`] of their RMS). The nominal
/// model's for no terms; `None` when that prediction failed.
///
/// # Errors
/// As [`refine_by_shooting`](super::refine_by_shooting).
pub(crate) fn shooting_errors(scorer: &Scorer<'_>, r: &Refined, terms: &[Term], options: &DiagnoseOptions) -> Result<Option<std::sync::Arc<kstep::Errors>>> {
    if terms.is_empty() {
        return Ok(scorer.cv_errors(terms));
    }
    Ok(Some(std::sync::Arc::new(try_from(scorer, &shooting_options(scorer), r, terms, options)?.errors)))
}

/// [`try_set`] of `terms`, each half started also from `r`'s answer on that half where they
/// share terms.
fn try_from(scorer: &Scorer<'_>, sopts: &shooting::Options, r: &Refined, terms: &[Term], options: &DiagnoseOptions) -> Result<Tried> {
    let before = as_tried(r);
    let earlier = |half: usize, designs: &[TermDesign]| before.halves.get(half).map(|h| transfer(&before, h, terms, designs)).into_iter().collect::<Vec<_>>();
    try_set(scorer, &r.runs, sopts, &r.name, terms, &earlier, options.stop.as_deref())
}

/// The set of `r` as its two-fold cross-validation fitted it (terms, designs, each half's
/// answer), the starts of a set with a term more or less ([`transfer`]).
pub(super) fn as_tried(r: &Refined) -> Tried {
    let (terms, designs, halves) = &r.halves;
    Tried {
        name: r.name.clone(),
        terms: terms.clone(),
        designs: designs.clone(),
        halves: halves.clone(),
        cv: r.cv.clone(),
        cv_per_run: Vec::new(),
        score: r.score,
        test: kstep::FoldTest::of(&[]),
        errors: r.errors.clone(),
    }
}
