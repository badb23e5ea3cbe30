//! The drive between command and joint: `torque_gain` (τ_applied = k τ_cmd; column
//! `(1 − k_j) τ_j`, k within [`GAIN_RANGE`]), `torque_offset` (τ_applied = τ_cmd + offset;
//! column `−1`) and `torque_saturation` (τ_applied = clamp(τ_cmd, ±L); the fixed column
//! `τ_j − clamp(τ_j, ±L_j)`, L searched on a grid).
//!
//! Physical ranges: a gain within [`GAIN_RANGE`]; an offset no larger than the largest torque
//! commanded on its joint (a sensor bias or a drive's zero error is a fraction of the torques
//! it carries). A term fitted at the edge of its range is no finding
//! (see [`crate::select::plausible`]).

use simgap_sim::{Effect, EffectKind};

use super::effects::{list_per_joint, per_joint as reported, sig3, unit_of, Entry, FittedTerm};
use super::{per_joint, Column, EffectReport, Term, TermDesign};
use crate::prepare::dataset::FitData;

/// Plausible range of a torque gain `k` (fitted as `1 − k`).
pub(crate) const GAIN_RANGE: (f64, f64) = (0.2, 5.0);

/// The columns of an actuator term.
pub(super) fn design(term: &Term, data: &[FitData]) -> TermDesign {
    let dof = data[0].dof;
    match *term {
        Term::Gain(j) => TermDesign { cols: vec![per_joint(data, j, |d, i| d.tau[i])], lo: vec![1.0 - GAIN_RANGE.1], hi: vec![1.0 - GAIN_RANGE.0], ..Default::default() },
        Term::Offset(j) => {
            let tau_max = data.iter().flat_map(|d| d.tau.iter().skip(j).step_by(dof)).fold(0.0f64, |m, t| m.max(t.abs()));
            let bound = if tau_max > 0.0 { tau_max } else { f64::INFINITY };
            // an offset acts while the drive is enabled (a servo with torque off applies nothing)
            TermDesign { cols: vec![per_joint(data, j, |d, i| -d.enabled[i])], lo: vec![-bound], hi: vec![bound], ..Default::default() }
        }
        Term::Saturation { joint, limit } => {
            let mut v = Vec::new();
            for d in data {
                let m = d.smoothed_torque_map(|_, tau, out| {
                    out.fill(0.0);
                    out[joint] = tau[joint] - tau[joint].clamp(-limit, limit);
                });
                v.extend((0..d.len()).map(|s| m[s * dof + joint]));
            }
            TermDesign::fixed(Column::new(Some(joint), v))
        }
        _ => TermDesign::default(),
    }
}

/// A gain within [`GAIN_RANGE`]; an offset and a limit are always possible.
pub(super) fn physical(term: &Term, theta: &[f64]) -> bool {
    let tol = 1e-12;
    match term {
        Term::Gain(_) => (GAIN_RANGE.0 - tol..=GAIN_RANGE.1 + tol).contains(&(1.0 - theta[0])),
        _ => true,
    }
}

/// Adds the term to the simulator's actuator effects.
pub(super) fn apply(f: &FittedTerm, n: usize, out: &mut Vec<Effect>) {
    let th = &f.theta;
    match f.term {
        Term::Gain(j) => {
            if let Effect::TorqueGain { k } = super::effects::slot(out, Effect::TorqueGain { k: vec![1.0; n] }) {
                k[j] = 1.0 - th[0];
            }
        }
        Term::Offset(j) => {
            if let Effect::TorqueOffset { offset } = super::effects::slot(out, Effect::TorqueOffset { offset: vec![0.0; n] }) {
                offset[j] = th[0];
            }
        }
        Term::Saturation { joint, limit } => {
            if let Effect::TorqueSaturation { limit: l } = super::effects::slot(out, Effect::TorqueSaturation { limit: vec![f64::INFINITY; n] }) {
                l[joint] = limit;
            }
        }
        _ => {}
    }
}

/// The term's parameters in its report entry.
pub(super) fn report(f: &FittedTerm, entry: &mut Entry<'_>) {
    let ci = |s: f64| 1.96 * s;
    let (th, sd) = (&f.theta, &f.std);
    match f.term {
        Term::Gain(_) => entry.push("k", 1.0 - th[0], ci(sd[0])),
        Term::Offset(_) => entry.push("offset", th[0], ci(sd[0])),
        Term::Saturation { limit, .. } => entry.push("limit", limit, f64::NAN),
        _ => {}
    }
}

/// The actuator effect in words.
pub(super) fn describe(e: &EffectReport) -> String {
    match e.effect {
        EffectKind::TorqueGain => {
            let parts: Vec<String> = reported(e, "k").iter().map(|(j, k)| format!("k = {} on {j} (the drive delivers {:.0} % of the command)", sig3(*k), 100.0 * k)).collect();
            format!("torque gain {}", parts.join(", "))
        }
        EffectKind::TorqueOffset => format!("torque offset {}", list_per_joint(e, "offset")),
        _ => {
            let unit = unit_of(e, "limit");
            let parts: Vec<String> = reported(e, "limit").iter().map(|(j, l)| format!("±{} {unit} on {j}", sig3(*l))).collect();
            format!("torque saturation at {}", parts.join(", "))
        }
    }
}

/// A saturation's description completed by the torque gain selected with it: the simulator
/// clamps the command first and then scales it (`k · clamp(τ_cmd, ±limit)`), so the most the
/// drive delivers is `k · limit`, which the description states.
pub(super) fn describe_limit_with_gain(entries: &mut [EffectReport]) {
    let is = |e: &EffectReport, kind: EffectKind| e.effect == kind;
    let gains: Vec<(String, f64)> = entries.iter().filter(|e| is(e, EffectKind::TorqueGain)).flat_map(|e| reported(e, "k").into_iter().map(|(j, k)| (j.to_string(), k))).collect();
    for e in entries.iter_mut().filter(|e| is(e, EffectKind::TorqueSaturation)) {
        let unit = unit_of(e, "limit").to_string();
        let most: Vec<String> =
            reported(e, "limit").iter().filter_map(|(j, l)| gains.iter().find(|(g, _)| g == j).map(|(_, k)| format!("±{} {unit} on {j}", sig3(k * l)))).collect();
        if !most.is_empty() {
            e.description.push_str(&format!(" of the command, before the torque gain: the drive delivers at most {}", most.join(", ")));
        }
    }
}
