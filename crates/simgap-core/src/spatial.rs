//! Spatial (6-D) algebra on pairs of 3-vectors, angular part first (Featherstone 2008, ch. 2).
//!
//! Everything here is expressed in one frame given by the caller; the dynamics algorithms of
//! this crate use the world frame with the world origin as reference point.

use nalgebra::{Matrix3, Vector3};

pub use crate::sincos::sin_cos;

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
        Motion { angular: self.angular.cross(&m.angular), linear: self.angular.cross(&m.linear) + self.linear.cross(&m.angular) }
    }

    /// Force cross product `self ×* f`.
    #[inline]
    pub fn cross_force(&self, f: &Force) -> Force {
        Force { moment: self.angular.cross(&f.moment) + self.linear.cross(&f.force), force: self.angular.cross(&f.force) }
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
    pub const IDENTITY: Transform = Transform { rotation: Matrix3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0), translation: Vector3::new(0.0, 0.0, 0.0) };

    /// Builds a transform from URDF `xyz` and `rpy` (fixed-axis roll, pitch, yaw: R = Rz(y) Ry(p) Rx(r)).
    pub fn from_xyz_rpy(xyz: [f64; 3], rpy: [f64; 3]) -> Self {
        let (sr, cr) = rpy[0].sin_cos();
        let (sp, cp) = rpy[1].sin_cos();
        let (sy, cy) = rpy[2].sin_cos();
        let rotation = Matrix3::new(cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr, sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr, -sp, cp * sr, cp * cr);
        Transform { rotation, translation: Vector3::from(xyz) }
    }

    /// Composition `self * other` (apply `other` first).
    #[inline]
    pub fn compose(&self, other: &Transform) -> Transform {
        Transform { rotation: self.rotation * other.rotation, translation: self.rotation * other.translation + self.translation }
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
    pub const ZERO: SpatialInertia = SpatialInertia { mass: 0.0, first_moment: Vector3::new(0.0, 0.0, 0.0), rotational: Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0) };

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
    #[inline(always)]
    pub fn transformed(&self, x: &Transform) -> SpatialInertia {
        let r = &x.rotation;
        let t = &x.translation;
        let hr = r * self.first_moment;
        // rotate about the origin, then shift the reference point by t
        let rot = r * self.rotational * r.transpose();
        let shift = Matrix3::from_diagonal_element(2.0 * hr.dot(t)) - t * hr.transpose() - hr * t.transpose() + cross_t_cross(t, t) * self.mass;
        SpatialInertia { mass: self.mass, first_moment: hr + t * self.mass, rotational: rot + shift }
    }

    /// Spatial momentum (or force) `I m`.
    #[inline]
    pub fn mul_motion(&self, m: &Motion) -> Force {
        Force { moment: self.rotational * m.angular + self.first_moment.cross(&m.linear), force: m.linear * self.mass - self.first_moment.cross(&m.angular) }
    }

    /// Time derivative of this inertia for a body moving with spatial velocity `v`
    /// (both in this fixed frame): `İ = v ×* I − I v×`.
    #[inline(always)]
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
        SpatialInertia { mass: self.mass + o.mass, first_moment: self.first_moment + o.first_moment, rotational: self.rotational + o.rotational }
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
        Force { moment: self.rotational * m.angular + self.first_moment.cross(&m.linear), force: -self.first_moment.cross(&m.angular) }
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
