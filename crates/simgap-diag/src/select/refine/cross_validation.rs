//! One candidate set's two-fold cross-validation by multiple shooting ([`try_set`]): its halves
//! fitted on alternate fifths of the fit runs from the torque-residual fit and the answers of
//! sets tried before it ([`transfer`]), and predicted on the fifths they did not see.

use rayon::prelude::*;

use crate::error::Result;
use crate::lsq;
use crate::prediction::kstep::{self, FOLDS_PER_RUN};
use crate::select::scorer::Scorer;
use crate::select::shooting;
use crate::vocabulary::fitted_terms;
use crate::vocabulary::{effects, Term, TermDesign};

/// A set tried by the shooting stage: its two-fold cross-validation.
pub(crate) struct Tried {
    pub(crate) name: String,
    pub(crate) terms: Vec<Term>,
    pub(crate) designs: Vec<TermDesign>,
    /// The fits on each half of the fit runs.
    pub(crate) halves: Vec<nalgebra::DVector<f64>>,
    pub(crate) cv: Vec<f64>,
    /// Cross-validated k-step RMS per horizon of each fit run [rad] (empty where not kept).
    pub(crate) cv_per_run: Vec<Vec<f64>>,
    pub(crate) score: f64,
    /// Whether its gain over the nominal model holds fold by fold.
    pub(crate) test: kstep::FoldTest,
    /// The cross-validated errors of every fit window (empty where not kept), for fold tests
    /// against other sets.
    pub(crate) errors: kstep::Errors,
}

/// Levenberg–Marquardt iterations at most of a shooting fit on servo logs (10 elsewhere,
/// [`shooting::Options`]). A servo's drive gain, torque limit and load-dependent friction trade
/// with one another, and their fits were still descending at 10: on the Rhoban XL330 logs the
/// final fits of two folds of four stopped there, and 25 took the held-out `sin_time_square`
/// logs' 0.5 s k-step error from 51.4 to 38.8 mrad. (For every set on every log, it changed the
/// DFKI case study in the third digit and, on one synthetic double-pendulum replay, let a set
/// with an inertial correction beat the torque-residual fit on the fit runs by 2.3 % and predict
/// the held-out run five times worse.)
const SERVO_ITERATIONS: usize = 25;

/// The options of the shooting fits of these logs: [`SERVO_ITERATIONS`] on servo logs.
pub(super) fn shooting_options(scorer: &Scorer<'_>) -> shooting::Options {
    let mut o = shooting::Options::default();
    if scorer.prep.servo.is_some() {
        o.max_iterations = SERVO_ITERATIONS;
    }
    o
}

/// θ of the set `to` from the answer `theta` of the set `from`: shared terms keep their values,
/// the others start at 0 (no friction, no rotor inertia, the URDF's inertia), so that a larger
/// set starts where a smaller one ended.
pub(super) fn transfer(from: &Tried, theta: &nalgebra::DVector<f64>, to: &[Term], to_designs: &[TermDesign]) -> nalgebra::DVector<f64> {
    let k: usize = to_designs.iter().map(|d| d.cols.len()).sum();
    let mut out = nalgebra::DVector::zeros(k);
    let mut c = 0;
    for (t, d) in to.iter().zip(to_designs) {
        let mut cf = 0;
        for (tf, df) in from.terms.iter().zip(&from.designs) {
            if tf == t && df.cols.len() == d.cols.len() {
                out.rows_mut(c, d.cols.len()).copy_from(&theta.rows(cf, d.cols.len()));
            }
            cf += df.cols.len();
        }
        c += d.cols.len();
    }
    out
}

/// The starts [`starts`] gives, in words, in its order.
pub(super) const START_NAMES: [&str; 2] = ["the torque-residual fit", "the torque-residual fit with the URDF's inertia"];

/// Starts of a shooting fit: the torque-residual fit `theta`, and the same with the URDF's
/// inertia where the set corrects it.
pub(super) fn starts(designs: &[TermDesign], theta: nalgebra::DVector<f64>) -> Vec<nalgebra::DVector<f64>> {
    let mut c = 0;
    let mut urdf = theta.clone();
    let mut inertial = false;
    for d in designs {
        if d.inertial.is_some() {
            urdf.rows_mut(c, d.cols.len()).fill(0.0);
            inertial = true;
        }
        c += d.cols.len();
    }
    if inertial {
        vec![theta, urdf]
    } else {
        vec![theta]
    }
}

/// Extra starts of a half's shooting fit (the half, the set's designs): answers of other sets on
/// the same half.
pub(super) type EarlierStarts<'a> = dyn Fn(usize, &[TermDesign]) -> Vec<nalgebra::DVector<f64>> + 'a;

/// The answers of [`try_set`]'s halves, in words, in its order: half `h` holds out the folds
/// (fifths of every run) whose index has parity `h`, and is fitted on the others.
pub(super) const HALF_NAMES: [&str; 2] = ["the answer fitted on the 2nd and 4th fifths of every fit run", "the answer fitted on the 1st, 3rd and 5th fifths"];

/// One set's two-fold cross-validation by multiple shooting: each half of the fit runs' folds
/// (alternate fifths of every run) fitted on the other half alone, from its torque-residual fit
/// and `earlier(half, designs)`, and predicted with it.
pub(super) fn try_set(
    scorer: &Scorer<'_>,
    shoot_runs: &shooting::Windows,
    sopts: &shooting::Options,
    name: &str,
    terms: &[Term],
    earlier: &EarlierStarts<'_>,
    stop: Option<&std::sync::atomic::AtomicBool>,
) -> Result<Tried> {
    let (model, formulation, ctx, prep) = (scorer.model, scorer.formulation, scorer.ctx, scorer.prep);
    let n = model.dof();
    let (designs, gr, _) = ctx.fit_terms(terms);
    let mut merged: Vec<kstep::Errors> =
        prep.fit_pred.iter().map(|pr| kstep::Errors { horizons: prep.horizons.len(), dof: n, sq: vec![f64::NAN; pr.windows() * prep.horizons.len() * n] }).collect();
    let mut halves = Vec::new();
    for half in 0..2 {
        let held = |f: usize| (f % FOLDS_PER_RUN) % 2 == half;
        let keep = |r: usize, w: usize| !held(shoot_runs[r].fold[w]);
        let problem = shooting::Problem { model, formulation, terms, designs: &designs, runs: shoot_runs, keep: &keep, options: sopts };
        let mut from = starts(&designs, lsq::theta_without(&gr, &held));
        from.extend(earlier(half, &designs));
        let shot = shooting::fit(&problem, &from, stop)?;
        let eff = effects::to_effects(model, &fitted_terms(terms, &designs, &shot.theta, None));
        let errs: Vec<kstep::Errors> =
            prep.fit_pred.par_iter().map(|pr| kstep::predict(model, formulation, &eff, pr, &prep.horizons, &|w| held(pr.fold[w]))).collect::<Result<_>>()?;
        for (m, e) in merged.iter_mut().zip(&errs) {
            for (a, v) in m.sq.iter_mut().zip(&e.sq) {
                if v.is_finite() {
                    *a = *v;
                }
            }
        }
        halves.push(shot.theta);
    }
    let mut all = kstep::Errors { horizons: prep.horizons.len(), dof: n, sq: Vec::new() };
    for m in &merged {
        all.sq.extend_from_slice(&m.sq);
    }
    let cv = all.rms();
    let score = kstep::score(&cv, &scorer.nominal);
    let test = scorer.against_nominal(&all);
    let cv_per_run = merged.iter().map(kstep::Errors::rms).collect();
    Ok(Tried { name: name.to_string(), terms: terms.to_vec(), designs, halves, cv, cv_per_run, score, test, errors: all })
}
