//! `cogging`: a torque ripple −A sin(N q) of a motor's magnets (column `sin(N q_j)`, A free,
//! N periods per revolution searched on a grid).

use simgap_sim::Effect;

use super::effects::{per_joint as reported, sig3, unit_of, Entry};
use super::{per_joint, EffectReport, TermDesign};
use crate::prepare::dataset::FitData;

/// The column of a cogging torque of `periods` per revolution on joint `joint`.
pub(super) fn design(joint: usize, periods: f64, data: &[FitData]) -> TermDesign {
    TermDesign::free(vec![per_joint(data, joint, |d, i| (periods * d.q[i]).sin())])
}

/// Adds the cogging of joint `joint` to the simulator's.
pub(super) fn apply(joint: usize, periods: f64, theta: &[f64], n: usize, out: &mut Vec<Effect>) {
    if let Effect::Cogging { amplitude, periods_per_rev } = super::effects::slot(out, Effect::Cogging { amplitude: vec![0.0; n], periods_per_rev: vec![1.0; n] }) {
        amplitude[joint] = theta[0];
        periods_per_rev[joint] = periods;
    }
}

/// The cogging's parameters in its report entry.
pub(super) fn report(periods: f64, th: &[f64], sd: &[f64], entry: &mut Entry<'_>) {
    entry.push("amplitude", th[0], 1.96 * sd[0]);
    entry.push("periods_per_rev", periods, f64::NAN);
}

/// The cogging in words.
pub(super) fn describe(e: &EffectReport) -> String {
    let unit = unit_of(e, "amplitude");
    let parts: Vec<String> = reported(e, "amplitude")
        .iter()
        .zip(reported(e, "periods_per_rev"))
        .map(|((j, a), (_, n))| format!("{} {unit}, {n:.0} periods per revolution on {j}", sig3(a.abs())))
        .collect();
    format!("cogging torque {}", parts.join(", "))
}
