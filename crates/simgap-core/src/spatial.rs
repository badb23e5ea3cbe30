//! Spatial (6-D) algebra on pairs of 3-vectors, angular part first (Featherstone 2008, ch. 2).
//!
//! Everything here is expressed in one frame given by the caller; the dynamics algorithms of
//! this crate use the world frame with the world origin as reference point.

use nalgebra::{Matrix3, Vector3};

/// `(sin x, cos x)`, within 1 ulp of the correctly rounded values, inlined.
///
/// Every algorithm evaluates one `sin_cos` per revolute joint, and the out-of-line libm call
/// was the largest single cost of the kinematics. This is musl's (FreeBSD's) kernel: argument
/// reduction by π/2 in three parts (Cody–Waite, exact for |x| < 2²⁰ π/2) and degree-13/14
/// minimax polynomials on [−π/4, π/4]; larger or non-finite arguments go to libm.
#[inline]
pub fn sin_cos(x: f64) -> (f64, f64) {
    const TOINT: f64 = 1.5 / f64::EPSILON;
    const INVPIO2: f64 = std::f64::consts::FRAC_2_PI;
    const PIO2_1: f64 = 1.570_796_326_734_125_614_17e0;
    const PIO2_1T: f64 = 6.077_100_506_506_192_249_32e-11;
    const PIO2_2: f64 = 6.077_100_506_303_965_976_60e-11;
    const PIO2_2T: f64 = 2.022_266_248_795_950_631_54e-21;
    const PIO2_3: f64 = 2.022_266_248_711_166_455_80e-21;
    const PIO2_3T: f64 = 8.478_427_660_368_899_569_97e-32;
    let ix = (x.to_bits() >> 32) as u32 & 0x7fff_ffff;
    if ix <= 0x3fe9_21fb {
        // |x| <= π/4: no reduction
        return (sin_kernel(x, 0.0), cos_kernel(x, 0.0));
    }
    if ix >= 0x4139_21fb {
        // |x| >= 2²⁰ π/2, inf or nan
        return x.sin_cos();
    }
    // x = n π/2 + (y0 + y1), |y0 + y1| <= π/4
    let fk = x * INVPIO2 + TOINT - TOINT;
    let n = fk as i32;
    let mut r = x - fk * PIO2_1;
    let mut w = fk * PIO2_1T;
    let mut y0 = r - w;
    let ex = (ix >> 20) as i32;
    let ey = ((y0.to_bits() >> 52) & 0x7ff) as i32;
    if ex - ey > 16 {
        // second round, good to 118 bits
        let t = r;
        w = fk * PIO2_2;
        r = t - w;
        w = fk * PIO2_2T - ((t - r) - w);
        y0 = r - w;
        let ey = ((y0.to_bits() >> 52) & 0x7ff) as i32;
        if ex - ey > 49 {
            // third round, good to 151 bits
            let t = r;
            w = fk * PIO2_3;
            r = t - w;
            w = fk * PIO2_3T - ((t - r) - w);
            y0 = r - w;
        }
    }
    let y1 = (r - y0) - w;
    let (s, c) = (sin_kernel(y0, y1), cos_kernel(y0, y1));
    match n & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// sin(x + y) for |x + y| <= π/4, y the tail of x (musl `__sin`).
#[inline(always)]
fn sin_kernel(x: f64, y: f64) -> f64 {
    const S1: f64 = -1.666_666_666_666_663_243_48e-1;
    const S2: f64 = 8.333_333_333_322_489_461_24e-3;
    const S3: f64 = -1.984_126_982_985_794_931_34e-4;
    const S4: f64 = 2.755_731_370_707_006_767_89e-6;
    const S5: f64 = -2.505_076_025_340_686_341_95e-8;
    const S6: f64 = 1.589_690_995_211_550_102_21e-10;
    let z = x * x;
    let w = z * z;
    let r = S2 + z * (S3 + z * S4) + z * w * (S5 + z * S6);
    let v = z * x;
    x - ((z * (0.5 * y - v * r) - y) - v * S1)
}

/// cos(x + y) for |x + y| <= π/4, y the tail of x (musl `__cos`).
#[inline(always)]
fn cos_kernel(x: f64, y: f64) -> f64 {
    const C1: f64 = 4.166_666_666_666_660_190_37e-2;
    const C2: f64 = -1.388_888_888_887_410_957_49e-3;
    const C3: f64 = 2.480_158_728_947_672_941_78e-5;
    const C4: f64 = -2.755_731_435_139_066_330_35e-7;
    const C5: f64 = 2.087_572_321_298_174_827_90e-9;
    const C6: f64 = -1.135_964_755_778_819_482_65e-11;
    let z = x * x;
    let w = z * z;
    let r = z * (C1 + z * (C2 + z * C3)) + w * w * (C4 + z * (C5 + z * C6));
    let hz = 0.5 * z;
    let w = 1.0 - hz;
    w + (((1.0 - w) - hz) + (z * r - x * y))
}

/// A spatial motion vector (twist or spatial acceleration): angular part, then the linear
/// velocity of the point at the frame origin.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Motion {
    /// Angular velocity [rad/s] (or acceleration).
    pub angular: Vector3<f64>,
    /// Linear velocity [m/s] of the body point at the frame origin (or its acceleration).
    pub linear: Vector3<f64>,
}

/// A spatial force vector (wrench): moment about the frame origin, then the force.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Force {
    /// Moment about the frame origin [N·m].
    pub moment: Vector3<f64>,
    /// Force [N].
    pub force: Vector3<f64>,
}

impl Motion {
    /// The zero motion.
    pub const ZERO: Motion = Motion { angular: Vector3::new(0.0, 0.0, 0.0), linear: Vector3::new(0.0, 0.0, 0.0) };

    /// Builds a motion from its parts.
    #[inline]
    pub fn new(angular: Vector3<f64>, linear: Vector3<f64>) -> Self {
        Motion { angular, linear }
    }

    /// Motion cross product `self × m` (the derivative of `m` moving with velocity `self`).
    #[inline]
    pub fn cross_motion(&self, m: &Motion) -> Motion {
        Motion {
            angular: self.angular.cross(&m.angular),
            linear: self.angular.cross(&m.linear) + self.linear.cross(&m.angular),
        }
    }

    /// Force cross product `self ×* f`.
    #[inline]
    pub fn cross_force(&self, f: &Force) -> Force {
        Force {
            moment: self.angular.cross(&f.moment) + self.linear.cross(&f.force),
            force: self.angular.cross(&f.force),
        }
    }

    /// Power pairing `selfᵀ f`.
    #[inline]
    pub fn dot(&self, f: &Force) -> f64 {
        self.angular.dot(&f.moment) + self.linear.dot(&f.force)
    }

    /// `self * s + other`, component-wise.
    #[inline]
    pub fn scale_add(&self, s: f64, other: &Motion) -> Motion {
        Motion { angular: self.angular * s + other.angular, linear: self.linear * s + other.linear }
    }
}

impl std::ops::Add for Motion {
    type Output = Motion;
    #[inline]
    fn add(self, o: Motion) -> Motion {
        Motion { angular: self.angular + o.angular, linear: self.linear + o.linear }
    }
}

impl std::ops::Sub for Motion {
    type Output = Motion;
    #[inline]
    fn sub(self, o: Motion) -> Motion {
        Motion { angular: self.angular - o.angular, linear: self.linear - o.linear }
    }
}

impl Force {
    /// The zero force.
    pub const ZERO: Force = Force { moment: Vector3::new(0.0, 0.0, 0.0), force: Vector3::new(0.0, 0.0, 0.0) };
}

impl std::ops::Add for Force {
    type Output = Force;
    #[inline]
    fn add(self, o: Force) -> Force {
        Force { moment: self.moment + o.moment, force: self.force + o.force }
    }
}

impl std::ops::AddAssign for Force {
    #[inline]
    fn add_assign(&mut self, o: Force) {
        self.moment += o.moment;
        self.force += o.force;
    }
}

impl std::ops::Sub for Force {
    type Output = Force;
    #[inline]
    fn sub(self, o: Force) -> Force {
        Force { moment: self.moment - o.moment, force: self.force - o.force }
    }
}

impl std::ops::Mul<f64> for Force {
    type Output = Force;
    #[inline]
    fn mul(self, s: f64) -> Force {
        Force { moment: self.moment * s, force: self.force * s }
    }
}

/// A rigid transform: `p_parent = rotation * p_child + translation`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// Rotation from child to parent coordinates.
    pub rotation: Matrix3<f64>,
    /// Position of the child origin in parent coordinates [m].
    pub translation: Vector3<f64>,
}

impl Default for Transform {
    fn default() -> Self {
        Transform::IDENTITY
    }
}

impl Transform {
    /// The identity transform.
    pub const IDENTITY: Transform = Transform {
        rotation: Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
        translation: Vector3::new(0.0, 0.0, 0.0),
    };

    /// Builds a transform from URDF `xyz` and `rpy` (fixed-axis roll, pitch, yaw: R = Rz(y) Ry(p) Rx(r)).
    pub fn from_xyz_rpy(xyz: [f64; 3], rpy: [f64; 3]) -> Self {
        let (sr, cr) = rpy[0].sin_cos();
        let (sp, cp) = rpy[1].sin_cos();
        let (sy, cy) = rpy[2].sin_cos();
        let rotation = Matrix3::new(
            cy * cp,
            cy * sp * sr - sy * cr,
            cy * sp * cr + sy * sr,
            sy * cp,
            sy * sp * sr + cy * cr,
            sy * sp * cr - cy * sr,
            -sp,
            cp * sr,
            cp * cr,
        );
        Transform { rotation, translation: Vector3::from(xyz) }
    }

    /// Composition `self * other` (apply `other` first).
    #[inline]
    pub fn compose(&self, other: &Transform) -> Transform {
        Transform {
            rotation: self.rotation * other.rotation,
            translation: self.rotation * other.translation + self.translation,
        }
    }

    /// Maps a point from child to parent coordinates.
    #[inline]
    pub fn apply_point(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * p + self.translation
    }
}

/// Rigid-body inertia about the frame origin, by its ten parameters: mass, first moment of
/// mass `h = m c` and rotational inertia `ibar` about the frame origin (not the centre of mass).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpatialInertia {
    /// Mass [kg].
    pub mass: f64,
    /// First moment of mass `m c` [kg·m].
    pub first_moment: Vector3<f64>,
    /// Rotational inertia about the frame origin [kg·m²].
    pub rotational: Matrix3<f64>,
}

impl Default for SpatialInertia {
    fn default() -> Self {
        SpatialInertia::ZERO
    }
}

/// `[a]×ᵀ [b]× = (a·b) 1 − b aᵀ`.
#[inline]
fn cross_t_cross(a: &Vector3<f64>, b: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::from_diagonal_element(a.dot(b)) - b * a.transpose()
}

impl SpatialInertia {
    /// The massless body.
    pub const ZERO: SpatialInertia =
        SpatialInertia { mass: 0.0, first_moment: Vector3::new(0.0, 0.0, 0.0), rotational: Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0) };

    /// Inertia of a body of mass `mass` whose centre of mass is at `com` and whose rotational
    /// inertia about the centre of mass is `inertia_com` (parallel-axis theorem).
    pub fn from_com(mass: f64, com: Vector3<f64>, inertia_com: Matrix3<f64>) -> Self {
        SpatialInertia { mass, first_moment: com * mass, rotational: inertia_com + cross_t_cross(&com, &com) * mass }
    }

    /// Centre of mass (zero for a massless body) [m].
    pub fn com(&self) -> Vector3<f64> {
        if self.mass > 0.0 {
            self.first_moment / self.mass
        } else {
            Vector3::zeros()
        }
    }

    /// Rotational inertia about the centre of mass [kg·m²].
    pub fn inertia_about_com(&self) -> Matrix3<f64> {
        if self.mass > 0.0 {
            let c = self.com();
            self.rotational - cross_t_cross(&c, &c) * self.mass
        } else {
            self.rotational
        }
    }

    /// The same inertia expressed in the parent frame of `x`.
    #[inline]
    pub fn transformed(&self, x: &Transform) -> SpatialInertia {
        let r = &x.rotation;
        let t = &x.translation;
        let hr = r * self.first_moment;
        // rotate about the origin, then shift the reference point by t
        let rot = r * self.rotational * r.transpose();
        let shift = Matrix3::from_diagonal_element(2.0 * hr.dot(t)) - t * hr.transpose() - hr * t.transpose()
            + cross_t_cross(t, t) * self.mass;
        SpatialInertia { mass: self.mass, first_moment: hr + t * self.mass, rotational: rot + shift }
    }

    /// Spatial momentum (or force) `I m`.
    #[inline]
    pub fn mul_motion(&self, m: &Motion) -> Force {
        Force {
            moment: self.rotational * m.angular + self.first_moment.cross(&m.linear),
            force: m.linear * self.mass - self.first_moment.cross(&m.angular),
        }
    }

    /// Time derivative of this inertia for a body moving with spatial velocity `v`
    /// (both in this fixed frame): `İ = v ×* I − I v×`.
    #[inline]
    pub fn rate(&self, v: &Motion) -> InertiaRate {
        let w = &v.angular;
        let v0 = &v.linear;
        let h = &self.first_moment;
        // [w]× I − I [w]× = M + Mᵀ with M = [w]× I, since I is symmetric and [w]× skew
        let m = w.cross_matrix() * self.rotational;
        let hv = h * v0.transpose();
        let rotational = m + m.transpose() + Matrix3::from_diagonal_element(2.0 * v0.dot(h)) - hv - hv.transpose();
        InertiaRate { first_moment: v0 * self.mass + w.cross(h), rotational }
    }
}

impl std::ops::Add for SpatialInertia {
    type Output = SpatialInertia;
    #[inline]
    fn add(self, o: SpatialInertia) -> SpatialInertia {
        SpatialInertia {
            mass: self.mass + o.mass,
            first_moment: self.first_moment + o.first_moment,
            rotational: self.rotational + o.rotational,
        }
    }
}

impl std::ops::AddAssign for SpatialInertia {
    #[inline]
    fn add_assign(&mut self, o: SpatialInertia) {
        self.mass += o.mass;
        self.first_moment += o.first_moment;
        self.rotational += o.rotational;
    }
}

/// Time derivative of a [`SpatialInertia`] (mass is constant, so it has no mass part).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InertiaRate {
    /// Rate of the first moment of mass [kg·m/s].
    pub first_moment: Vector3<f64>,
    /// Rate of the rotational inertia about the origin [kg·m²/s].
    pub rotational: Matrix3<f64>,
}

impl Default for InertiaRate {
    fn default() -> Self {
        InertiaRate { first_moment: Vector3::zeros(), rotational: Matrix3::zeros() }
    }
}

impl InertiaRate {
    /// `İ m`.
    #[inline]
    pub fn mul_motion(&self, m: &Motion) -> Force {
        Force {
            moment: self.rotational * m.angular + self.first_moment.cross(&m.linear),
            force: -self.first_moment.cross(&m.angular),
        }
    }
}

impl std::ops::AddAssign for InertiaRate {
    #[inline]
    fn add_assign(&mut self, o: InertiaRate) {
        self.first_moment += o.first_moment;
        self.rotational += o.rotational;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sin_cos_matches_libm_within_two_ulps() {
        let close = |a: f64, b: f64| (a.is_nan() && b.is_nan()) || (a - b).abs() <= 2.0 * f64::EPSILON * b.abs().max(f64::MIN_POSITIVE);
        let mut x = -1.0e4;
        while x < 1.0e4 {
            for v in [x, x * 1e-3, x * 1e-6, 2.0e6 * x] {
                let ((s, c), (s0, c0)) = (sin_cos(v), v.sin_cos());
                assert!(close(s, s0) && close(c, c0), "sin_cos({v}) = ({s}, {c}), libm ({s0}, {c0})");
            }
            x += 0.123_456_789;
        }
        for v in [0.0, -0.0, 1e-300, std::f64::consts::FRAC_PI_4, std::f64::consts::PI, 1.0e300, f64::INFINITY, f64::NAN] {
            let ((s, c), (s0, c0)) = (sin_cos(v), v.sin_cos());
            assert!(close(s, s0) && close(c, c0), "sin_cos({v}) = ({s}, {c}), libm ({s0}, {c0})");
        }
    }

    #[test]
    fn inertia_transform_matches_point_masses() {
        // two point masses, expressed in a child frame, then moved to a parent frame
        let pts = [(1.5, Vector3::new(0.1, -0.2, 0.3)), (0.7, Vector3::new(-0.4, 0.05, 0.2))];
        let mut child = SpatialInertia::ZERO;
        for (m, p) in &pts {
            child += SpatialInertia::from_com(*m, *p, Matrix3::zeros());
        }
        let x = Transform::from_xyz_rpy([0.3, -0.1, 0.7], [0.2, -0.5, 1.1]);
        let mut expected = SpatialInertia::ZERO;
        for (m, p) in &pts {
            expected += SpatialInertia::from_com(*m, x.apply_point(p), Matrix3::zeros());
        }
        let got = child.transformed(&x);
        assert!((got.first_moment - expected.first_moment).norm() < 1e-12);
        assert!((got.rotational - expected.rotational).norm() < 1e-12);
    }

    #[test]
    fn inertia_rate_is_symmetric_and_matches_finite_difference() {
        let body = SpatialInertia::from_com(2.0, Vector3::new(0.3, 0.1, -0.2), Matrix3::new(0.1, 0.01, 0.0, 0.01, 0.2, 0.02, 0.0, 0.02, 0.3));
        let v = Motion::new(Vector3::new(0.4, -1.0, 0.7), Vector3::new(0.2, 0.5, -0.3));
        let rate = body.rate(&v);
        assert!((rate.rotational - rate.rotational.transpose()).norm() < 1e-12);
        // move the body by a small screw and difference
        let dt = 1e-7;
        let rot = nalgebra::Rotation3::new(v.angular * dt).into_inner();
        // a point p moves as p' = R p + (v0 dt) to first order (v0: velocity of the body point at the origin)
        let x = Transform { rotation: rot, translation: v.linear * dt };
        let moved = body.transformed(&x);
        let fd_h = (moved.first_moment - body.first_moment) / dt;
        let fd_i = (moved.rotational - body.rotational) / dt;
        assert!((fd_h - rate.first_moment).norm() < 1e-5);
        assert!((fd_i - rate.rotational).norm() < 1e-5);
    }
}
