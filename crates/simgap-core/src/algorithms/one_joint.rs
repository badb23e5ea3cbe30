//! The closed form of a one-joint arm (a servo's pendulum, a linear axis): forward dynamics in
//! a few flops and one `sin_cos`, from coefficients generated from the model by
//! [`closed_forms`](crate::algorithms::closed_forms).
//!
//! One joint from a fixed base moves one rigid body (its links merged) whose inertia about or
//! along the joint's axis does not change with q: H is a constant and C = 0 in both
//! formulations (Ḣ = 0). The potential energy is `u0 + u1 cos q + u2 sin q` about a turning
//! axis (the centre of mass turns on a circle) and `u0 + u1 q` along a sliding one. H is sampled
//! once, U at four angles (or two positions); `g = ∂U/∂q` follows analytically. The general
//! algorithms remain the reference (the tests compare both to 1e-10 relative).

/// The generated closed form of a one-joint arm.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct OneJoint {
    /// H [kg·m² or kg].
    h: f64,
    /// U's coefficients of `cos q` and `sin q` (turning), or of `q` and nothing (sliding) [J,
    /// J/m].
    u: [f64; 2],
    /// Whether the joint turns.
    rotational: bool,
}

impl OneJoint {
    /// The closed form with H = `h` and U's coefficients `u` (`cos q`, `sin q` when
    /// `rotational`, else `q`, 0).
    pub(crate) fn from_coefficients(h: f64, u: [f64; 2], rotational: bool) -> OneJoint {
        OneJoint { h, u, rotational }
    }

    /// g(q) = ∂U/∂q [N·m or N].
    #[inline]
    pub(crate) fn gravity(&self, q: f64) -> f64 {
        if self.rotational {
            let (s, c) = q.sin_cos();
            -self.u[0] * s + self.u[1] * c
        } else {
            self.u[0]
        }
    }

    /// q̈ = (τ − g) / (H + ia) into `out`, with rotor inertia `ia` (0 for none); false (and `out`
    /// untouched) when `H + ia` is not positive.
    #[inline]
    pub(crate) fn forward_dynamics(&self, q: &[f64], tau: &[f64], ia: f64, out: &mut [f64]) -> bool {
        let h = self.h + ia;
        if !(h > 0.0) {
            return false;
        }
        out[0] = (tau[0] - self.gravity(q[0])) / h;
        true
    }
}
