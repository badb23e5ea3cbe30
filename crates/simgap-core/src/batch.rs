//! Dynamics terms of many states at once, several states per SIMD register.
//!
//! Each function evaluates one quantity on a batch of `N` states laid out state after state:
//! a joint-vector input is `N · dof` numbers (state `k` at `k·dof .. (k+1)·dof`), a vector
//! output `N · dof`, a matrix output `N · dof²` with each state's matrix row-major (row `i`
//! = equation `i`), the layout of a C-ordered `(N, dof)` / `(N, dof, dof)` numpy array.
//! Conventions are those of the crate root.
//!
//! The states are packed into structure-of-arrays lanes (8 per register with AVX-512, 4 with
//! AVX2, chosen at run time by CPU feature) and run through the same world-frame algorithms as
//! the one-state functions; on other CPUs each state goes through the one-state function (the
//! reference). Results agree with the one-state functions to rounding (1e-12 relative in the
//! tests). One call runs on the calling thread and allocates only its scratch space; split a
//! large batch across threads by splitting the slices.
//!
//! ```
//! use simgap_core::{batch, mass_matrix, Model, Workspace};
//!
//! let model = Model::paper_arm();
//! let q = [0.1, 0.2, 0.3, 0.4, 0.5, 0.6]; // three states of two joints
//! let mut h = vec![0.0; 3 * 4];
//! batch::mass_matrix_batch(&model, &q, &mut h);
//! let second = mass_matrix(&model, &mut Workspace::new(&model), &q[2..4]);
//! assert!((h[4] - second[(0, 0)]).abs() < 1e-12 && (h[5] - second[(0, 1)]).abs() < 1e-12);
//! ```

use std::sync::atomic::{AtomicUsize, Ordering};

use nalgebra::DMatrix;

use crate::algorithms::soa::{self, InertiaLevel, SoaWs, Wanted};
use crate::algorithms::workspace::Workspace;
use crate::formulation::Formulation;
use crate::lanes::Lanes;
use crate::model::Model;

/// Lane width forced by [`set_batch_lanes`] (0: chosen by CPU feature).
static FORCED_LANES: AtomicUsize = AtomicUsize::new(0);

/// The number of states the batch functions put in one SIMD register on this CPU: 8
/// (AVX-512), 4 (AVX2) or 1 (no SIMD path: one state at a time through the one-state functions).
pub fn batch_lanes() -> usize {
    let best = best_lanes();
    match FORCED_LANES.load(Ordering::Relaxed) {
        0 => best,
        forced => forced.min(best),
    }
}

/// Forces a lane width at most the CPU's (8, 4 or 1; `None` restores the automatic choice),
/// process-wide. For tests and benchmarks of the fallbacks.
#[doc(hidden)]
pub fn set_batch_lanes(lanes: Option<usize>) {
    FORCED_LANES.store(lanes.unwrap_or(0), Ordering::Relaxed);
}

fn best_lanes() -> usize {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f") {
            return 8;
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            return 4;
        }
    }
    1
}

/// What one batch call computes.
#[derive(Clone, Copy)]
enum Kind {
    /// Matrices of the second-order pass, and g from the composite inertias.
    Terms { want: Wanted, g: bool },
    /// g alone.
    Gravity,
    /// Newton–Euler: `H q̈ + C q̇ (+ g)`, or `½ Ḣ q̇ (+ g)` for the simplified formulation.
    Rnea { qdd: bool, gravity: bool, formulation: Formulation },
}

/// Inputs and outputs of one batch call.
struct Job<'a> {
    kind: Kind,
    q: &'a [f64],
    qd: &'a [f64],
    qdd: &'a [f64],
    h: &'a mut [f64],
    c: &'a mut [f64],
    hd: &'a mut [f64],
    /// The vector output (g, or the torque of Newton–Euler).
    v: &'a mut [f64],
}

impl Job<'_> {
    /// Checks every length against `model` and runs the job.
    fn run(mut self, model: &Model) {
        let n = model.dof();
        assert!(self.q.len() % n == 0, "q: expected a multiple of dof = {n} numbers, got {}", self.q.len());
        let count = self.q.len() / n;
        for (what, len, per_state) in [
            ("qd", self.qd.len(), n),
            ("qdd", self.qdd.len(), n),
            ("mass matrix output", self.h.len(), n * n),
            ("coriolis matrix output", self.c.len(), n * n),
            ("mass matrix derivative output", self.hd.len(), n * n),
            ("vector output", self.v.len(), n),
        ] {
            assert!(len == 0 || len == count * per_state, "{what}: expected {} numbers ({count} states), got {len}", count * per_state);
        }
        if count == 0 {
            return;
        }
        match batch_lanes() {
            #[cfg(target_arch = "x86_64")]
            8 => unsafe { run_avx512(model, &mut self) },
            #[cfg(target_arch = "x86_64")]
            4 => unsafe { run_avx2(model, &mut self) },
            _ => run_scalar(model, &mut self),
        }
    }
}

/// # Safety
/// The CPU supports AVX-512F.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
unsafe fn run_avx512(model: &Model, job: &mut Job<'_>) {
    drive::<8>(model, job);
}

/// # Safety
/// The CPU supports AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn run_avx2(model: &Model, job: &mut Job<'_>) {
    drive::<4>(model, job);
}

/// Packs `W` states per lane, runs the lane kernels, unpacks.
#[inline(always)]
fn drive<const W: usize>(model: &Model, job: &mut Job<'_>) {
    let n = model.dof();
    let nn = n * n;
    let count = job.q.len() / n;
    let mut ws = SoaWs::<W>::new(n);
    let mut first = 0;
    while first < count {
        let used = (count - first).min(W);
        // gather: lane k holds state first + k (unused lanes repeat the last state)
        let gather = |src: &[f64], dst: &mut [Lanes<W>]| {
            for (i, d) in dst.iter_mut().enumerate() {
                for (k, x) in d.0.iter_mut().enumerate() {
                    *x = src[(first + k.min(used - 1)) * n + i];
                }
            }
        };
        gather(job.q, &mut ws.q);
        if !job.qd.is_empty() {
            gather(job.qd, &mut ws.qd);
        }
        if !job.qdd.is_empty() {
            gather(job.qdd, &mut ws.qdd);
        }
        // the kernels
        match job.kind {
            Kind::Terms { want, g } => {
                soa::kinematics(model, &mut ws, InertiaLevel::Full);
                soa::composites(&mut ws);
                if want.c.is_some() || want.hd {
                    soa::velocities(&mut ws);
                    soa::momenta_and_rates(&mut ws);
                }
                soa::fill(&mut ws, want);
                if g {
                    soa::gravity(model, &mut ws, true);
                }
            }
            Kind::Gravity => {
                soa::kinematics(model, &mut ws, InertiaLevel::FirstMoment);
                soa::gravity(model, &mut ws, false);
            }
            Kind::Rnea { qdd, gravity, formulation } => {
                soa::kinematics(model, &mut ws, InertiaLevel::Full);
                soa::velocities(&mut ws);
                soa::rnea(model, &mut ws, qdd, gravity, formulation);
            }
        }
        // scatter: each state's outputs are contiguous
        let scatter = |src: &[Lanes<W>], dst: &mut [f64], width: usize| {
            if dst.is_empty() {
                return;
            }
            for k in 0..used {
                let out = &mut dst[(first + k) * width..(first + k + 1) * width];
                for (o, s) in out.iter_mut().zip(src) {
                    *o = s.0[k];
                }
            }
        };
        scatter(&ws.h, &mut *job.h, nn);
        scatter(&ws.c, &mut *job.c, nn);
        scatter(&ws.hd, &mut *job.hd, nn);
        match job.kind {
            Kind::Rnea { .. } => scatter(&ws.tau, &mut *job.v, n),
            _ => scatter(&ws.g, &mut *job.v, n),
        }
        first += W;
    }
}

/// One state at a time through the one-state functions.
fn run_scalar(model: &Model, job: &mut Job<'_>) {
    let n = model.dof();
    let nn = n * n;
    let count = job.q.len() / n;
    let mut ws = Workspace::new(model);
    let mut m = DMatrix::zeros(n, n);
    let zero = vec![0.0; n];
    let row_major = |m: &DMatrix<f64>, out: &mut [f64]| {
        for i in 0..n {
            for j in 0..n {
                out[i * n + j] = m[(i, j)];
            }
        }
    };
    for k in 0..count {
        let q = &job.q[k * n..(k + 1) * n];
        let qd = if job.qd.is_empty() { &zero[..] } else { &job.qd[k * n..(k + 1) * n] };
        let qdd = if job.qdd.is_empty() { &zero[..] } else { &job.qdd[k * n..(k + 1) * n] };
        match job.kind {
            Kind::Terms { want, g } => {
                if want.h {
                    crate::mass_matrix_into(model, &mut ws, q, &mut m);
                    row_major(&m, &mut job.h[k * nn..(k + 1) * nn]);
                }
                if let Some(f) = want.c {
                    crate::coriolis_matrix_into(model, &mut ws, q, qd, f, &mut m);
                    row_major(&m, &mut job.c[k * nn..(k + 1) * nn]);
                }
                if want.hd {
                    crate::mass_matrix_derivative_into(model, &mut ws, q, qd, &mut m);
                    row_major(&m, &mut job.hd[k * nn..(k + 1) * nn]);
                }
                if g {
                    crate::gravity_torques_into(model, &mut ws, q, &mut job.v[k * n..(k + 1) * n]);
                }
            }
            Kind::Gravity => crate::gravity_torques_into(model, &mut ws, q, &mut job.v[k * n..(k + 1) * n]),
            Kind::Rnea { qdd: with_qdd, gravity, formulation } => {
                let out = &mut job.v[k * n..(k + 1) * n];
                match (with_qdd, gravity) {
                    (true, _) => crate::inverse_dynamics_into(model, &mut ws, q, qd, qdd, out),
                    (false, true) => crate::bias_torques_into(model, &mut ws, q, qd, formulation, out),
                    (false, false) => crate::coriolis_torques_into(model, &mut ws, q, qd, formulation, out),
                }
            }
        }
    }
}

fn job<'a>(kind: Kind, q: &'a [f64], qd: &'a [f64], qdd: &'a [f64]) -> Job<'a> {
    Job { kind, q, qd, qdd, h: &mut [], c: &mut [], hd: &mut [], v: &mut [] }
}

/// Mass matrices H(q) of a batch of states: `out` holds `N` row-major `dof × dof` matrices.
///
/// The batch form of [`mass_matrix`](crate::mass_matrix) (composite rigid body algorithm).
///
/// `q`: `N · dof` joint positions, state after state; `out`: `N · dof²` numbers.
///
/// # Panics
/// If `q.len()` is not a multiple of `model.dof()` or `out` does not hold `N · dof²` numbers.
pub fn mass_matrix_batch(model: &Model, q: &[f64], out: &mut [f64]) {
    let want = Wanted { h: true, c: None, hd: false };
    Job { h: out, ..job(Kind::Terms { want, g: false }, q, &[], &[]) }.run(model)
}

/// Coriolis matrices C(q, q̇) of the chosen formulation for a batch of states (the batch form
/// of [`coriolis_matrix`](crate::coriolis_matrix)).
///
/// `q`, `qd`: `N · dof` numbers each; `out`: `N · dof²` (row-major matrices).
///
/// # Panics
/// If a length does not match.
pub fn coriolis_matrix_batch(model: &Model, q: &[f64], qd: &[f64], formulation: Formulation, out: &mut [f64]) {
    let want = Wanted { h: false, c: Some(formulation), hd: false };
    Job { c: out, ..job(Kind::Terms { want, g: false }, q, qd, &[]) }.run(model)
}

/// Ḣ(q, q̇) for a batch of states (the batch form of
/// [`mass_matrix_derivative`](crate::mass_matrix_derivative)).
///
/// # Panics
/// If a length does not match.
pub fn mass_matrix_derivative_batch(model: &Model, q: &[f64], qd: &[f64], out: &mut [f64]) {
    let want = Wanted { h: false, c: None, hd: true };
    Job { hd: out, ..job(Kind::Terms { want, g: false }, q, qd, &[]) }.run(model)
}

/// Gravity torques g(q) for a batch of states (the batch form of
/// [`gravity_torques`](crate::gravity_torques)); `out`: `N · dof`.
///
/// # Panics
/// If a length does not match.
pub fn gravity_torques_batch(model: &Model, q: &[f64], out: &mut [f64]) {
    Job { v: out, ..job(Kind::Gravity, q, &[], &[]) }.run(model)
}

/// Coriolis and centrifugal torques C(q, q̇) q̇ for a batch of states (the batch form of
/// [`coriolis_torques`](crate::coriolis_torques), Newton–Euler); `out`: `N · dof`.
///
/// # Panics
/// If a length does not match.
pub fn coriolis_torques_batch(model: &Model, q: &[f64], qd: &[f64], formulation: Formulation, out: &mut [f64]) {
    Job { v: out, ..job(Kind::Rnea { qdd: false, gravity: false, formulation }, q, qd, &[]) }.run(model)
}

/// Bias torques C(q, q̇) q̇ + g(q) for a batch of states (the batch form of
/// [`bias_torques`](crate::bias_torques)); `out`: `N · dof`.
///
/// # Panics
/// If a length does not match.
pub fn bias_torques_batch(model: &Model, q: &[f64], qd: &[f64], formulation: Formulation, out: &mut [f64]) {
    Job { v: out, ..job(Kind::Rnea { qdd: false, gravity: true, formulation }, q, qd, &[]) }.run(model)
}

/// Inverse dynamics τ = H q̈ + C q̇ + g (true Coriolis torque) for a batch of states (the batch
/// form of [`inverse_dynamics`](crate::inverse_dynamics), Newton–Euler); `out`: `N · dof`.
///
/// # Panics
/// If a length does not match.
pub fn inverse_dynamics_batch(model: &Model, q: &[f64], qd: &[f64], qdd: &[f64], out: &mut [f64]) {
    let kind = Kind::Rnea { qdd: true, gravity: true, formulation: Formulation::EulerLagrange };
    Job { v: out, ..job(kind, q, qd, qdd) }.run(model)
}

/// H, C (chosen formulation) and g for a batch of states in one pass each (the batch form of
/// [`dynamics_terms`](crate::dynamics_terms)): `h` and `c` hold `N · dof²` numbers
/// (row-major matrices), `g` holds `N · dof`.
///
/// # Panics
/// If a length does not match.
pub fn dynamics_terms_batch(model: &Model, q: &[f64], qd: &[f64], formulation: Formulation, h: &mut [f64], c: &mut [f64], g: &mut [f64]) {
    let n = model.dof();
    let count = q.len() / n.max(1);
    assert!(h.len() == count * n * n && c.len() == count * n * n && g.len() == count * n, "dynamics terms outputs: expected {count} states");
    let want = Wanted { h: true, c: Some(formulation), hd: false };
    Job { h, c, v: g, ..job(Kind::Terms { want, g: true }, q, qd, &[]) }.run(model)
}
