//! The L² index of the seed paper (eq. 127): `L²[x] = sqrt( 1/(t − t0) ∫_{t0}^{t} ‖x‖² dt )`,
//! the root mean square of a signal over time, integrated by the trapezoid rule.

use crate::error::{Error, Result};
use crate::run::{Experiment, Run, Sample};
use crate::sink::{RunEnd, Sink};

/// `L²[x]` of a row-major signal `x` (`t.len() × dof`) sampled at times `t`, trapezoid rule.
/// Zero for fewer than two samples or a zero time span.
///
/// # Panics
/// If `x.len() != t.len() * dof`.
pub fn l2_index(t: &[f64], x: &[f64], dof: usize) -> f64 {
    assert_eq!(x.len(), t.len() * dof, "l2_index: x must have t.len() * dof values");
    let sq = |k: usize| x[k * dof..(k + 1) * dof].iter().map(|v| v * v).sum::<f64>();
    mean_square(t, sq).sqrt()
}

/// `L²` of each column of a row-major signal (one value per joint).
///
/// # Panics
/// If `x.len() != t.len() * dof`.
pub fn l2_per_joint(t: &[f64], x: &[f64], dof: usize) -> Vec<f64> {
    assert_eq!(x.len(), t.len() * dof, "l2_per_joint: x must have t.len() * dof values");
    (0..dof).map(|j| mean_square(t, |k| x[k * dof + j].powi(2)).sqrt()).collect()
}

/// `1/(t_end − t_0) ∫ f dt` by the trapezoid rule on samples `f(k)`.
fn mean_square(t: &[f64], f: impl Fn(usize) -> f64) -> f64 {
    if t.len() < 2 {
        return 0.0;
    }
    let span = t[t.len() - 1] - t[0];
    if span <= 0.0 {
        return 0.0;
    }
    let mut acc = 0.0;
    let mut prev = f(0);
    for k in 1..t.len() {
        let cur = f(k);
        acc += 0.5 * (prev + cur) * (t[k] - t[k - 1]);
        prev = cur;
    }
    acc / span
}

/// L² indices of a difference signal.
#[derive(Clone, Debug, PartialEq)]
pub struct L2Report {
    /// Joint names (the order of the per-joint vectors).
    pub joints: Vec<String>,
    /// `L²` of the whole vector [rad or m].
    pub overall: f64,
    /// `L²` of each joint.
    pub per_joint: Vec<f64>,
    /// Maximum absolute difference of each joint.
    pub max_abs_per_joint: Vec<f64>,
    /// Time span used `(start, end)` [s].
    pub span: (f64, f64),
    /// Number of samples used.
    pub samples: usize,
}

fn report(joints: Vec<String>, t: &[f64], x: &[f64]) -> L2Report {
    let n = joints.len();
    let max_abs_per_joint = (0..n).map(|j| (0..t.len()).map(|k| x[k * n + j].abs()).fold(0.0, f64::max)).collect();
    L2Report {
        overall: l2_index(t, x, n),
        per_joint: l2_per_joint(t, x, n),
        max_abs_per_joint,
        span: (t.first().copied().unwrap_or(0.0), t.last().copied().unwrap_or(0.0)),
        samples: t.len(),
        joints,
    }
}

/// Linear interpolation of column `j` of row-major `m` (`t.len()` rows, `n` columns) at `s`,
/// with `k` a hint (the interval index is searched from there).
fn interp(t: &[f64], m: &[f64], n: usize, j: usize, s: f64, k: &mut usize) -> f64 {
    while *k + 2 < t.len() && t[*k + 1] <= s {
        *k += 1;
    }
    if t.len() == 1 {
        return m[j];
    }
    let (a, b) = (t[*k], t[*k + 1]);
    let w = ((s - a) / (b - a)).clamp(0.0, 1.0);
    (1.0 - w) * m[*k * n + j] + w * m[(*k + 1) * n + j]
}

/// `L²` of the position difference `q_a − q_b`, with `b` linearly resampled onto `a`'s
/// sample times and joints matched by name (`a`'s joint order). Only `a`'s samples inside
/// `b`'s time span and inside `window = (start, end)` [s] (inclusive) are used.
///
/// # Errors
/// [`Error::JointMismatch`] when a joint of `a` is not in `b`; [`Error::Invalid`] when fewer
/// than two samples remain.
pub fn l2_between(a: &Run, b: &Run, window: Option<(f64, f64)>) -> Result<L2Report> {
    let map: Vec<usize> = a
        .joints
        .iter()
        .map(|j| {
            b.joints.iter().position(|x| x == j).ok_or_else(|| Error::JointMismatch {
                source_name: b.source.clone(),
                joint: j.clone(),
                problem: format!("is in '{}' but not in this run", a.source),
            })
        })
        .collect::<Result<_>>()?;
    let (n, nb) = (a.dof(), b.dof());
    let (b0, b1) = match (b.t.first(), b.t.last()) {
        (Some(x), Some(y)) => (*x, *y),
        _ => return Err(Error::Invalid { what: "run".into(), message: format!("'{}' has no sample", b.source) }),
    };
    let tol = 1e-9 * (1.0 + b1.abs());
    let (w0, w1) = window.unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
    let mut t = Vec::new();
    let mut x = Vec::new();
    let mut hint = 0;
    for k in 0..a.len() {
        let s = a.t[k];
        if s < b0 - tol || s > b1 + tol || s < w0 || s > w1 {
            continue;
        }
        t.push(s);
        for (i, &j) in map.iter().enumerate() {
            let mut h = hint;
            let qb = interp(&b.t, &b.q, nb, j, s, &mut h);
            x.push(a.q[k * n + i] - qb);
            if i + 1 == n {
                hint = h;
            }
        }
    }
    if t.len() < 2 {
        return Err(Error::Invalid { what: "L2 window".into(), message: format!("{} common samples of '{}' and '{}'; expected at least 2", t.len(), a.source, b.source) });
    }
    Ok(report(a.joints.clone(), &t, &x))
}

/// `L²` of the tracking error `q̃ = q_ref − q` of a run (eq. 127 as the paper uses it),
/// optionally restricted to `window = (start, end)` [s].
///
/// # Errors
/// [`Error::Invalid`] when the run has no reference or fewer than two samples remain.
pub fn l2_tracking(run: &Run, window: Option<(f64, f64)>) -> Result<L2Report> {
    if run.q_ref.len() != run.q.len() {
        return Err(Error::Invalid { what: "run".into(), message: format!("'{}' has no reference positions", run.source) });
    }
    let n = run.dof();
    let (w0, w1) = window.unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
    let mut t = Vec::new();
    let mut x = Vec::new();
    for k in 0..run.len() {
        if run.t[k] < w0 || run.t[k] > w1 {
            continue;
        }
        t.push(run.t[k]);
        x.extend((0..n).map(|i| run.q_ref[k * n + i] - run.q[k * n + i]));
    }
    if t.len() < 2 {
        return Err(Error::Invalid { what: "L2 window".into(), message: format!("{} samples of '{}' in the window; expected at least 2", t.len(), run.source) });
    }
    Ok(report(run.joints.clone(), &t, &x))
}

/// The L² index (eq. 127) of a signal computed as its samples arrive, in constant memory: the
/// same trapezoid sums, in the same order, as [`l2_index`] and [`l2_per_joint`] on the whole
/// signal, so the results agree to the last bit.
#[derive(Clone, Debug, PartialEq)]
pub struct L2Accumulator {
    joints: Vec<String>,
    t0: Option<f64>,
    t_last: f64,
    prev: Vec<f64>,
    acc: f64,
    acc_per_joint: Vec<f64>,
    max_abs: Vec<f64>,
    samples: usize,
}

impl L2Accumulator {
    /// An empty accumulator for signals over `joints`.
    pub fn new(joints: Vec<String>) -> Self {
        let n = joints.len();
        L2Accumulator { joints, t0: None, t_last: 0.0, prev: vec![0.0; n], acc: 0.0, acc_per_joint: vec![0.0; n], max_abs: vec![0.0; n], samples: 0 }
    }

    /// Adds the sample `x` (one value per joint [rad or m]) at time `t` [s], after every earlier one.
    ///
    /// # Panics
    /// If `x.len()` is not the number of joints.
    pub fn push(&mut self, t: f64, x: &[f64]) {
        assert_eq!(x.len(), self.joints.len(), "L2Accumulator::push: one value per joint");
        let sq: f64 = x.iter().map(|v| v * v).sum();
        if self.t0.is_some() {
            let dt = t - self.t_last;
            let prev_sq: f64 = self.prev.iter().map(|v| v * v).sum();
            self.acc += 0.5 * (prev_sq + sq) * dt;
            for j in 0..x.len() {
                self.acc_per_joint[j] += 0.5 * (self.prev[j].powi(2) + x[j].powi(2)) * dt;
            }
        } else {
            self.t0 = Some(t);
        }
        for j in 0..x.len() {
            self.max_abs[j] = self.max_abs[j].max(x[j].abs());
        }
        self.prev.copy_from_slice(x);
        self.t_last = t;
        self.samples += 1;
    }

    /// The report so far.
    ///
    /// # Errors
    /// [`Error::Invalid`] with fewer than two samples.
    pub fn report(&self) -> Result<L2Report> {
        let Some(t0) = self.t0.filter(|_| self.samples >= 2) else {
            return Err(Error::Invalid { what: "L2 window".into(), message: format!("{} samples; expected at least 2", self.samples) });
        };
        let span = self.t_last - t0;
        let root = |acc: f64| if span > 0.0 { (acc / span).sqrt() } else { 0.0 };
        Ok(L2Report {
            joints: self.joints.clone(),
            overall: root(self.acc),
            per_joint: self.acc_per_joint.iter().map(|a| root(*a)).collect(),
            max_abs_per_joint: self.max_abs.clone(),
            span: (t0, self.t_last),
            samples: self.samples,
        })
    }
}

/// A [`Sink`] that keeps only the L² index of the tracking error `q_ref − q` (as
/// [`l2_tracking`] of the whole run would give it), in constant memory.
#[derive(Clone, Debug, Default)]
pub struct TrackingL2Sink {
    acc: Option<L2Accumulator>,
    x: Vec<f64>,
}

impl TrackingL2Sink {
    /// An empty sink.
    pub fn new() -> Self {
        Self::default()
    }

    /// The tracking L² of the samples recorded so far.
    ///
    /// # Errors
    /// [`Error::Invalid`] with fewer than two samples.
    pub fn report(&self) -> Result<L2Report> {
        match &self.acc {
            Some(a) => a.report(),
            None => Err(Error::Invalid { what: "L2 window".into(), message: "no sample; expected at least 2".into() }),
        }
    }
}

impl Sink for TrackingL2Sink {
    fn begin(&mut self, joints: &[String], _experiment: &Experiment) -> Result<()> {
        self.acc = Some(L2Accumulator::new(joints.to_vec()));
        self.x = vec![0.0; joints.len()];
        Ok(())
    }

    fn record(&mut self, s: &Sample<'_>) -> Result<()> {
        let Some(acc) = self.acc.as_mut() else { return Err(Error::Invalid { what: "sink".into(), message: "record before begin".into() }) };
        for i in 0..self.x.len() {
            self.x[i] = s.q_ref[i] - s.q[i];
        }
        acc.push(s.t, &self.x);
        Ok(())
    }

    fn finish(&mut self, _end: &RunEnd) -> Result<()> {
        Ok(())
    }
}
