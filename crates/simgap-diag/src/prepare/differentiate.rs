//! A smoothing differentiator: local cubic least-squares fits over a sliding time window
//! (Savitzky–Golay, generalised to non-uniform stamps).
//!
//! At sample k the polynomial `p(s) = c0 + c1 s + c2 s² + c3 s³`, `s = (t − t_k)/h`, is fitted to
//! the samples within `half` neighbours on each side; the smoothed value is `c0`, the
//! derivative `c1/h` and the second derivative `2 c2/h²`. Samples closer than `half` to either
//! end are dropped by the callers ([`Smoother::valid`]).
//!
//! Torques are zero-order-hold signals (constant over each sample interval). So that both sides
//! of the equation of motion see exactly the same filter, a torque is filtered with the Peano
//! kernel of the second-derivative weights `w`: if `L[q] = Σ_i w_i q(t_i)` estimates q̈, then for
//! any q with q̈ = u piecewise constant, `L[q] = Σ_j u_j v_j` with
//! `v_j = Σ_i w_i ((t_i − t_j)₊² − (t_i − t_{j+1})₊²) / 2` ([`Smoother::apply_zoh`]).

use nalgebra::{Matrix4, Vector4};

/// A sliding-window local-polynomial smoother over one time base.
#[derive(Clone, Debug)]
pub(crate) struct Smoother {
    t: Vec<f64>,
    half: usize,
    /// Weights (value, first and second derivative, zero-order-hold kernel), `2 half + 1` each:
    /// one shared set when the sampling is uniform, else one set per valid sample (from
    /// `half`) when they fit in [`MAX_CACHED_WEIGHTS`], else none (computed on the fly).
    weights: Vec<[Vec<f64>; 4]>,
    uniform: bool,
}

/// At most this many weights are kept per smoother for non-uniform stamps (32 MB).
const MAX_CACHED_WEIGHTS: usize = 4_000_000;

impl Smoother {
    /// A smoother over times `t` (strictly increasing) with a window of about `window` seconds.
    pub(crate) fn new(t: &[f64], window: f64) -> Smoother {
        let n = t.len();
        let dt = if n > 1 { (t[n - 1] - t[0]) / (n - 1) as f64 } else { 1.0 };
        let half = ((window / dt / 2.0).round() as usize).clamp(3, 200);
        let uniform = n > 1 && t.windows(2).all(|w| ((w[1] - w[0]) - dt).abs() <= 1e-3 * dt);
        let mut s = Smoother { t: t.to_vec(), half, weights: Vec::new(), uniform };
        if uniform && n > 2 * half {
            let w = s.compute_weights(half);
            s.weights.push(w);
        } else if !uniform && n > 2 * half && n * (2 * half + 1) * 4 <= MAX_CACHED_WEIGHTS {
            // non-uniform stamps: every signal filtered here reuses the per-sample fits
            s.weights = s.valid().map(|k| s.compute_weights(k)).collect();
        }
        s
    }

    /// Half-width of the window in samples.
    pub(crate) fn half(&self) -> usize {
        self.half
    }

    /// The range of samples with a full window.
    pub(crate) fn valid(&self) -> std::ops::Range<usize> {
        let n = self.t.len();
        if n <= 2 * self.half {
            0..0
        } else {
            self.half..n - self.half
        }
    }

    fn compute_weights(&self, k: usize) -> [Vec<f64>; 4] {
        let h = self.half;
        let tk = self.t[k];
        let scale = (self.t[k + h] - self.t[k - h]).max(f64::MIN_POSITIVE) / 2.0;
        // normal equations of the cubic fit
        let mut a = Matrix4::<f64>::zeros();
        let rows: Vec<Vector4<f64>> = (k - h..=k + h)
            .map(|i| {
                let s = (self.t[i] - tk) / scale;
                Vector4::new(1.0, s, s * s, s * s * s)
            })
            .collect();
        for r in &rows {
            a += r * r.transpose();
        }
        let inv = a.try_inverse().unwrap_or_else(Matrix4::zeros);
        // weights: row d of (AᵀA)⁻¹ Aᵀ, scaled to derivatives in time
        let mut w = [Vec::with_capacity(rows.len()), Vec::with_capacity(rows.len()), Vec::with_capacity(rows.len()), Vec::new()];
        for r in &rows {
            let c = inv * r;
            w[0].push(c[0]);
            w[1].push(c[1] / scale);
            w[2].push(2.0 * c[2] / (scale * scale));
        }
        // Peano kernel of the second-derivative weights over each sample interval
        let pos2 = |x: f64| if x > 0.0 { x * x } else { 0.0 };
        let ts = &self.t[k - h..=k + h];
        w[3] = (0..2 * h + 1)
            .map(|j| {
                if j == 2 * h {
                    return 0.0;
                }
                (0..2 * h + 1).map(|i| w[2][i] * (pos2(ts[i] - ts[j]) - pos2(ts[i] - ts[j + 1])) / 2.0).sum()
            })
            .collect();
        w
    }

    /// Filters a zero-order-hold signal (value `x_j` held over `[t_j, t_{j+1})`) with the
    /// kernel that matches [`Smoother::apply`]`(q, 2)` (module docs).
    pub(crate) fn apply_zoh(&self, x: &[f64], dof: usize) -> Vec<f64> {
        self.apply(x, dof, 3)
    }

    /// The zero-order-hold filter of [`Smoother::apply_zoh`] at each sample of `at` (each in
    /// [`Smoother::valid`]) of a one-channel signal `x` (one value per sample).
    pub(crate) fn apply_zoh_at(&self, x: &[f64], at: &[usize]) -> Vec<f64> {
        let h = self.half;
        at.iter().map(|&k| self.weights_at(k, 3).iter().zip(&x[k - h..=k + h]).map(|(w, x)| w * x).sum()).collect()
    }

    /// The weights of derivative `deriv` (3: the zero-order-hold kernel) of the window centred
    /// on sample `k`: shared on uniform stamps, precomputed per sample, or computed here.
    fn weights_at(&self, k: usize, deriv: usize) -> std::borrow::Cow<'_, [f64]> {
        if self.uniform {
            std::borrow::Cow::Borrowed(&self.weights[0][deriv])
        } else if !self.weights.is_empty() {
            std::borrow::Cow::Borrowed(&self.weights[k - self.half][deriv])
        } else {
            let mut all = self.compute_weights(k);
            std::borrow::Cow::Owned(std::mem::take(&mut all[deriv]))
        }
    }

    /// Applies the filter to a row-major `len × dof` signal: `deriv` 0 = smoothed value,
    /// 1 = first derivative, 2 = second derivative (3 = [`Smoother::apply_zoh`]). Samples
    /// outside [`Smoother::valid`] are 0.
    pub(crate) fn apply(&self, x: &[f64], dof: usize, deriv: usize) -> Vec<f64> {
        let n = self.t.len();
        assert_eq!(x.len(), n * dof, "signal length");
        let mut out = vec![0.0; x.len()];
        let h = self.half;
        // samples whose row is all zero; a window of them filters to zero (sparse signals,
        // such as the torque above a saturation limit, cost almost nothing)
        let mut zeros_before = Vec::with_capacity(n + 1);
        zeros_before.push(0usize);
        for k in 0..n {
            let z = x[k * dof..(k + 1) * dof].iter().all(|v| *v == 0.0);
            zeros_before.push(zeros_before[k] + usize::from(z));
        }
        for k in self.valid() {
            if zeros_before[k + h + 1] - zeros_before[k - h] == 2 * h + 1 {
                continue;
            }
            let w = self.weights_at(k, deriv);
            for j in 0..dof {
                let mut acc = 0.0;
                for (m, wi) in w.iter().enumerate() {
                    acc += wi * x[(k - h + m) * dof + j];
                }
                out[k * dof + j] = acc;
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filtering_at_chosen_samples_equals_filtering_every_sample() {
        let uniform: Vec<f64> = (0..300).map(|i| i as f64 * 0.002).collect();
        let jittered: Vec<f64> = (0..300).map(|i| i as f64 * 0.002 + 0.0004 * ((i * 7 % 5) as f64)).collect();
        for t in [uniform, jittered] {
            let s = Smoother::new(&t, 0.05);
            let x: Vec<f64> = t.iter().map(|&t| (7.0 * t).sin().signum() + 0.3 * t).collect();
            let every = s.apply_zoh(&x, 1);
            let at: Vec<usize> = s.valid().step_by(3).collect();
            for (k, v) in at.iter().zip(s.apply_zoh_at(&x, &at)) {
                assert!((every[*k] - v).abs() < 1e-12, "k = {k}: {v} against {}", every[*k]);
            }
        }
    }

    #[test]
    fn differentiates_a_cubic_exactly_on_nonuniform_stamps() {
        let t: Vec<f64> = (0..200).map(|i| i as f64 * 0.01 + 0.002 * ((i * 7 % 5) as f64)).collect();
        let x: Vec<f64> = t.iter().map(|&t| 1.0 + 2.0 * t - 0.5 * t * t + 0.3 * t * t * t).collect();
        let s = Smoother::new(&t, 0.1);
        let d1 = s.apply(&x, 1, 1);
        let d2 = s.apply(&x, 1, 2);
        // a zero-order-hold "acceleration" filtered like q̈ of its double integral
        let u: Vec<f64> = t.iter().map(|&t| if t < 1.0 { 1.0 } else { -2.0 }).collect();
        let mut q = vec![0.0; t.len()];
        let mut v = 0.0;
        for k in 1..t.len() {
            let dt = t[k] - t[k - 1];
            q[k] = q[k - 1] + v * dt + 0.5 * u[k - 1] * dt * dt;
            v += u[k - 1] * dt;
        }
        let a = s.apply(&q, 1, 2);
        let b = s.apply_zoh(&u, 1);
        for k in s.valid() {
            assert!((a[k] - b[k]).abs() < 1e-9, "k = {k}: {} vs {}", a[k], b[k]);
        }
        for k in s.valid() {
            let tk = t[k];
            assert!((d1[k] - (2.0 - tk + 0.9 * tk * tk)).abs() < 1e-8);
            assert!((d2[k] - (-1.0 + 1.8 * tk)).abs() < 1e-7);
        }
    }
}
