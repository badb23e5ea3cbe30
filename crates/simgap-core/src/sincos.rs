//! `sin` and `cos` of one angle at once, inlined: the kernel of every revolute joint's
//! transform, for one angle ([`sin_cos`]) and for the `W` lanes of the batch functions
//! (`sin_cos_lanes`, the same numbers bit for bit).
//!
//! A port of musl's (FreeBSD's) `sin`/`cos`: argument reduction by π/2 in three parts
//! (Cody–Waite) and the minimax polynomials `__sin`/`__cos` on [−π/4, π/4]. The constants are
//! musl's, digit for digit; this is the only copy of them.
#![allow(clippy::excessive_precision)]

/// `1.5 / ε`: adding and subtracting it rounds to an integer.
const TOINT: f64 = 1.5 / f64::EPSILON;
/// 2/π.
const INVPIO2: f64 = std::f64::consts::FRAC_2_PI;
/// The first 33 bits of π/2, and π/2 − `PIO2_1`.
const PIO2_1: f64 = 1.570_796_326_734_125_614_17e0;
const PIO2_1T: f64 = 6.077_100_506_506_192_249_32e-11;
/// The second 33 bits of π/2, and π/2 − (`PIO2_1` + `PIO2_2`).
const PIO2_2: f64 = 6.077_100_506_303_965_976_60e-11;
const PIO2_2T: f64 = 2.022_266_248_795_950_631_54e-21;
/// The third 33 bits of π/2, and π/2 − (`PIO2_1` + `PIO2_2` + `PIO2_3`).
const PIO2_3: f64 = 2.022_266_248_711_166_455_80e-21;
const PIO2_3T: f64 = 8.478_427_660_368_899_569_97e-32;

/// `(sin x, cos x)`, within 1 ulp of the correctly rounded values, inlined.
///
/// Every algorithm evaluates one `sin_cos` per revolute joint, and the out-of-line libm call
/// was the largest single cost of the kinematics. This is musl's (FreeBSD's) kernel: argument
/// reduction by π/2 in three parts (Cody–Waite, exact for |x| < 2²⁰ π/2) and degree-13/14
/// minimax polynomials on [−π/4, π/4]; larger or non-finite arguments go to libm.
#[inline]
pub fn sin_cos(x: f64) -> (f64, f64) {
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

/// `(sin x, cos x)` of `W` angles, lane by lane: the same numbers as [`sin_cos`] bit for bit,
/// its reduction and kernels written as loops over the lanes (one vector instruction each
/// inside a `#[target_feature]` function); lanes that need more than one reduction round (or
/// are beyond its range) are redone by [`sin_cos`].
#[inline(always)]
pub(crate) fn sin_cos_lanes<const W: usize>(x: [f64; W]) -> ([f64; W], [f64; W]) {
    let mut y0 = [0.0; W];
    let mut y1 = [0.0; W];
    let mut quadrant = [0u64; W];
    let mut slow = false;
    // one Cody–Waite round in every lane (none where |x| <= π/4)
    for k in 0..W {
        let ix = (x[k].to_bits() >> 32) & 0x7fff_ffff;
        let small = ix <= 0x3fe9_21fb;
        let t = x[k] * INVPIO2 + TOINT;
        let fk = if small { 0.0 } else { t - TOINT };
        quadrant[k] = if small { 0 } else { t.to_bits() & 3 };
        let r = x[k] - fk * PIO2_1;
        let w = fk * PIO2_1T;
        let y = r - w;
        let ex = (ix >> 20) as i64;
        let ey = ((y.to_bits() >> 52) & 0x7ff) as i64;
        slow |= (ix >= 0x4139_21fb) | (!small & (ex - ey > 16));
        y0[k] = if small { x[k] } else { y };
        y1[k] = if small { 0.0 } else { (r - y) - w };
    }
    // polynomial kernels on [−π/4, π/4], then the quadrant
    let mut s = [0.0; W];
    let mut c = [0.0; W];
    for k in 0..W {
        let (sk, ck) = (sin_kernel(y0[k], y1[k]), cos_kernel(y0[k], y1[k]));
        let swap = quadrant[k] & 1 == 1;
        let (sk, ck) = if swap { (ck, sk) } else { (sk, ck) };
        s[k] = if quadrant[k] & 2 == 2 { -sk } else { sk };
        c[k] = if (quadrant[k] == 1) | (quadrant[k] == 2) { -ck } else { ck };
    }
    if slow {
        for k in 0..W {
            (s[k], c[k]) = sin_cos(x[k]);
        }
    }
    (s, c)
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
    fn lane_sin_cos_equals_the_scalar_sin_cos_bit_for_bit() {
        let mut x: f64 = -2.0e3;
        let mut checked = 0;
        while x < 2.0e3 {
            let xs = [x, x * 1e-3, x * 1e-7, 2.0e6 * x, std::f64::consts::FRAC_PI_2 * (x / 7.0).round(), std::f64::consts::FRAC_PI_4 * (1.0 + 1e-12 * x), -x, f64::NAN];
            let (s, c) = sin_cos_lanes(xs);
            for k in 0..8 {
                let (s0, c0) = sin_cos(xs[k]);
                assert!(s[k].to_bits() == s0.to_bits() || (s0.is_nan() && s[k].is_nan()), "sin({}) = {} vs {}", xs[k], s[k], s0);
                assert!(c[k].to_bits() == c0.to_bits() || (c0.is_nan() && c[k].is_nan()), "cos({}) = {} vs {}", xs[k], c[k], c0);
                checked += 1;
            }
            x += 0.012_345_678_9;
        }
        assert!(checked > 1_000_000);
    }
}
