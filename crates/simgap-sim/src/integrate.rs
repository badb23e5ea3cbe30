//! Fixed-step RK4, the linearly implicit ROS2 and adaptive Dormand–Prince 5(4) for
//! `ẏ = f(t, y)`, allocation-free after construction.
//!
//! References: E. Hairer, S. P. Nørsett, G. Wanner, *Solving Ordinary Differential Equations I*,
//! 2nd ed., 1993, §II.1 (RK4) and §II.4–5 (Dormand–Prince 5(4), step size control);
//! J. G. Verwer, E. J. Spee, J. G. Blom, W. Hundsdorfer, "A second-order Rosenbrock method
//! applied to photochemical dispersion problems", *SIAM J. Sci. Comput.* 20(4), 1999 (ROS2).

/// Which integrator the simulator uses within each sample period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Integrator {
    /// Classic fourth-order Runge–Kutta, `substeps` equal steps per sample.
    Rk4,
    /// Dormand–Prince 5(4) with error control, for reference solutions: a step is accepted
    /// when `‖err_i / (atol + rtol·max(|y_i|, |y_new,i|))‖_rms <= 1`.
    Adaptive {
        /// Relative tolerance.
        rtol: f64,
        /// Absolute tolerance [state units].
        atol: f64,
    },
}

/// Scratch space of [`Rk4::step`].
#[derive(Clone, Debug)]
pub struct Rk4 {
    k1: Vec<f64>,
    k2: Vec<f64>,
    k3: Vec<f64>,
    k4: Vec<f64>,
    tmp: Vec<f64>,
}

impl Rk4 {
    /// Scratch space for states of length `n`.
    pub fn new(n: usize) -> Self {
        Rk4 { k1: vec![0.0; n], k2: vec![0.0; n], k3: vec![0.0; n], k4: vec![0.0; n], tmp: vec![0.0; n] }
    }

    /// One RK4 step of size `h` from `(t, y)`, overwriting `y`.
    pub fn step<F: FnMut(f64, &[f64], &mut [f64])>(&mut self, f: &mut F, t: f64, h: f64, y: &mut [f64]) {
        self.derivative(f, t, y);
        self.step_from_derivative(f, t, h, y);
    }

    /// The derivative `f(t, y)` (RK4's first stage), kept for [`Rk4::step_from_derivative`].
    pub fn derivative<F: FnMut(f64, &[f64], &mut [f64])>(&mut self, f: &mut F, t: f64, y: &[f64]) -> &[f64] {
        f(t, y, &mut self.k1);
        &self.k1
    }

    /// One RK4 step of size `h` from `(t, y)` whose first stage [`Rk4::derivative`] computed at
    /// the same `(t, y)`, overwriting `y`.
    pub fn step_from_derivative<F: FnMut(f64, &[f64], &mut [f64])>(&mut self, f: &mut F, t: f64, h: f64, y: &mut [f64]) {
        let n = y.len();
        for i in 0..n {
            self.tmp[i] = y[i] + 0.5 * h * self.k1[i];
        }
        f(t + 0.5 * h, &self.tmp, &mut self.k2);
        for i in 0..n {
            self.tmp[i] = y[i] + 0.5 * h * self.k2[i];
        }
        f(t + 0.5 * h, &self.tmp, &mut self.k3);
        for i in 0..n {
            self.tmp[i] = y[i] + h * self.k3[i];
        }
        f(t + h, &self.tmp, &mut self.k4);
        for i in 0..n {
            y[i] += h / 6.0 * (self.k1[i] + 2.0 * self.k2[i] + 2.0 * self.k3[i] + self.k4[i]);
        }
    }
}

/// ROS2's `γ = 1 + 1/√2`: the method is L-stable with the exact Jacobian.
pub const ROS2_GAMMA: f64 = 1.0 + std::f64::consts::FRAC_1_SQRT_2;

/// Scratch space of [`Ros2::step`], the two-stage Rosenbrock W-method of Verwer et al. (1999):
///
/// ```text
/// (I − γhJ) k₁ = f(t, y)
/// (I − γhJ) k₂ = f(t + h, y + h k₁) − 2 k₁
/// y₊ = y + 3/2 h k₁ + 1/2 h k₂,        γ = 1 + 1/√2
/// ```
///
/// Second order for any matrix `J` (with `J = 0` it is Heun's method), and L-stable where `J`
/// is the Jacobian of the stiff part: a rate `λ` of `J` far above `1/h` is damped out within the
/// step instead of asking for `h λ ≤ 2.8` as RK4 does. The caller supplies the solve with
/// `I − γhJ`.
#[derive(Clone, Debug)]
pub struct Ros2 {
    k1: Vec<f64>,
    k2: Vec<f64>,
    tmp: Vec<f64>,
}

impl Ros2 {
    /// Scratch space for states of length `n`.
    pub fn new(n: usize) -> Self {
        Ros2 { k1: vec![0.0; n], k2: vec![0.0; n], tmp: vec![0.0; n] }
    }

    /// One step of size `h` from `(t, y)`, overwriting `y`. `solve(r)` overwrites `r` with
    /// `(I − γhJ)⁻¹ r` for the caller's `J` and this `h` (`γ` = [`ROS2_GAMMA`]).
    pub fn step<F: FnMut(f64, &[f64], &mut [f64]), S: FnMut(&mut [f64])>(&mut self, f: &mut F, solve: &mut S, t: f64, h: f64, y: &mut [f64]) {
        let n = y.len();
        f(t, y, &mut self.k1);
        solve(&mut self.k1);
        for i in 0..n {
            self.tmp[i] = y[i] + h * self.k1[i];
        }
        f(t + h, &self.tmp, &mut self.k2);
        for i in 0..n {
            self.k2[i] -= 2.0 * self.k1[i];
        }
        solve(&mut self.k2);
        for i in 0..n {
            y[i] += h * (1.5 * self.k1[i] + 0.5 * self.k2[i]);
        }
    }
}

// Dormand–Prince 5(4) tableau
const C2: f64 = 1.0 / 5.0;
const C3: f64 = 3.0 / 10.0;
const C4: f64 = 4.0 / 5.0;
const C5: f64 = 8.0 / 9.0;
const A21: f64 = 1.0 / 5.0;
const A31: f64 = 3.0 / 40.0;
const A32: f64 = 9.0 / 40.0;
const A41: f64 = 44.0 / 45.0;
const A42: f64 = -56.0 / 15.0;
const A43: f64 = 32.0 / 9.0;
const A51: f64 = 19372.0 / 6561.0;
const A52: f64 = -25360.0 / 2187.0;
const A53: f64 = 64448.0 / 6561.0;
const A54: f64 = -212.0 / 729.0;
const A61: f64 = 9017.0 / 3168.0;
const A62: f64 = -355.0 / 33.0;
const A63: f64 = 46732.0 / 5247.0;
const A64: f64 = 49.0 / 176.0;
const A65: f64 = -5103.0 / 18656.0;
const B1: f64 = 35.0 / 384.0;
const B3: f64 = 500.0 / 1113.0;
const B4: f64 = 125.0 / 192.0;
const B5: f64 = -2187.0 / 6784.0;
const B6: f64 = 11.0 / 84.0;
// error coefficients: fifth-order minus fourth-order weights
const E1: f64 = 71.0 / 57600.0;
const E3: f64 = -71.0 / 16695.0;
const E4: f64 = 71.0 / 1920.0;
const E5: f64 = -17253.0 / 339200.0;
const E6: f64 = 22.0 / 525.0;
const E7: f64 = -1.0 / 40.0;

/// Adaptive Dormand–Prince 5(4) integrator with its scratch space and step-size memory.
#[derive(Clone, Debug)]
pub struct Dopri5 {
    /// Relative tolerance.
    pub rtol: f64,
    /// Absolute tolerance.
    pub atol: f64,
    k: [Vec<f64>; 7],
    tmp: Vec<f64>,
    ynew: Vec<f64>,
    h: f64,
    /// Accepted steps so far.
    pub accepted: usize,
    /// Rejected steps so far.
    pub rejected: usize,
}

impl Dopri5 {
    /// An integrator for states of length `n`.
    pub fn new(n: usize, rtol: f64, atol: f64) -> Self {
        Dopri5 { rtol, atol, k: std::array::from_fn(|_| vec![0.0; n]), tmp: vec![0.0; n], ynew: vec![0.0; n], h: 0.0, accepted: 0, rejected: 0 }
    }

    /// Integrates from `t0` to `t1` in place. Returns false when the step size collapses
    /// (non-finite state or derivative): `y` is then filled with NaN.
    pub fn integrate<F: FnMut(f64, &[f64], &mut [f64])>(&mut self, f: &mut F, t0: f64, t1: f64, y: &mut [f64]) -> bool {
        let n = y.len();
        let span = t1 - t0;
        if span <= 0.0 {
            return true;
        }
        if self.h <= 0.0 || self.h > span {
            self.h = span;
        }
        let mut t = t0;
        let hmin = span * 1e-12;
        while t < t1 {
            let mut h = self.h.min(t1 - t);
            let last = t + h >= t1 - 1e-15 * t1.abs().max(1.0);
            if last {
                h = t1 - t;
            }
            // stages
            f(t, y, &mut self.k[0]);
            self.stage(y, h, &[A21], 1);
            f(t + C2 * h, &self.tmp, &mut self.k[1]);
            self.stage(y, h, &[A31, A32], 2);
            f(t + C3 * h, &self.tmp, &mut self.k[2]);
            self.stage(y, h, &[A41, A42, A43], 3);
            f(t + C4 * h, &self.tmp, &mut self.k[3]);
            self.stage(y, h, &[A51, A52, A53, A54], 4);
            f(t + C5 * h, &self.tmp, &mut self.k[4]);
            self.stage(y, h, &[A61, A62, A63, A64, A65], 5);
            f(t + h, &self.tmp, &mut self.k[5]);
            for i in 0..n {
                self.ynew[i] = y[i] + h * (B1 * self.k[0][i] + B3 * self.k[2][i] + B4 * self.k[3][i] + B5 * self.k[4][i] + B6 * self.k[5][i]);
            }
            let (ynew, k6) = (&self.ynew, &mut self.k[6]);
            f(t + h, ynew, k6);
            // error estimate, rms norm
            let mut err = 0.0;
            for i in 0..n {
                let e = h * (E1 * self.k[0][i] + E3 * self.k[2][i] + E4 * self.k[3][i] + E5 * self.k[4][i] + E6 * self.k[5][i] + E7 * self.k[6][i]);
                let sc = self.atol + self.rtol * y[i].abs().max(self.ynew[i].abs());
                err += (e / sc).powi(2);
            }
            let err = (err / n as f64).sqrt();
            if !err.is_finite() {
                self.h = h * 0.1;
                self.rejected += 1;
                if self.h < hmin {
                    y.fill(f64::NAN);
                    return false;
                }
                continue;
            }
            // step size control (safety 0.9, factor within [0.2, 5])
            let factor = (0.9 * err.powf(-0.2)).clamp(0.2, 5.0);
            if err <= 1.0 {
                y.copy_from_slice(&self.ynew);
                t = if last { t1 } else { t + h };
                self.accepted += 1;
                if !last || factor < 1.0 {
                    self.h = h * factor;
                }
            } else {
                self.rejected += 1;
                self.h = h * factor.min(1.0);
                if self.h < hmin {
                    y.fill(f64::NAN);
                    return false;
                }
            }
        }
        true
    }

    fn stage(&mut self, y: &[f64], h: f64, a: &[f64], s: usize) {
        for i in 0..y.len() {
            let mut acc = 0.0;
            for j in 0..s {
                acc += a[j] * self.k[j][i];
            }
            self.tmp[i] = y[i] + h * acc;
        }
    }
}
