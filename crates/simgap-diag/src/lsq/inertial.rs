//! Physically consistent inertial corrections: link inertias fitted in the log-Cholesky
//! parameterisation of the pseudo-inertia, regularised toward the URDF, the centre of mass kept
//! within reach of the link.
//!
//! A link's ten inertial parameters π = (m, h, Ī) (mass, first moment `h = m c`, rotational
//! inertia about the joint frame's origin) are physically consistent exactly when its
//! pseudo-inertia
//!
//! ```text
//! J = [ Σ   h ]      Σ = ½ tr(Ī) 1 − Ī   (second moment of the mass about the origin)
//!     [ hᵀ  m ]
//! ```
//!
//! is positive definite (Wensing, Kim & Slotine, "Linear matrix inequalities for physically
//! consistent inertial parameter identification", IEEE RA-L 2017). The log-Cholesky
//! parameterisation (Rucker & Wensing, "Smooth parameterization of rigid-body inertia", IEEE
//! RA-L 2022) writes `J = U Uᵀ` with
//!
//! ```text
//! U = e^α [ e^d1  s12   s13   t1 ]
//!         [ 0     e^d2  s23   t2 ]
//!         [ 0     0     e^d3  t3 ]
//!         [ 0     0     0     1  ]
//! ```
//!
//! so that every φ = (α, d1, d2, d3, s12, s23, s13, t1, t2, t3) ∈ ℝ¹⁰ gives a physical body
//! (mass `e^{2α}` > 0, `J` positive definite) and every physical body has one φ. The centre of
//! mass is `t` itself, so keeping it within reach is a ball constraint on `t`.
//!
//! The torque residual is linear in the corrections Δπ = π(φ) − π_URDF (columns of the
//! regressor), so the weighted least-squares objective is the quadratic
//! `½ θᵀ G θ − cᵀ θ` of [`crate::lsq`] over the scaled corrections θ = D⁻¹ Δπ, plus the prior
//! `½ μ ‖θ‖²` toward the URDF. It is minimised by Levenberg–Marquardt on φ (together with the
//! other terms' linear, bounded parameters): the problem is convex in π over a convex set, so
//! the smooth map φ ↦ π has no spurious minimum.
//!
//! **Reach** (documented rule): the centre of mass of link i stays in the ball about its joint
//! origin of radius ρᵢ = 1.25 · max(|p_{i+1}|, |cᵢ|, 0.1 L) for a link with a child joint at
//! `p_{i+1}`, and ρ = max(1.5 · max(|c|, r_g, 0.1 L), 1.25 · ℓ) for the last link (no child
//! joint: its extent is judged from its URDF centre of mass `c`, its radius of gyration
//! `r_g = √(tr I_c / 2m)`, and ℓ, the longest joint-to-joint distance of the chain: a forearm or a
//! tool flange may be as long as the links before it, and a tool sits at its far end), with L the
//! length of the chain (joint-to-joint distances plus the last link's |c|). A payload's centre of
//! mass obeys the last link's ball.
//!
//! **Plausibility bounds**: a corrected link's mass stays within a factor [`MASS_FACTOR`] of the
//! URDF's, and the diagonal of the Cholesky factor of its second moment about the centre of mass
//! (per unit mass) at least [`MIN_RADIUS`]. A correction at one of these bounds says the data pull
//! further than a correction of this URDF can go.

use nalgebra::{DMatrix, DVector, Matrix3, Matrix4, Vector3};
use simgap_core::{inertia_from_parameters, inertial_parameters, Model, SpatialInertia, PARAMS_PER_LINK};

/// Prior of the inertial correction: the URDF parameters, their scales, the reach of every link,
/// the prior weight.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct InertialPrior {
    /// Stacked URDF inertial parameters, `10 · dof` (see [`simgap_core::inertial_parameters`]).
    pub nominal: Vec<f64>,
    /// Nominal magnitude of each stacked parameter (the unit of the fitted corrections).
    pub scales: Vec<f64>,
    /// Radius of the ball, about each link's joint origin, its centre of mass stays in [m].
    pub reach: Vec<f64>,
    /// Axis of each joint in its link frame (for the report).
    pub axes: Vec<[f64; 3]>,
    /// Weight of the prior relative to the mean diagonal of the data Gram (see [`solve`]).
    pub weight: f64,
    /// Number of directions of the stacked parameters the fit data excite (for the report).
    pub identifiable: usize,
}

/// A corrected link's mass stays within this factor of the URDF's (a URDF further off is a wrong
/// model, not one to correct).
pub(crate) const MASS_FACTOR: f64 = 3.0;

/// Smallest principal radius of a corrected link's mass about its centre of mass [m] (strictly
/// physical: a positive-definite pseudo-inertia, reached in finitely many steps).
pub(crate) const MIN_RADIUS: f64 = 1e-3;

/// Iterations of Levenberg–Marquardt at most.
const MAX_ITERATIONS: usize = 40;

/// Default weight of the prior: the correction along a direction the data excite less than
/// 1e-3 of an average parameter stays near the URDF.
pub(crate) const DEFAULT_PRIOR_WEIGHT: f64 = 1e-3;

impl std::ops::Deref for InertialPrior {
    type Target = [f64];
    /// The scales (what [`crate::select::parameter_scales`] returned before the prior existed).
    fn deref(&self) -> &[f64] {
        &self.scales
    }
}

impl InertialPrior {
    /// The prior of `model`'s links (scales as in [`crate::select::parameter_scales`]).
    pub(crate) fn new(model: &Model) -> InertialPrior {
        let n = model.dof();
        let joints = model.joints();
        let avg = model.total_mass() / n.max(1) as f64;
        let l = 0.1;
        let scales: Vec<f64> = joints
            .iter()
            .flat_map(|j| {
                let m = j.inertia.mass.max(0.01 * avg).max(1e-6);
                [m, m * l, m * l, m * l, m * l * l, m * l * l, m * l * l, m * l * l, m * l * l, m * l * l]
            })
            .collect();
        let nominal: Vec<f64> = joints.iter().flat_map(|j| inertial_parameters(&j.inertia)).collect();
        let reach = link_reach(model);
        let axes = joints.iter().map(|j| [j.axis.x, j.axis.y, j.axis.z]).collect();
        InertialPrior { nominal, scales, reach, axes, weight: DEFAULT_PRIOR_WEIGHT, identifiable: 0 }
    }

    /// Number of links.
    pub(crate) fn links(&self) -> usize {
        self.reach.len()
    }

    /// The corrected parameters of link `i` for scaled corrections `theta` (all links).
    pub(crate) fn corrected(&self, theta: &[f64], i: usize) -> [f64; PARAMS_PER_LINK] {
        std::array::from_fn(|k| {
            let a = PARAMS_PER_LINK * i + k;
            self.nominal[a] + self.scales[a] * theta.get(a).copied().unwrap_or(0.0)
        })
    }

    /// Whether a corrected link's mass sits at a [`MASS_FACTOR`] bound (within 0.1 %): the
    /// data pull further than a correction of this URDF can go.
    pub(crate) fn at_mass_bound(&self, theta: &[f64]) -> bool {
        (0..self.links()).any(|i| {
            let m0 = self.nominal[i * PARAMS_PER_LINK];
            let ratio = self.corrected(theta, i)[0] / m0;
            m0 > 0.0 && (ratio <= 1.001 / MASS_FACTOR || ratio >= 0.999 * MASS_FACTOR)
        })
    }

    /// Whether the corrected links are physical: mass > 0, pseudo-inertia positive definite,
    /// centre of mass within reach (a relative tolerance of 1e-6 on each).
    pub(crate) fn is_physical(&self, theta: &[f64]) -> bool {
        (0..self.links()).all(|i| {
            let p = self.corrected(theta, i);
            link_is_physical(&p, self.reach[i] * (1.0 + 1e-6) + 1e-9)
        })
    }
}

/// Whether ten inertial parameters are a physical body whose centre of mass lies within `reach`
/// of the origin: mass > 0 and a positive (semi-)definite pseudo-inertia (eigenvalues above
/// −1e-9 of its scale).
pub(crate) fn link_is_physical(p: &[f64; PARAMS_PER_LINK], reach: f64) -> bool {
    if p.iter().any(|v| !v.is_finite()) || p[0] <= 0.0 {
        return false;
    }
    let j = pseudo_inertia(p);
    let eig = j.symmetric_eigen();
    let scale = j.diagonal().iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-300);
    let c = Vector3::new(p[1], p[2], p[3]) / p[0];
    eig.eigenvalues.iter().all(|&l| l > -1e-9 * scale) && c.norm() <= reach
}

/// The pseudo-inertia `[[Σ, h], [hᵀ, m]]` of ten inertial parameters.
pub(crate) fn pseudo_inertia(p: &[f64; PARAMS_PER_LINK]) -> Matrix4<f64> {
    let s = inertia_from_parameters(p);
    let sigma = Matrix3::from_diagonal_element(0.5 * s.rotational.trace()) - s.rotational;
    let h = s.first_moment;
    let mut j = Matrix4::zeros();
    j.fixed_view_mut::<3, 3>(0, 0).copy_from(&sigma);
    j.fixed_view_mut::<3, 1>(0, 3).copy_from(&h);
    j.fixed_view_mut::<1, 3>(3, 0).copy_from(&h.transpose());
    j[(3, 3)] = s.mass;
    j
}

/// The ten inertial parameters of a pseudo-inertia (the inverse of [`pseudo_inertia`]; linear).
pub(crate) fn parameters_of_pseudo_inertia(j: &Matrix4<f64>) -> [f64; PARAMS_PER_LINK] {
    let sigma = j.fixed_view::<3, 3>(0, 0).into_owned();
    let ibar = Matrix3::from_diagonal_element(sigma.trace()) - sigma;
    inertial_parameters(&SpatialInertia { mass: j[(3, 3)], first_moment: Vector3::new(j[(0, 3)], j[(1, 3)], j[(2, 3)]), rotational: ibar })
}

/// `U(φ)` of the log-Cholesky parameterisation, φ = (α, d1, d2, d3, s12, s23, s13, t1, t2, t3).
fn u_of(phi: &[f64]) -> Matrix4<f64> {
    let e = phi[0].exp();
    e * Matrix4::new(phi[1].exp(), phi[4], phi[6], phi[7], 0.0, phi[2].exp(), phi[5], phi[8], 0.0, 0.0, phi[3].exp(), phi[9], 0.0, 0.0, 0.0, 1.0)
}

/// The ten inertial parameters of log-Cholesky parameters φ (always physical).
pub(crate) fn parameters_of_log_cholesky(phi: &[f64]) -> [f64; PARAMS_PER_LINK] {
    let u = u_of(phi);
    parameters_of_pseudo_inertia(&(u * u.transpose()))
}

/// `∂π/∂φ` (10 × 10, column k = derivative along φ_k).
pub(crate) fn jacobian_log_cholesky(phi: &[f64]) -> nalgebra::SMatrix<f64, 10, 10> {
    let u = u_of(phi);
    let e = phi[0].exp();
    let mut out = nalgebra::SMatrix::<f64, 10, 10>::zeros();
    for k in 0..10 {
        let mut du = Matrix4::zeros();
        match k {
            0 => du = u,
            1..=3 => du[(k - 1, k - 1)] = e * phi[k].exp(),
            4 => du[(0, 1)] = e,
            5 => du[(1, 2)] = e,
            6 => du[(0, 2)] = e,
            _ => du[(k - 7, 3)] = e,
        }
        let dj = du * u.transpose() + u * du.transpose();
        let dp = parameters_of_pseudo_inertia(&dj);
        for (r, v) in dp.iter().enumerate() {
            out[(r, k)] = *v;
        }
    }
    out
}

/// Log-Cholesky parameters of a body given by ten inertial parameters. A body that is not
/// strictly physical (zero mass, a singular or indefinite inertia, as URDFs sometimes write) is
/// first made so: mass at least `min_mass`, second moment about the centre of mass raised to at
/// least `(1 cm)²` per axis.
pub(crate) fn log_cholesky_of_parameters(p: &[f64; PARAMS_PER_LINK], min_mass: f64) -> [f64; 10] {
    let s = inertia_from_parameters(p);
    let m = s.mass.max(min_mass).max(1e-12);
    let c = if s.mass > 0.0 { s.first_moment / s.mass } else { Vector3::zeros() };
    let ic = if s.mass > 0.0 { s.inertia_about_com() } else { s.rotational };
    // second moment about the centre of mass per unit mass, made positive definite
    let sig = (Matrix3::from_diagonal_element(0.5 * ic.trace()) - ic) / m;
    let eig = sig.symmetric_eigen();
    let floor = 1e-4f64;
    let d = eig.eigenvalues.map(|l| l.max(floor));
    let sig = eig.eigenvectors * Matrix3::from_diagonal(&d) * eig.eigenvectors.transpose();
    // R Rᵀ = sig with R upper triangular: reverse the order, lower Cholesky, reverse back
    let perm = Matrix3::new(0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 0.0, 0.0);
    let l = (perm * sig * perm).cholesky().map(|c| c.l()).unwrap_or_else(|| Matrix3::from_diagonal_element(floor.sqrt()));
    let r = perm * l * perm;
    [0.5 * m.ln(), r[(0, 0)].ln(), r[(1, 1)].ln(), r[(2, 2)].ln(), r[(0, 1)], r[(1, 2)], r[(0, 2)], c.x, c.y, c.z]
}

/// Reach of every link's centre of mass (see the module documentation for the rule) [m].
pub(crate) fn link_reach(model: &Model) -> Vec<f64> {
    let joints = model.joints();
    let n = joints.len();
    let com = |i: usize| joints[i].inertia.com().norm();
    let length: f64 = joints.iter().skip(1).map(|j| j.placement.translation.norm()).sum::<f64>() + if n > 0 { com(n - 1) } else { 0.0 };
    let floor = (0.1 * length).max(0.02);
    let longest = joints.iter().skip(1).map(|j| j.placement.translation.norm()).fold(0.0f64, f64::max);
    (0..n)
        .map(|i| {
            if i + 1 < n {
                1.25 * joints[i + 1].placement.translation.norm().max(com(i)).max(floor)
            } else {
                let s = &joints[i].inertia;
                let rg = if s.mass > 0.0 { (s.inertia_about_com().trace().max(0.0) / (2.0 * s.mass)).sqrt() } else { 0.0 };
                (1.5 * com(i).max(rg).max(floor)).max(1.25 * longest)
            }
        })
        .collect()
}

/// Projects the centre of mass `t` of log-Cholesky parameters into the ball of radius `reach`.
pub(crate) fn project_reach(phi: &mut [f64], reach: f64) {
    let n = (phi[7] * phi[7] + phi[8] * phi[8] + phi[9] * phi[9]).sqrt();
    if n > reach {
        for v in &mut phi[7..10] {
            *v *= reach / n;
        }
    }
}

/// Minimises `½ θᵀ G θ − cᵀ θ + ½ μ ‖θ_I‖²` where θ_I (columns `first .. first + 10 dof`) are the
/// scaled inertial corrections of `prior`, constrained to physical links within reach, and the
/// other columns are linear parameters within `[lo, hi]`. μ = `prior.weight` × the mean diagonal
/// of `G` over θ_I.
///
/// Levenberg–Marquardt on (linear parameters, log-Cholesky φ), started from the URDF; linear
/// parameters are kept in their box (a parameter at a bound whose gradient points out is held),
/// centres of mass are projected into their balls. Returns θ and the iterate x = (linear
/// parameters, φ) it came from.
///
/// `start`: the iterate of an earlier solution of a nearby problem (the same terms on other
/// data: a cross-validation fold, a resample), to start from in place of the URDF. The problem is
/// convex in the inertial parameters over a convex set, so the start changes how many
/// iterations reach the minimum, not the minimum; when the iterations stop before it (they are
/// capped), a start near it ends nearer.
pub(crate) fn solve(prior: &InertialPrior, first: usize, g: &DMatrix<f64>, c: &DVector<f64>, lo: &[f64], hi: &[f64], start: Option<&[f64]>) -> (DVector<f64>, Vec<f64>) {
    let k = g.nrows();
    let nl = prior.links();
    let w = PARAMS_PER_LINK * nl;
    assert!(first + w <= k, "inertial columns {first}..{} out of {k}", first + w);
    let lin: Vec<usize> = (0..k).filter(|&i| i < first || i >= first + w).collect();
    let mean_diag = (first..first + w).map(|i| g[(i, i)]).sum::<f64>() / w as f64;
    let mu = prior.weight * mean_diag.max(1e-300);
    let avg_mass = prior.nominal.iter().step_by(PARAMS_PER_LINK).sum::<f64>() / nl.max(1) as f64;
    let theta_of = |phi: &[f64], z: &[f64]| -> DVector<f64> {
        let mut th = DVector::zeros(k);
        for (a, &i) in lin.iter().enumerate() {
            th[i] = z[a];
        }
        for l in 0..nl {
            let p = parameters_of_log_cholesky(&phi[10 * l..10 * l + 10]);
            for (a, v) in p.iter().enumerate() {
                let idx = PARAMS_PER_LINK * l + a;
                th[first + idx] = (v - prior.nominal[idx]) / prior.scales[idx];
            }
        }
        th
    };
    let objective = |th: &DVector<f64>| -> f64 {
        let prior_term: f64 = (first..first + w).map(|i| th[i] * th[i]).sum();
        0.5 * th.dot(&(g * th)) - c.dot(th) + 0.5 * mu * prior_term
    };
    // the start without an earlier solution: the URDF, the linear parameters fitted with it
    let urdf_start = || -> Vec<f64> {
        let phi: Vec<f64> = (0..nl)
            .flat_map(|i| {
                let p: [f64; PARAMS_PER_LINK] = std::array::from_fn(|a| prior.nominal[PARAMS_PER_LINK * i + a]);
                let mut f = log_cholesky_of_parameters(&p, 1e-6 * avg_mass.max(1e-6));
                project_reach(&mut f, prior.reach[i]);
                f
            })
            .collect();
        let th0 = theta_of(&phi, &vec![0.0; lin.len()]);
        let gl = DMatrix::from_fn(lin.len(), lin.len(), |a, b| g[(lin[a], lin[b])]);
        let rhs = DVector::from_fn(lin.len(), |a, _| c[lin[a]] - (first..first + w).map(|j| g[(lin[a], j)] * th0[j]).sum::<f64>());
        let (llo, lhi): (Vec<f64>, Vec<f64>) = lin.iter().map(|&i| (lo[i], hi[i])).unzip();
        let z = crate::lsq::bounded::solve_bounded(&gl, &rhs, &llo, &lhi).0;
        z.iter().chain(&phi).copied().collect()
    };
    let nx = lin.len() + 10 * nl;
    // bounds of x = (z, φ): the linear parameters' boxes; per link the mass within a factor
    // MASS_FACTOR of the URDF's, every principal radius of the mass about the COM ≥ MIN_RADIUS
    let mut xlo: Vec<f64> = lin.iter().map(|&i| lo[i]).collect();
    let mut xhi: Vec<f64> = lin.iter().map(|&i| hi[i]).collect();
    for l in 0..nl {
        let m0 = prior.nominal[PARAMS_PER_LINK * l].max(1e-6 * avg_mass.max(1e-6));
        xlo.extend([0.5 * (m0 / MASS_FACTOR).ln(), MIN_RADIUS.ln(), MIN_RADIUS.ln(), MIN_RADIUS.ln()]);
        xhi.extend([0.5 * (m0 * MASS_FACTOR).ln(), f64::INFINITY, f64::INFINITY, f64::INFINITY]);
        xlo.extend([f64::NEG_INFINITY; 6]);
        xhi.extend([f64::INFINITY; 6]);
    }
    // (an earlier solution of the same prior is within its bounds and reach already)
    let mut x: Vec<f64> = match start {
        Some(x0) if x0.len() == nx && x0.iter().all(|v| v.is_finite()) => x0.to_vec(),
        _ => urdf_start(),
    };
    for (a, v) in x.iter_mut().enumerate() {
        *v = v.clamp(xlo[a], xhi[a]);
    }
    let split = |x: &[f64]| -> (Vec<f64>, Vec<f64>) { (x[..lin.len()].to_vec(), x[lin.len()..].to_vec()) };
    let (z0, phi0) = split(&x);
    let mut th = theta_of(&phi0, &z0);
    let mut f = objective(&th);
    let mut lambda = 1e-3;
    let mut small = 0;
    let mut gp = g.clone();
    for i in first..first + w {
        gp[(i, i)] += mu;
    }
    for _ in 0..MAX_ITERATIONS {
        // gradient and Gauss–Newton Hessian of the objective in x
        let resid = &gp * &th - c;
        let (grad, hess) = normal_equations(prior, first, &lin, &gp, &resid, &x);
        // parameters held at a bound the gradient pushes against
        let free: Vec<usize> = (0..nx).filter(|&a| !((x[a] <= xlo[a] && grad[a] > 0.0) || (x[a] >= xhi[a] && grad[a] < 0.0))).collect();
        let hmax = free.iter().map(|&a| hess[(a, a)]).fold(0.0, f64::max).max(1e-300);
        let mut improved = false;
        for _ in 0..30 {
            let a = DMatrix::from_fn(free.len(), free.len(), |r, s| hess[(free[r], free[s])] + if r == s { lambda * (hess[(free[r], free[r])] + 1e-9 * hmax) } else { 0.0 });
            let b = DVector::from_fn(free.len(), |r, _| -grad[free[r]]);
            let Some(step) = a.cholesky().map(|ch| ch.solve(&b)) else {
                lambda *= 10.0;
                continue;
            };
            let mut x2 = x.clone();
            for (r, &a) in free.iter().enumerate() {
                x2[a] = (x[a] + step[r]).clamp(xlo[a], xhi[a]);
            }
            for l in 0..nl {
                let o = lin.len() + 10 * l;
                project_reach(&mut x2[o..o + 10], prior.reach[l]);
            }
            let (z2, phi2) = split(&x2);
            let th2 = theta_of(&phi2, &z2);
            let f2 = objective(&th2);
            if f2.is_finite() && f2 <= f {
                small = if (f - f2) <= 1e-6 * f.abs() { small + 1 } else { 0 };
                x = x2;
                th = th2;
                f = f2;
                lambda = (lambda / 3.0).max(1e-12);
                improved = true;
                break;
            }
            lambda *= 4.0;
        }
        if !improved || small >= 2 || lambda > 1e12 {
            break;
        }
    }
    (th, x)
}

/// The gradient `Jᵀ r` and the Gauss–Newton Hessian `Jᵀ G J` of `½ θᵀ G θ − cᵀ θ` in the
/// coordinates x = (linear parameters `lin`, log-Cholesky φ of every link) of [`solve`], with
/// `r = G θ − c` and J = ∂θ/∂x: the identity on the linear parameters and, per link l, the
/// scaled block `B_l = diag(1 / scales) ∂π/∂φ_l` (10 × 10) on the inertial columns from
/// `first`. Formed block by block (`G[lin, I_l] B_l`, `B_lᵀ G[I_l, I_m] B_m`), never through
/// the dense Jacobian.
fn normal_equations(prior: &InertialPrior, first: usize, lin: &[usize], g: &DMatrix<f64>, resid: &DVector<f64>, x: &[f64]) -> (DVector<f64>, DMatrix<f64>) {
    let (nlin, nl) = (lin.len(), prior.links());
    let nx = nlin + 10 * nl;
    // the scaled Jacobian block of every link
    let blocks: Vec<nalgebra::SMatrix<f64, 10, 10>> = (0..nl)
        .map(|l| {
            let o = nlin + 10 * l;
            let mut b = jacobian_log_cholesky(&x[o..o + 10]);
            for r in 0..PARAMS_PER_LINK {
                let s = prior.scales[PARAMS_PER_LINK * l + r];
                for q in 0..10 {
                    b[(r, q)] /= s;
                }
            }
            b
        })
        .collect();
    // gradient: r on the linear parameters, B_lᵀ r_l per link
    let mut grad = DVector::<f64>::zeros(nx);
    for (a, &i) in lin.iter().enumerate() {
        grad[a] = resid[i];
    }
    for (l, b) in blocks.iter().enumerate() {
        let r = resid.fixed_rows::<10>(first + PARAMS_PER_LINK * l);
        grad.fixed_rows_mut::<10>(nlin + 10 * l).copy_from(&(b.transpose() * r));
    }
    // Hessian: G on the linear parameters, then each link against them and against the links
    let mut hess = DMatrix::<f64>::zeros(nx, nx);
    for (a, &i) in lin.iter().enumerate() {
        for (b, &j) in lin.iter().enumerate() {
            hess[(a, b)] = g[(i, j)];
        }
    }
    for (l, bl) in blocks.iter().enumerate() {
        let ol = first + PARAMS_PER_LINK * l;
        for (a, &i) in lin.iter().enumerate() {
            let row = g.fixed_view::<1, 10>(i, ol) * bl;
            hess.fixed_view_mut::<1, 10>(a, nlin + 10 * l).copy_from(&row);
            hess.fixed_view_mut::<10, 1>(nlin + 10 * l, a).copy_from(&row.transpose());
        }
        for (m, bm) in blocks.iter().enumerate().skip(l) {
            let h = bl.transpose() * g.fixed_view::<10, 10>(ol, first + PARAMS_PER_LINK * m) * bm;
            hess.fixed_view_mut::<10, 10>(nlin + 10 * l, nlin + 10 * m).copy_from(&h);
            if m != l {
                hess.fixed_view_mut::<10, 10>(nlin + 10 * m, nlin + 10 * l).copy_from(&h.transpose());
            }
        }
    }
    (grad, hess)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn log_cholesky_round_trips_a_physical_body() {
        let s = SpatialInertia::from_com(2.0, Vector3::new(0.1, -0.05, 0.3), Matrix3::new(0.02, 0.001, 0.0, 0.001, 0.03, 0.002, 0.0, 0.002, 0.025));
        let p = inertial_parameters(&s);
        let phi = log_cholesky_of_parameters(&p, 1e-9);
        let back = parameters_of_log_cholesky(&phi);
        for (a, b) in p.iter().zip(&back) {
            assert!((a - b).abs() < 1e-12, "{p:?} vs {back:?}");
        }
    }

    #[test]
    fn log_cholesky_jacobian_matches_finite_differences() {
        let phi = [0.3, -1.0, -1.2, -0.8, 0.05, -0.02, 0.01, 0.1, 0.0, -0.2];
        let jac = jacobian_log_cholesky(&phi);
        for k in 0..10 {
            let (mut a, mut b) = (phi, phi);
            a[k] += 1e-6;
            b[k] -= 1e-6;
            let (pa, pb) = (parameters_of_log_cholesky(&a), parameters_of_log_cholesky(&b));
            for r in 0..10 {
                let fd = (pa[r] - pb[r]) / 2e-6;
                assert!((fd - jac[(r, k)]).abs() < 1e-6 * (1.0 + fd.abs()), "d π{r} / d φ{k}: {fd} vs {}", jac[(r, k)]);
            }
        }
    }

    #[test]
    fn log_cholesky_inertia_is_physical_for_any_parameters() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for _ in 0..2000 {
            let phi: [f64; 10] = std::array::from_fn(|_| rng.random_range(-4.0..4.0));
            let p = parameters_of_log_cholesky(&phi);
            let s = inertia_from_parameters(&p);
            assert!(s.mass > 0.0, "mass {}", s.mass);
            // principal moments about the centre of mass non-negative and obeying the triangle inequality
            let mut l: Vec<f64> = s.inertia_about_com().symmetric_eigenvalues().iter().copied().collect();
            l.sort_by(f64::total_cmp);
            let tol = 1e-9 * l[2].abs().max(1e-300);
            assert!(l[0] > -tol && l[0] + l[1] >= l[2] - tol, "principal moments {l:?}");
            assert!(pseudo_inertia(&p).symmetric_eigenvalues().iter().all(|&e| e > -1e-9 * p[0].max(1.0)));
            let com = s.first_moment / s.mass;
            assert!((com - Vector3::new(phi[7], phi[8], phi[9])).norm() < 1e-9 * (1.0 + com.norm()), "the COM is t");
        }
    }

    #[test]
    fn block_normal_equations_equal_the_dense_jacobian_products() {
        // a 3-link chain's prior, two linear columns before the inertial ones and one after
        let prior = InertialPrior::new(&simgap_core::Model::random_chain(3, 5));
        let (first, nl) = (2, prior.links());
        let k = first + PARAMS_PER_LINK * nl + 1;
        let lin: Vec<usize> = (0..k).filter(|&i| i < first || i >= first + PARAMS_PER_LINK * nl).collect();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let a = DMatrix::from_fn(k + 5, k, |_, _| rng.random_range(-1.0..1.0));
        let g = a.transpose() * a;
        let resid = DVector::from_fn(k, |_, _| rng.random_range(-1.0..1.0));
        let x: Vec<f64> = (0..lin.len() + 10 * nl).map(|_| rng.random_range(-1.0..1.0)).collect();
        // the dense J = ∂θ/∂x
        let mut jac = DMatrix::<f64>::zeros(k, x.len());
        for (a, &i) in lin.iter().enumerate() {
            jac[(i, a)] = 1.0;
        }
        for l in 0..nl {
            let o = lin.len() + 10 * l;
            let jl = jacobian_log_cholesky(&x[o..o + 10]);
            for r in 0..PARAMS_PER_LINK {
                let idx = PARAMS_PER_LINK * l + r;
                for q in 0..10 {
                    jac[(first + idx, o + q)] = jl[(r, q)] / prior.scales[idx];
                }
            }
        }
        let (grad, hess) = normal_equations(&prior, first, &lin, &g, &resid, &x);
        let (grad_dense, hess_dense) = (jac.transpose() * &resid, jac.transpose() * &g * &jac);
        assert!((&grad - &grad_dense).amax() <= 1e-9 * grad_dense.amax(), "gradient differs by {}", (&grad - &grad_dense).amax());
        assert!((&hess - &hess_dense).amax() <= 1e-9 * hess_dense.amax(), "Hessian differs by {}", (&hess - &hess_dense).amax());
    }
}
