//! The prediction windows of a run: the smoothed states a k-step prediction restarts from, the
//! window starts and their ends at each horizon, and the fold of each window. Built once per run
//! in the prepare stage; [`crate::prediction::kstep`] predicts over them.

use simgap_sim::{Run, SensorParams};

use crate::prepare::differentiate::Smoother;

/// Default prediction horizons [s].
pub(crate) const DEFAULT_HORIZONS: [f64; 3] = [0.1, 0.25, 0.5];

/// At most this many windows per held-out run (the stride grows on long runs).
pub(crate) const MAX_WINDOWS_PER_RUN: usize = 200;

/// At most this many windows per fit run, where every candidate set is scored.
pub(crate) const FIT_WINDOWS_PER_RUN: usize = 48;

/// A run prepared for k-step prediction: smoothed states, windows and the controller set-up.
#[derive(Clone, Debug)]
pub(crate) struct PredictionRun {
    /// The model-aligned run.
    pub run: Run,
    /// Smoothed positions at every sample (row-major; meaningful on the valid range).
    pub q_hat: Vec<f64>,
    /// Smoothed velocities at every sample.
    pub qd_hat: Vec<f64>,
    /// Window start samples.
    pub starts: Vec<usize>,
    /// Per window, per horizon: the end sample (or `usize::MAX` when past the run).
    pub ends: Vec<Vec<usize>>,
    /// Fold of each window (contiguous fifths of the run, numbered from `fold_base`).
    pub fold: Vec<usize>,
    /// The sensors of the feedback controller.
    pub sensor: SensorParams,
    /// Controller sample period [s] (the median spacing of the stamps when unknown).
    pub period: f64,
}

/// Folds per run for cross-validated prediction (matches the torque fit's contiguous folds).
pub(crate) const FOLDS_PER_RUN: usize = crate::lsq::BLOCKS_PER_RUN / crate::lsq::BLOCKS_PER_FOLD;

impl PredictionRun {
    /// Prepares `run` (model-aligned) for prediction at `horizons`, smoothing with a window of
    /// `window` seconds; at most `max_windows` windows, numbered in folds from `fold_base`.
    pub(crate) fn new(run: Run, horizons: &[f64], window: f64, sensor: SensorParams, fold_base: usize, max_windows: usize) -> PredictionRun {
        let n = run.dof();
        let smoother = Smoother::new(&run.t, window);
        let q_hat = smoother.apply(&run.q, n, 0);
        let qd_hat = smoother.apply(&run.q, n, 1);
        let valid = smoother.valid();
        let period = median_spacing(&run.t);
        let period = run.experiment.as_ref().map(|e| e.sample_period).filter(|p| p.is_finite() && *p > 0.0).unwrap_or(period);
        let mut starts = Vec::new();
        let mut ends = Vec::new();
        let mut fold = Vec::new();
        if !valid.is_empty() {
            let stride_t = horizons.iter().cloned().fold(f64::INFINITY, f64::min).max(period);
            let span = run.t[valid.end - 1] - run.t[valid.start];
            let stride_t = stride_t.max(span / max_windows.max(1) as f64);
            let mut next_t = run.t[valid.start];
            for k in valid.clone() {
                if run.t[k] + 1e-12 < next_t {
                    continue;
                }
                next_t = run.t[k] + stride_t;
                let e: Vec<usize> = horizons
                    .iter()
                    .map(|&h| {
                        let target = run.t[k] + h;
                        let j = run.t.partition_point(|&t| t < target - 0.5 * period);
                        if j < valid.end && h > 0.0 {
                            j
                        } else {
                            usize::MAX
                        }
                    })
                    .collect();
                if e.iter().all(|&x| x == usize::MAX) {
                    break;
                }
                // the fold of the window's start, as the torque fit's contiguous folds cut the run
                fold.push(fold_base + ((k - valid.start) * FOLDS_PER_RUN / valid.len()).min(FOLDS_PER_RUN - 1));
                starts.push(k);
                ends.push(e);
            }
        }
        PredictionRun { run, q_hat, qd_hat, starts, ends, fold, sensor, period }
    }

    /// Number of windows.
    pub(crate) fn windows(&self) -> usize {
        self.starts.len()
    }
}

/// The median spacing of increasing stamps [s] (1 for fewer than two).
pub(crate) fn median_spacing(t: &[f64]) -> f64 {
    if t.len() < 2 {
        return 1.0;
    }
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    let mid = d.len() / 2;
    *d.select_nth_unstable_by(mid, f64::total_cmp).1
}
