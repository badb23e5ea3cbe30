//! `time_delay`: τ_applied(t) = τ_cmd(t − d) for the whole robot; the fixed column
//! `τ(t) − τ(t − d)` (smoothed like the accelerations), d searched on a grid.

use super::effects::sig3;
use super::{Column, EffectReport, TermDesign};
use crate::prepare::dataset::FitData;

/// The fixed column of a delay of `delay` seconds.
pub(super) fn design(delay: f64, data: &[FitData]) -> TermDesign {
    let dof = data[0].dof;
    let mut v = Vec::new();
    for d in data {
        let period = d.raw.experiment.as_ref().map_or(d.raw.duration() / (d.raw.len().max(2) - 1) as f64, |e| e.sample_period);
        let m = d.smoothed_torque_map(|k, tau, out| {
            for j in 0..dof {
                out[j] = tau[j] - d.delayed_torque(k, delay, period, j);
            }
        });
        v.extend(m);
    }
    TermDesign::fixed(Column::new(None, v))
}

/// The delay in words.
pub(super) fn describe(e: &EffectReport) -> String {
    let delay = match e.parameters.get("delay") {
        Some(super::Param::Number(x)) => *x,
        _ => f64::NAN,
    };
    format!("actuation delay of {} ms (whole robot)", sig3(1e3 * delay))
}
