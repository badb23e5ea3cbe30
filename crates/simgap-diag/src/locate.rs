//! Where: per-joint shares of the gap, worst time segments labelled by phase, and correlations
//! of the torque residual with the state.

use std::collections::BTreeMap;

use simgap_sim::Run;

use crate::prepare::dataset::FitData;

/// Per-joint figures.
#[derive(Clone, Debug, serde::Serialize)]
pub struct JointGap {
    /// Joint name.
    pub joint: String,
    /// L² of (nominal closed-loop simulation − measured) over the fit runs [rad].
    pub sim_l2: f64,
    /// L² of the inverse-dynamics torque residual [N·m].
    pub torque_residual_l2: f64,
    /// Share of the total squared simulation gap.
    pub share: f64,
    /// With a measured torque in the logs: RMS of (delivered − commanded) torque, the
    /// actuator's part of the gap [N·m]; `null` without one.
    pub actuator_residual_l2: Option<f64>,
    /// With a measured torque: RMS of (delivered torque − H q̈ − C q̇ − g), the mechanics' part
    /// [N·m]; `null` without one.
    pub mechanics_residual_l2: Option<f64>,
}

/// A time segment where the gap is largest.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Segment {
    /// Log name.
    pub log: String,
    /// Start [s].
    pub start: f64,
    /// End [s].
    pub end: f64,
    /// RMS position error in the segment [rad].
    pub rms_error: f64,
    /// The joint with the largest error there.
    pub joint: String,
    /// `transient`, `steady_state` or `velocity_reversal`.
    pub phase: String,
}

/// The `where` section of the report.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Where {
    /// Per joint.
    pub per_joint: Vec<JointGap>,
    /// Worst segments, worst first.
    pub worst_segments: Vec<Segment>,
    /// Per joint: Pearson correlation of the torque residual with `q`, `qd`, `sign_qd`, `qdd`,
    /// `tau`.
    pub correlations: BTreeMap<String, BTreeMap<String, f64>>,
}

fn pearson(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len()) as f64;
    if n < 2.0 {
        return 0.0;
    }
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    if saa <= 0.0 || sbb <= 0.0 {
        0.0
    } else {
        sab / (saa * sbb).sqrt()
    }
}

/// Phase of a segment of a measured run.
fn phase(run: &Run, k0: usize, k1: usize) -> &'static str {
    let n = run.dof();
    let qd = |k: usize, j: usize| run.q.get((k + 1) * n + j).map_or(0.0, |b| (b - run.q[k * n + j]) / (run.t[k + 1] - run.t[k]).max(1e-12));
    let last = run.len().saturating_sub(1);
    let vmax: Vec<f64> = (0..n).map(|j| (0..last).map(|k| qd(k, j).abs()).fold(0.0, f64::max)).collect();
    for j in 0..n {
        let th = 0.05 * vmax[j];
        let mut sign = 0.0;
        for k in k0..k1.min(last) {
            let v = qd(k, j);
            if v.abs() > th {
                if sign != 0.0 && v.signum() != sign {
                    return "velocity_reversal";
                }
                sign = v.signum();
            }
        }
    }
    let moving = (0..n).any(|j| (k0..k1.min(last)).map(|k| qd(k, j).abs()).sum::<f64>() / ((k1.min(last) - k0).max(1) as f64) > 0.1 * vmax[j]);
    if moving {
        "transient"
    } else {
        "steady_state"
    }
}

/// Builds the `where` section from the fit data, the measured runs and their nominal
/// simulations.
pub(crate) fn locate(joints: &[String], data: &[FitData], measured: &[Run], nominal: &[Option<Run>]) -> Where {
    let n = joints.len();
    // simulation gap per joint and worst windows
    let mut sq = vec![0.0; n];
    let mut span = 0.0;
    let mut segments = Vec::new();
    for (run, sim) in measured.iter().zip(nominal) {
        let Some(sim) = sim else { continue };
        let m = run.len().min(sim.len());
        if m < 2 {
            continue;
        }
        let err: Vec<f64> = (0..m * n).map(|i| sim.q[i] - run.q[i]).collect();
        for (j, s) in sq.iter_mut().enumerate() {
            let x: Vec<f64> = (0..m).map(|k| err[k * n + j]).collect();
            let l2 = simgap_sim::l2_index(&run.t[..m], &x, 1);
            *s += l2 * l2 * run.duration();
        }
        span += run.duration();
        let win = (m / 40).max(2);
        let mut k = 0;
        while k + win <= m {
            let mut e2 = 0.0;
            let mut per = vec![0.0; n];
            for i in k..k + win {
                for (j, p) in per.iter_mut().enumerate() {
                    *p += err[i * n + j].powi(2);
                }
            }
            for p in &per {
                e2 += p;
            }
            let jmax = (0..n).max_by(|&a, &b| per[a].total_cmp(&per[b])).unwrap_or(0);
            segments.push(Segment {
                log: run.source.clone(),
                start: run.t[k] - run.t[0],
                end: run.t[k + win - 1] - run.t[0],
                rms_error: (e2 / (win * n) as f64).sqrt(),
                joint: joints[jmax].clone(),
                phase: phase(run, k, k + win).into(),
            });
            k += win;
        }
    }
    segments.sort_by(|a, b| b.rms_error.total_cmp(&a.rms_error));
    segments.truncate(5);
    let total: f64 = sq.iter().sum();
    // torque residual per joint
    let mut per_joint = Vec::new();
    let mut correlations = BTreeMap::new();
    for j in 0..n {
        let col = |f: &dyn Fn(&FitData) -> &Vec<f64>| -> Vec<f64> { data.iter().flat_map(|d| (0..d.len()).map(move |s| f(d)[s * n + j])).collect() };
        let r = col(&|d| &d.residual);
        let rl2 = (r.iter().map(|v| v * v).sum::<f64>() / r.len().max(1) as f64).sqrt();
        // with a measured torque: actuator (commanded → delivered) and mechanics (delivered →
        // motion) apart, over the runs that have one
        let measured: Vec<&FitData> = data.iter().filter(|d| !d.tau_measured.is_empty()).collect();
        let rms_over = |f: &dyn Fn(&FitData, usize) -> f64| -> Option<f64> {
            let v: Vec<f64> = measured.iter().flat_map(|d| (0..d.len()).map(move |s| f(d, s))).collect();
            (!v.is_empty()).then(|| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt())
        };
        let actuator = rms_over(&|d, s| d.tau_measured[s * n + j] - d.tau[s * n + j]);
        let mechanics = rms_over(&|d, s| d.residual[s * n + j] - (d.tau[s * n + j] - d.tau_measured[s * n + j]));
        per_joint.push(JointGap {
            joint: joints[j].clone(),
            sim_l2: if span > 0.0 { (sq[j] / span).sqrt() } else { f64::NAN },
            torque_residual_l2: rl2,
            share: if total > 0.0 { sq[j] / total } else { f64::NAN },
            actuator_residual_l2: actuator,
            mechanics_residual_l2: mechanics,
        });
        let qd = col(&|d| &d.qd);
        let sign: Vec<f64> = qd.iter().map(|v| v.signum()).collect();
        let mut c = BTreeMap::new();
        c.insert("q".to_string(), pearson(&r, &col(&|d| &d.q)));
        c.insert("qd".to_string(), pearson(&r, &qd));
        c.insert("sign_qd".to_string(), pearson(&r, &sign));
        c.insert("qdd".to_string(), pearson(&r, &col(&|d| &d.qdd)));
        c.insert("tau".to_string(), pearson(&r, &col(&|d| &d.tau)));
        correlations.insert(joints[j].clone(), c);
    }
    Where { per_joint, worst_segments: segments, correlations }
}
