//! The sensors a log shows (velocity estimate, encoder resolution, a recorder's low-pass
//! filter), inferred once per run in the prepare stage.

use simgap_sim::{Run, SensorParams, VelocityEstimate};

use crate::prepare::lowpass::recorder_bandwidth;

/// The sensors a log shows, inferred from its samples: what the re-simulated controller must
/// see for an effect-free run to re-simulate to the quantisation level.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct InferredSensors {
    /// Log name.
    pub log: String,
    /// `backward_difference` (the logged velocity is the difference of the logged positions
    /// over the sample period), `given` (set by the experiment) or `exact` (anything else: a
    /// filtered or measured velocity, taken as exact).
    pub velocity: String,
    /// Encoder counts per revolution when the logged positions are multiples of one increment.
    pub counts_per_rev: Option<f64>,
    /// When the logged positions carry no measurement noise, the bandwidth [Hz] of the
    /// low-pass filter their recorder applied (what they hold ends there; see
    /// [`crate::prepare::lowpass`]); `None` for positions as an encoder gives them.
    pub recorder_lowpass_hz: Option<f64>,
}

impl InferredSensors {
    /// As simulator sensor parameters (no noise).
    pub fn params(&self) -> SensorParams {
        let mut s = SensorParams::exact();
        s.counts_per_rev = self.counts_per_rev;
        if self.velocity == "backward_difference" {
            s.velocity = VelocityEstimate::BackwardDifference;
        }
        s
    }
}

/// The sensors of a (model-aligned) run: the experiment's `counts_per_rev` and `velocity`
/// (`backward_difference` | `exact`) entries when given, else inferred from the samples.
///
/// - Velocity: backward difference when `q̇_k = (q_k − q_{k−1}) / T` holds on at least 99 % of
///   the moving samples to 1e-6 relative (T the experiment's sample period), else exact.
/// - Encoder: the smallest non-zero position increment `r` of each rotational joint; when every
///   logged position is an integer multiple of `r` (to 1e-4 of `r`) on every joint alike and
///   `2π / r` is at least 1,000 counts, `counts_per_rev = 2π / r`.
pub(crate) fn infer_sensors(run: &Run) -> InferredSensors {
    let n = run.dof();
    let given_counts = run.experiment.as_ref().and_then(|e| e.extra.get("counts_per_rev")).and_then(|v| v.parse::<f64>().ok()).filter(|c| c.is_finite() && *c > 0.0);
    let given_velocity = run.experiment.as_ref().and_then(|e| e.extra.get("velocity")).cloned();
    let period = run.experiment.as_ref().map(|e| e.sample_period).unwrap_or(0.0);
    let rows = run.len();
    // velocity: backward difference of the logged positions?
    let velocity = match given_velocity.as_deref() {
        Some("backward_difference") | Some("exact") => given_velocity.clone().unwrap_or_default(),
        _ if period > 0.0 && rows > 2 && run.qd.len() == rows * n => {
            let (mut moving, mut matching) = (0usize, 0usize);
            for k in 1..rows {
                for j in 0..n {
                    let v = run.qd[k * n + j];
                    let bd = (run.q[k * n + j] - run.q[(k - 1) * n + j]) / period;
                    if v.abs() > 1e-9 || bd.abs() > 1e-9 {
                        moving += 1;
                        if (v - bd).abs() <= 1e-6 * v.abs().max(bd.abs()) + 1e-12 {
                            matching += 1;
                        }
                    }
                }
            }
            if moving > 0 && matching as f64 >= 0.99 * moving as f64 {
                "backward_difference".to_string()
            } else {
                "exact".to_string()
            }
        }
        _ => "exact".to_string(),
    };
    // encoder: positions on a common grid?
    let counts_per_rev = given_counts.or_else(|| {
        let mut r = f64::INFINITY;
        for k in 1..rows {
            for j in 0..n {
                let d = (run.q[k * n + j] - run.q[(k - 1) * n + j]).abs();
                if d > 1e-12 {
                    r = r.min(d);
                }
            }
        }
        if !r.is_finite() || std::f64::consts::TAU / r < 1000.0 {
            return None;
        }
        let counts = (std::f64::consts::TAU / r).round();
        let r = std::f64::consts::TAU / counts;
        let on_grid = run.q.iter().all(|q| {
            let m = q / r;
            (m - m.round()).abs() <= 1e-4
        });
        on_grid.then_some(counts)
    });
    InferredSensors { log: run.source.clone(), velocity, counts_per_rev, recorder_lowpass_hz: recorder_bandwidth(run) }
}
