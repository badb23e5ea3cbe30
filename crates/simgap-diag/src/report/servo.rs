//! What a diagnosis of servo runs adds to the report's notes: where the held-out gap lies by
//! the servo's phase (torque off, holding, moving), and what its logs cannot separate (the
//! winding temperature from the gain when both rise together).

use simgap_sim::Run;

use crate::prediction::kstep::Errors;
use crate::prepare::windows::PredictionRun;

/// Below this speed [rad/s or m/s] an enabled servo is holding rather than moving.
const HOLDING_SPEED: f64 = 0.05;

/// The phase of a servo window at its start sample.
fn phase(pr: &PredictionRun, k0: usize) -> usize {
    let n = pr.run.dof();
    if (0..n).all(|j| !pr.run.drive.enabled(k0, j, n)) {
        0
    } else if (0..n).all(|j| pr.qd_hat[k0 * n + j].abs() < HOLDING_SPEED) {
        1
    } else {
        2
    }
}

/// Per phase (torque off, holding, moving): the held-out k-step RMS at horizon `h` (index into
/// the horizons) of the nominal model, the corrected one and the floor, pooled over runs, with
/// the number of windows; a note naming where the corrected model is furthest from the floor.
pub(crate) fn phase_note(runs: &[PredictionRun], before: &[Errors], after: &[Errors], floor: &[Errors], h: usize, horizon: f64, unit: &str) -> Option<String> {
    if !runs.iter().any(|r| crate::prepare::servo::is_servo(&r.run)) {
        return None;
    }
    const NAMES: [&str; 3] = ["torque off", "holding", "moving"];
    // per phase: sums of squared errors (before, after, floor) and window counts
    let mut sums = [[0.0f64; 3]; 3];
    let mut count = [0usize; 3];
    for (i, pr) in runs.iter().enumerate() {
        let dof = pr.run.dof();
        for (w, &k0) in pr.starts.iter().enumerate() {
            let at = |e: &Errors| -> Option<f64> {
                let s: f64 = (0..dof).map(|j| e.sq[(w * e.horizons + h) * dof + j]).sum();
                s.is_finite().then_some(s)
            };
            let (Some(b), Some(a), Some(f)) = (at(&before[i]), at(&after[i]), at(&floor[i])) else { continue };
            let p = phase(pr, k0);
            sums[p][0] += b;
            sums[p][1] += a;
            sums[p][2] += f;
            count[p] += 1;
        }
    }
    let parts: Vec<String> = (0..3)
        .filter(|&p| count[p] > 0)
        .map(|p| {
            let rms = |s: f64| (s / count[p] as f64).sqrt();
            format!("{} ({} windows): {:.3e} → {:.3e} {unit} (floor {:.3e})", NAMES[p], count[p], rms(sums[p][0]), rms(sums[p][1]), rms(sums[p][2]))
        })
        .collect();
    Some(format!("where, by the servo's phase at the window's start (held-out k-step error at {horizon} s, nominal → corrected): {}", parts.join("; ")))
}

/// A note when the logs' temperatures rise with another of their differences (the gain, the
/// order of the runs): the diagnosis fits one servo, and a drive that weakens as it warms looks
/// like a gain or friction that changes between logs.
pub(crate) fn temperature_note<'a>(runs: impl Iterator<Item = &'a Run>) -> Option<String> {
    let means: Vec<(String, f64)> =
        runs.filter(|r| !r.drive.temperature.is_empty()).map(|r| (r.source.clone(), r.drive.temperature.iter().sum::<f64>() / r.drive.temperature.len() as f64)).collect();
    if means.len() < 2 {
        return None;
    }
    let (lo, hi) = means.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (_, t)| (a.min(*t), b.max(*t)));
    (hi - lo >= 5.0).then(|| {
        format!(
            "the servo's temperature differs between logs ({lo:.1}–{hi:.1} °C mean per log): the winding resistance rises about 0.4 % per °C, so a drive constant that changes with temperature cannot be told from one that changes with the gain or the order of the runs; the diagnosis fits one servo for all logs"
        )
    })
}
