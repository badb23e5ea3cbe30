//! Weighted least squares over block Gram matrices: fits, cross-validation and block bootstrap
//! without revisiting the samples.

pub(crate) mod bounded;
pub(crate) mod design;
pub(crate) mod inertial;

use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

use crate::lsq::design::{Column, TermDesign};
use crate::lsq::inertial::InertialPrior;
pub(crate) use bounded::solve_bounded;

/// Blocks per run for the bootstrap; cross-validation folds group [`BLOCKS_PER_FOLD`] of them.
pub(crate) const BLOCKS_PER_RUN: usize = 20;
/// Bootstrap blocks per cross-validation fold (so 5 contiguous folds per run).
pub(crate) const BLOCKS_PER_FOLD: usize = 4;

/// The inertial columns' scales and their block Grams.
type InertialGram = (Vec<f64>, Vec<DMatrix<f64>>);

/// At most this many products are kept by [`PairCache`] (8 bytes each: 64 MiB).
const PAIR_CACHE_FLOATS: usize = 8 << 20;

/// Block inner products of pairs of design columns already computed ([`Problem::dot_blocks`]):
/// a selection fits hundreds of sets that share most of their columns. A column is named by the
/// address of its shared values; the entry holds a weak reference to each, which keeps that
/// address from being reused by another column (not the values) while the entry exists. Design
/// columns are never changed in place.
#[derive(Debug, Default)]
struct PairCache {
    map: std::collections::HashMap<PairKey, PairEntry>,
    floats: usize,
}

/// A pair of columns: the address of each one's values and its joint.
type PairKey = (usize, Option<usize>, usize, Option<usize>);

/// The columns' values (held weakly) and their block products.
type PairEntry = (std::sync::Weak<Vec<f64>>, std::sync::Weak<Vec<f64>>, Vec<f64>);

/// What the fitting problem reads of one prepared run (the prepare stage's fit data implements
/// it, so `lsq` depends on no stage).
pub(crate) trait Samples {
    /// Degrees of freedom.
    fn dof(&self) -> usize;
    /// Number of samples.
    fn samples(&self) -> usize;
    /// Nominal residual [N·m or N], row-major by sample and joint.
    fn residual(&self) -> &[f64];
    /// Commanded torque [N·m or N], row-major by sample and joint.
    fn tau(&self) -> &[f64];
}

/// The fitting problem: residuals of all runs, joint weights and sample blocks.
#[derive(Clone, Debug)]
pub(crate) struct Problem {
    /// Degrees of freedom.
    pub dof: usize,
    /// Total samples over runs.
    pub samples: usize,
    /// Block of every sample.
    pub block_of: Vec<usize>,
    /// First sample of every block, and the number of samples last (`blocks + 1` entries):
    /// blocks are contiguous.
    block_start: Vec<usize>,
    /// Number of blocks.
    pub blocks: usize,
    /// Weight of each joint's rows (1 / RMS of its commanded torque).
    pub weights: Vec<f64>,
    /// RMS commanded torque per joint (filtered, fit samples).
    pub tau_rms: Vec<f64>,
    /// Nominal residual, global column.
    pub y: Column,
    /// The block Grams of the inertial correction's columns with themselves, by their scales (the
    /// same columns recur in every fit of a selection).
    inertial_gram: std::sync::Arc<std::sync::Mutex<Option<InertialGram>>>,
    /// The block products of design-column pairs computed so far.
    pair_cache: std::sync::Arc<std::sync::Mutex<PairCache>>,
}

impl Problem {
    /// Builds the problem from prepared runs.
    pub(crate) fn new<S: Samples>(data: &[S]) -> Problem {
        let dof = data[0].dof();
        let mut block_of = Vec::new();
        let mut blocks = 0;
        for d in data {
            let n = d.samples();
            for s in 0..n {
                block_of.push(blocks + (s * BLOCKS_PER_RUN / n.max(1)).min(BLOCKS_PER_RUN - 1));
            }
            blocks += BLOCKS_PER_RUN;
        }
        let y = Column::new(None, data.iter().flat_map(|d| d.residual().iter().copied()).collect());
        let samples = block_of.len();
        let rms = |f: &dyn Fn(usize, usize) -> f64, j: usize| ((0..samples).map(|s| f(s, j).powi(2)).sum::<f64>() / samples.max(1) as f64).sqrt();
        let tau: Vec<f64> = data.iter().flat_map(|d| d.tau().iter().copied()).collect();
        let tau_rms: Vec<f64> = (0..dof).map(|j| rms(&|s, j| tau[s * dof + j], j)).collect();
        // each joint's rows in units of its own commanded torque, so joints count alike
        let weights = (0..dof).map(|j| 1.0 / tau_rms[j].max(rms(&|s, j| y.values[s * dof + j], j)).max(1e-9)).collect();
        let block_start = (0..=blocks).map(|b| block_of.partition_point(|&x| x < b)).collect();
        Problem { dof, samples, block_of, block_start, blocks, weights, tau_rms, y, inertial_gram: Default::default(), pair_cache: Default::default() }
    }

    /// The problem with the rows `rows` ((sample, joint) pairs) left out: their residual is zero,
    /// and so are their columns in designs taken through [`TermDesign::without_rows`], so that
    /// they add nothing to a fit; the blocks and the joints' weights stay those of all rows, and
    /// the caches of column products start empty.
    pub(crate) fn without_rows(&self, rows: &[(usize, usize)]) -> Problem {
        let mut y = self.y.clone();
        y.zero_rows(rows, self.dof);
        Problem {
            dof: self.dof,
            samples: self.samples,
            block_of: self.block_of.clone(),
            block_start: self.block_start.clone(),
            blocks: self.blocks,
            weights: self.weights.clone(),
            tau_rms: self.tau_rms.clone(),
            y,
            inertial_gram: Default::default(),
            pair_cache: Default::default(),
        }
    }

    /// Weighted inner product of two columns per (block, joint): `out[block · dof + joint]`.
    fn dot_blocks(&self, a: &Column, b: &Column, out: &mut [f64]) {
        out.fill(0.0);
        let dof = self.dof;
        // blocks are contiguous ranges of samples: each sum runs over its range in order
        let ranges = self.block_start.windows(2).enumerate().map(|(bl, r)| (bl, r[0]..r[1]));
        match (a.joint, b.joint) {
            (Some(ja), Some(jb)) => {
                if ja == jb {
                    let w2 = self.weights[ja].powi(2);
                    for (bl, r) in ranges {
                        let mut acc = 0.0;
                        for (x, y) in a.values[r.clone()].iter().zip(&b.values[r]) {
                            acc += w2 * x * y;
                        }
                        out[bl * dof + ja] = acc;
                    }
                }
            }
            (Some(j), None) | (None, Some(j)) => {
                let (pj, g) = if a.joint.is_some() { (a, b) } else { (b, a) };
                let w2 = self.weights[j].powi(2);
                for (bl, r) in ranges {
                    let mut acc = 0.0;
                    for s in r {
                        acc += w2 * pj.values[s] * g.values[s * dof + j];
                    }
                    out[bl * dof + j] = acc;
                }
            }
            (None, None) => {
                let w2: Vec<f64> = self.weights.iter().map(|w| w * w).collect();
                for (bl, r) in ranges {
                    let acc = &mut out[bl * dof..(bl + 1) * dof];
                    for s in r {
                        let (ra, rb) = (&a.values[s * dof..(s + 1) * dof], &b.values[s * dof..(s + 1) * dof]);
                        for j in 0..dof {
                            acc[j] += w2[j] * ra[j] * rb[j];
                        }
                    }
                }
            }
        }
    }

    /// [`Problem::dot_blocks`] of two design columns, from the pair cache when computed before.
    fn dot_blocks_cached(&self, a: &Column, b: &Column, out: &mut [f64]) {
        use std::sync::Arc;
        let key = (Arc::as_ptr(&a.values) as usize, a.joint, Arc::as_ptr(&b.values) as usize, b.joint);
        if let Some((_, _, v)) = self.pair_cache.lock().expect("pair cache").map.get(&key) {
            out.copy_from_slice(v);
            return;
        }
        self.dot_blocks(a, b, out);
        let mut cache = self.pair_cache.lock().expect("pair cache");
        if cache.floats + out.len() <= PAIR_CACHE_FLOATS {
            cache.floats += out.len();
            cache.map.insert(key, (Arc::downgrade(&a.values), Arc::downgrade(&b.values), out.to_vec()));
        }
    }

    /// Total weighted rows (samples × dof).
    pub(crate) fn rows(&self) -> f64 {
        (self.samples * self.dof) as f64
    }
}

/// The block Gram matrices of a set of terms.
#[derive(Clone, Debug)]
pub(crate) struct Grams {
    /// Free columns (k).
    pub k: usize,
    /// Per (block, joint), index `block · dof + joint`: XᵀW²X (k × k).
    pub g: Vec<DMatrix<f64>>,
    /// Per (block, joint): XᵀW²y'.
    pub c: Vec<DVector<f64>>,
    /// Per (block, joint): y'ᵀW²y'.
    pub s: Vec<f64>,
    /// Degrees of freedom (joints per block).
    pub dof: usize,
    /// Lower bound of each column's parameter (`-∞` when free).
    pub lo: Vec<f64>,
    /// Upper bound of each column's parameter (`+∞` when free).
    pub hi: Vec<f64>,
    /// The inertial correction among the terms, if any: its first column and its prior.
    pub inertial: Option<(usize, std::sync::Arc<InertialPrior>)>,
}

impl Grams {
    /// Minimises `½ θᵀ g θ − cᵀ θ` (a sum of these Grams' blocks) under the physical constraints
    /// of the terms: bounds on linear parameters ([`solve_bounded`]) and, with an inertial
    /// correction, physically consistent links ([`crate::lsq::inertial::solve`]). Returns θ.
    pub(crate) fn solve(&self, g: &DMatrix<f64>, c: &DVector<f64>) -> DVector<f64> {
        self.solve_from(g, c, None).0
    }

    /// [`Grams::solve`] started from `start`, the [`Start`] of an earlier solution of the same
    /// terms on other data (a fold, a resample); returns θ and its own start for the next.
    pub(crate) fn solve_from(&self, g: &DMatrix<f64>, c: &DVector<f64>, start: Option<&Start>) -> (DVector<f64>, Option<Start>) {
        match &self.inertial {
            Some((first, prior)) => {
                let (theta, x) = crate::lsq::inertial::solve(prior, *first, g, c, &self.lo, &self.hi, start.map(|s| s.0.as_slice()));
                (theta, Some(Start(x)))
            }
            None => (solve_bounded(g, c, &self.lo, &self.hi).0, None),
        }
    }
}

/// Where the iterative solve of an inertial correction stands after a solution: started from it,
/// a nearby problem (the same terms fitted on a fold or a resample of the data) converges in a
/// few iterations instead of from the URDF. Only terms with an inertial correction have one.
#[derive(Clone, Debug)]
pub(crate) struct Start(Vec<f64>);

/// Builds the Gram matrices of `terms` (their designs given) against the nominal residual
/// minus their fixed offsets.
pub(crate) fn grams(p: &Problem, designs: &[&TermDesign]) -> Grams {
    grams_against(p, &p.y, designs)
}

/// [`grams`] against another residual `y` (a global column over the problem's rows).
pub(crate) fn grams_against(p: &Problem, y: &Column, designs: &[&TermDesign]) -> Grams {
    grams_against_known(p, y, designs, None)
}

/// `y·y` per (block, joint) of a global column, as [`grams_against`] computes it: pass it to
/// [`grams_against_known`] when many designs without offset are fitted against one `y`.
pub(crate) fn block_squares(p: &Problem, y: &Column) -> Vec<f64> {
    let mut buf = vec![0.0; p.blocks * p.dof];
    p.dot_blocks(y, y, &mut buf);
    buf
}

/// [`grams_against`] with `y·y` per block already known (`y_squares` from [`block_squares`]
/// of the same `y`; used only when no design has a fixed offset, which changes `y`).
pub(crate) fn grams_against_known(p: &Problem, y: &Column, designs: &[&TermDesign], y_squares: Option<&[f64]>) -> Grams {
    // y' = y − Σ offsets, as a global column (y itself without offsets)
    let has_offset = designs.iter().any(|d| d.offset.is_some());
    let shifted;
    let y = if has_offset {
        let mut v = y.clone();
        let values = std::sync::Arc::make_mut(&mut v.values);
        for d in designs {
            if let Some(off) = &d.offset {
                for s in 0..p.samples {
                    for j in 0..p.dof {
                        values[s * p.dof + j] -= off.at(s, j, p.dof);
                    }
                }
            }
        }
        shifted = v;
        &shifted
    } else {
        y
    };
    let cols: Vec<&Column> = designs.iter().flat_map(|d| d.cols.iter()).collect();
    let k = cols.len();
    let (mut lo, mut hi) = (Vec::with_capacity(k), Vec::with_capacity(k));
    let mut inertial = None;
    for d in designs {
        if let Some(prior) = &d.inertial {
            inertial = Some((lo.len(), prior.clone()));
        }
        for i in 0..d.cols.len() {
            lo.push(d.lo.get(i).copied().unwrap_or(f64::NEG_INFINITY));
            hi.push(d.hi.get(i).copied().unwrap_or(f64::INFINITY));
        }
    }
    let nb = p.blocks * p.dof;
    let mut g = vec![DMatrix::zeros(k, k); nb];
    let mut c = vec![DVector::zeros(k); nb];
    let mut s = vec![0.0; nb];
    let mut buf = vec![0.0; nb];
    // the inertial columns' own block, computed once per problem
    let mut done = vec![false; k];
    for (first, d) in designs.iter().scan(0, |c, d| {
        let f = *c;
        *c += d.cols.len();
        Some((f, d))
    }) {
        let Some(prior) = &d.inertial else { continue };
        let mut cache = p.inertial_gram.lock().expect("inertial Gram cache");
        if cache.as_ref().is_none_or(|(scales, _)| *scales != prior.scales) {
            let ki = d.cols.len();
            let mut blocks = vec![DMatrix::zeros(ki, ki); nb];
            for a in 0..ki {
                for b in a..ki {
                    p.dot_blocks(&d.cols[a], &d.cols[b], &mut buf);
                    for (bl, v) in buf.iter().enumerate() {
                        blocks[bl][(a, b)] = *v;
                        blocks[bl][(b, a)] = *v;
                    }
                }
            }
            *cache = Some((prior.scales.clone(), blocks));
        }
        let blocks = &cache.as_ref().expect("filled").1;
        for (bl, m) in blocks.iter().enumerate() {
            g[bl].view_mut((first, first), m.shape()).copy_from(m);
        }
        for x in done.iter_mut().skip(first).take(d.cols.len()) {
            *x = true;
        }
    }
    // columns that are zero everywhere (parameters a planar motion does not see) add nothing
    let zero: Vec<bool> = cols.iter().map(|c| c.values.iter().all(|v| *v == 0.0)).collect();
    for a in 0..k {
        for b in a..k {
            if (done[a] && done[b]) || zero[a] || zero[b] {
                continue;
            }
            p.dot_blocks_cached(cols[a], cols[b], &mut buf);
            for (bl, v) in buf.iter().enumerate() {
                g[bl][(a, b)] = *v;
                g[bl][(b, a)] = *v;
            }
        }
        if zero[a] {
            continue;
        }
        // (against the problem's own residual, the products are kept like the columns' own)
        if std::sync::Arc::ptr_eq(&y.values, &p.y.values) {
            p.dot_blocks_cached(cols[a], y, &mut buf);
        } else {
            p.dot_blocks(cols[a], y, &mut buf);
        }
        for (bl, v) in buf.iter().enumerate() {
            c[bl][a] = *v;
        }
    }
    match y_squares {
        Some(known) if !has_offset => s.copy_from_slice(known),
        _ => {
            p.dot_blocks(y, y, &mut buf);
            s.copy_from_slice(&buf);
        }
    }
    Grams { k, g, c, s, dof: p.dof, lo, hi, inertial }
}

/// Result of fitting a set of terms.
#[derive(Clone, Debug)]
pub(crate) struct Fit {
    /// Parameters, in column order.
    pub theta: DVector<f64>,
    /// Cross-validated weighted mean squared residual (contiguous folds).
    pub cv_mse: f64,
    /// The same per joint (mean over that joint's rows).
    pub cv_joint: Vec<f64>,
}

/// Sums the Grams of the (block, joint) cells `keep(block, joint)` accepts.
pub(crate) fn sum_blocks(gr: &Grams, keep: impl Fn(usize, usize) -> bool) -> (DMatrix<f64>, DVector<f64>, f64) {
    let mut g = DMatrix::zeros(gr.k, gr.k);
    let mut c = DVector::zeros(gr.k);
    let mut s = 0.0;
    for b in 0..gr.g.len() {
        if keep(b / gr.dof, b % gr.dof) {
            g += &gr.g[b];
            c += &gr.c[b];
            s += gr.s[b];
        }
    }
    (g, c, s)
}

fn sse(g: &DMatrix<f64>, c: &DVector<f64>, s: f64, theta: &DVector<f64>) -> f64 {
    (s - 2.0 * theta.dot(c) + theta.dot(&(g * theta))).max(0.0)
}

/// Fits and cross-validates, every fit (all data and each fold) under the terms' physical
/// constraints (see [`Grams::solve`]); the folds start from the fit on all data.
pub(crate) fn fit(p: &Problem, gr: &Grams) -> Fit {
    match cross_validate_unless(p, gr, f64::INFINITY) {
        Ok(f) | Err(f) => f,
    }
}

/// A set [`fit_unless`] did not cross-validate, with what is known of its residual.
#[derive(Clone, Debug)]
pub(crate) enum Rejected {
    /// Its fit on all the data: `cv_mse` is the in-sample mean squared residual, a lower bound of
    /// the cross-validated one, and `cv_joint` is empty.
    Fitted(Fit),
    /// A lower bound of its in-sample mean squared residual: the least-squares minimum without
    /// the physical constraints, bounds and prior (see [`least_squares_floor`]); not even the
    /// constrained fit on all the data was made.
    Floor(f64),
}

/// A lower bound of the mean squared residual any parameters of the set leave on all the data:
/// the unconstrained least-squares minimum `s − cᵀ G⁻¹ c` (over the number of rows), less a
/// relative 1e-9 for the ridge of 1e-12 of the mean diagonal that keeps `G` invertible where a
/// column is zero. The constrained and regularised fit leaves at least this much, and the
/// cross-validated residual at least that: a set whose floor is above what a step needs is
/// rejected by one Cholesky factorisation instead of the iterative solve of an inertial
/// correction.
pub(crate) fn least_squares_floor(p: &Problem, gr: &Grams) -> f64 {
    let (mut g, c, s) = sum_blocks(gr, |_, _| true);
    let k = gr.k;
    if k == 0 {
        return s.max(0.0) / p.rows();
    }
    let ridge = 1e-12 * (0..k).map(|i| g[(i, i)].abs()).sum::<f64>() / k as f64;
    let g0 = g.clone();
    for i in 0..k {
        g[(i, i)] += ridge.max(f64::MIN_POSITIVE);
    }
    let Some(ch) = g.cholesky() else { return 0.0 };
    let theta = ch.solve(&c);
    let floor = sse(&g0, &c, s, &theta) * (1.0 - 1e-9) / p.rows();
    if floor.is_finite() {
        floor
    } else {
        0.0
    }
}

/// [`fit`], unless the set's cross-validated residual is known to be at least `reject_at`: its
/// fit on all the data leaves that much in sample, or (for a set with an inertial correction,
/// before its iterative solve) its [`least_squares_floor`] does; the folds are then not fitted.
/// (Fold f's held-out cells are fitted no better by the fit that did not see them than by the
/// fit on all the data: each fit minimises its own training cells under the same constraints,
/// so J_f(θ₋f) ≥ J_f(θ) with J_f the squared residual of f's cells. Exact for the linear and
/// box-bounded terms; for an inertial correction, whose prior weight follows its training Gram
/// and whose solve is iterative, up to those differences: on the 7-DOF arm no set's
/// cross-validated residual fell below its in-sample one.)
pub(crate) fn fit_unless(p: &Problem, gr: &Grams, reject_at: f64) -> Result<Fit, Rejected> {
    // an inertial correction's iterative solve is spared where the floor already rejects
    if gr.inertial.is_some() && reject_at.is_finite() {
        let floor = least_squares_floor(p, gr);
        if floor >= reject_at {
            return Err(Rejected::Floor(floor));
        }
    }
    cross_validate_unless(p, gr, reject_at).map_err(Rejected::Fitted)
}

/// The fit on all the data alone ([`fit`] without its cross-validation): `cv_mse` is the
/// in-sample mean squared residual and `cv_joint` is empty.
pub(crate) fn fit_whole(p: &Problem, gr: &Grams) -> Fit {
    match cross_validate_unless(p, gr, f64::NEG_INFINITY) {
        Ok(f) | Err(f) => f,
    }
}

/// [`fit_unless`] without the floor: the fit on all the data (as `Err`) when its in-sample
/// residual is at least `reject_at` (never for an infinite `reject_at`).
fn cross_validate_unless(p: &Problem, gr: &Grams, reject_at: f64) -> Result<Fit, Fit> {
    let folds = p.blocks / BLOCKS_PER_FOLD;
    // per fold, the sum over its blocks of every joint's cells and of each joint's; the blocks
    // after the last whole fold are in every training set
    let (k, dof) = (gr.k, p.dof);
    let mut fold_g = vec![DMatrix::zeros(k, k); folds];
    let mut fold_c = vec![DVector::zeros(k); folds];
    let mut cell: Vec<(DMatrix<f64>, DVector<f64>, f64)> = vec![(DMatrix::zeros(k, k), DVector::zeros(k), 0.0); folds * dof];
    let (mut rest_g, mut rest_c) = (DMatrix::zeros(k, k), DVector::zeros(k));
    for b in 0..gr.g.len() {
        let (block, j) = (b / dof, b % dof);
        let f = block / BLOCKS_PER_FOLD;
        if f < folds {
            let e = &mut cell[f * dof + j];
            e.0 += &gr.g[b];
            e.1 += &gr.c[b];
            e.2 += gr.s[b];
        } else {
            rest_g += &gr.g[b];
            rest_c += &gr.c[b];
        }
    }
    for f in 0..folds {
        for j in 0..dof {
            fold_g[f] += &cell[f * dof + j].0;
            fold_c[f] += &cell[f * dof + j].1;
        }
    }
    let (mut g, mut c) = (rest_g.clone(), rest_c.clone());
    for f in 0..folds {
        g += &fold_g[f];
        c += &fold_c[f];
    }
    let (theta, start) = gr.solve_from(&g, &c, None);
    let in_mse = sse(&g, &c, gr.s.iter().sum(), &theta) / p.rows();
    if reject_at < f64::INFINITY && in_mse >= reject_at {
        return Err(Fit { theta, cv_mse: in_mse, cv_joint: Vec::new() });
    }
    let mut cv_joint = vec![0.0; dof];
    for f in 0..folds {
        let (mut gt, mut ct) = (rest_g.clone(), rest_c.clone());
        for o in (0..folds).filter(|&o| o != f) {
            gt += &fold_g[o];
            ct += &fold_c[o];
        }
        let (th, _) = gr.solve_from(&gt, &ct, start.as_ref());
        for (j, cv) in cv_joint.iter_mut().enumerate() {
            let (gv, cvv, sv) = &cell[f * dof + j];
            *cv += sse(gv, cvv, *sv, &th);
        }
    }
    let cv_mse = cv_joint.iter().sum::<f64>() / p.rows();
    let cv_joint = cv_joint.iter().map(|v| v / p.samples.max(1) as f64).collect();
    Ok(Fit { theta, cv_mse, cv_joint })
}

/// Block-bootstrap standard deviations of the parameters (`draws` resamples, fixed seed), each
/// draw fitted under the terms' physical constraints.
pub(crate) fn bootstrap_std(gr: &Grams, draws: usize, seed: u64) -> DVector<f64> {
    let nb = gr.g.len() / gr.dof;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut sum = DVector::zeros(gr.k);
    let mut sum2 = DVector::zeros(gr.k);
    // whole blocks (all joints) are resampled
    let blocks: Vec<(DMatrix<f64>, DVector<f64>)> = (0..nb)
        .map(|b| {
            let mut g = DMatrix::zeros(gr.k, gr.k);
            let mut c = DVector::zeros(gr.k);
            for j in 0..gr.dof {
                g += &gr.g[b * gr.dof + j];
                c += &gr.c[b * gr.dof + j];
            }
            (g, c)
        })
        .collect();
    // every draw starts from the fit on all the data; the draws' blocks are drawn in turn from
    // the one generator, the draws fitted in parallel (an inertial correction's solve is
    // iterative) and summed in their order
    let start = whole_fit_start(gr);
    let picks: Vec<Vec<usize>> = (0..draws).map(|_| (0..nb).map(|_| rng.random_range(0..nb)).collect()).collect();
    let thetas: Vec<DVector<f64>> = picks
        .par_iter()
        .map(|pick| {
            let mut g = DMatrix::zeros(gr.k, gr.k);
            let mut c = DVector::zeros(gr.k);
            for &b in pick {
                g += &blocks[b].0;
                c += &blocks[b].1;
            }
            gr.solve_from(&g, &c, start.as_ref()).0
        })
        .collect();
    for th in &thetas {
        sum += th;
        sum2 += th.component_mul(th);
    }
    let n = draws as f64;
    (sum2 / n - (&sum / n).component_mul(&(&sum / n))).map(|v| v.max(0.0).sqrt())
}

/// The parameters fitted without the contiguous folds `held(fold)` ([`BLOCKS_PER_FOLD`] blocks
/// each: a fifth of a fit run), under the terms' physical constraints (`|_| false`: all the fit
/// data).
pub(crate) fn theta_without(gr: &Grams, held: &dyn Fn(usize) -> bool) -> DVector<f64> {
    theta_without_from(gr, held, None)
}

/// [`theta_without`] started from an earlier solution's [`Start`].
fn theta_without_from(gr: &Grams, held: &dyn Fn(usize) -> bool, start: Option<&Start>) -> DVector<f64> {
    let (g, c, _) = sum_blocks(gr, |b, _| !held(b / BLOCKS_PER_FOLD));
    gr.solve_from(&g, &c, start).0
}

/// The [`Start`] of the fit on all the data, for the fits of its folds and resamples (`None`
/// without an inertial correction, whose solve needs none).
fn whole_fit_start(gr: &Grams) -> Option<Start> {
    gr.inertial.as_ref()?;
    let (g, c, _) = sum_blocks(gr, |_, _| true);
    gr.solve_from(&g, &c, None).1
}

/// The parameters fitted without each contiguous fold ([`theta_without`]), each started from
/// the fit on all the data.
pub(crate) fn fold_thetas(gr: &Grams) -> Vec<DVector<f64>> {
    let folds = gr.g.len() / gr.dof / BLOCKS_PER_FOLD;
    let start = whole_fit_start(gr);
    (0..folds).map(|f| theta_without_from(gr, &|g| g == f, start.as_ref())).collect()
}

/// The 97.5 % quantile of the standard normal: a two-sided 95 % interval is ±`Z95` σ.
pub(crate) const Z95: f64 = 1.959_963_985;

/// The 97.5 % quantile of Student's t with `nu` degrees of freedom (the half-width of a
/// two-sided 95 % interval in standard errors): the Cornish–Fisher expansion about the normal
/// quantile 1.959964 to order `nu⁻⁴`, within 0.2 % of the exact value for `nu ≥ 3`; `nu = 1, 2`
/// are the exact 12.706 and 4.303.
pub(crate) fn t_quantile_975(nu: usize) -> f64 {
    let z = Z95;
    match nu {
        0 => f64::INFINITY,
        1 => 12.706_204_736,
        2 => 4.302_652_730,
        _ => {
            let n = nu as f64;
            z + (z.powi(3) + z) / (4.0 * n)
                + (5.0 * z.powi(5) + 16.0 * z.powi(3) + 3.0 * z) / (96.0 * n * n)
                + (3.0 * z.powi(7) + 19.0 * z.powi(5) + 17.0 * z.powi(3) - 15.0 * z) / (384.0 * n.powi(3))
                + (79.0 * z.powi(9) + 776.0 * z.powi(7) + 1482.0 * z.powi(5) - 1920.0 * z.powi(3) - 945.0 * z) / (92160.0 * n.powi(4))
        }
    }
}

/// Standard deviations from the delete-one-fold jackknife, scaled so that ±1.96 of them is the
/// 95 % interval: `σ_J² = (G − 1)/G Σ_f (θ₍f₎ − θ̄)²` over the `G` contiguous folds of the fit
/// runs (each a fifth of a run, [`fold_thetas`]), times `(t₀.₉₇₅,G−1 / 1.96)²`.
///
/// Why: the residual left after a fit is not white noise. Smoothing, a friction shape the
/// vocabulary approximates, a Stribeck velocity taken from a grid, an effect left out: these
/// errors depend on the motion and persist over seconds, so the parameters fitted on one part of
/// a run differ from those fitted on another by more than the sample noise says. The
/// delete-a-group jackknife is the cluster-robust (sandwich) variance with whole folds as
/// clusters: it measures how much the estimate moves when a fifth of a run is left out, which
/// holds that motion-dependent error; the 0.2 s block bootstrap ([`bootstrap_std`]) treats such
/// errors as independent from block to block and misses most of them. With `G` folds the
/// variance estimate has `G − 1` degrees of freedom, hence Student's quantile.
pub(crate) fn jackknife_std(gr: &Grams) -> DVector<f64> {
    let thetas = fold_thetas(gr);
    let g = thetas.len();
    if g < 2 {
        return DVector::from_element(gr.k, f64::NAN);
    }
    let mean = thetas.iter().fold(DVector::zeros(gr.k), |a, t| a + t) / g as f64;
    let ss = thetas.iter().fold(DVector::zeros(gr.k), |a: DVector<f64>, t| a + (t - &mean).component_mul(&(t - &mean)));
    let scale = t_quantile_975(g - 1) / Z95;
    (ss * ((g as f64 - 1.0) / g as f64)).map(|v| v.max(0.0).sqrt() * scale)
}

/// The larger, per parameter, of the delete-one-fold jackknife ([`jackknife_std`]) and the block
/// bootstrap `boot`: the resampling spread, without the pipeline's shared error (see
/// [`crate::select::uncertainty`]).
pub(crate) fn resampling_std(gr: &Grams, boot: &DVector<f64>) -> DVector<f64> {
    larger_spread(boot, &jackknife_std(gr))
}

/// Per parameter, the larger of the block bootstrap's `boot` and the jackknife's `jack` (the
/// bootstrap's where the jackknife has none).
pub(crate) fn larger_spread(boot: &DVector<f64>, jack: &DVector<f64>) -> DVector<f64> {
    DVector::from_fn(boot.len(), |i, _| if jack[i].is_finite() { jack[i].max(boot[i]) } else { boot[i] })
}
