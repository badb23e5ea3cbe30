//! The scorer: sets of terms scored by cross-validated k-step prediction of the fit runs, the one
//! helper for "fit → effects → predict → combine", memoised per set.

use simgap_core::{Formulation, Model};
use simgap_sim::Effect;

use crate::lsq::{self, design::TermDesign};
use crate::prediction::kstep::{self, FOLDS_PER_RUN};
use crate::prepare::Prepared;
use crate::select::{self, Context};
use crate::vocabulary::fitted_terms;
use crate::vocabulary::{effects, Term, TermKey};

/// Scores sets of terms by cross-validated prediction on the fit runs: the one helper for
/// "fit → effects → predict → combine".
pub(crate) struct Scorer<'a> {
    pub(crate) model: &'a Model,
    pub(crate) formulation: Formulation,
    pub(crate) ctx: &'a Context<'a>,
    pub(crate) prep: &'a Prepared,
    pub(crate) nominal: Vec<f64>,
    /// The fold of every fit window, in the order of [`Scorer::cv_errors`].
    pub(crate) folds: Vec<usize>,
    /// Cross-validated errors of the sets scored so far (the selection revisits sets); `None`
    /// for a set that is no answer (inadmissible, or a prediction that failed).
    pub(crate) memo: std::sync::Mutex<std::collections::HashMap<Vec<TermKey>, Option<std::sync::Arc<kstep::Errors>>>>,
    /// The driven servo joints some fit log shows stalled, once asked for
    /// ([`crate::select::refine::stalled_joints`]).
    pub(crate) stalled: std::sync::OnceLock<Vec<usize>>,
}

impl Scorer<'_> {
    pub(crate) fn new<'a>(model: &'a Model, formulation: Formulation, ctx: &'a Context<'a>, prep: &'a Prepared) -> Scorer<'a> {
        let folds = prep.fit_pred.iter().flat_map(|pr| pr.fold.iter().copied()).collect();
        let mut s = Scorer { model, formulation, ctx, prep, nominal: Vec::new(), folds, memo: Default::default(), stalled: Default::default() };
        s.nominal = s.cv(&[]);
        s
    }

    /// Cross-validated k-step RMS per horizon on the fit runs: each fold predicted by the terms
    /// fitted without it (infinite for a set that is no answer).
    pub(crate) fn cv(&self, terms: &[Term]) -> Vec<f64> {
        self.cv_errors(terms).map_or_else(|| vec![f64::INFINITY; self.prep.horizons.len()], |e| e.rms())
    }

    /// The cross-validated errors of every fit window (see [`Scorer::cv`]), memoised.
    pub(crate) fn cv_errors(&self, terms: &[Term]) -> Option<std::sync::Arc<kstep::Errors>> {
        let mut key: Vec<TermKey> = terms.iter().map(Term::key).collect();
        key.sort_unstable();
        if let Some(v) = self.memo.lock().ok().and_then(|m| m.get(&key).cloned()) {
            return v;
        }
        let v = self.cv_uncached(terms).map(std::sync::Arc::new);
        if let Ok(mut m) = self.memo.lock() {
            m.insert(key, v.clone());
        }
        v
    }

    pub(crate) fn cv_uncached(&self, terms: &[Term]) -> Option<kstep::Errors> {
        crate::cost::add_set();
        let folds = self.prep.fit_runs.len() * FOLDS_PER_RUN;
        if terms.is_empty() {
            return kstep::predict_cv(self.model, self.formulation, &self.prep.fit_pred, &self.prep.horizons, folds, &|_| Vec::new()).ok();
        }
        let designs: Vec<TermDesign> = terms.iter().map(|t| self.ctx.design(t)).collect();
        // the set's Grams, built at most once (for its fit when not cached, and its folds)
        let gr = std::cell::OnceCell::new();
        let grams = || {
            gr.get_or_init(|| {
                let refs: Vec<&TermDesign> = designs.iter().collect();
                lsq::grams(&self.ctx.problem, &refs)
            })
        };
        let all = self.ctx.fit_set_with(terms, || lsq::fit(&self.ctx.problem, grams()));
        // a set whose fit on all the fit data leaves an effect at a plausibility bound (a
        // payload at its largest mass) is no answer, however well it predicts
        if !select::admissible(&designs, terms, &all.theta) {
            return None;
        }
        // a set holding play is fitted without the samples where its gap is open, which the
        // torque residual reads as rotor inertia, friction or gain (the gap's timing from the
        // rotor inertia fitted on every sample)
        let open = open_gap_rows(terms, &designs, &all.theta, self.ctx.data);
        let masked;
        let gr = if open.is_empty() {
            grams()
        } else {
            let problem = self.ctx.problem.without_rows(&open);
            let without: Vec<TermDesign> = designs.iter().map(|d| d.without_rows(&open, problem.dof)).collect();
            let refs: Vec<&TermDesign> = without.iter().collect();
            masked = lsq::grams(&problem, &refs);
            if !select::admissible(&designs, terms, &lsq::fit(&problem, &masked).theta) {
                return None;
            }
            &masked
        };
        // each fold predicted by the parameters fitted without it (the same contiguous fifths
        // of the runs as the torque fit's folds)
        let effects_of = |f: usize| -> Vec<Effect> {
            let theta = lsq::theta_without(gr, &|g| g == f);
            effects::to_effects(self.model, &fitted_terms(terms, &designs, &theta, None))
        };
        kstep::predict_cv(self.model, self.formulation, &self.prep.fit_pred, &self.prep.horizons, folds, &effects_of).ok()
    }

    /// The fold test ([`kstep::FoldTest`]) of windows' errors `errors` against the nominal
    /// model's.
    pub(crate) fn against_nominal(&self, errors: &kstep::Errors) -> kstep::FoldTest {
        match self.cv_errors(&[]) {
            Some(nominal) => kstep::FoldTest::of(&kstep::fold_ratios(errors, &nominal, &self.folds)),
            None => kstep::FoldTest::of(&[]),
        }
    }

    /// The fold test of the set `with` against the set `without`: whether what `with` adds
    /// helps in every part of the fit runs, not in a few windows only.
    pub(crate) fn gain_test(&self, with: &[Term], without: &[Term]) -> kstep::FoldTest {
        match (self.cv_errors(with), self.cv_errors(without)) {
            (Some(a), Some(b)) => kstep::FoldTest::of(&kstep::fold_ratios(&a, &b, &self.folds)),
            _ => kstep::FoldTest::of(&[]),
        }
    }

    /// One number per set: the geometric mean over horizons of its cross-validated k-step error
    /// relative to the nominal model's (lower is better).
    pub(crate) fn score(&self, terms: &[Term]) -> f64 {
        kstep::score(&self.cv(terms), &self.nominal)
    }
}

/// The (sample, joint) rows of the fit runs `data` where the play of a backlash term of `terms`
/// is open ([`crate::vocabulary::backlash::open_samples`]), with the rotor inertia `theta` gives
/// the set's rotor on that joint; none for a set without play or without that rotor.
fn open_gap_rows(terms: &[Term], designs: &[TermDesign], theta: &nalgebra::DVector<f64>, data: &[crate::prepare::dataset::FitData]) -> Vec<(usize, usize)> {
    let mut rows = Vec::new();
    for t in terms {
        let Term::Backlash { joint, width } = *t else { continue };
        if let Some(ia) = crate::vocabulary::rotor::fitted(terms, designs, theta, joint) {
            rows.extend(crate::vocabulary::backlash::open_samples(data, joint, width, ia).into_iter().map(|s| (s, joint)));
        }
    }
    rows
}
