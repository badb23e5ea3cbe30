//! The dynamics algorithms on [`Lanes`]: `W` states at once, structure of arrays.
//!
//! The same world-frame formulation as the scalar algorithms (kinematics, composite rigid body
//! algorithm, the second-order pass of [`coriolis`](crate::algorithms::coriolis), Newton–Euler,
//! and the articulated-body algorithm of [`aba`](crate::algorithms::aba)), written once for any
//! lane width: `W = 8` and `W = 4` serve the batch functions of [`crate::batch`], `W = 1` the
//! articulated-body algorithm of one state. Every function here is `#[inline(always)]` so that it
//! is compiled with the target features of the batch entry point that calls it.

use crate::formulation::Formulation;
use crate::lanes::{Frc, Ine, Lanes, Mot, Rate, Sym, M3, V3};
use crate::model::Model;

/// Per-link temporaries and lane outputs of one block of `W` states.
#[derive(Clone, Debug)]
pub(crate) struct SoaWs<const W: usize> {
    pub(crate) n: usize,
    pub(crate) q: Vec<Lanes<W>>,
    pub(crate) qd: Vec<Lanes<W>>,
    pub(crate) qdd: Vec<Lanes<W>>,
    pub(crate) r: Vec<M3<W>>,
    pub(crate) t: Vec<V3<W>>,
    pub(crate) s: Vec<Mot<W>>,
    pub(crate) v: Vec<Mot<W>>,
    pub(crate) sd: Vec<Mot<W>>,
    pub(crate) inertia: Vec<Ine<W>>,
    pub(crate) comp: Vec<Ine<W>>,
    pub(crate) mom: Vec<Frc<W>>,
    pub(crate) rate: Vec<Rate<W>>,
    pub(crate) f: Vec<Frc<W>>,
    /// Articulated inertias (ABA), 21 lanes each.
    pub(crate) art: Vec<Sym6<W>>,
    pub(crate) u: Vec<Frc<W>>,
    pub(crate) dinv: Vec<Lanes<W>>,
    /// Outputs: `n × n` row-major matrices and `n` vectors.
    pub(crate) h: Vec<Lanes<W>>,
    pub(crate) c: Vec<Lanes<W>>,
    pub(crate) hd: Vec<Lanes<W>>,
    pub(crate) g: Vec<Lanes<W>>,
    pub(crate) tau: Vec<Lanes<W>>,
    /// The Euler–Lagrange velocity torque C q̇ of the last simplified [`rnea`].
    pub(crate) el: Vec<Lanes<W>>,
}

impl<const W: usize> SoaWs<W> {
    pub(crate) fn new(n: usize) -> Self {
        let z = Lanes::zero();
        SoaWs {
            n,
            q: vec![z; n],
            qd: vec![z; n],
            qdd: vec![z; n],
            r: vec![M3([[z; 3]; 3]); n],
            t: vec![V3::zero(); n],
            s: vec![Mot::zero(); n],
            v: vec![Mot::zero(); n],
            sd: vec![Mot::zero(); n],
            inertia: vec![Ine::zero(); n],
            comp: vec![Ine::zero(); n],
            mom: vec![Frc::zero(); n],
            rate: vec![Rate::zero(); n],
            f: vec![Frc::zero(); n],
            art: vec![Sym6([z; 21]); n],
            u: vec![Frc::zero(); n],
            dinv: vec![z; n],
            h: vec![z; n * n],
            c: vec![z; n * n],
            hd: vec![z; n * n],
            g: vec![z; n],
            tau: vec![z; n],
            el: vec![z; n],
        }
    }
}

/// How much of each link's inertia [`kinematics`] moves to the world frame.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum InertiaLevel {
    /// Mass and first moment (enough for g).
    FirstMoment,
    /// The whole spatial inertia.
    Full,
}

/// Poses, world subspaces `S_i` and (per `level`) world link inertias from `ws.q`.
#[inline(always)]
pub(crate) fn kinematics<const W: usize>(model: &Model, ws: &mut SoaWs<W>, level: InertiaLevel) {
    // forward pass: compose joint transforms from the root
    for (i, joint) in model.joints().iter().enumerate() {
        let cache = model.joint_cache(i);
        let rotational = joint.kind.is_rotational();
        let (rl, tl) = if rotational {
            let (s, c) = ws.q[i].sin_cos();
            (M3::rodrigues(&cache.a, &cache.b, &cache.d, s, c), V3::splat(&joint.placement.translation))
        } else {
            (M3::splat(&joint.placement.rotation), V3::splat(&cache.placed_axis).scale(ws.q[i]) + V3::splat(&joint.placement.translation))
        };
        let (r, t, axis) = if i == 0 {
            (rl, tl, V3::splat(&cache.placed_axis))
        } else {
            let (rp, tp) = (&ws.r[i - 1], ws.t[i - 1]);
            let t = if rotational { rp.mul_c(&joint.placement.translation) } else { rp.mul_v(tl) } + tp;
            (rp.mul(&rl), t, rp.mul_c(&cache.placed_axis))
        };
        ws.s[i] = if rotational { Mot { w: axis, v: t.cross(axis) } } else { Mot { w: V3::zero(), v: axis } };
        let body = &joint.inertia;
        match level {
            InertiaLevel::FirstMoment => {
                ws.inertia[i] = Ine { m: Lanes::splat(body.mass), h: r.mul_c(&body.first_moment) + t.scale_f(body.mass), i: Sym::zero() };
            }
            InertiaLevel::Full => ws.inertia[i] = Ine::transformed(body.mass, &body.first_moment, &body.rotational, &r, t),
        }
        ws.r[i] = r;
        ws.t[i] = t;
    }
}

/// Link velocities `v_i = v_{i−1} + S_i q̇_i` and subspace rates `Ṡ_i = v_i × S_i` from `ws.qd`.
#[inline(always)]
pub(crate) fn velocities<const W: usize>(ws: &mut SoaWs<W>) {
    let mut v = Mot::zero();
    // forward pass: accumulate joint velocities from the root
    for i in 0..ws.n {
        v = ws.s[i].scale_add(ws.qd[i], v);
        ws.v[i] = v;
        ws.sd[i] = v.cross_motion(ws.s[i]);
    }
}

/// Composite inertias `Ic_i = Σ_{l ≥ i} I_l`.
#[inline(always)]
pub(crate) fn composites<const W: usize>(ws: &mut SoaWs<W>) {
    let n = ws.n;
    // backward pass: add each subtree to its parent
    let mut acc = ws.inertia[n - 1];
    ws.comp[n - 1] = acc;
    for i in (0..n - 1).rev() {
        acc = ws.inertia[i] + acc;
        ws.comp[i] = acc;
    }
}

/// Subtree momenta `h_i = Σ I_l v_l` and composite inertia rates `İc_i = Σ İ_l`.
#[inline(always)]
pub(crate) fn momenta_and_rates<const W: usize>(ws: &mut SoaWs<W>) {
    let mut momentum = Frc::zero();
    let mut rate = Rate::zero();
    // backward pass
    for i in (0..ws.n).rev() {
        let inertia = &ws.inertia[i];
        let v = ws.v[i];
        momentum = momentum + inertia.mul_motion(v);
        rate = rate + inertia.rate(v);
        ws.mom[i] = momentum;
        ws.rate[i] = rate;
    }
}

/// Which matrices [`fill`] writes into `ws.h`, `ws.c`, `ws.hd`.
#[derive(Clone, Copy)]
pub(crate) struct Wanted {
    pub(crate) h: bool,
    pub(crate) c: Option<Formulation>,
    pub(crate) hd: bool,
}

/// H, C and Ḣ from the composite inertias (and, for C and Ḣ, the second-order pass), with
/// the formulas of [`crate::algorithms::coriolis`].
#[inline(always)]
pub(crate) fn fill<const W: usize>(ws: &mut SoaWs<W>, want: Wanted) {
    let n = ws.n;
    let second = want.c.is_some() || want.hd;
    let half = Lanes::splat(0.5);
    for j in 0..n {
        let s_j = ws.s[j];
        let ic = &ws.comp[j];
        let f1 = ic.mul_motion(s_j);
        if !second {
            // H only: H_ij = S_i·Ic_j S_j
            for i in 0..=j {
                let hij = ws.s[i].dot(f1);
                ws.h[i * n + j] = hij;
                ws.h[j * n + i] = hij;
            }
            continue;
        }
        let ic_sd = ic.mul_motion(ws.sd[j]);
        let f2 = ws.rate[j].mul_motion(s_j) + ic_sd;
        let f3 = s_j.cross_force(ws.mom[j]) + ic_sd;
        let plus = (f2 + f3).scale(half);
        let minus = (f2 - f3).scale(half);
        for i in 0..=j {
            let (s_i, sd_i) = (ws.s[i], ws.sd[i]);
            let sd_f1 = sd_i.dot(f1);
            let s_f2 = s_i.dot(f2);
            if want.h {
                let hij = s_i.dot(f1);
                ws.h[i * n + j] = hij;
                ws.h[j * n + i] = hij;
            }
            if want.hd {
                let v = sd_f1 + s_f2;
                ws.hd[i * n + j] = v;
                ws.hd[j * n + i] = v;
            }
            match want.c {
                Some(Formulation::EulerLagrange) => {
                    ws.c[i * n + j] = s_i.dot(plus);
                    if i < j {
                        ws.c[j * n + i] = sd_f1 + s_i.dot(minus);
                    }
                }
                Some(Formulation::Simplified) => {
                    let v = (sd_f1 + s_f2) * 0.5;
                    ws.c[i * n + j] = v;
                    ws.c[j * n + i] = v;
                }
                None => {}
            }
        }
    }
}

/// g into `ws.g` from the mass and first moment of each subtree (`ws.comp` when `composite`,
/// else summed here from `ws.inertia`): `g_i = S_i · (−h_i × g, −m_i g)`.
#[inline(always)]
pub(crate) fn gravity<const W: usize>(model: &Model, ws: &mut SoaWs<W>, composite: bool) {
    let g = model.gravity();
    let (mut mass, mut first) = (Lanes::zero(), V3::zero());
    // backward pass: subtree mass and first moment, projected on each joint
    for i in (0..ws.n).rev() {
        if composite {
            (mass, first) = (ws.comp[i].m, ws.comp[i].h);
        } else {
            mass += ws.inertia[i].m;
            first = first + ws.inertia[i].h;
        }
        let f = Frc { n: -first.cross_c(&g), f: -V3::splat(&g).scale(mass) };
        ws.g[i] = ws.s[i].dot(f);
    }
}

/// Newton–Euler into `ws.tau`: `H q̈ + C q̇ (+ g)` with `q̈ = ws.qdd` when `with_qdd` (else 0).
/// For [`Formulation::Simplified`] (only with `with_qdd` false) `½ Ḣ q̇ (+ g)`. Needs
/// [`kinematics`] at [`InertiaLevel::Full`] and [`velocities`].
#[inline(always)]
pub(crate) fn rnea<const W: usize>(model: &Model, ws: &mut SoaWs<W>, with_qdd: bool, with_gravity: bool, formulation: Formulation) {
    let n = ws.n;
    let simplified = formulation == Formulation::Simplified;
    let gravity_in_pass = with_gravity && !simplified;
    let mut a = if gravity_in_pass { Mot { w: V3::zero(), v: -V3::splat(&model.gravity()) } } else { Mot::zero() };
    // forward pass: link accelerations and the forces that produce them
    for i in 0..n {
        a = ws.sd[i].scale_add(ws.qd[i], a);
        if with_qdd {
            a = ws.s[i].scale_add(ws.qdd[i], a);
        }
        let inertia = &ws.inertia[i];
        let v = ws.v[i];
        let h = inertia.mul_motion(v);
        ws.f[i] = inertia.mul_motion(a) + v.cross_force(h);
        ws.mom[i] = h;
    }
    // backward pass: each joint carries its subtree
    let (mut f, mut h) = (Frc::zero(), Frc::zero());
    for i in (0..n).rev() {
        f = f + ws.f[i];
        h = h + ws.mom[i];
        let c = ws.s[i].dot(f);
        ws.el[i] = c;
        ws.tau[i] = if simplified { (c + ws.sd[i].dot(h)) * 0.5 } else { c };
    }
    if with_gravity && simplified {
        gravity(model, ws, false);
        for i in 0..n {
            ws.tau[i] += ws.g[i];
        }
    }
}

/// A symmetric 6×6 matrix of lanes (articulated inertia), upper triangle row by row.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Sym6<const W: usize>(pub(crate) [Lanes<W>; 21]);

/// Index of entry `(r, c)`, `r <= c`, in [`Sym6`].
const fn sym6_index(r: usize, c: usize) -> usize {
    r * 6 - r * (r + 1) / 2 + c
}

impl<const W: usize> Sym6<W> {
    #[inline(always)]
    fn get(&self, r: usize, c: usize) -> Lanes<W> {
        if r <= c {
            self.0[sym6_index(r, c)]
        } else {
            self.0[sym6_index(c, r)]
        }
    }

    /// The rigid-body inertia as a 6×6 matrix acting on (angular, linear).
    #[inline(always)]
    fn from_inertia(i: &Ine<W>) -> Self {
        let [xx, yy, zz, xy, xz, yz] = i.i.0;
        let h = i.h;
        let z = Lanes::zero();
        // [[Ibar, [h]×], [[h]×ᵀ, m 1]]
        Sym6([
            xx, xy, xz, z, -h.z, h.y, //
            yy, yz, h.z, z, -h.x, //
            zz, -h.y, h.x, z, //
            i.m, z, z, //
            i.m, z, //
            i.m,
        ])
    }

    #[inline(always)]
    fn mul(&self, m: Mot<W>) -> Frc<W> {
        let x = [m.w.x, m.w.y, m.w.z, m.v.x, m.v.y, m.v.z];
        let row = |r: usize| {
            let mut acc = self.get(r, 0) * x[0];
            for (c, xc) in x.iter().enumerate().skip(1) {
                acc += self.get(r, c) * *xc;
            }
            acc
        };
        Frc { n: V3 { x: row(0), y: row(1), z: row(2) }, f: V3 { x: row(3), y: row(4), z: row(5) } }
    }
}

impl<const W: usize> std::ops::AddAssign for Sym6<W> {
    #[inline(always)]
    fn add_assign(&mut self, o: Self) {
        for k in 0..21 {
            self.0[k] += o.0[k];
        }
    }
}

#[inline(always)]
fn frc_array<const W: usize>(f: Frc<W>) -> [Lanes<W>; 6] {
    [f.n.x, f.n.y, f.n.z, f.f.x, f.f.y, f.f.z]
}

/// Forward dynamics by the articulated-body algorithm (Featherstone 2008, §7.3), in world
/// coordinates (no transforms between passes): `ws.tau` holds τ on entry and q̈ on return,
/// for the true (Euler–Lagrange) bias. Needs [`kinematics`] at [`InertiaLevel::Full`] and
/// [`velocities`].
#[inline(always)]
pub(crate) fn aba<const W: usize>(model: &Model, ws: &mut SoaWs<W>, armature: &[f64]) {
    let n = ws.n;
    // forward pass: articulated inertias start as the link inertias, bias forces v ×* I v
    for i in 0..n {
        let inertia = &ws.inertia[i];
        let v = ws.v[i];
        ws.art[i] = Sym6::from_inertia(inertia);
        ws.f[i] = v.cross_force(inertia.mul_motion(v));
    }
    // backward pass: U = IA S, D = Sᵀ U, u = τ − Sᵀ pA; hand IA − U Uᵀ/D and
    // pA + Ia c + U u/D to the parent (c = Ṡ q̇, the velocity-product acceleration)
    for i in (0..n).rev() {
        let s = ws.s[i];
        let u_vec = ws.art[i].mul(s);
        let mut d = s.dot(u_vec);
        // rotor inertia on the joint: D = Sᵀ IA S + ia (H + diag(ia))
        if let Some(&a) = armature.get(i) {
            d += Lanes::splat(a);
        }
        let dinv = recip(d);
        let u = ws.tau[i] - s.dot(ws.f[i]);
        ws.u[i] = u_vec;
        ws.dinv[i] = dinv;
        ws.tau[i] = u;
        if i > 0 {
            let uu = frc_array(u_vec);
            let mut ia = ws.art[i];
            for r in 0..6 {
                let ur = uu[r] * dinv;
                for c in r..6 {
                    ia.0[sym6_index(r, c)] = ia.0[sym6_index(r, c)] - ur * uu[c];
                }
            }
            let c = ws.sd[i].scale_add(ws.qd[i], Mot::zero());
            let pa = ws.f[i] + ia.mul(c) + u_vec.scale(u * dinv);
            ws.art[i - 1] += ia;
            ws.f[i - 1] = ws.f[i - 1] + pa;
        }
    }
    // forward pass: accelerations from the root (gravity as a base acceleration)
    let mut a = Mot { w: V3::zero(), v: -V3::splat(&model.gravity()) };
    for i in 0..n {
        a = ws.sd[i].scale_add(ws.qd[i], a);
        let qdd = (ws.tau[i] - a.dot(ws.u[i])) * ws.dinv[i];
        a = ws.s[i].scale_add(qdd, a);
        ws.tau[i] = qdd;
    }
}

/// `1 / x` lane by lane.
#[inline(always)]
fn recip<const W: usize>(x: Lanes<W>) -> Lanes<W> {
    let mut r = x.0;
    for v in &mut r {
        *v = 1.0 / *v;
    }
    Lanes(r)
}
