//! Least squares on a Gram matrix: the minimum-norm solution and the solution within bounds on
//! each parameter (a leaf: it knows nothing of the terms).

use nalgebra::{DMatrix, DVector};

/// Minimum-norm least-squares solution of `G θ = c` (eigenvalues below `1e-10 · max` dropped);
/// returns θ and the effective rank.
pub(crate) fn solve(g: &DMatrix<f64>, c: &DVector<f64>) -> (DVector<f64>, usize) {
    let k = g.nrows();
    if k == 0 {
        return (DVector::zeros(0), 0);
    }
    let eig = g.clone().symmetric_eigen();
    let max = eig.eigenvalues.iter().cloned().fold(0.0, f64::max);
    let mut theta = DVector::zeros(k);
    let mut rank = 0;
    for (i, &l) in eig.eigenvalues.iter().enumerate() {
        if l > 1e-10 * max && l > 0.0 {
            let v = eig.eigenvectors.column(i);
            theta += v * (v.dot(c) / l);
            rank += 1;
        }
    }
    (theta, rank)
}

/// Minimises `½ θᵀ G θ − cᵀ θ` subject to `lo ≤ θ ≤ hi` (infinite bounds allowed): a primal
/// active-set method (Lawson & Hanson, *Solving Least Squares Problems*, 1974, ch. 23, for
/// bounds on both sides). When the minimum-norm unconstrained solution ([`solve`]) is within the
/// bounds it is the answer; otherwise parameters are held at the bounds they reach, and released
/// when the gradient pulls them back inside. Returns θ and the effective rank of the free block.
pub(crate) fn solve_bounded(g: &DMatrix<f64>, c: &DVector<f64>, lo: &[f64], hi: &[f64]) -> (DVector<f64>, usize) {
    let k = g.nrows();
    let inside = |th: &DVector<f64>| (0..k).all(|i| th[i] >= lo[i] && th[i] <= hi[i]);
    let (theta, rank) = solve(g, c);
    if lo.len() < k || inside(&theta) {
        return (theta, rank);
    }
    // start: every bounded parameter at the feasible value nearest zero
    let mut th = DVector::from_fn(k, |i, _| 0.0f64.clamp(lo[i], hi[i]));
    let mut held: Vec<bool> = (0..k).map(|i| th[i] == lo[i] || th[i] == hi[i]).collect();
    let mut rank = 0;
    for _ in 0..(10 * k + 20) {
        // minimise over the free parameters with the held ones fixed
        let free: Vec<usize> = (0..k).filter(|&i| !held[i]).collect();
        let gf = DMatrix::from_fn(free.len(), free.len(), |a, b| g[(free[a], free[b])]);
        let cf = DVector::from_fn(free.len(), |a, _| c[free[a]] - (0..k).filter(|&j| held[j]).map(|j| g[(free[a], j)] * th[j]).sum::<f64>());
        let (sf, r) = solve(&gf, &cf);
        rank = r;
        // step toward it until the first bound
        let mut alpha = 1.0f64;
        let mut hit = None;
        for (a, &i) in free.iter().enumerate() {
            let d = sf[a] - th[i];
            let t = if sf[a] < lo[i] {
                (lo[i] - th[i]) / d
            } else if sf[a] > hi[i] {
                (hi[i] - th[i]) / d
            } else {
                continue;
            };
            if t < alpha {
                alpha = t.max(0.0);
                hit = Some(i);
            }
        }
        for (a, &i) in free.iter().enumerate() {
            th[i] = (th[i] + alpha * (sf[a] - th[i])).clamp(lo[i], hi[i]);
        }
        if let Some(i) = hit {
            th[i] = if (th[i] - lo[i]).abs() <= (th[i] - hi[i]).abs() { lo[i] } else { hi[i] };
            held[i] = true;
            continue;
        }
        // the free minimum is feasible: release the held parameter the gradient pulls inside most
        let w = c - g * &th;
        let scale = w.amax().max(1e-300);
        let release = (0..k).filter(|&i| held[i]).map(|i| (i, if th[i] <= lo[i] { w[i] } else { -w[i] })).filter(|&(_, v)| v > 1e-12 * scale).max_by(|a, b| a.1.total_cmp(&b.1));
        match release {
            Some((i, _)) => held[i] = false,
            None => break,
        }
    }
    (th, rank)
}
