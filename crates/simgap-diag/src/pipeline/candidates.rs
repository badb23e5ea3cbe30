//! The candidates stage: every effect of the vocabulary alone, as one group of terms
//! ([`crate::select::screen::candidate_groups`]), scored by cross-validated k-step prediction of
//! the fit runs.

use crate::pipeline::runner::Stages;
use crate::prediction::kstep;
use crate::prepare::Prepared;
use crate::select::scorer::Scorer;
use crate::select::screen::{candidate_groups, drop_passive_actuator_terms};
use crate::select::Context;
use crate::vocabulary::Term;

/// Every effect alone, as the stages after the selection compare with.
pub(crate) struct Candidates {
    /// Per effect, its name and its terms (on every joint where it is a candidate).
    pub(crate) groups: Vec<(&'static str, Vec<Term>)>,
    /// Per group, its cross-validated k-step RMS per horizon on the fit runs [rad or m] (NaN
    /// when the diagnosis was stopped before it).
    pub(crate) alone_cv: Vec<Vec<f64>>,
    /// Per group, its k-step score against the nominal model ([`kstep::score`]).
    pub(crate) alone_score: Vec<f64>,
}

/// The candidates stage: the groups (best grid member per joint against the nominal residual,
/// actuator terms of passive joints left out), each scored alone by prediction. Starts the
/// counted steps of the candidates and the screen (`selected`: the number of selected terms,
/// part of the margin).
pub(crate) fn candidates(ctx: &Context<'_>, scorer: &Scorer<'_>, prep: &Prepared, selected: usize, stages: &mut Stages<'_>) -> Candidates {
    // every effect of the vocabulary alone
    let groups: Vec<(&'static str, Vec<Term>)> = candidate_groups(ctx, &ctx.problem.y)
        .into_iter()
        .map(|(n, mut t)| {
            drop_passive_actuator_terms(&mut t, &prep.passive);
            (n, t)
        })
        .filter(|(_, t)| !t.is_empty())
        .collect();
    // counted steps: one per group here and one in the screen, with the margin the progress
    // bar has always had
    stages.count(groups.len() * 2 + selected + 4);
    // each scored alone by cross-validated k-step prediction of the fit runs
    let alone_cv: Vec<Vec<f64>> = groups
        .iter()
        .map(|(_, t)| {
            stages.tick("scoring candidates by prediction");
            if stages.stopped() {
                return vec![f64::NAN; prep.horizons.len()];
            }
            scorer.cv(t)
        })
        .collect();
    let alone_score: Vec<f64> = alone_cv.iter().map(|v| kstep::score(v, &scorer.nominal)).collect();
    Candidates { groups, alone_cv, alone_score }
}
