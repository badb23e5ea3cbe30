//! Multiple shooting: the parameters of a set of terms chosen to minimise the k-step prediction
//! error, not the torque residual.
//!
//! The torque-residual fit ([`crate::lsq`]) needs accelerations differentiated from positions;
//! on jittery stamps, with a friction shape the vocabulary only approximates, or with effects
//! the residual sees poorly (inertia against gravity on a slow motion), it is biased, and the
//! bias shows when the fitted model predicts. Here the same parameters are fitted to what the
//! diagnosis is judged on:
//!
//! 1. every fit run is cut into consecutive windows of [`Options::window`] seconds (spread
//!    evenly instead beyond [`MAX_WINDOWS`] in all); each window
//!    restarts the model (with the terms at parameters θ) from the measured (smoothed) state and
//!    drives it as [`kstep::predict`] does (logged torque, or the logged controller);
//! 2. the residuals are the position errors at [`Options::points`] evenly spaced instants of
//!    every window, each divided by the nominal model's RMS error at that instant (so that
//!    early and late instants weigh alike, as in [`kstep::score`]), plus the prior rows
//!    `√μ θ_I` that keep an inertial correction near the URDF where the data say nothing;
//! 3. Levenberg–Marquardt on a forward-difference Jacobian, in coordinates x where the
//!    physical constraints are boxes: a linear parameter is x = θ within its term's bounds
//!    (friction, rotor inertia ≥ 0, a payload's mass within its bound, a gain within its
//!    range); an inertial correction is the log-Cholesky parameters of every link (always a
//!    physical body, see [`crate::lsq::inertial`]) with the mass within [`inertial::MASS_FACTOR`] of
//!    the URDF's, principal radii at least [`inertial::MIN_RADIUS`] and the centre of mass
//!    projected into its link's reach.
//!
//! The Jacobian is recomputed by forward differences every third iteration and after a failed
//! step, and updated by Broyden's rank-one formula in between; parameters the data do not see at
//! the start (a planar arm's out-of-plane inertia) are held where they are.
//!
//! **Uncertainty**: the covariance of θ is `σ² (JᵀJ)⁻¹` mapped from x to θ, with J the Jacobian
//! of the last iteration (pseudo-inverse over the directions the data see) and `σ² = ‖r‖² / (N − P)`. The errors of one window are correlated
//! (they accumulate along it), so these intervals are narrower than the real spread.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use simgap_core::{Formulation, Model, PARAMS_PER_LINK};

use crate::error::{Error, Result};
use crate::lsq::inertial::{self, InertialPrior};
use crate::prediction::kstep::{self, PredictionRun, FOLDS_PER_RUN};
use crate::vocabulary::effects;
use crate::vocabulary::fitted_terms;
use crate::vocabulary::{Term, TermDesign};

/// Options of a multiple-shooting fit.
#[derive(Clone, Debug)]
pub(crate) struct Options {
    /// Length of every shooting window [s].
    pub window: f64,
    /// Instants per window at which the error counts (evenly spaced, the last at the window's end).
    pub points: usize,
    /// Levenberg–Marquardt iterations at most (10 by default; the shooting stage raises it on
    /// servo logs, see `refine::SERVO_ITERATIONS`).
    pub max_iterations: usize,
    /// Weight of the prior of an inertial correction: moving every scaled inertial parameter by
    /// one unit costs this fraction of the nominal model's total (normalised) error. Weak: it
    /// keeps directions the data do not see near the URDF; on the DFKI double pendulum a weight
    /// of 1e-2 held link 2's inertia halfway between the URDF and what prediction asks for.
    pub prior_weight: f64,
}

impl Default for Options {
    fn default() -> Options {
        Options { window: 0.5, points: 5, max_iterations: 10, prior_weight: 1e-4 }
    }
}

impl Options {
    /// The instants (from each window's start) at which the error counts [s].
    pub(crate) fn horizons(&self) -> Vec<f64> {
        let p = self.points.max(1);
        (1..=p).map(|i| self.window * i as f64 / p as f64).collect()
    }
}

/// The fit runs cut into consecutive shooting windows; window folds numbered as the fit runs'
/// k-step folds (run `i` from `i ·` [`FOLDS_PER_RUN`]), so that a cross-validation can leave a
/// fold out of both.
///
/// The search (every set's cross-validation, the refits and spreads) uses at most
/// [`SEARCH_WINDOWS`] windows in all, the final fit of the chosen set at most [`MAX_WINDOWS`]
/// ([`Windows::whole`]): longer fit runs get theirs spread evenly, in proportion to their
/// durations, so that a fit's cost stops growing with the logs' length.
pub(crate) fn shooting_runs(fit_pred: &[PredictionRun], smoothing: f64, options: &Options) -> Windows {
    let search = window_counts(fit_pred, options, SEARCH_WINDOWS);
    let whole = window_counts(fit_pred, options, MAX_WINDOWS);
    let consecutive = window_counts(fit_pred, options, usize::MAX).iter().sum();
    // the final fit's windows are cut only where they are more than the search's
    let whole = (whole != search).then(|| Box::new(Windows { runs: cut(fit_pred, smoothing, options, &whole), done: Mutex::default(), whole: None, consecutive }));
    Windows { runs: cut(fit_pred, smoothing, options, &search), done: Mutex::default(), whole, consecutive }
}

/// The windows of [`Options::window`] of each fit run: all consecutive ones (at least one), at
/// most `most` in all (each run's share in proportion to its duration, rounded up) beyond that.
fn window_counts(fit_pred: &[PredictionRun], options: &Options, most: usize) -> Vec<usize> {
    let total: f64 = fit_pred.iter().map(|pr| pr.run.duration()).sum();
    fit_pred
        .iter()
        .map(|pr| {
            let consecutive = ((pr.run.duration() / options.window).floor() as usize).max(1);
            let share = (most as f64 * pr.run.duration() / total.max(f64::MIN_POSITIVE)).ceil() as usize;
            consecutive.min(share.max(1))
        })
        .collect()
}

/// The fit runs cut into `counts[i]` windows each (spread evenly where fewer than the
/// consecutive ones).
fn cut(fit_pred: &[PredictionRun], smoothing: f64, options: &Options, counts: &[usize]) -> Vec<PredictionRun> {
    let horizons = options.horizons();
    fit_pred
        .iter()
        .zip(counts)
        .enumerate()
        .map(|(i, (pr, &windows))| PredictionRun::new(pr.run.clone(), &horizons, smoothing, pr.sensor.clone(), i * FOLDS_PER_RUN, windows))
        .collect()
}

/// The fit runs cut into shooting windows ([`shooting_runs`]), with the fits already done on
/// them.
///
/// A fit is a deterministic function of its problem and of the start it begins from (the
/// starts' costs, the Jacobian's columns and the trial steps are computed in a fixed order), and
/// the stages ask for the same fit more than once: the same set's cross-validation tried again
/// after a term left and came back; a half of a set's cross-validation fitted again from its own
/// answer for the intervals. A fit asked again from the same start is answered from here, bit
/// for bit what it would compute; so is a fit from the answer of a fit that no step moved from
/// its start (that answer is its start mapped to the constraints' coordinates and back, equal
/// to rounding, where the fit stops again).
pub(crate) struct Windows {
    /// The runs, each cut into windows.
    pub runs: Vec<PredictionRun>,
    /// Fits done, by [`key_at`].
    done: Mutex<HashMap<Vec<u8>, Shot>>,
    /// The windows of the final fit where they are more than the search's ([`Windows::whole`]).
    whole: Option<Box<Windows>>,
    /// Consecutive windows the fit runs hold.
    consecutive: usize,
}

impl Windows {
    /// The windows of the chosen set's final fit: every consecutive window of the fit runs up
    /// to [`MAX_WINDOWS`] (these windows themselves where the search already has them all).
    pub(crate) fn whole(&self) -> &Windows {
        self.whole.as_deref().unwrap_or(self)
    }

    /// Windows the search uses, windows the final fit uses and consecutive windows the fit runs
    /// hold: the first two are spread evenly over the runs where they are fewer than the third.
    pub(crate) fn counts(&self) -> (usize, usize, usize) {
        (self.count(), self.whole().count(), self.consecutive)
    }

    /// Windows in all.
    fn count(&self) -> usize {
        self.runs.iter().map(|pr| pr.windows()).sum()
    }

    /// Number of starts whose fit these windows answer.
    #[cfg(test)]
    pub(crate) fn fits_done(&self) -> usize {
        self.done.lock().map_or(0, |d| d.len())
    }
}

impl std::ops::Deref for Windows {
    type Target = [PredictionRun];
    fn deref(&self) -> &[PredictionRun] {
        &self.runs
    }
}

/// What a fit on [`Windows`] depends on besides the windows and its start, as bytes: the model
/// and formulation, the terms and their designs' layout and bounds, the options, and which
/// windows count ([`key_at`] appends the start).
fn problem_key(p: &Problem<'_>) -> Vec<u8> {
    let mut key = format!("{:?}|{:?}|{:?}|{:?}|", p.model, p.formulation, p.terms, p.options).into_bytes();
    for d in p.designs {
        key.extend_from_slice(&d.cols.len().to_le_bytes());
        for v in d.lo.iter().chain(&d.hi) {
            key.extend_from_slice(&v.to_bits().to_le_bytes());
        }
        key.extend_from_slice(format!("{:?}|", d.inertial).as_bytes());
    }
    for (r, pr) in p.runs.iter().enumerate() {
        key.extend((0..pr.windows()).map(|w| u8::from((p.keep)(r, w))));
        key.push(b'|');
    }
    key
}

/// The key of the fit of the problem keyed `problem` from the start `theta`.
fn key_at(problem: &[u8], theta: &[f64]) -> Vec<u8> {
    let mut key = Vec::with_capacity(problem.len() + 8 * theta.len());
    key.extend_from_slice(problem);
    for v in theta {
        key.extend_from_slice(&v.to_bits().to_le_bytes());
    }
    key
}

/// Shooting windows of all fit runs at most in the chosen set's final fit: 400 windows of 0.5 s
/// (200 s of logs, 2,000 instants per joint) fit a set's tens of parameters many times over;
/// more only cost time (three 120 s SO-101 episodes would make 720).
pub(crate) const MAX_WINDOWS: usize = 400;

/// Shooting windows of all fit runs at most in the search (every set's two-fold
/// cross-validation, the refits after a term left, the spreads): 200 windows of 0.5 s (100 s of
/// logs). On the SO-101 case study's three 120 s fit episodes (720 windows, the final fit on 402),
/// searching on 201 instead of 402 took the diagnosis from 222 s to 110 s wall and selected the same effects with
/// a rotor inertia on elbow_flex too; its held-out k-step errors moved from 0.0227 / 0.0325 /
/// 0.0345 rad to 0.0213 / 0.0332 / 0.0346 at 0.1 / 0.25 / 0.5 s, whole episodes from 0.0136 to
/// 0.0131. Logs of 100 s or less (every other case study, the self-check) are searched on all
/// their windows, as before.
pub(crate) const SEARCH_WINDOWS: usize = 200;

/// A multiple-shooting fit.
#[derive(Clone, Debug)]
pub(crate) struct Shot {
    /// Fitted column coefficients, laid out as [`crate::vocabulary::fit_terms`]'s θ.
    pub theta: DVector<f64>,
    /// Their standard deviations from `σ² (JᵀJ)⁻¹` (see the module documentation).
    pub std: DVector<f64>,
    /// Mean squared normalised residual (data rows) at the start.
    pub cost_start: f64,
    /// The same at the answer.
    pub cost: f64,
    /// Levenberg–Marquardt iterations done.
    pub iterations: usize,
    /// Which of the starts the fit began from (the one of lowest cost), by its index.
    pub start: usize,
}

/// The problem: a model, terms (with their designs, for bounds and layout) and windows.
pub(crate) struct Problem<'a> {
    /// The model.
    pub model: &'a Model,
    /// Its formulation.
    pub formulation: Formulation,
    /// The terms.
    pub terms: &'a [Term],
    /// Their designs (bounds, number of columns, inertial prior).
    pub designs: &'a [TermDesign],
    /// Shooting windows ([`shooting_runs`]).
    pub runs: &'a Windows,
    /// Which windows count: `keep(run, window)`.
    pub keep: &'a (dyn Fn(usize, usize) -> bool + Sync),
    /// Options.
    pub options: &'a Options,
}

/// Coordinates x of θ in which the physical constraints are boxes.
struct Layout {
    /// Number of θ columns.
    k: usize,
    /// θ indices of the linear parameters (x = θ there, in this order first).
    lin: Vec<usize>,
    /// The inertial correction: its first θ column and prior.
    inertial: Option<(usize, Arc<InertialPrior>)>,
    lo: Vec<f64>,
    hi: Vec<f64>,
}

impl Layout {
    fn new(designs: &[TermDesign]) -> Layout {
        let mut lin = Vec::new();
        let mut inertial_of = None;
        let (mut lo, mut hi) = (Vec::new(), Vec::new());
        let mut c = 0;
        for d in designs {
            let k = d.cols.len();
            match &d.inertial {
                Some(prior) => inertial_of = Some((c, prior.clone())),
                None => {
                    for a in 0..k {
                        lin.push(c + a);
                        lo.push(d.lo.get(a).copied().unwrap_or(f64::NEG_INFINITY));
                        hi.push(d.hi.get(a).copied().unwrap_or(f64::INFINITY));
                    }
                }
            }
            c += k;
        }
        if let Some((_, prior)) = &inertial_of {
            // per link: mass within MASS_FACTOR of the URDF's, principal radii ≥ MIN_RADIUS
            let nl = prior.links();
            let avg_mass = prior.nominal.iter().step_by(PARAMS_PER_LINK).sum::<f64>() / nl.max(1) as f64;
            for l in 0..nl {
                let m0 = prior.nominal[PARAMS_PER_LINK * l].max(1e-6 * avg_mass.max(1e-6));
                let r = inertial::MIN_RADIUS.ln();
                lo.extend([0.5 * (m0 / inertial::MASS_FACTOR).ln(), r, r, r]);
                hi.extend([0.5 * (m0 * inertial::MASS_FACTOR).ln(), f64::INFINITY, f64::INFINITY, f64::INFINITY]);
                lo.extend([f64::NEG_INFINITY; 6]);
                hi.extend([f64::INFINITY; 6]);
            }
        }
        Layout { k: c, lin, inertial: inertial_of, lo, hi }
    }

    fn nx(&self) -> usize {
        self.lo.len()
    }

    /// x of θ (clamped into the boxes; an inertial correction made strictly physical first).
    fn x_of(&self, theta: &DVector<f64>) -> Vec<f64> {
        let mut x: Vec<f64> = self.lin.iter().map(|&i| theta[i]).collect();
        if let Some((first, prior)) = &self.inertial {
            let nl = prior.links();
            let avg_mass = prior.nominal.iter().step_by(PARAMS_PER_LINK).sum::<f64>() / nl.max(1) as f64;
            let th = &theta.as_slice()[*first..*first + PARAMS_PER_LINK * nl];
            for l in 0..nl {
                let p = prior.corrected(th, l);
                let mut phi = inertial::log_cholesky_of_parameters(&p, 1e-6 * avg_mass.max(1e-6));
                inertial::project_reach(&mut phi, prior.reach[l]);
                x.extend(phi);
            }
        }
        self.project(&mut x);
        x
    }

    /// Clamps x into the boxes and every centre of mass into its ball.
    fn project(&self, x: &mut [f64]) {
        for (a, v) in x.iter_mut().enumerate() {
            *v = v.clamp(self.lo[a], self.hi[a]);
        }
        if let Some((_, prior)) = &self.inertial {
            let o = self.lin.len();
            for l in 0..prior.links() {
                inertial::project_reach(&mut x[o + 10 * l..o + 10 * (l + 1)], prior.reach[l]);
            }
        }
    }

    fn theta_of(&self, x: &[f64]) -> DVector<f64> {
        let mut th = DVector::zeros(self.k);
        for (a, &i) in self.lin.iter().enumerate() {
            th[i] = x[a];
        }
        if let Some((first, prior)) = &self.inertial {
            let o = self.lin.len();
            for l in 0..prior.links() {
                let p = inertial::parameters_of_log_cholesky(&x[o + 10 * l..o + 10 * (l + 1)]);
                for (a, v) in p.iter().enumerate() {
                    let idx = PARAMS_PER_LINK * l + a;
                    th[first + idx] = (v - prior.nominal[idx]) / prior.scales[idx];
                }
            }
        }
        th
    }

    /// ∂θ/∂x (k × nx).
    fn dtheta_dx(&self, x: &[f64]) -> DMatrix<f64> {
        let mut t = DMatrix::zeros(self.k, self.nx());
        for (a, &i) in self.lin.iter().enumerate() {
            t[(i, a)] = 1.0;
        }
        if let Some((first, prior)) = &self.inertial {
            let o = self.lin.len();
            for l in 0..prior.links() {
                let jl = inertial::jacobian_log_cholesky(&x[o + 10 * l..o + 10 * (l + 1)]);
                for r in 0..PARAMS_PER_LINK {
                    let idx = PARAMS_PER_LINK * l + r;
                    for q in 0..10 {
                        t[(first + idx, o + 10 * l + q)] = jl[(r, q)] / prior.scales[idx];
                    }
                }
            }
        }
        t
    }
}

/// Residual evaluator: simulates the kept windows and normalises their errors.
struct Evaluator<'a> {
    p: &'a Problem<'a>,
    layout: Layout,
    horizons: Vec<f64>,
    /// Per horizon: the nominal model's RMS error over the kept windows [rad].
    reference: Vec<f64>,
    /// Number of data rows.
    rows: usize,
    /// √μ of the prior rows.
    prior_sqrt: f64,
}

impl<'a> Evaluator<'a> {
    fn new(p: &'a Problem<'a>) -> Result<Evaluator<'a>> {
        let layout = Layout::new(p.designs);
        let horizons = p.options.horizons();
        let mut ev = Evaluator { p, layout, horizons, reference: Vec::new(), rows: 0, prior_sqrt: 0.0 };
        // the nominal model's error per instant is the unit of every residual
        let nominal = ev.errors(&[])?;
        let nh = ev.horizons.len();
        let (mut s, mut c) = (vec![0.0; nh], vec![0usize; nh]);
        for e in &nominal {
            for w in 0..e.windows() {
                for h in 0..nh {
                    let row = &e.sq[(w * nh + h) * e.dof..(w * nh + h + 1) * e.dof];
                    if row[0].is_finite() {
                        s[h] += row.iter().sum::<f64>();
                        c[h] += 1;
                    }
                }
            }
        }
        ev.reference = (0..nh).map(|h| if c[h] > 0 && s[h] > 0.0 { (s[h] / c[h] as f64).sqrt() } else { 1.0 }).collect();
        ev.rows = c.iter().sum::<usize>() * p.model.dof();
        if let Some((_, prior)) = &ev.layout.inertial {
            let n_i = (PARAMS_PER_LINK * prior.links()) as f64;
            ev.prior_sqrt = (p.options.prior_weight * ev.rows as f64 / n_i).sqrt();
        }
        Ok(ev)
    }

    /// Squared errors of every kept window of every run with `effects`.
    fn errors(&self, effects: &[simgap_sim::Effect]) -> Result<Vec<kstep::Errors>> {
        let p = self.p;
        p.runs.par_iter().enumerate().map(|(r, pr)| kstep::predict(p.model, p.formulation, effects, pr, &self.horizons, &|w| (p.keep)(r, w))).collect()
    }

    /// The residual vector at x: data rows (|e| / reference, kept windows, instants, joints),
    /// then the prior rows.
    fn residuals(&self, x: &[f64]) -> Result<Vec<f64>> {
        let theta = self.layout.theta_of(x);
        let fitted = fitted_terms(self.p.terms, self.p.designs, &theta, None);
        let eff = effects::to_effects(self.p.model, &fitted);
        let errors = self.errors(&eff)?;
        let nh = self.horizons.len();
        let mut out = Vec::with_capacity(self.rows + self.layout.k);
        for (r, e) in errors.iter().enumerate() {
            let pr = &self.p.runs[r];
            for w in 0..e.windows() {
                if !(self.p.keep)(r, w) {
                    continue;
                }
                for h in 0..nh {
                    if pr.ends[w][h] == usize::MAX {
                        continue;
                    }
                    for j in 0..e.dof {
                        let sq = e.sq[(w * nh + h) * e.dof + j];
                        // |e| carries the same gradient of ‖e‖² as e itself (sign(e)·∂e)
                        let v = if sq.is_finite() { sq.sqrt() } else { std::f64::consts::PI };
                        out.push(v / self.reference[h]);
                    }
                }
            }
        }
        if let Some((first, prior)) = &self.layout.inertial {
            for i in 0..PARAMS_PER_LINK * prior.links() {
                out.push(self.prior_sqrt * theta[first + i]);
            }
        }
        Ok(out)
    }

    fn data_cost(&self, r: &[f64]) -> f64 {
        let n = self.rows.min(r.len()).max(1);
        r[..n].iter().map(|v| v * v).sum::<f64>() / n as f64
    }
}

/// Iterations between fresh finite-difference Jacobians.
const REFRESH: usize = 3;

/// Relative decrease of the cost below which an iteration counts as small (two in a row stop).
const TOLERANCE: f64 = 2e-3;

fn stopped(stop: Option<&AtomicBool>) -> Result<()> {
    match stop {
        Some(s) if s.load(Ordering::Relaxed) => Err(Error::Interrupted),
        _ => Ok(()),
    }
}

/// Fits the terms' parameters by multiple shooting, from the start of lowest cost among
/// `starts` (θ vectors laid out as [`crate::vocabulary::fit_terms`]'s, e.g. the torque-residual fit).
///
/// # Errors
/// Controller set-up errors of [`kstep::predict`]; [`Error::Interrupted`] when `stop` is set.
pub(crate) fn fit(problem: &Problem<'_>, starts: &[DVector<f64>], stop: Option<&AtomicBool>) -> Result<Shot> {
    let ev = Evaluator::new(problem)?;
    let layout = &ev.layout;
    // the start of lowest cost
    let mut best: Option<(usize, Vec<f64>, Vec<f64>, f64)> = None;
    for (i, s) in starts.iter().enumerate() {
        stopped(stop)?;
        let x = layout.x_of(s);
        let r = ev.residuals(&x)?;
        let f = r.iter().map(|v| v * v).sum::<f64>();
        if best.as_ref().is_none_or(|b| f < b.3) {
            best = Some((i, x, r, f));
        }
    }
    let Some((start, x, r, f)) = best else {
        return Err(Error::Input("multiple shooting needs at least one start".into()));
    };
    // the same fit done before on these windows, or one that found no step from this start
    let problem_key = problem_key(problem);
    let key = key_at(&problem_key, starts[start].as_slice());
    let done = problem.runs.done.lock().ok().and_then(|d| d.get(&key).cloned());
    if let Some(done) = done {
        return Ok(Shot { start, ..done });
    }
    let shot = descend(&ev, start, x, r, f, stop)?;
    if let Ok(mut d) = problem.runs.done.lock() {
        // a fit that no step moved from its start ends there: from its answer (its start,
        // through the constraints' coordinates and back) it would stop again
        if shot.iterations <= 1 && shot.cost == shot.cost_start {
            d.insert(key_at(&problem_key, shot.theta.as_slice()), shot.clone());
        }
        d.insert(key, shot.clone());
    }
    Ok(shot)
}

/// Levenberg–Marquardt from `x` (start number `start`, residuals `r`, cost `f`).
fn descend(ev: &Evaluator<'_>, start: usize, mut x: Vec<f64>, mut r: Vec<f64>, mut f: f64, stop: Option<&AtomicBool>) -> Result<Shot> {
    let (layout, problem) = (&ev.layout, ev.p);
    let nx = layout.nx();
    let cost_start = ev.data_cost(&r);
    // a set without parameters (no terms, or only grid members) has nothing to fit
    if nx == 0 {
        return Ok(Shot { theta: layout.theta_of(&x), std: DVector::zeros(layout.k), cost_start, cost: cost_start, iterations: 0, start });
    }
    let mut lambda = 1e-2;
    let mut small = 0;
    let mut iterations = 0;
    let mut jac = DMatrix::<f64>::zeros(r.len(), nx);
    // a fresh finite-difference Jacobian every REFRESH iterations (and after a failed step),
    // Broyden's rank-one update in between
    let mut fresh_due = true;
    let mut since_fresh = 0;
    // parameters the data do not see at the first Jacobian (a planar arm's out-of-plane
    // inertia) are held: their columns are not recomputed
    let mut active: Vec<bool> = vec![true; nx];
    let mut first = true;
    for _ in 0..problem.options.max_iterations {
        stopped(stop)?;
        iterations += 1;
        if fresh_due || since_fresh >= REFRESH {
            let idx: Vec<usize> = (0..nx).filter(|&a| active[a]).collect();
            let cols: Vec<Result<Vec<f64>>> = idx
                .par_iter()
                .map(|&a| {
                    // (a column costs a prediction of every window: a stop is seen within one)
                    stopped(stop)?;
                    // forward differences, a step away from a bound
                    let mut x2 = x.clone();
                    let mut h = 1e-6 * x[a].abs().max(1.0);
                    if x[a] + h > layout.hi[a] {
                        h = -h;
                    }
                    x2[a] += h;
                    let r2 = ev.residuals(&x2)?;
                    Ok(r2.iter().zip(&r).map(|(b, a0)| (b - a0) / h).collect())
                })
                .collect();
            for (col, &a) in cols.into_iter().zip(&idx) {
                for (i, v) in col?.iter().enumerate() {
                    jac[(i, a)] = *v;
                }
            }
            if first {
                // seen by the data: a column (per unit of the parameter's magnitude) above 1e-7 of the largest
                let seen: Vec<f64> = (0..nx).map(|a| jac.view((0, a), (ev.rows, 1)).norm() * x[a].abs().max(1e-2)).collect();
                let top = seen.iter().cloned().fold(0.0, f64::max);
                for a in 0..nx {
                    active[a] = seen[a] > 1e-7 * top;
                }
                first = false;
            }
            fresh_due = false;
            since_fresh = 0;
        }
        let rv = DVector::from_column_slice(&r);
        let grad = jac.transpose() * &rv;
        let hess = jac.transpose() * &jac;
        // parameters held at a bound the descent direction pushes against, or unseen
        let free: Vec<usize> = (0..nx).filter(|&a| active[a] && !((x[a] <= layout.lo[a] && grad[a] > 0.0) || (x[a] >= layout.hi[a] && grad[a] < 0.0))).collect();
        if free.is_empty() {
            break;
        }
        let hmax = free.iter().map(|&a| hess[(a, a)]).fold(0.0, f64::max).max(1e-300);
        let mut improved = false;
        for _ in 0..6 {
            stopped(stop)?;
            let m = DMatrix::from_fn(free.len(), free.len(), |i, j| hess[(free[i], free[j])] + if i == j { lambda * (hess[(free[i], free[i])] + 1e-9 * hmax) } else { 0.0 });
            let b = DVector::from_fn(free.len(), |i, _| -grad[free[i]]);
            let Some(step) = m.cholesky().map(|c| c.solve(&b)) else {
                lambda *= 10.0;
                continue;
            };
            let mut x2 = x.clone();
            for (i, &a) in free.iter().enumerate() {
                x2[a] += step[i];
            }
            layout.project(&mut x2);
            let r2 = ev.residuals(&x2)?;
            let f2 = r2.iter().map(|v| v * v).sum::<f64>();
            if f2.is_finite() && f2 < f {
                small = if f - f2 <= TOLERANCE * f { small + 1 } else { 0 };
                // Broyden: J ← J + (Δr − J Δx) Δxᵀ / ‖Δx‖²
                let dx = DVector::from_fn(nx, |a, _| x2[a] - x[a]);
                let nn = dx.norm_squared();
                if nn > 0.0 {
                    let dr = DVector::from_fn(r.len(), |i, _| r2[i] - r[i]);
                    let u = (dr - &jac * &dx) / nn;
                    jac += u * dx.transpose();
                }
                x = x2;
                r = r2;
                f = f2;
                lambda = (lambda / 4.0).max(1e-9);
                improved = true;
                since_fresh += 1;
                break;
            }
            lambda *= 4.0;
        }
        if !improved {
            // a step that fails on an updated Jacobian gets a fresh one; on a fresh one, stop
            if since_fresh == 0 {
                break;
            }
            fresh_due = true;
            lambda = (lambda / 256.0).max(1e-9);
            continue;
        }
        if small >= 2 {
            break;
        }
    }
    // covariance: σ² (JᵀJ)⁻¹ in x, mapped to θ (a pseudo-inverse where J is rank-deficient)
    let n = r.len();
    let sigma2 = f / (n.saturating_sub(nx)).max(1) as f64;
    let hess = jac.transpose() * &jac;
    let eig = hess.symmetric_eigen();
    let lmax = eig.eigenvalues.iter().cloned().fold(0.0, f64::max);
    let inv_vals = eig.eigenvalues.map(|l| if l > 1e-12 * lmax && l > 0.0 { 1.0 / l } else { 0.0 });
    let cov_x = &eig.eigenvectors * DMatrix::from_diagonal(&inv_vals) * eig.eigenvectors.transpose() * sigma2;
    let t = layout.dtheta_dx(&x);
    let cov = &t * cov_x * t.transpose();
    let std = DVector::from_fn(layout.k, |i, _| cov[(i, i)].max(0.0).sqrt());
    Ok(Shot { theta: layout.theta_of(&x), std, cost_start, cost: ev.data_cost(&r), iterations, start })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vocabulary::Column;

    #[test]
    fn layout_round_trips_linear_and_inertial_parameters() {
        let model = Model::paper_arm();
        let prior = Arc::new(InertialPrior::new(&model));
        let w = PARAMS_PER_LINK * model.dof();
        let lin = TermDesign { cols: vec![Column::new(Some(0), vec![])], lo: vec![0.0], hi: vec![f64::INFINITY], inertial: None, offset: None };
        let inert = TermDesign { cols: (0..w).map(|_| Column::new(None, vec![])).collect(), inertial: Some(prior.clone()), ..Default::default() };
        let layout = Layout::new(&[lin, inert]);
        assert_eq!(layout.k, 1 + w);
        assert_eq!(layout.nx(), 1 + 10 * model.dof());
        // a physical correction: link 1 10 % heavier, same centre of mass and inertia scaled
        let mut theta = DVector::zeros(1 + w);
        theta[0] = 0.3;
        for a in 0..PARAMS_PER_LINK {
            theta[1 + a] = 0.1 * prior.nominal[a] / prior.scales[a];
        }
        let x = layout.x_of(&theta);
        let back = layout.x_of(&layout.theta_of(&x));
        for a in 0..x.len() {
            assert!((back[a] - x[a]).abs() < 1e-9 * (1.0 + x[a].abs()), "x{a}: {} vs {}", back[a], x[a]);
        }
        assert!((layout.theta_of(&x)[0] - 0.3).abs() < 1e-12);
        // a negative friction start is clamped to its bound
        theta[0] = -1.0;
        assert_eq!(layout.x_of(&theta)[0], 0.0);
        // ∂θ/∂x by finite differences
        let t = layout.dtheta_dx(&x);
        for a in 0..layout.nx() {
            let mut x2 = x.clone();
            x2[a] += 1e-7;
            let d = (layout.theta_of(&x2) - layout.theta_of(&x)) / 1e-7;
            for i in 0..layout.k {
                assert!((d[i] - t[(i, a)]).abs() < 1e-4 * (1.0 + d[i].abs()), "∂θ{i}/∂x{a}: {} vs {}", d[i], t[(i, a)]);
            }
        }
    }
}
