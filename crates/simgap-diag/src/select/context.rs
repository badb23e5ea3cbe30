//! The shared context of a selection ([`Context`]): the fit runs' problem, the identifiable
//! inertial directions and their prior, the limits the logs allow, and the caches of designs,
//! fits and bounds that the selection's steps share.

use nalgebra::{DMatrix, DVector};
use simgap_core::PARAMS_PER_LINK;
use std::sync::Arc;

use crate::lsq::inertial::InertialPrior;
use crate::lsq::{fit, grams, Fit, Grams, Problem};
use crate::prepare::dataset::FitData;
use crate::prepare::width::DryWidth;
use crate::vocabulary::fit_designs;
use crate::vocabulary::{design, Column, Term, TermDesign};

/// Shared context of a selection.
pub(crate) struct Context<'a> {
    /// Prepared fit runs.
    pub data: &'a [FitData],
    /// The problem.
    pub problem: Problem,
    /// Identifiable inertial directions (the excited directions of the stacked parameters).
    pub inertial_basis: DMatrix<f64>,
    /// Prior of the inertial correction (URDF parameters, reach, weight chosen by
    /// cross-validation).
    pub prior: Arc<InertialPrior>,
    /// Per joint, the lowest torque saturation limit the logs allow: the torque the drive is
    /// seen to deliver (`tau_measured`, when logged) [N·m].
    pub saturation_floor: Vec<f64>,
    /// Sample period (for the delay grid) [s].
    pub sample_period: f64,
    /// The dry-friction widths the data allow on every joint ([`FitData::dry_width`]).
    pub dry_width: Vec<DryWidth>,
    /// Designs already built, by term (the same grid members recur at every step).
    cache: std::sync::Mutex<std::collections::HashMap<crate::vocabulary::TermKey, std::sync::Arc<TermDesign>>>,
    /// The payload's basis, built at its first search.
    pub(super) payload: std::sync::OnceLock<PayloadBasis>,
    /// Fits already made, by the terms fitted in their order (exchange moves, polishing and
    /// pruning fit the same sets again).
    fits: std::sync::Mutex<std::collections::HashMap<Vec<crate::vocabulary::TermKey>, Fit>>,
    /// What is known of sets not cross-validated ([`crate::lsq::Rejected`]).
    bounds: std::sync::Mutex<std::collections::HashMap<Vec<crate::vocabulary::TermKey>, Bound>>,
}

/// What is known of a set that was not cross-validated: a lower bound of its cross-validated
/// residual (its least-squares floor, or its in-sample residual once fitted on all the data),
/// and its parameters fitted on all the data when they were.
#[derive(Clone, Debug, Default)]
struct Bound {
    floor: f64,
    theta: Option<DVector<f64>>,
}

/// The key of a set of terms in the context's caches (the terms in their order).
fn set_key(terms: &[Term]) -> Vec<crate::vocabulary::TermKey> {
    terms.iter().map(Term::key).collect()
}

/// Rows per block of [`PayloadBasis::block_bounds`].
pub(super) const PAYLOAD_BLOCK: usize = 32;

/// What every payload search shares: the last link's ten regressor columns (a payload at `c` is
/// their combination by [`point_mass_parameters`](crate::vocabulary::point_mass_parameters)),
/// row-major and as free columns, and the largest commanded torque.
pub(super) struct PayloadBasis {
    /// Per row, the basis entries that are not zero in every row (a planar motion leaves
    /// most of them zero), row-major, rows by decreasing Euclidean norm.
    pub(super) rows: Vec<f64>,
    /// The norm of each of those rows.
    pub(super) norms: Vec<f64>,
    /// Which of the ten parameters those entries belong to.
    pub(super) nonzero: Vec<usize>,
    /// Per block of [`PAYLOAD_BLOCK`] consecutive rows, the largest magnitude of each entry
    /// (row-major, one row of `nonzero.len()` per block): `Σ_i bound_i |π_i|` bounds every
    /// `|row · π|` of the block.
    pub(super) block_bounds: Vec<f64>,
    pub(super) design: TermDesign,
    pub(super) tau_max: f64,
}

impl<'a> Context<'a> {
    /// Builds the context; `prior` holds the model's inertial parameters, their scales and the
    /// reach of every link (see [`parameter_scales`]).
    pub(crate) fn new(data: &'a [FitData], sample_period: f64, prior: &InertialPrior) -> Context<'a> {
        let problem = Problem::new(data);
        let inertial_basis = inertial_basis(&problem, data, prior);
        let dof = problem.dof;
        let saturation_floor = (0..dof)
            .map(|j| {
                // the largest torque the drive delivered
                data.iter().flat_map(|d| d.raw.tau_measured.iter().skip(j).step_by(d.dof)).filter(|x| x.is_finite()).fold(0.0f64, |m, x| m.max(x.abs()))
            })
            .collect();
        let mut prior = prior.clone();
        prior.identifiable = inertial_basis.ncols();
        let dry_width = data.first().map_or_else(Vec::new, |d| d.dry_width.clone());
        let mut ctx = Context {
            data,
            problem,
            inertial_basis,
            prior: Arc::new(prior),
            saturation_floor,
            sample_period,
            dry_width,
            cache: Default::default(),
            payload: Default::default(),
            fits: Default::default(),
            bounds: Default::default(),
        };
        if ctx.inertial_basis.ncols() > 0 {
            let w = ctx.choose_prior_weight();
            let mut prior = (*ctx.prior).clone();
            prior.weight = w;
            ctx.prior = Arc::new(prior);
        }
        ctx
    }

    /// The weight of the inertial prior that cross-validates best on the nominal residual (the
    /// largest within 1 % of the best, so that weakly excited directions stay at the URDF).
    fn choose_prior_weight(&self) -> f64 {
        let p = &self.problem;
        let d = design(&Term::InertialError { prior: self.prior.clone() }, self.data);
        let gr = grams(p, &[&d]);
        let scores: Vec<(f64, f64)> = [1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0]
            .iter()
            .map(|&w| {
                let mut prior = (*self.prior).clone();
                prior.weight = w;
                let mut g = gr.clone();
                g.inertial = g.inertial.map(|(first, _)| (first, Arc::new(prior)));
                (w, fit(p, &g).cv_mse)
            })
            .collect();
        let best = scores.iter().map(|s| s.1).fold(f64::INFINITY, f64::min);
        scores.iter().filter(|s| s.1 <= best * 1.01).map(|s| s.0).fold(crate::lsq::inertial::DEFAULT_PRIOR_WEIGHT.min(1e-6), f64::max)
    }

    /// Whether a torque saturation limit is possible: not below the torque the drive is seen to
    /// deliver, and not below commands whose full torque the motion shows. On the samples the
    /// limit would clamp, the residual `r` left by the other terms must follow the clamped excess
    /// `τ − clamp(τ, ±L)`: its least-squares coefficient on it is at least 0.5 (a limit the
    /// joint's acceleration contradicts has a coefficient near 0).
    pub(crate) fn saturation_plausible(&self, t: &Term, resid: &Column) -> bool {
        let Term::Saturation { joint, limit } = *t else { return true };
        if limit < self.saturation_floor.get(joint).copied().unwrap_or(0.0) {
            return false;
        }
        let d = self.design_shared(t);
        let Some(x) = &d.offset else { return true };
        let dof = self.problem.dof;
        let (mut a, mut b) = (0.0, 0.0);
        for (s, &v) in x.values.iter().enumerate() {
            if v != 0.0 {
                a += v * resid.values[s * dof + joint];
                b += v * v;
            }
        }
        b <= 0.0 || a / b >= 0.5
    }

    /// The largest commanded torque of joint `j` (a saturation there clamps nothing).
    pub(super) fn max_command(&self, j: usize) -> f64 {
        self.data.iter().flat_map(|d| d.raw.tau.iter().skip(j).step_by(d.dof)).fold(0.0f64, |m, v| m.max(v.abs()))
    }

    /// The fit of `terms` on the torque residual ([`crate::lsq::fit`] of their Grams), whose
    /// designs are `designs` (each the [`Context::design`] of its term), made once per set.
    pub(crate) fn fit_set(&self, terms: &[Term], designs: &[TermDesign]) -> Fit {
        debug_assert_eq!(terms.len(), designs.len());
        self.fit_set_with(terms, || {
            let refs: Vec<&TermDesign> = designs.iter().collect();
            fit(&self.problem, &grams(&self.problem, &refs))
        })
    }

    /// [`Context::fit_set`] when its cross-validated residual may be below `reject_at`; `None`
    /// when it is not (see [`crate::lsq::fit_unless`]: the folds are then not fitted).
    pub(crate) fn fit_set_below(&self, terms: &[Term], designs: &[TermDesign], reject_at: f64) -> Option<Fit> {
        let key = set_key(terms);
        if let Some(f) = self.fits.lock().expect("fit cache").get(&key) {
            return (f.cv_mse < reject_at).then(|| f.clone());
        }
        if self.bounds.lock().expect("fit cache").get(&key).is_some_and(|b| b.floor >= reject_at) {
            return None;
        }
        let refs: Vec<&TermDesign> = designs.iter().collect();
        let rejected = match crate::lsq::fit_unless(&self.problem, &grams(&self.problem, &refs), reject_at) {
            Ok(f) => {
                self.fits.lock().expect("fit cache").insert(key, f.clone());
                return (f.cv_mse < reject_at).then_some(f);
            }
            Err(crate::lsq::Rejected::Fitted(f)) => Bound { floor: f.cv_mse, theta: Some(f.theta) },
            Err(crate::lsq::Rejected::Floor(floor)) => Bound { floor, theta: None },
        };
        self.learn(key, rejected);
        None
    }

    /// Keeps what was learnt of a set not cross-validated (the larger floor, any parameters).
    fn learn(&self, key: Vec<crate::vocabulary::TermKey>, bound: Bound) {
        let mut bounds = self.bounds.lock().expect("fit cache");
        let b = bounds.entry(key).or_default();
        b.floor = b.floor.max(bound.floor);
        if bound.theta.is_some() {
            b.theta = bound.theta;
        }
    }

    /// A lower bound of the cross-validated residual of `terms` (the largest known, else their
    /// least-squares floor, which is then kept).
    pub(crate) fn residual_floor(&self, terms: &[Term], designs: &[TermDesign]) -> f64 {
        let key = set_key(terms);
        if let Some(b) = self.bounds.lock().expect("fit cache").get(&key) {
            return b.floor;
        }
        let refs: Vec<&TermDesign> = designs.iter().collect();
        let floor = crate::lsq::least_squares_floor(&self.problem, &grams(&self.problem, &refs));
        self.learn(key, Bound { floor, theta: None });
        floor
    }

    /// The parameters of `terms` fitted on all the data (those of [`Context::fit_set`], without
    /// its cross-validation when the set was not fitted before).
    pub(crate) fn theta_of_set(&self, terms: &[Term], designs: &[TermDesign]) -> DVector<f64> {
        let key = set_key(terms);
        if let Some(f) = self.fits.lock().expect("fit cache").get(&key) {
            return f.theta.clone();
        }
        if let Some(theta) = self.bounds.lock().expect("fit cache").get(&key).and_then(|b| b.theta.clone()) {
            return theta;
        }
        let refs: Vec<&TermDesign> = designs.iter().collect();
        let f = crate::lsq::fit_whole(&self.problem, &grams(&self.problem, &refs));
        self.learn(key, Bound { floor: f.cv_mse, theta: Some(f.theta.clone()) });
        f.theta
    }

    /// [`Context::fit_set`] with the fit made by `fit_of` (called only when the set was not
    /// fitted before: a caller that needs the set's Grams anyway builds them once).
    pub(crate) fn fit_set_with(&self, terms: &[Term], fit_of: impl FnOnce() -> Fit) -> Fit {
        let key = set_key(terms);
        if let Some(f) = self.fits.lock().expect("fit cache").get(&key) {
            return f.clone();
        }
        let f = fit_of();
        self.fits.lock().expect("fit cache").insert(key, f.clone());
        f
    }

    /// The designs of `terms` (from the cache), their Grams and their fit
    /// ([`crate::vocabulary::fit_terms`] with cached designs, whose column products the problem
    /// keeps).
    pub(crate) fn fit_terms(&self, terms: &[Term]) -> (Vec<TermDesign>, Grams, Fit) {
        fit_designs(&self.problem, terms.iter().map(|t| self.design(t)).collect())
    }

    /// Designs a term (the inertial error uses the identifiable basis), from the cache when it
    /// was built before.
    pub(crate) fn design(&self, t: &Term) -> TermDesign {
        self.design_shared(t).as_ref().clone()
    }

    pub(super) fn design_shared(&self, t: &Term) -> std::sync::Arc<TermDesign> {
        let key = t.key();
        if let Some(d) = self.cache.lock().expect("design cache").get(&key) {
            return d.clone();
        }
        let d = std::sync::Arc::new(design(t, self.data));
        self.cache.lock().expect("design cache").insert(key, d.clone());
        d
    }

    /// The inertial-error term: physically consistent corrections of every link, regularised
    /// toward the URDF.
    pub(crate) fn inertial_term(&self) -> Term {
        Term::InertialError { prior: self.prior.clone() }
    }
}

/// Nominal magnitudes of the stacked inertial parameters: per link `m̄` for the mass, `m̄ ℓ` for
/// the first moments and `m̄ ℓ²` for the rotational inertia, with `m̄` the link mass (at least
/// 1 % of the average) and `ℓ = 0.1 m`. Fitting in these units makes the minimum-norm
/// correction spread over the links as their nominal parameters do, which keeps it physical.
///
/// Returned inside the [`InertialPrior`] of the model (which dereferences to the scales), with
/// the URDF parameters and the reach of every link.
pub(crate) fn parameter_scales(model: &simgap_core::Model) -> InertialPrior {
    InertialPrior::new(model)
}

/// Directions of the stacked inertial parameters the fit data excites (eigenvectors of the
/// weighted regressor Gram with eigenvalue above 1e-8 of the largest).
fn inertial_basis(p: &Problem, data: &[FitData], scales: &[f64]) -> DMatrix<f64> {
    let dof = p.dof;
    let width = PARAMS_PER_LINK * dof;
    if data.iter().any(|d| d.regressor.is_empty()) {
        return DMatrix::zeros(width, 0);
    }
    let mut g = DMatrix::<f64>::zeros(width, width);
    for d in data {
        for s in 0..d.len() {
            for j in 0..dof {
                let row = &d.regressor[(s * dof + j) * width..(s * dof + j + 1) * width];
                let w2 = p.weights[j].powi(2);
                for a in 0..width {
                    if row[a] == 0.0 {
                        continue;
                    }
                    for b in a..width {
                        g[(a, b)] += w2 * row[a] * row[b];
                    }
                }
            }
        }
    }
    // in scaled units: G_s = D G D, basis = D V
    let g = DMatrix::from_fn(width, width, |a, b| if a <= b { g[(a, b)] } else { g[(b, a)] } * scales[a] * scales[b]);
    let eig = g.symmetric_eigen();
    let max = eig.eigenvalues.iter().cloned().fold(0.0, f64::max);
    let keep: Vec<usize> = (0..width).filter(|&i| eig.eigenvalues[i] > 1e-8 * max).collect();
    DMatrix::from_fn(width, keep.len(), |r, c| scales[r] * eig.eigenvectors[(r, keep[c])])
}
