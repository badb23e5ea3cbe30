//! Which effect: candidate families, screening, forward stepwise selection validated by
//! cross-validation across runs and time blocks, backward pruning.
//!
//! A term enters when it lowers the cross-validated residual by at least
//! [`SelectOptions::min_relative_gain`] of the current value and
//! [`SelectOptions::min_nominal_gain`] of the nominal one, and when the torque it explains is
//! at least [`SelectOptions::min_torque_share`] of the commanded torque (RMS) on its joint:
//! effects too small to matter are reported, not selected.

pub(crate) mod alternatives;
pub(crate) mod plausible;
pub(crate) mod prediction;
pub(crate) mod refine;
pub(crate) mod scorer;
pub(crate) mod screen;
pub(crate) mod shooting;
mod stepwise;
pub(crate) mod uncertainty;

use nalgebra::{DMatrix, DVector};
use simgap_core::PARAMS_PER_LINK;

pub use crate::options::SelectOptions;
use crate::prepare::dataset::FitData;
use crate::prepare::width::DryWidth;
use std::sync::Arc;

use crate::lsq::inertial::InertialPrior;
use crate::lsq::{block_squares, fit, grams, grams_against_known, Fit, Grams, Problem};
use crate::vocabulary::{contract_parameters, fit_designs};
use crate::vocabulary::{design, largest_command, n_params, payload_basis_rows, payload_mass_bound, physical, point_mass_parameters, Column, Slot, Term, TermDesign};

/// Widths a Coulomb friction's grid tries on a joint (then refined within its range).
const DRY_WIDTH_GRID: usize = 8;

/// Widths a Stribeck friction's grid tries with each Stribeck velocity (one: the top of the
/// joint's range; its hump below vs shapes the sign near rest).
const STRIBECK_WIDTH_GRID: usize = 1;

/// A family of terms sharing an effect and a joint; nonlinear parameters are searched on a grid.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Family {
    /// A fixed term.
    Fixed(Term),
    /// Coulomb friction, its width `w` searched within the joint's [`DryWidth`].
    Coulomb(usize),
    /// Stribeck velocity searched, and its width `w` within the joint's [`DryWidth`].
    Stribeck(usize),
    /// Load-dependent friction, its width `w` searched like Coulomb friction's.
    LoadFriction(usize),
    /// Saturation limit searched.
    Saturation(usize),
    /// Cogging periods searched.
    Cogging(usize),
    /// Delay searched.
    Delay,
    /// Payload centre of mass re-linearised.
    Payload,
}

impl Family {
    /// A member of the family: every member occupies the same slot (see [`Term::slot`]).
    fn member(&self) -> Term {
        match *self {
            Family::Fixed(ref t) => t.clone(),
            Family::Coulomb(joint) => Term::Coulomb { joint, w: 1.0 },
            Family::Stribeck(joint) => Term::Stribeck { joint, vs: 1.0, w: 1.0 },
            Family::LoadFriction(joint) => Term::LoadFriction { joint, w: 1.0 },
            Family::Saturation(joint) => Term::Saturation { joint, limit: 1.0 },
            Family::Cogging(joint) => Term::Cogging { joint, periods: 1.0 },
            Family::Delay => Term::Delay { delay: 0.0 },
            Family::Payload => Term::Payload { com: [0.0; 3], max_mass: f64::INFINITY },
        }
    }
}

/// All candidate families for the fit runs `data` (back-EMF only on joints whose drive some
/// run disables: elsewhere it is viscous friction; a torque saturation only where no fit run was
/// low-pass filtered by its recorder; a rotor inertia only where the effort was not measured on
/// the link side of the gearbox).
pub(crate) fn families(data: &[FitData]) -> Vec<Family> {
    let dof = data.first().map_or(0, |d| d.dof);
    // a recorder's low-pass filter flattens the torque's peaks as a limit would: on such logs a
    // torque saturation cannot be told from it (`prepare::lowpass`)
    let saturation = !crate::prepare::lowpass::any_filtered(data);
    let rotor = crate::vocabulary::rotor::visible(data);
    let mut f = Vec::new();
    for j in 0..dof {
        f.push(Family::Fixed(Term::Viscous(j)));
        f.push(Family::Coulomb(j));
        f.push(Family::Stribeck(j));
        f.push(Family::LoadFriction(j));
        if crate::vocabulary::back_emf::separable(j, data) {
            f.push(Family::Fixed(Term::BackEmf(j)));
        }
        if rotor {
            f.push(Family::Fixed(Term::Armature(j)));
        }
        f.push(Family::Fixed(Term::Gain(j)));
        f.push(Family::Fixed(Term::Offset(j)));
        if saturation {
            f.push(Family::Saturation(j));
        }
        f.push(Family::Cogging(j));
        f.push(Family::Fixed(Term::Spring(j)));
    }
    f.push(Family::Delay);
    f.push(Family::Fixed(Term::CoriolisStructure));
    f.push(Family::Payload);
    f
}

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
    payload: std::sync::OnceLock<PayloadBasis>,
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

/// What every payload search shares: the last link's ten regressor columns (a payload at `c` is
/// their combination by [`point_mass_parameters`]), row-major and as free columns, and the
/// largest commanded torque.
struct PayloadBasis {
    /// Per row, the basis entries that are not zero in every row (a planar motion leaves
    /// most of them zero), row-major, rows by decreasing Euclidean norm.
    rows: Vec<f64>,
    /// The norm of each of those rows.
    norms: Vec<f64>,
    /// Which of the ten parameters those entries belong to.
    nonzero: Vec<usize>,
    design: TermDesign,
    tau_max: f64,
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
    fn max_command(&self, j: usize) -> f64 {
        self.data.iter().flat_map(|d| d.raw.tau.iter().skip(j).step_by(d.dof)).fold(0.0f64, |m, v| m.max(v.abs()))
    }

    fn grid(&self, family: &Family) -> Vec<Term> {
        match *family {
            Family::Fixed(ref t) => vec![t.clone()],
            Family::Coulomb(j) => self.dry_width[j].grid(DRY_WIDTH_GRID).into_iter().map(|w| Term::Coulomb { joint: j, w }).collect(),
            Family::LoadFriction(j) => self.dry_width[j].grid(DRY_WIDTH_GRID).into_iter().map(|w| Term::LoadFriction { joint: j, w }).collect(),
            Family::Stribeck(j) => {
                let widths = self.dry_width[j].grid(STRIBECK_WIDTH_GRID);
                let terms = (0..12).flat_map(|i| widths.iter().map(move |&w| Term::Stribeck { joint: j, vs: 0.01 * 1.6f64.powi(i), w }));
                terms.filter(|t| matches!(*t, Term::Stribeck { vs, w, .. } if crate::vocabulary::stribeck_resolvable(vs, w))).collect()
            }
            Family::Saturation(j) => {
                let max = self.max_command(j);
                let floor = self.saturation_floor[j];
                (1..=24)
                    .map(|i| Term::Saturation { joint: j, limit: max * (0.2 + 0.8 * (1.0 - (i as f64 / 25.0))) })
                    .filter(|t| matches!(t, Term::Saturation { limit, .. } if *limit >= floor))
                    .collect()
            }
            Family::Cogging(j) => (3..=64).map(|n| Term::Cogging { joint: j, periods: n as f64 }).collect(),
            Family::Delay => {
                let t = self.sample_period;
                [0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0, 24.0, 32.0].iter().map(|m| Term::Delay { delay: m * t }).collect()
            }
            Family::Payload => vec![Term::Payload { com: [0.0; 3], max_mass: self.max_payload() }],
        }
    }

    fn refine(&self, best: &Term, resid: &Column) -> Term {
        match *best {
            Term::Saturation { joint, limit } => {
                // coarse (±20 % in 2 % steps), then fine (±2 % in 0.2 % steps)
                // (only limits the data allow; the current one is among them)
                let allowed = |t: &Term| *t == *best || self.saturation_plausible(t, resid);
                let coarse: Vec<Term> = (-10..=10).map(|i| Term::Saturation { joint, limit: limit * (1.0 + 0.02 * i as f64) }).filter(allowed).collect();
                let Term::Saturation { limit, .. } = screen_best(self, &coarse, resid).0 else { unreachable!() };
                let at = Term::Saturation { joint, limit };
                let allowed = |t: &Term| *t == at || self.saturation_plausible(t, resid);
                let fine: Vec<Term> = (-10..=10).map(|i| Term::Saturation { joint, limit: limit * (1.0 + 0.002 * i as f64) }).filter(allowed).collect();
                screen_best(self, &fine, resid).0
            }
            Term::Delay { delay } => {
                let cands: Vec<Term> = (-8..=8).map(|i| Term::Delay { delay: (delay * (1.0 + 0.05 * i as f64)).max(1e-6) }).collect();
                screen_best(self, &cands, resid).0
            }
            Term::Coulomb { joint, w } => {
                // ±60 % in 10 % steps, within the range the data allow
                let range = self.dry_width[joint];
                let mut cands: Vec<Term> = (-5..=5).map(|i| Term::Coulomb { joint, w: range.clamp(w * 1.1f64.powi(i)) }).collect();
                cands.dedup();
                screen_best(self, &cands, resid).0
            }
            Term::Stribeck { joint, vs, w } => {
                let near = (-5..=5).map(|i| vs * 1.1f64.powi(i));
                let cands: Vec<Term> = near.filter(|&v| v == vs || crate::vocabulary::stribeck_resolvable(v, w)).map(|vs| Term::Stribeck { joint, vs, w }).collect();
                screen_best(self, &cands, resid).0
            }
            Term::LoadFriction { joint, w } => {
                let range = self.dry_width[joint];
                let mut cands: Vec<Term> = (-5..=5).map(|i| Term::LoadFriction { joint, w: range.clamp(w * 1.1f64.powi(i)) }).collect();
                cands.dedup();
                screen_best(self, &cands, resid).0
            }
            Term::Payload { .. } => self.payload_search(resid, &[]),
            ref other => other.clone(),
        }
    }

    /// The best member of a family against the current residual.
    pub(crate) fn best_of(&self, family: &Family, resid: &Column) -> Term {
        let mut cands = self.grid(family);
        if let Family::Saturation(j) = *family {
            // limits the logs contradict are not candidates; with none left, a limit that
            // clamps nothing
            cands.retain(|t| self.saturation_plausible(t, resid));
            if cands.is_empty() {
                return Term::Saturation { joint: j, limit: self.max_command(j).max(self.saturation_floor[j]) };
            }
        }
        let (best, _) = screen_best(self, &cands, resid);
        self.refine(&best, resid)
    }

    /// [`Context::best_of`]; the payload's centre of mass is searched jointly with the other
    /// selected terms `rest` (so they cannot absorb part of it first).
    pub(crate) fn best_of_with(&self, family: &Family, resid: &Column, rest: &[TermDesign]) -> Term {
        match family {
            Family::Payload => self.payload_search(resid, rest),
            _ => self.best_of(family, resid),
        }
    }

    /// The payload's centre of mass: a linear first guess (mass and first moment of the last
    /// link), then Nelder–Mead on the cross-validation-free fit residual of `rest` + payload.
    fn payload_search(&self, resid: &Column, rest: &[TermDesign]) -> Term {
        let p = &self.problem;
        let (th, _) = screen_fit(p, &crate::vocabulary::payload_linear_design(self.data), resid);
        let c0 = if th.len() == 4 && th[0].abs() > 1e-9 { [th[1] / th[0], th[2] / th[0], th[3] / th[0]] } else { [0.0; 3] };
        // the centre of mass stays within reach of the last link
        let reach = self.prior.reach.last().copied().unwrap_or(f64::INFINITY);
        let within = |c: &[f64; 3]| -> [f64; 3] {
            let n = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
            if n > reach {
                c.map(|x| x * reach / n)
            } else {
                *c
            }
        };
        let c0 = within(&c0.map(|x| if x.is_finite() { x } else { 0.0 }));
        // more starts: the last link's first moment is identified better than its mass, whose
        // linear estimate can even come out negative and send h/m to the opposite side of the
        // link; its direction at a quarter, half and the whole of the reach, and the link's origin
        let mut starts = Vec::new();
        if th.len() == 4 {
            let h = [th[1], th[2], th[3]];
            let norm = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
            let r = if reach.is_finite() && reach > 0.0 { reach } else { 0.2 };
            if norm > 0.0 && norm.is_finite() {
                starts.extend([0.25, 0.5, 1.0].map(|f| within(&h.map(|x| x / norm * f * r))));
            }
        }
        starts.push([0.0; 3]);
        let max_mass = self.max_payload();
        // the Grams of `rest` and of the ten basis columns, once: the payload's inner products
        // are then linear and quadratic forms in π(c) (equal to the column's own up to rounding)
        let basis = self.payload.get_or_init(|| {
            let rows = payload_basis_rows(self.data);
            let cols: Vec<Column> = (0..PARAMS_PER_LINK).map(|i| Column::new(None, rows.iter().skip(i).step_by(PARAMS_PER_LINK).copied().collect())).collect();
            let nonzero: Vec<usize> = (0..PARAMS_PER_LINK).filter(|&i| cols[i].values.iter().any(|v| *v != 0.0)).collect();
            let mut compact: Vec<(f64, Vec<f64>)> = rows
                .chunks_exact(PARAMS_PER_LINK)
                .map(|r| {
                    let v: Vec<f64> = nonzero.iter().map(|&i| r[i]).collect();
                    (v.iter().map(|x| x * x).sum::<f64>().sqrt(), v)
                })
                .collect();
            compact.sort_by(|a, b| b.0.total_cmp(&a.0));
            let norms = compact.iter().map(|r| r.0).collect();
            let rows = compact.into_iter().flat_map(|r| r.1).collect();
            PayloadBasis { rows, norms, nonzero, design: TermDesign::free(cols), tau_max: largest_command(self.data) }
        });
        let mut refs: Vec<&TermDesign> = rest.iter().collect();
        refs.push(&basis.design);
        let full = grams(p, &refs);
        let k = full.k - PARAMS_PER_LINK;
        let (mut g_full, mut c_full, mut s) = (DMatrix::zeros(full.k, full.k), DVector::zeros(full.k), 0.0);
        for b in 0..full.g.len() {
            g_full += &full.g[b];
            c_full += &full.c[b];
            s += full.s[b];
        }
        let (mut lo, mut hi) = (full.lo[..k].to_vec(), full.hi[..k].to_vec());
        lo.push(0.0);
        hi.push(f64::INFINITY);
        let mut solver = Grams { k: k + 1, g: Vec::new(), c: Vec::new(), s: Vec::new(), dof: p.dof, lo, hi, inertial: full.inertial.clone() };
        let mut g = DMatrix::zeros(k + 1, k + 1);
        g.view_mut((0, 0), (k, k)).copy_from(&g_full.view((0, 0), (k, k)));
        let mut c = DVector::zeros(k + 1);
        c.rows_mut(0, k).copy_from(&c_full.rows(0, k));
        let mut sse = |com: &[f64; 3]| -> f64 {
            let pi = point_mass_parameters(within(com));
            // the mass bound from the column's largest entry, as the payload's design states it
            // (the entries left out are zero: the same sums); |row·π| <= ‖row‖ ‖π‖, so once
            // that bound falls below the largest entry found, no later row can exceed it
            let pi_nz: Vec<f64> = basis.nonzero.iter().map(|&i| pi[i]).collect();
            let pi_norm = pi_nz.iter().map(|x| x * x).sum::<f64>().sqrt();
            let mut col_max = 0.0f64;
            if !pi_nz.is_empty() {
                for (row, norm) in basis.rows.chunks_exact(pi_nz.len()).zip(&basis.norms) {
                    if norm * pi_norm * (1.0 + 1e-9) < col_max {
                        break;
                    }
                    col_max = col_max.max(row.iter().zip(&pi_nz).map(|(a, b)| a * b).sum::<f64>().abs());
                }
            }
            solver.hi[k] = payload_mass_bound(col_max, basis.tau_max, max_mass);
            // the payload column's inner products: Y π against the rest, itself and the residual
            for a in 0..k {
                let v: f64 = (0..PARAMS_PER_LINK).map(|i| pi[i] * g_full[(a, k + i)]).sum();
                g[(a, k)] = v;
                g[(k, a)] = v;
            }
            g[(k, k)] = (0..PARAMS_PER_LINK).map(|i| pi[i] * (0..PARAMS_PER_LINK).map(|l| pi[l] * g_full[(k + i, k + l)]).sum::<f64>()).sum();
            c[k] = (0..PARAMS_PER_LINK).map(|i| pi[i] * c_full[k + i]).sum();
            let t = solver.solve(&g, &c);
            s - 2.0 * t.dot(&c) + t.dot(&(&g * &t))
        };
        // the best of the searches from h/m and from every other start
        let mut search = |start: [f64; 3]| {
            let com = within(&nelder_mead(&mut sse, start, 0.02, 60));
            (com, sse(&com))
        };
        let mut best = search(c0);
        for start in starts {
            let found = search(start);
            if found.1 < best.1 {
                best = found;
            }
        }
        Term::Payload { com: best.0, max_mass }
    }

    /// The largest plausible payload [kg]: twice the mass of the chain's links in the URDF.
    fn max_payload(&self) -> f64 {
        let total: f64 = self.prior.nominal.iter().step_by(simgap_core::PARAMS_PER_LINK).sum();
        if total > 0.0 {
            2.0 * total
        } else {
            f64::INFINITY
        }
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

    fn design_shared(&self, t: &Term) -> std::sync::Arc<TermDesign> {
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

/// Minimises `f` over 3-vectors by Nelder–Mead from `x0` with initial step `step`.
fn nelder_mead(mut f: impl FnMut(&[f64; 3]) -> f64, x0: [f64; 3], step: f64, iters: usize) -> [f64; 3] {
    let mut pts: Vec<([f64; 3], f64)> = (0..4)
        .map(|i| {
            let mut x = x0;
            if i > 0 {
                x[i - 1] += step;
            }
            (x, f(&x))
        })
        .collect();
    for _ in 0..iters {
        pts.sort_by(|a, b| a.1.total_cmp(&b.1));
        let mut centroid = [0.0; 3];
        for p in &pts[..3] {
            for k in 0..3 {
                centroid[k] += p.0[k] / 3.0;
            }
        }
        let along = |t: f64| -> [f64; 3] { std::array::from_fn(|k| centroid[k] + t * (pts[3].0[k] - centroid[k])) };
        let xr = along(-1.0);
        let fr = f(&xr);
        if fr < pts[0].1 {
            let xe = along(-2.0);
            let fe = f(&xe);
            pts[3] = if fe < fr { (xe, fe) } else { (xr, fr) };
        } else if fr < pts[2].1 {
            pts[3] = (xr, fr);
        } else {
            let xc = along(0.5);
            let fc = f(&xc);
            if fc < pts[3].1 {
                pts[3] = (xc, fc);
            } else {
                let best = pts[0].0;
                for p in pts.iter_mut().skip(1) {
                    p.0 = std::array::from_fn(|k| best[k] + 0.5 * (p.0[k] - best[k]));
                    p.1 = f(&p.0);
                }
            }
        }
    }
    pts.sort_by(|a, b| a.1.total_cmp(&b.1));
    pts[0].0
}

/// Directions of the stacked inertial parameters the fit data excites (eigenvectors of the
/// weighted regressor Gram with eigenvalue above 1e-8 of the largest).
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

/// Least-squares fit of one design against a residual column: (θ, weighted SSE).
fn screen_fit(p: &Problem, d: &TermDesign, resid: &Column) -> (DVector<f64>, f64) {
    screen_fit_known(p, d, resid, None)
}

/// [`screen_fit`] with `resid·resid` per block known (see [`grams_against_known`]).
fn screen_fit_known(p: &Problem, d: &TermDesign, resid: &Column, resid_squares: Option<&[f64]>) -> (DVector<f64>, f64) {
    let gr = grams_against_known(p, resid, &[d], resid_squares);
    let (mut g, mut c, mut s) = (DMatrix::zeros(gr.k, gr.k), DVector::zeros(gr.k), 0.0);
    for b in 0..gr.g.len() {
        g += &gr.g[b];
        c += &gr.c[b];
        s += gr.s[b];
    }
    let th = gr.solve(&g, &c);
    let sse = s - 2.0 * th.dot(&c) + th.dot(&(&g * &th));
    (th, sse)
}

fn screen_best(ctx: &Context<'_>, cands: &[Term], resid: &Column) -> (Term, f64) {
    let p = &ctx.problem;
    let mut best = (cands[0].clone(), f64::INFINITY);
    // resid·resid once for the members without a fixed offset
    let mut squares: Option<Vec<f64>> = None;
    for t in cands {
        let d = ctx.design_shared(t);
        if d.offset.is_none() && squares.is_none() {
            squares = Some(block_squares(p, resid));
        }
        let (th, sse) = screen_fit_known(p, &d, resid, squares.as_deref());
        // a Stribeck member without a static level above the Coulomb level is Coulomb friction
        if matches!(t, Term::Stribeck { .. }) && !(th[1] > 0.0) {
            continue;
        }
        if sse < best.1 {
            best = (t.clone(), sse);
        }
    }
    best
}

/// The residual left by a fitted set of terms, as a global column.
pub(crate) fn residual_after(p: &Problem, designs: &[TermDesign], theta: &DVector<f64>) -> Column {
    let dof = p.dof;
    let mut r = p.y.clone();
    let values = Arc::make_mut(&mut r.values);
    let mut c = 0;
    for d in designs {
        if let Some(off) = &d.offset {
            for s in 0..p.samples {
                for j in 0..dof {
                    values[s * dof + j] -= off.at(s, j, dof);
                }
            }
        }
        for col in &d.cols {
            let th = theta[c];
            c += 1;
            for s in 0..p.samples {
                for j in 0..dof {
                    values[s * dof + j] -= th * col.at(s, j, dof);
                }
            }
        }
    }
    r
}

/// RMS torque a fitted term explains on each joint.
pub(crate) fn term_torque_rms(p: &Problem, d: &TermDesign, theta: &[f64]) -> Vec<f64> {
    let dof = p.dof;
    let mut acc = vec![0.0; dof];
    for s in 0..p.samples {
        for (j, a) in acc.iter_mut().enumerate() {
            let mut v = d.offset.as_ref().map_or(0.0, |o| o.at(s, j, dof));
            for (col, th) in d.cols.iter().zip(theta) {
                v += th * col.at(s, j, dof);
            }
            *a += v * v;
        }
    }
    acc.iter().map(|a| (a / p.samples.max(1) as f64).sqrt()).collect()
}

/// One step of the selection log.
#[derive(Clone, Debug)]
pub(crate) struct Step {
    /// The term considered.
    pub term: Term,
    /// Cross-validated MSE with it (weighted).
    pub cv_mse: f64,
    /// Whether it entered.
    pub accepted: bool,
    /// Why (not).
    pub reason: String,
}

/// Outcome of the selection.
#[derive(Clone, Debug)]
pub(crate) struct Selection {
    /// Selected terms.
    pub terms: Vec<Term>,
    /// Their joint fit.
    pub fit: Fit,
    /// Designs of the selected terms.
    pub designs: Vec<TermDesign>,
    /// Cross-validated MSE of the nominal model.
    pub nominal_cv_mse: f64,
    /// The log of decisions.
    pub log: Vec<Step>,
}

/// Whether `t` may join `terms`: one term per slot, and no torque gain together with an
/// inertial error (a gain on every joint and scaled inertial parameters are the same robot, so
/// together they admit the trivial fit k = 0, π = 0).
pub(crate) fn slot_taken(terms: &[Term], t: &Term) -> bool {
    let gain_vs_inertia = |a: &Term, b: &Term| matches!(a, Term::Gain(_)) && matches!(b, Term::InertialError { .. });
    terms.iter().any(|s| s.shares_slot(t) || gain_vs_inertia(s, t) || gain_vs_inertia(t, s))
}

/// Whether a fitted parameter of a term sits at a plausibility bound other than zero (a payload
/// at its largest mass, a torque gain at an end of [`GAIN_RANGE`], a corrected link's mass at a
/// factor [`crate::lsq::inertial::MASS_FACTOR`] of the URDF's): the data pull further than the
/// effect can go, so the term stands in for something else and is not an answer. A parameter
/// at zero (no friction) is an absent effect, not a stand-in.
pub(crate) fn at_plausibility_bound(d: &TermDesign, theta: &[f64]) -> bool {
    if let Some(prior) = &d.inertial {
        return prior.at_mass_bound(theta);
    }
    let tol = |b: f64| 1e-6 * b.abs().max(1e-9);
    theta.iter().enumerate().any(|(k, &x)| {
        let (lo, hi) = (d.lo.get(k).copied().unwrap_or(f64::NEG_INFINITY), d.hi.get(k).copied().unwrap_or(f64::INFINITY));
        (hi.is_finite() && hi != 0.0 && x >= hi - tol(hi)) || (lo.is_finite() && lo != 0.0 && x <= lo + tol(lo))
    })
}

/// Whether every term of a set (its designs and joint parameters, as [`Context::fit_terms`] gives them)
/// is physical and none stands at a plausibility bound.
pub(crate) fn admissible(designs: &[TermDesign], terms: &[Term], theta: &DVector<f64>) -> bool {
    let mut c = 0;
    for (t, d) in terms.iter().zip(designs) {
        let k = d.cols.len();
        let th = &theta.as_slice()[c..c + k];
        if !physical(t, &contract_parameters(t, th)) || at_plausibility_bound(d, th) {
            return false;
        }
        c += k;
    }
    true
}

/// The cross-validated figure a term is judged on: its joint's for a per-joint term, the
/// whole robot's otherwise.
fn cv_of(f: &Fit, t: &Term) -> f64 {
    match t.joint() {
        Some(j) => f.cv_joint[j],
        None => f.cv_mse,
    }
}

pub(crate) use stepwise::{repolish, select};
