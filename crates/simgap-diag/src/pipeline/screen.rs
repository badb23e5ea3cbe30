//! The screen stage: every candidate effect alone, fitted on the fit runs and scored on the
//! held-out runs (k-step and closed loop), for the report's table of candidates.

use rayon::prelude::*;

use crate::error::Result;
use crate::lsq::{self, bootstrap_std};
use crate::pipeline::candidates::Candidates;
use crate::pipeline::chosen::Chosen;
use crate::pipeline::how_far::HowFar;
use crate::pipeline::runner::Stages;
use crate::prediction::{kstep, resim};
use crate::prepare::Prepared;
use crate::report::Candidate;
use crate::select::scorer::Scorer;
use crate::vocabulary::effects::FittedTerm;
use crate::vocabulary::{effects, fit_terms, fitted_terms, Term};

/// One candidate fitted alone: its terms with their values and resampling spread, its
/// cross-validated torque-residual MSE, its held-out k-step RMS per horizon [rad or m] and its
/// held-out closed-loop L² gap [rad or m].
type Screened = (Vec<FittedTerm>, f64, Vec<f64>, f64);

/// The screen stage: each group of `candidates` fitted alone on the fit runs and predicted on
/// the held-out runs, as many at a time as there are threads (one held-out run predicts on one
/// thread); ranked by cross-validated prediction on the fit runs, then by torque residual
/// removed. `chosen` says which are selected and why the others are not; `how_far` gives the
/// nominal model's held-out gap each is compared with.
///
/// # Errors
/// [`crate::Error::Interrupted`] when the diagnosis is stopped (checked before each batch).
pub(crate) fn screen(scorer: &Scorer<'_>, prep: &Prepared, candidates: &Candidates, chosen: &Chosen, how_far: &HowFar, stages: &mut Stages<'_>) -> Result<Vec<Candidate>> {
    // every candidate alone on the held-out runs, a batch of as many as there are threads
    let mut screened = Vec::with_capacity(candidates.groups.len());
    for chunk in candidates.groups.chunks(rayon::current_num_threads().max(1)) {
        for _ in chunk {
            stages.tick("screening candidates on held-out runs");
        }
        stages.check()?;
        screened.par_extend(chunk.par_iter().map(|(_, terms)| screen_one(scorer, prep, terms)));
    }
    // each with its figures and why it is or is not selected
    let mut screened_candidates = Vec::new();
    for (gi, ((name, terms), (fitted_c, cv_mse, kstep_after, l2))) in candidates.groups.iter().zip(screened).enumerate() {
        let rep = effects::to_reports(scorer.model, &fitted_c).into_iter().next();
        let unphysical: Vec<String> = fitted_c.iter().filter(|f| !crate::vocabulary::physical(&f.term, &f.theta)).map(|f| f.term.describe(&prep.joints)).collect();
        let selected = chosen.selection.terms.iter().any(|t| t.effect_name() == *name);
        let reason = if selected {
            "selected".to_string()
        } else if let Some(s) = chosen.selection.log.iter().rev().find(|s| s.term.effect_name() == *name) {
            s.reason.clone()
        } else if !unphysical.is_empty() {
            format!("fitted alone it is not physical ({})", unphysical.join(", "))
        } else {
            format!(
                "alone it predicts the fit runs at {:.3} of the nominal model's k-step error (cross-validated); not among the best terms of any selection step",
                candidates.alone_score[gi]
            )
        };
        let (joints_c, parameters, uncertainty, units) = match rep {
            Some(r) => (r.joints, r.parameters, r.uncertainty, r.units),
            None => (vec![], Default::default(), Default::default(), Default::default()),
        };
        screened_candidates.push(Candidate {
            rank: 0,
            effect: terms[0].kind(),
            joints: joints_c,
            parameters,
            uncertainty,
            units,
            cv_residual_reduction: if chosen.selection.nominal_cv_mse > 0.0 { 1.0 - cv_mse / chosen.selection.nominal_cv_mse } else { 0.0 },
            holdout_l2_after: l2,
            holdout_ratio: if how_far.before > 0.0 { l2 / how_far.before } else { f64::NAN },
            holdout_kstep_after: kstep_after,
            fit_kstep_cv: candidates.alone_cv[gi].clone(),
            selected,
            reason,
        });
    }
    // rank: by cross-validated prediction on the fit runs, then by torque residual removed
    let score_of = |c: &Candidate| kstep::score(&c.fit_kstep_cv, &scorer.nominal);
    screened_candidates.sort_by(|a, b| score_of(a).total_cmp(&score_of(b)).then(b.cv_residual_reduction.total_cmp(&a.cv_residual_reduction)));
    for (i, c) in screened_candidates.iter_mut().enumerate() {
        c.rank = i + 1;
    }

    Ok(screened_candidates)
}

/// One candidate's `terms` fitted alone on the fit runs, with their resampling spread only (the
/// pipeline's shared error is measured for the selected set), predicted on the held-out runs.
fn screen_one(scorer: &Scorer<'_>, prep: &Prepared, terms: &[Term]) -> Screened {
    let (model, formulation, horizons) = (scorer.model, scorer.formulation, &prep.horizons);
    // fitted alone on the torque residual
    let (designs, gr, f) = fit_terms(&scorer.ctx.problem, &prep.data, terms);
    let std = lsq::resampling_std(&gr, &bootstrap_std(&gr, 50, 11));
    let fitted_c = fitted_terms(terms, &designs, &f.theta, Some(&std));
    let eff = effects::to_effects(model, &fitted_c);
    // predicted k steps ahead and re-simulated in closed loop on the held-out runs
    let kstep_after = kstep::predict_all(model, formulation, &eff, &prep.hold_pred, horizons).map(|e| e.0.rms()).unwrap_or_else(|_| vec![f64::NAN; horizons.len()]);
    let gaps: Vec<resim::RunGap> = prep.hold_runs.par_iter().map(|r| resim::gap(model, formulation, &eff, r).0).collect();
    let l2 = resim::combine(&gaps, &prep.hold_runs).0;
    (fitted_c, f.cv_mse, kstep_after, l2)
}
