//! Several states per SIMD register: the lane type [`Lanes`] and the spatial algebra of the
//! lane kernels (structure of arrays: each number of a vector or inertia holds `W` states).
//!
//! The operations are plain element-wise loops over `[f64; W]`; compiled inside a function with
//! `#[target_feature(enable = "avx2")]` (W = 4) or `"avx512f"` (W = 8) they become one vector
//! instruction each. No operation is fused (no FMA), so every lane computes exactly what the
//! same code computes on one `f64`.

use std::ops::{Add, AddAssign, Mul, Neg, Sub};

use nalgebra::{Matrix3, Vector3};

/// `W` numbers, one per state.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(transparent)]
pub(crate) struct Lanes<const W: usize>(pub(crate) [f64; W]);

impl<const W: usize> Lanes<W> {
    /// The same number in every lane.
    #[inline(always)]
    pub(crate) fn splat(x: f64) -> Self {
        Lanes([x; W])
    }

    /// Zero in every lane.
    #[inline(always)]
    pub(crate) fn zero() -> Self {
        Lanes([0.0; W])
    }

    /// `(sin x, cos x)` lane by lane, the same numbers as [`crate::sincos::sin_cos`] bit for
    /// bit (see `sincos::sin_cos_lanes`).
    #[inline(always)]
    pub(crate) fn sin_cos(self) -> (Self, Self) {
        let (s, c) = crate::sincos::sin_cos_lanes(self.0);
        (Lanes(s), Lanes(c))
    }
}

macro_rules! lane_op {
    ($tr:ident, $f:ident, $op:tt) => {
        // `r[k] = r[k] $op o` is the one spelling a macro can give every operator
        #[allow(clippy::assign_op_pattern)]
        impl<const W: usize> $tr for Lanes<W> {
            type Output = Self;
            #[inline(always)]
            fn $f(self, o: Self) -> Self {
                let mut r = self.0;
                for k in 0..W {
                    r[k] = r[k] $op o.0[k];
                }
                Lanes(r)
            }
        }
        #[allow(clippy::assign_op_pattern)]
        impl<const W: usize> $tr<f64> for Lanes<W> {
            type Output = Self;
            #[inline(always)]
            fn $f(self, o: f64) -> Self {
                let mut r = self.0;
                for k in 0..W {
                    r[k] = r[k] $op o;
                }
                Lanes(r)
            }
        }
    };
}
lane_op!(Add, add, +);
lane_op!(Sub, sub, -);
lane_op!(Mul, mul, *);

impl<const W: usize> Neg for Lanes<W> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        let mut r = self.0;
        for x in &mut r {
            *x = -*x;
        }
        Lanes(r)
    }
}

impl<const W: usize> AddAssign for Lanes<W> {
    #[inline(always)]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}

/// A 3-vector of lanes.
#[derive(Clone, Copy, Debug)]
pub(crate) struct V3<const W: usize> {
    pub(crate) x: Lanes<W>,
    pub(crate) y: Lanes<W>,
    pub(crate) z: Lanes<W>,
}

impl<const W: usize> V3<W> {
    #[inline(always)]
    pub(crate) fn zero() -> Self {
        V3 { x: Lanes::zero(), y: Lanes::zero(), z: Lanes::zero() }
    }
    #[inline(always)]
    pub(crate) fn splat(v: &Vector3<f64>) -> Self {
        V3 { x: Lanes::splat(v.x), y: Lanes::splat(v.y), z: Lanes::splat(v.z) }
    }
    #[inline(always)]
    pub(crate) fn scale(self, s: Lanes<W>) -> Self {
        V3 { x: self.x * s, y: self.y * s, z: self.z * s }
    }
    #[inline(always)]
    pub(crate) fn scale_f(self, s: f64) -> Self {
        V3 { x: self.x * s, y: self.y * s, z: self.z * s }
    }
    #[inline(always)]
    pub(crate) fn cross(self, o: Self) -> Self {
        V3 { x: self.y * o.z - self.z * o.y, y: self.z * o.x - self.x * o.z, z: self.x * o.y - self.y * o.x }
    }
    #[inline(always)]
    pub(crate) fn dot(self, o: Self) -> Lanes<W> {
        self.x * o.x + self.y * o.y + self.z * o.z
    }
    /// `self × c` for a constant `c`.
    #[inline(always)]
    pub(crate) fn cross_c(self, o: &Vector3<f64>) -> Self {
        V3 { x: self.y * o.z - self.z * o.y, y: self.z * o.x - self.x * o.z, z: self.x * o.y - self.y * o.x }
    }
}

impl<const W: usize> Add for V3<W> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        V3 { x: self.x + o.x, y: self.y + o.y, z: self.z + o.z }
    }
}
impl<const W: usize> Sub for V3<W> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        V3 { x: self.x - o.x, y: self.y - o.y, z: self.z - o.z }
    }
}
impl<const W: usize> Neg for V3<W> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        V3 { x: -self.x, y: -self.y, z: -self.z }
    }
}

/// A 3×3 matrix of lanes, row-major.
#[derive(Clone, Copy, Debug)]
pub(crate) struct M3<const W: usize>(pub(crate) [[Lanes<W>; 3]; 3]);

impl<const W: usize> M3<W> {
    #[inline(always)]
    pub(crate) fn splat(m: &Matrix3<f64>) -> Self {
        let mut out = [[Lanes::zero(); 3]; 3];
        for (r, row) in out.iter_mut().enumerate() {
            for (c, x) in row.iter_mut().enumerate() {
                *x = Lanes::splat(m[(r, c)]);
            }
        }
        M3(out)
    }
    /// `a + b cos + d sin` for constants `a`, `b`, `d`.
    #[inline(always)]
    pub(crate) fn rodrigues(a: &Matrix3<f64>, b: &Matrix3<f64>, d: &Matrix3<f64>, s: Lanes<W>, c: Lanes<W>) -> Self {
        let mut out = [[Lanes::zero(); 3]; 3];
        for (r, row) in out.iter_mut().enumerate() {
            for (k, x) in row.iter_mut().enumerate() {
                *x = c * b[(r, k)] + s * d[(r, k)] + a[(r, k)];
            }
        }
        M3(out)
    }
    #[inline(always)]
    pub(crate) fn mul(&self, o: &Self) -> Self {
        let (a, b) = (&self.0, &o.0);
        let mut out = [[Lanes::zero(); 3]; 3];
        for (r, row) in out.iter_mut().enumerate() {
            for (c, x) in row.iter_mut().enumerate() {
                *x = a[r][0] * b[0][c] + a[r][1] * b[1][c] + a[r][2] * b[2][c];
            }
        }
        M3(out)
    }
    #[inline(always)]
    pub(crate) fn mul_v(&self, v: V3<W>) -> V3<W> {
        let a = &self.0;
        V3 { x: a[0][0] * v.x + a[0][1] * v.y + a[0][2] * v.z, y: a[1][0] * v.x + a[1][1] * v.y + a[1][2] * v.z, z: a[2][0] * v.x + a[2][1] * v.y + a[2][2] * v.z }
    }
    /// `self v` for a constant `v`.
    #[inline(always)]
    pub(crate) fn mul_c(&self, v: &Vector3<f64>) -> V3<W> {
        let a = &self.0;
        V3 { x: a[0][0] * v.x + a[0][1] * v.y + a[0][2] * v.z, y: a[1][0] * v.x + a[1][1] * v.y + a[1][2] * v.z, z: a[2][0] * v.x + a[2][1] * v.y + a[2][2] * v.z }
    }
}

/// A symmetric 3×3 matrix of lanes: `[xx, yy, zz, xy, xz, yz]`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sym<const W: usize>(pub(crate) [Lanes<W>; 6]);

impl<const W: usize> Sym<W> {
    #[inline(always)]
    pub(crate) fn zero() -> Self {
        Sym([Lanes::zero(); 6])
    }
    #[inline(always)]
    pub(crate) fn mul_v(&self, v: V3<W>) -> V3<W> {
        let [xx, yy, zz, xy, xz, yz] = self.0;
        V3 { x: xx * v.x + xy * v.y + xz * v.z, y: xy * v.x + yy * v.y + yz * v.z, z: xz * v.x + yz * v.y + zz * v.z }
    }
}

impl<const W: usize> Add for Sym<W> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        let mut out = self.0;
        for (x, y) in out.iter_mut().zip(o.0) {
            *x += y;
        }
        Sym(out)
    }
}

/// A spatial motion of lanes (angular, then linear at the world origin).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Mot<const W: usize> {
    pub(crate) w: V3<W>,
    pub(crate) v: V3<W>,
}

/// A spatial force of lanes (moment about the world origin, then force).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Frc<const W: usize> {
    pub(crate) n: V3<W>,
    pub(crate) f: V3<W>,
}

impl<const W: usize> Mot<W> {
    #[inline(always)]
    pub(crate) fn zero() -> Self {
        Mot { w: V3::zero(), v: V3::zero() }
    }
    /// `self s + o`.
    #[inline(always)]
    pub(crate) fn scale_add(self, s: Lanes<W>, o: Self) -> Self {
        Mot { w: self.w.scale(s) + o.w, v: self.v.scale(s) + o.v }
    }
    /// Motion cross product `self × m`.
    #[inline(always)]
    pub(crate) fn cross_motion(self, m: Self) -> Self {
        Mot { w: self.w.cross(m.w), v: self.w.cross(m.v) + self.v.cross(m.w) }
    }
    /// Force cross product `self ×* f`.
    #[inline(always)]
    pub(crate) fn cross_force(self, f: Frc<W>) -> Frc<W> {
        Frc { n: self.w.cross(f.n) + self.v.cross(f.f), f: self.w.cross(f.f) }
    }
    /// Power pairing `selfᵀ f`.
    #[inline(always)]
    pub(crate) fn dot(self, f: Frc<W>) -> Lanes<W> {
        self.w.dot(f.n) + self.v.dot(f.f)
    }
}

impl<const W: usize> Add for Mot<W> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Mot { w: self.w + o.w, v: self.v + o.v }
    }
}

impl<const W: usize> Frc<W> {
    #[inline(always)]
    pub(crate) fn zero() -> Self {
        Frc { n: V3::zero(), f: V3::zero() }
    }
    #[inline(always)]
    pub(crate) fn scale(self, s: Lanes<W>) -> Self {
        Frc { n: self.n.scale(s), f: self.f.scale(s) }
    }
}

impl<const W: usize> Add for Frc<W> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Frc { n: self.n + o.n, f: self.f + o.f }
    }
}
impl<const W: usize> Sub for Frc<W> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Frc { n: self.n - o.n, f: self.f - o.f }
    }
}

/// A rigid-body inertia of lanes about the world origin: mass, first moment, rotational inertia.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Ine<const W: usize> {
    pub(crate) m: Lanes<W>,
    pub(crate) h: V3<W>,
    pub(crate) i: Sym<W>,
}

impl<const W: usize> Ine<W> {
    #[inline(always)]
    pub(crate) fn zero() -> Self {
        Ine { m: Lanes::zero(), h: V3::zero(), i: Sym::zero() }
    }

    /// `I m`.
    #[inline(always)]
    pub(crate) fn mul_motion(&self, m: Mot<W>) -> Frc<W> {
        Frc { n: self.i.mul_v(m.w) + self.h.cross(m.v), f: m.v.scale(self.m) - self.h.cross(m.w) }
    }

    /// The body inertia (`mass`, first moment `hb`, rotational `ib` about the link frame
    /// origin, constants) moved to the world by the pose `(r, t)`.
    #[inline(always)]
    pub(crate) fn transformed(mass: f64, hb: &Vector3<f64>, ib: &Matrix3<f64>, r: &M3<W>, t: V3<W>) -> Self {
        let hr = r.mul_c(hb);
        // rotate: r ib rᵀ (upper triangle)
        let mut a = [[Lanes::<W>::zero(); 3]; 3];
        for (row, out) in a.iter_mut().enumerate() {
            for (col, x) in out.iter_mut().enumerate() {
                *x = r.0[row][0] * ib[(0, col)] + r.0[row][1] * ib[(1, col)] + r.0[row][2] * ib[(2, col)];
            }
        }
        let rot = |p: usize, q: usize| a[p][0] * r.0[q][0] + a[p][1] * r.0[q][1] + a[p][2] * r.0[q][2];
        // shift the reference point by t: diag(2 hr·t + m t·t) − t hrᵀ − hr tᵀ − m t tᵀ
        let d = hr.dot(t) * 2.0 + t.dot(t) * mass;
        let tm = t.scale_f(mass);
        let off = |tp: Lanes<W>, tq: Lanes<W>, hp: Lanes<W>, hq: Lanes<W>, tmq: Lanes<W>| -(tp * hq + hp * tq + tp * tmq);
        let i = Sym([
            rot(0, 0) + d + off(t.x, t.x, hr.x, hr.x, tm.x),
            rot(1, 1) + d + off(t.y, t.y, hr.y, hr.y, tm.y),
            rot(2, 2) + d + off(t.z, t.z, hr.z, hr.z, tm.z),
            rot(0, 1) + off(t.x, t.y, hr.x, hr.y, tm.y),
            rot(0, 2) + off(t.x, t.z, hr.x, hr.z, tm.z),
            rot(1, 2) + off(t.y, t.z, hr.y, hr.z, tm.z),
        ]);
        Ine { m: Lanes::splat(mass), h: hr + tm, i }
    }

    /// `İ = v ×* I − I v×` for a body moving with velocity `v`.
    #[inline(always)]
    pub(crate) fn rate(&self, v: Mot<W>) -> Rate<W> {
        let (w, v0, h) = (v.w, v.v, self.h);
        let [xx, yy, zz, xy, xz, yz] = self.i.0;
        // columns of M = [w]× I
        let c0 = w.cross(V3 { x: xx, y: xy, z: xz });
        let c1 = w.cross(V3 { x: xy, y: yy, z: yz });
        let c2 = w.cross(V3 { x: xz, y: yz, z: zz });
        let d = v0.dot(h) * 2.0;
        let i = Sym([
            c0.x + c0.x + d - (h.x * v0.x + v0.x * h.x),
            c1.y + c1.y + d - (h.y * v0.y + v0.y * h.y),
            c2.z + c2.z + d - (h.z * v0.z + v0.z * h.z),
            c1.x + c0.y - (h.x * v0.y + v0.x * h.y),
            c2.x + c0.z - (h.x * v0.z + v0.x * h.z),
            c2.y + c1.z - (h.y * v0.z + v0.y * h.z),
        ]);
        Rate { h: v0.scale(self.m) + w.cross(h), i }
    }
}

impl<const W: usize> Add for Ine<W> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Ine { m: self.m + o.m, h: self.h + o.h, i: self.i + o.i }
    }
}

/// Time derivative of an [`Ine`] (no mass part).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Rate<const W: usize> {
    pub(crate) h: V3<W>,
    pub(crate) i: Sym<W>,
}

impl<const W: usize> Rate<W> {
    #[inline(always)]
    pub(crate) fn zero() -> Self {
        Rate { h: V3::zero(), i: Sym::zero() }
    }
    /// `İ m`.
    #[inline(always)]
    pub(crate) fn mul_motion(&self, m: Mot<W>) -> Frc<W> {
        Frc { n: self.i.mul_v(m.w) + self.h.cross(m.v), f: -self.h.cross(m.w) }
    }
}

impl<const W: usize> Add for Rate<W> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Rate { h: self.h + o.h, i: self.i + o.i }
    }
}
