//! Robustness to real logs: glitch samples and repeated logs.
//!
//! A glitch is one sample of one joint's position far from both its neighbours: a bus error,
//! an encoder wrap, a logger hiccup. Left in, one such sample bends the smoothing
//! differentiator over a whole window and can flip the answer. Sample `k` of joint `j` is a
//! glitch when its distance to the midpoint of its neighbours, `d_k = q_k − (q_{k−1} + q_{k+1})/2`,
//! exceeds
//! - 50 robust standard deviations of `d` over the run (1.4826 × its median absolute value),
//! - the step between its neighbours `|q_{k+1} − q_{k−1}|` (a real motion moves the neighbours
//!   apart at least as much as it bends between them),
//! - and what an acceleration of 2,000 rad/s² bends in one sample, `1000 Δt²`, 1e-3 rad and
//!   five steps of the encoder (the smallest non-zero increment of the joint).
//!
//! It is replaced by the midpoint of its neighbours, so the fit and the predictions never see
//! it, and reported with time and joint.

use simgap_sim::Run;

/// A glitch found and replaced.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Glitch {
    /// Log name.
    pub log: String,
    /// Sample index.
    pub sample: usize,
    /// Time since the log's start [s].
    pub t: f64,
    /// Joint name.
    pub joint: String,
    /// Logged value [rad or m].
    pub value: f64,
    /// Value put in its place (interpolated) [rad or m].
    pub replaced_by: f64,
}

impl std::fmt::Display for Glitch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: glitch at t = {:.4} s (sample {}) on {}: position {:.6} where its neighbours give {:.6}; replaced by interpolation and kept out of the fit",
            self.log, self.t, self.sample, self.joint, self.value, self.replaced_by
        )
    }
}

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mid = v.len() / 2;
    *v.select_nth_unstable_by(mid, f64::total_cmp).1
}

/// Finds position glitches in `run` (model-aligned), replaces them in place, and returns them.
pub(crate) fn repair_glitches(run: &mut Run) -> Vec<Glitch> {
    let n = run.dof();
    let rows = run.len();
    let mut found = Vec::new();
    if rows < 9 {
        return found;
    }
    for j in 0..n {
        let q: Vec<f64> = (0..rows).map(|k| run.q[k * n + j]).collect();
        let d: Vec<f64> = (0..rows).map(|k| if k == 0 || k + 1 == rows { 0.0 } else { q[k] - 0.5 * (q[k - 1] + q[k + 1]) }).collect();
        let mut abs: Vec<f64> = d.iter().map(|x| x.abs()).collect();
        let sigma = 1.4826 * median(&mut abs);
        // the encoder's step: the smallest non-zero increment (a toggle of a few counts is no glitch)
        let step = q.windows(2).map(|w| (w[1] - w[0]).abs()).filter(|d| *d > 0.0).fold(f64::INFINITY, f64::min);
        let step = if step.is_finite() { step } else { 0.0 };
        for k in 1..rows - 1 {
            let dt = run.t[k + 1] - run.t[k - 1];
            let floor = (1000.0 * dt * dt / 4.0).max(1e-3).max(5.0 * step);
            if d[k].abs() > (50.0 * sigma).max(floor) && d[k].abs() > (q[k + 1] - q[k - 1]).abs() {
                let value = 0.5 * (q[k - 1] + q[k + 1]);
                run.q[k * n + j] = value;
                found.push(Glitch { log: run.source.clone(), sample: k, t: run.t[k] - run.t[0], joint: run.joints[j].clone(), value: q[k], replaced_by: value });
            }
        }
    }
    found
}

/// Whether two (model-aligned) runs hold the same samples: same stamps relative to their
/// start, positions and efforts.
pub(crate) fn same_content(a: &Run, b: &Run) -> bool {
    a.len() == b.len() && a.dof() == b.dof() && a.q == b.q && a.tau == b.tau && a.t.iter().zip(&b.t).all(|(x, y)| (x - a.t[0]) == (y - b.t[0]))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run_with(q: Vec<f64>) -> Run {
        let mut r = Run::new(vec!["a".into()]);
        r.t = (0..q.len()).map(|k| k as f64 * 0.01).collect();
        r.q = q;
        r.source = "test".into();
        r
    }

    #[test]
    fn one_far_sample_is_a_glitch_and_is_interpolated() {
        let mut q: Vec<f64> = (0..200).map(|k| (k as f64 * 0.01).sin()).collect();
        let true_value = q[100];
        q[100] = 10.0;
        let mut r = run_with(q);
        let g = repair_glitches(&mut r);
        assert_eq!(g.len(), 1);
        assert_eq!(g[0].sample, 100);
        assert!((r.q[100] - true_value).abs() < 1e-4);
    }

    #[test]
    fn smooth_fast_motion_has_no_glitch() {
        let q: Vec<f64> = (0..2000).map(|k| 2.0 * (k as f64 * 0.01 * 7.0).sin() + (k as f64 * 0.01 * 31.0).cos()).collect();
        let mut r = run_with(q);
        assert!(repair_glitches(&mut r).is_empty());
    }
}
