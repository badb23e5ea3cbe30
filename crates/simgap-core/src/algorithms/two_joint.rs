//! Closed forms of two-joint arms with rotational joints (the seed paper's arm): H, C, g and
//! forward dynamics in a few dozen flops and two `sin_cos`, from coefficients generated from
//! the model by [`closed_forms`](crate::algorithms::closed_forms).
//!
//! For a serial chain whose two joints rotate, every entry of H depends on q2 alone and is a
//! trigonometric polynomial of degree 2 (the second link's inertia rotated by q2 twice), and
//! the potential energy U is of degree 1 in q1 times degree 1 in q2. The coefficients are
//! computed once per model and workspace by sampling the general algorithms (H at eight
//! values of q2, U on a 4 × 4 grid: exact discrete Fourier transforms for these degrees); then
//! `g = ∂U/∂q`, `∂H/∂q2` and the Christoffel symbols follow analytically. The general
//! algorithms remain the reference (the tests compare both to 1e-10 relative).

use nalgebra::{DMatrix, DVector};

use crate::formulation::Formulation;
use crate::lanes::Lanes;

/// The generated closed form of a two-joint arm.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct TwoJoint {
    /// `[h11, h12, h22]` coefficients of `1, cos q2, sin q2, cos 2q2, sin 2q2`.
    h: [[f64; 3]; 5],
    /// `u[a][b]`: coefficient of `φ_a(q1) φ_b(q2)` in U, `φ = (1, cos, sin)`.
    u: [[f64; 3]; 3],
}

/// `q̈`, or the terms, of one state.
pub(crate) struct Terms {
    /// `[h11, h12, h22]`.
    pub(crate) h: [f64; 3],
    /// `C` row-major.
    pub(crate) c: [f64; 4],
    pub(crate) g: [f64; 2],
}

impl TwoJoint {
    /// The closed form with H's coefficients `h` (`[h11, h12, h22]` of `1, cos q2, sin q2,
    /// cos 2q2, sin 2q2`) and U's coefficients `u` (`u[a][b]` of `φ_a(q1) φ_b(q2)`,
    /// `φ = (1, cos, sin)`), as [`closed_forms`](crate::algorithms::closed_forms) samples them.
    pub(crate) fn from_coefficients(h: [[f64; 3]; 5], u: [[f64; 3]; 3]) -> TwoJoint {
        TwoJoint { h, u }
    }

    /// H, C of `formulation` and g at `(q, qd)`.
    #[inline]
    pub(crate) fn terms(&self, q: &[f64], qd: &[f64], formulation: Formulation) -> Terms {
        // both angles in one two-lane evaluation (the same numbers as `sin_cos`)
        let (s, c) = Lanes([q[0], q[1]]).sin_cos();
        let ([s1, s2], [c1, c2]) = (s.0, c.0);
        // H and ∂H/∂q2 from the degree-2 polynomial in q2
        let (cc, ss) = (c2 * c2 - s2 * s2, 2.0 * s2 * c2);
        let basis = [1.0, c2, s2, cc, ss];
        let slope = [0.0, -s2, c2, -2.0 * ss, 2.0 * cc];
        let mut h = [0.0; 3];
        let mut d = [0.0; 3];
        for k in 0..5 {
            for e in 0..3 {
                h[e] += self.h[k][e] * basis[k];
                d[e] += self.h[k][e] * slope[k];
            }
        }
        // g = ∂U/∂q
        let (phi1, dphi1) = ([1.0, c1, s1], [0.0, -s1, c1]);
        let (phi2, dphi2) = ([1.0, c2, s2], [0.0, -s2, c2]);
        let mut g = [0.0; 2];
        for a in 0..3 {
            for b in 0..3 {
                g[0] += self.u[a][b] * dphi1[a] * phi2[b];
                g[1] += self.u[a][b] * phi1[a] * dphi2[b];
            }
        }
        // C: with ∂H/∂q1 = 0 and D = ∂H/∂q2, Euler–Lagrange C_ij = ½ Σ_k (∂_k H_ij + ∂_j H_ik − ∂_i H_jk) q̇_k
        let (d11, d12, d22) = (d[0], d[1], d[2]);
        let (v1, v2) = (qd[0], qd[1]);
        let c = match formulation {
            Formulation::EulerLagrange => [0.5 * d11 * v2, 0.5 * d11 * v1 + d12 * v2, -0.5 * d11 * v1, 0.5 * d22 * v2],
            Formulation::Simplified => [0.5 * d11 * v2, 0.5 * d12 * v2, 0.5 * d12 * v2, 0.5 * d22 * v2],
        };
        Terms { h, c, g }
    }

    /// [`crate::dynamics_terms_into`] for this arm.
    #[inline]
    pub(crate) fn terms_into(&self, q: &[f64], qd: &[f64], formulation: Formulation, h: &mut DMatrix<f64>, c: &mut DMatrix<f64>, g: &mut DVector<f64>) {
        let t = self.terms(q, qd, formulation);
        h[(0, 0)] = t.h[0];
        h[(0, 1)] = t.h[1];
        h[(1, 0)] = t.h[1];
        h[(1, 1)] = t.h[2];
        c[(0, 0)] = t.c[0];
        c[(0, 1)] = t.c[1];
        c[(1, 0)] = t.c[2];
        c[(1, 1)] = t.c[3];
        g[0] = t.g[0];
        g[1] = t.g[1];
    }

    /// q̈ = (H + diag(ia))⁻¹ (τ − C q̇ − g) into `out`, with rotor inertias `ia` [kg·m²] (zeros
    /// for none); false (and `out` untouched) when `H + diag(ia)` is not positive definite.
    #[inline]
    pub(crate) fn forward_dynamics(&self, q: &[f64], qd: &[f64], tau: &[f64], ia: [f64; 2], formulation: Formulation, out: &mut [f64]) -> bool {
        let t = self.terms(q, qd, formulation);
        let r1 = tau[0] - (t.c[0] * qd[0] + t.c[1] * qd[1] + t.g[0]);
        let r2 = tau[1] - (t.c[2] * qd[0] + t.c[3] * qd[1] + t.g[1]);
        let [h11, h12, h22] = t.h;
        let (h11, h22) = (h11 + ia[0], h22 + ia[1]);
        let det = h11 * h22 - h12 * h12;
        if !(h11 > 0.0 && det > 0.0) {
            return false;
        }
        let inv = 1.0 / det;
        out[0] = (h22 * r1 - h12 * r2) * inv;
        out[1] = (h11 * r2 - h12 * r1) * inv;
        true
    }
}
