//! A recorder's low-pass filter, told from the logged positions: no measurement noise above a
//! few hertz.
//!
//! An encoder's position carries at least its quantisation noise, white up to the Nyquist
//! frequency, and a real drive adds more. A recorder that low-pass filters what it logs (a
//! robot's state estimator, an export that smooths its signals) leaves none. The test is the
//! power spectral density of the position's second difference (Welch: Hann windows of
//! [`SEGMENT`] samples, half overlapping; the difference whitens the noise and lowers the motion
//! it must be told from) in the top half of the band, `f > fs/4`, relative to its peak:
//!
//! - logs of real encoders (12 to 20 bits; pendulums, a servo) and simulated 20-bit encoders:
//!   5·10⁻³ to 0.6;
//! - the same signals zero-phase filtered at 4–10 Hz: about 10⁻¹², the window's own leakage.
//!
//! A run whose every moving joint is below [`NO_NOISE_RATIO`] is filtered. Its bandwidth is the
//! highest frequency, over joints, at which the spectrum of the position's first difference is
//! still within [`BANDWIDTH_RATIO`] of its peak: an upper bound of what the logs hold, above the
//! filter's cut-off (by the window's leakage, up to about ten bins above the motion's peak).
//!
//! Why it matters: the recorder applied its filter to signals the plant's nonlinear dynamics
//! produced, so the logged torque is not what the dynamics of the logged motion need at the
//! peaks the filter flattens. A torque saturation, which also flattens peaks, cannot be told
//! from it on such logs.

use rustfft::num_complex::Complex;
use rustfft::FftPlanner;
use simgap_sim::Run;

/// Samples per Welch segment.
pub(crate) const SEGMENT: usize = 256;

/// Below this top-band-to-peak ratio of the second difference's spectrum a joint's position
/// holds no measurement noise (between the filtered signals' ~10⁻¹² and real encoders' ≥ 5·10⁻³,
/// five decades from each).
pub(crate) const NO_NOISE_RATIO: f64 = 1e-7;

/// The bandwidth is where the first difference's spectrum falls below this fraction of its
/// peak.
pub(crate) const BANDWIDTH_RATIO: f64 = 1e-6;

/// Whether a recorder low-pass filtered any of the fit runs `data` (each run's
/// [`FitData::recorder_bandwidth`](crate::prepare::dataset::FitData::recorder_bandwidth), set from
/// [`recorder_bandwidth`]).
pub(crate) fn any_filtered(data: &[crate::prepare::dataset::FitData]) -> bool {
    data.iter().any(|d| d.recorder_bandwidth.is_some())
}

/// The bandwidth [Hz] of a run whose positions were low-pass filtered by its recorder (see the
/// [module documentation](self)); `None` for a run whose positions carry measurement noise, whose
/// joints do not move, or that is shorter than two segments.
pub(crate) fn recorder_bandwidth(run: &Run) -> Option<f64> {
    let n = run.dof();
    let len = run.len();
    if n == 0 || len < 2 * SEGMENT + 2 {
        return None;
    }
    let fs = 1.0 / crate::prepare::windows::median_spacing(&run.t);
    let mut planner = FftPlanner::new();
    let fft = planner.plan_fft_forward(SEGMENT);
    let window: Vec<f64> = (0..SEGMENT).map(|i| 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / SEGMENT as f64).cos()).collect();
    let mut bandwidth: Option<f64> = None;
    for j in 0..n {
        let q = run.column(&run.q, j);
        let d1: Vec<f64> = q.windows(2).map(|w| w[1] - w[0]).collect();
        let d2: Vec<f64> = d1.windows(2).map(|w| w[1] - w[0]).collect();
        // a joint that does not move says nothing
        if d1.iter().all(|v| *v == 0.0) {
            continue;
        }
        let p2 = welch(&d2, &window, fft.as_ref());
        let peak2 = p2.iter().copied().fold(0.0, f64::max);
        let top = SEGMENT / 4;
        let top2 = p2[top + 1..].iter().sum::<f64>() / (p2.len() - top - 1) as f64;
        if !(peak2 > 0.0) || top2 / peak2 >= NO_NOISE_RATIO {
            return None;
        }
        let p1 = welch(&d1, &window, fft.as_ref());
        let (k_peak, peak1) = p1.iter().copied().enumerate().fold((0, 0.0), |a, (k, v)| if v > a.1 { (k, v) } else { a });
        let k_band = (k_peak..p1.len()).find(|&k| p1[k] < BANDWIDTH_RATIO * peak1).unwrap_or(p1.len() - 1);
        let f = k_band as f64 * fs / SEGMENT as f64;
        bandwidth = Some(bandwidth.map_or(f, |b: f64| b.max(f)));
    }
    bandwidth
}

/// The one-sided Welch spectrum of `x` (unscaled: only its ratios are used): Hann windows of
/// [`SEGMENT`] samples (`window`), half overlapping, each less its mean; `SEGMENT / 2 + 1` bins.
fn welch(x: &[f64], window: &[f64], fft: &dyn rustfft::Fft<f64>) -> Vec<f64> {
    let mut psd = vec![0.0; SEGMENT / 2 + 1];
    let mut buf = vec![Complex::new(0.0, 0.0); SEGMENT];
    let mut start = 0;
    while start + SEGMENT <= x.len() {
        let seg = &x[start..start + SEGMENT];
        let mean = seg.iter().sum::<f64>() / SEGMENT as f64;
        for (b, (v, w)) in buf.iter_mut().zip(seg.iter().zip(window)) {
            *b = Complex::new((v - mean) * w, 0.0);
        }
        fft.process(&mut buf);
        for (p, b) in psd.iter_mut().zip(&buf) {
            *p += b.norm_sqr();
        }
        start += SEGMENT / 2;
    }
    psd
}
