//! What is left: a test of the torque residual after the selected effects, per joint and phase
//! of motion, that says whether it is noise or structure the vocabulary does not hold.
//!
//! For joint j the residual r = τ − ID(q, q̇, q̈) − Σ (selected terms) [N·m] on the fit samples is
//! binned by each of a few signals of the run (the joint's position, velocity, acceleration and
//! commanded torque, and the time since the log's start): ten bins at the signal's deciles. The
//! bin means are estimated on one half of the time blocks and predict the other half, both ways
//! round; the **explained share** of a signal is
//!
//! > 1 − Σ (r − m̂_bin)² / Σ (r − m̂)²   (m̂: means of the other half)
//!
//! floored at 0. An unstructured residual (noise, or an error no signal here orders) gives
//! shares near 0 whatever the binning; a friction of a shape outside the vocabulary shows up as
//! a share of the velocity, cogging or a geometry error as a share of the position, an
//! actuator non-linearity as a share of the torque, a drift (temperature) as a share of time.
//! Splitting halves by time block keeps a smooth residual from explaining itself through
//! neighbouring samples.
//!
//! Phases: moving forward (q̇ > v₀), backward (q̇ < −v₀) and near rest (|q̇| ≤ v₀), with v₀ 5 % of
//! the joint's RMS velocity: a residual concentrated near rest or in one direction points at the
//! friction model.

use crate::lsq::Problem;
use crate::prepare::dataset::FitData;
use crate::vocabulary::Column;

/// Number of bins per signal.
const BINS: usize = 10;

/// A signal's explained share from which the residual counts as structured.
pub(crate) const STRUCTURE_SHARE: f64 = 0.2;

/// Below this RMS relative to the joint's RMS commanded torque, the residual is negligible.
pub(crate) const NEGLIGIBLE_SHARE: f64 = 0.02;

/// The residual of one joint after the selected effects.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ResidualTest {
    /// Joint name.
    pub joint: String,
    /// RMS residual torque on the fit samples [`unit`].
    pub rms: f64,
    /// The unit of `rms` and `phase_rms`: N·m on a turning joint, N on a linear one.
    pub unit: String,
    /// `rms` over the RMS commanded torque of the joint (-).
    pub share_of_torque: f64,
    /// RMS residual per phase of motion [`unit`]: `forward`, `backward`, `near_rest` (`null` for a
    /// phase with no samples).
    pub phase_rms: std::collections::BTreeMap<String, f64>,
    /// Explained share of the residual per signal (`position`, `velocity`, `acceleration`,
    /// `torque`, `time`), on held-out halves (-).
    pub explained_by: std::collections::BTreeMap<String, f64>,
    /// `negligible`, `noise-like` or `structured`.
    pub kind: String,
}

impl ResidualTest {
    /// The signal that explains most of the residual, with its share.
    pub fn strongest(&self) -> Option<(&str, f64)> {
        self.explained_by.iter().filter(|(_, v)| v.is_finite()).max_by(|a, b| a.1.total_cmp(b.1)).map(|(k, v)| (k.as_str(), *v))
    }

    /// One sentence for the report's notes.
    pub fn sentence(&self) -> String {
        let head = format!("{}: {:.3e} {} RMS of torque residual left ({:.1} % of its commanded torque)", self.joint, self.rms, self.unit, 100.0 * self.share_of_torque);
        match self.kind.as_str() {
            "negligible" => format!("{head}: negligible"),
            "structured" => {
                let (what, share) = self.strongest().unwrap_or(("?", f64::NAN));
                let hint = match what {
                    "velocity" => "a friction of a shape the vocabulary does not hold, or a velocity-dependent effect",
                    "position" => "a position-dependent torque (cogging, a spring, a gravity or geometry error)",
                    "acceleration" => "an inertia error the selected effects do not reach",
                    "torque" => "an actuator non-linearity (torque-dependent gain or limit)",
                    "time" => "a drift over the run (temperature, warming drives)",
                    _ => "structure",
                };
                format!("{head}: structured, {:.0} % of it follows the joint's {what} on held-out halves: {hint}{}", 100.0 * share, self.phase_remark())
            }
            _ => format!(
                "{head}: noise-like, no binning by position, velocity, acceleration, torque or time explains more than {:.0} % of it on held-out halves{}",
                100.0 * STRUCTURE_SHARE,
                self.phase_remark()
            ),
        }
    }

    /// A remark when one phase holds most of the residual.
    fn phase_remark(&self) -> String {
        let ph: Vec<(&String, f64)> = self.phase_rms.iter().filter(|(_, v)| v.is_finite()).map(|(k, v)| (k, *v)).collect();
        let Some((name, top)) = ph.iter().copied().max_by(|a, b| a.1.total_cmp(&b.1)) else { return String::new() };
        let others = ph.iter().filter(|(k, _)| *k != name).map(|(_, v)| *v).fold(0.0f64, f64::max);
        if ph.len() > 1 && top > 1.5 * others {
            format!("; it is largest {} ({top:.3e} {} RMS)", name.replace('_', " ").replace("forward", "moving forward").replace("backward", "moving backward"), self.unit)
        } else {
            String::new()
        }
    }
}

/// Decile edges of `v` (BINS − 1 interior edges).
fn edges(v: &[f64]) -> Vec<f64> {
    let mut s: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if s.is_empty() {
        return Vec::new();
    }
    s.sort_by(f64::total_cmp);
    (1..BINS).map(|k| s[(k * s.len() / BINS).min(s.len() - 1)]).collect()
}

fn bin(edges: &[f64], x: f64) -> usize {
    edges.partition_point(|e| *e < x)
}

/// Explained share of `r` by the bins of `signal`, estimated across the two halves `half`.
fn explained_share(r: &[f64], signal: &[f64], half: &[bool]) -> f64 {
    let e = edges(signal);
    if e.is_empty() {
        return f64::NAN;
    }
    // bin sums per half
    let mut sum = [[0.0; BINS], [0.0; BINS]];
    let mut cnt = [[0usize; BINS], [0usize; BINS]];
    let (mut tot, mut n) = ([0.0; 2], [0usize; 2]);
    for ((&x, &s), &h) in r.iter().zip(signal).zip(half) {
        let h = h as usize;
        let b = bin(&e, s);
        sum[h][b] += x;
        cnt[h][b] += 1;
        tot[h] += x;
        n[h] += 1;
    }
    if n[0] == 0 || n[1] == 0 {
        return f64::NAN;
    }
    let (mut sse, mut sst) = (0.0, 0.0);
    for ((&x, &s), &h) in r.iter().zip(signal).zip(half) {
        // the other half's means
        let o = 1 - h as usize;
        let mean = tot[o] / n[o] as f64;
        let b = bin(&e, s);
        let m = if cnt[o][b] > 0 { sum[o][b] / cnt[o][b] as f64 } else { mean };
        sse += (x - m).powi(2);
        sst += (x - mean).powi(2);
    }
    if sst > 0.0 {
        (1.0 - sse / sst).max(0.0)
    } else {
        0.0
    }
}

/// Tests the residual `r` (as [`crate::select::residual_after`] gives it) joint by joint.
pub(crate) fn test(p: &Problem, data: &[FitData], r: &Column, joints: &[String], kinds: &[simgap_core::JointKind]) -> Vec<ResidualTest> {
    let dof = p.dof;
    // signals in the order of the stacked samples
    let stack = |f: &dyn Fn(&FitData) -> &[f64], j: usize| -> Vec<f64> { data.iter().flat_map(|d| f(d).iter().skip(j).step_by(dof).copied()).collect() };
    let time: Vec<f64> = data.iter().flat_map(|d| d.t.iter().map(move |t| t - d.t.first().copied().unwrap_or(0.0))).collect();
    let half: Vec<bool> = p.block_of.iter().map(|b| b % 2 == 1).collect();
    (0..dof)
        .map(|j| {
            let rj: Vec<f64> = (0..p.samples).map(|s| r.at(s, j, dof)).collect();
            let rms = |v: &[f64]| if v.is_empty() { f64::NAN } else { (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt() };
            let total = rms(&rj);
            let share_of_torque = total / p.tau_rms[j].max(1e-12);
            let (q, qd, qdd, tau) = (stack(&|d| &d.q, j), stack(&|d| &d.qd, j), stack(&|d| &d.qdd, j), stack(&|d| &d.tau, j));
            let v0 = 0.05 * rms(&qd);
            let phase = |keep: &dyn Fn(f64) -> bool| -> f64 {
                let v: Vec<f64> = rj.iter().zip(&qd).filter(|(_, v)| keep(**v)).map(|(x, _)| *x).collect();
                rms(&v)
            };
            let phase_rms = [("forward", phase(&|v| v > v0)), ("backward", phase(&|v| v < -v0)), ("near_rest", phase(&|v| v.abs() <= v0))]
                .into_iter()
                .map(|(k, v)| (k.to_string(), v))
                .collect();
            let explained_by: std::collections::BTreeMap<String, f64> = [("position", &q), ("velocity", &qd), ("acceleration", &qdd), ("torque", &tau), ("time", &time)]
                .into_iter()
                .map(|(k, s)| (k.to_string(), explained_share(&rj, s, &half)))
                .collect();
            let strongest = explained_by.values().copied().filter(|v| v.is_finite()).fold(0.0f64, f64::max);
            let kind = if share_of_torque < NEGLIGIBLE_SHARE {
                "negligible"
            } else if strongest >= STRUCTURE_SHARE {
                "structured"
            } else {
                "noise-like"
            };
            ResidualTest {
                joint: joints.get(j).cloned().unwrap_or_else(|| format!("joint {j}")),
                rms: total,
                unit: simgap_sim::Quantity::Effort.unit(kinds.get(j).copied().unwrap_or(simgap_core::JointKind::Revolute)).to_string(),
                share_of_torque,
                phase_rms,
                explained_by,
                kind: kind.into(),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn halves(n: usize) -> Vec<bool> {
        (0..n).map(|s| (s * 20 / n) % 2 == 1).collect()
    }

    #[test]
    fn white_noise_explains_nothing_and_a_function_of_the_signal_explains_most() {
        let n = 4000;
        let x: Vec<f64> = (0..n).map(|s| (s as f64 * 0.01).sin()).collect();
        // deterministic pseudo-noise
        let mut state = 12345u64;
        let noise: Vec<f64> = (0..n)
            .map(|_| {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                ((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
            })
            .collect();
        let h = halves(n);
        let share_noise = explained_share(&noise, &x, &h);
        assert!(share_noise < 0.05, "noise explained {share_noise}");
        let structured: Vec<f64> = x.iter().zip(&noise).map(|(x, e)| x.signum() * 1.0 + 0.2 * e).collect();
        let share = explained_share(&structured, &x, &h);
        assert!(share > 0.8, "sign(x) explained only {share}");
    }
}
