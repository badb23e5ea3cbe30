//! Fit data: logs aligned to the model, smoothed, differentiated, and the nominal
//! inverse-dynamics residual `r = τ_cmd − (H q̈ + C q̇ + g)`.

use simgap_core::{bias_torques_into, inverse_dynamics_regressor_into, mass_matrix_into, Formulation, Model, Workspace, PARAMS_PER_LINK};
use simgap_sim::{DelayLine, Run};

use crate::error::{Error, Result};
use crate::lsq::Samples;
use crate::prepare::differentiate::Smoother;
use crate::prepare::width::DryWidth;

/// Options of the data preparation.
#[derive(Clone, Debug)]
pub struct PrepareOptions {
    /// Window of the smoothing differentiator [s] (default 0.05).
    pub window: f64,
    /// At most this many samples per run are used for fitting (evenly strided; default 3000).
    pub max_samples: usize,
    /// Compute the inertial-parameter regressor (needed for `payload` and `inertial_error`).
    pub regressor: bool,
    /// The logged effort is measured on the link side of the gearbox (joint-torque sensors, as
    /// on torque-sensing arms), not the torque the drive was commanded (default false). The
    /// rotor's inertia and the motor's back-EMF act before such a sensor, so the data cannot
    /// show them and neither is tried.
    pub link_side_torque: bool,
}

impl Default for PrepareOptions {
    fn default() -> Self {
        PrepareOptions { window: 0.05, max_samples: 3000, regressor: true, link_side_torque: false }
    }
}

/// Reorders a run's columns to the model's joint order (joints matched by name).
///
/// # Errors
/// [`Error::Log`] when a model joint is missing from the log, when the log is too short, or
/// when its time or values are not finite and increasing.
pub(crate) fn align_run(model: &Model, run: &Run) -> Result<Run> {
    let names: Vec<String> = model.joint_names().iter().map(|s| s.to_string()).collect();
    let log = if run.source.is_empty() { "<run>".to_string() } else { run.source.clone() };
    let mut out = simgap_sim::reorder_joints(run, &names, true).map_err(|e| match e {
        simgap_sim::Error::JointMismatch { joint, .. } => Error::Log {
            log: log.clone(),
            message: format!("joint '{joint}' of model '{}' is not in the log (log joints: {:?}); expected every model joint", model.name(), run.joints),
        },
        other => Error::Log { log: log.clone(), message: other.to_string() },
    })?;
    out.source = log.clone();
    let samples = out.t.len();
    // a servo logs no torque: its drive command is formed from its duty or goal later
    let servo = crate::prepare::servo::is_servo(&out);
    if out.q.len() != samples * out.dof() || (!servo && out.tau.len() != samples * out.dof()) {
        return Err(Error::Log { log, message: "positions and efforts must be logged for every sample".into() });
    }
    if let Some(k) = out.t.windows(2).position(|w| !(w[1] > w[0])) {
        return Err(Error::Log { log, message: format!("time is not strictly increasing at sample {} (t = {} then {})", k + 1, out.t[k], out.t[k + 1]) });
    }
    if let Some(v) = out.t.iter().chain(&out.q).chain(&out.tau).find(|v| !v.is_finite()) {
        return Err(Error::Log { log, message: format!("non-finite value {v} in time, position or effort") });
    }
    Ok(out)
}

/// One run prepared for fitting. Matrices are row-major `len × dof` over the kept samples.
#[derive(Clone, Debug)]
pub struct FitData {
    /// Log name.
    pub name: String,
    /// Degrees of freedom.
    pub dof: usize,
    /// Kept sample times.
    pub t: Vec<f64>,
    /// Smoothed positions.
    pub q: Vec<f64>,
    /// Smoothed velocities (derivative of the positions).
    pub qd: Vec<f64>,
    /// Smoothed accelerations.
    pub qdd: Vec<f64>,
    /// Commanded torque filtered like the accelerations (see [`Smoother::apply_zoh`]); for a
    /// servo the drive torque `τ_V − en (kt²/R) q̇` of its nominal motor law.
    pub tau: Vec<f64>,
    /// Whether each joint's drive is enabled (1) or its bridge open (0), filtered likewise (1
    /// throughout for a drive that logs no torque enable).
    pub enabled: Vec<f64>,
    /// A servo's nominal back-EMF `kt²/R` per joint [N·m·s/rad] (0 for other drives).
    pub back_emf: Vec<f64>,
    /// `en q̇`, the drive's enable times the velocity over every sample interval, filtered like
    /// the torque (the velocity a back-EMF torque follows; see
    /// [`FitData::filtered_velocity_map`]) [rad/s or m/s].
    pub enabled_qd: Vec<f64>,
    /// Delivered (measured) torque filtered likewise; empty when the log has none.
    pub tau_measured: Vec<f64>,
    /// Nominal residual `τ − (H q̈ + C q̇ + g)` with the model's formulation.
    pub residual: Vec<f64>,
    /// `(C_other − C) q̇`: what switching the formulation of C would add to the model torque.
    pub coriolis_delta: Vec<f64>,
    /// Inertial regressor per kept sample, `dof × 10 dof` row-major, when requested.
    pub regressor: Vec<f64>,
    /// Per joint `j`, the slope `∂(H q̈ + C q̇ + g)/∂q_j` of the model torque at every kept
    /// sample (`len × dof` row-major, central difference) [N·m/rad or N/m]: the torque an
    /// encoder offset of one unit on joint `j` adds (the joint is at `q + δ`).
    pub offset_slope: Vec<Vec<f64>>,
    /// Per joint, the largest diagonal entry `H_jj(q)` of the mass matrix over the kept
    /// samples: the link inertia the joint moves [kg·m² or kg].
    pub h_max: Vec<f64>,
    /// The widths `w` of the smoothed sign of dry friction the data allow, per joint [rad/s or
    /// m/s]: from this run alone by [`FitData::new`], from every fit run by the diagnosis (the
    /// same on each of them; see [`DryWidth`]).
    pub dry_width: Vec<DryWidth>,
    /// The bandwidth [Hz] of the low-pass filter the recorder applied to this run's positions,
    /// when they carry no measurement noise above it ([`crate::prepare::lowpass`]); `None` for
    /// positions as an encoder gives them. Set by the diagnosis from the sensors it infers (a
    /// run prepared alone, e.g. a synthetic one, has `None`).
    pub recorder_bandwidth: Option<f64>,
    /// The run's effort was measured on the link side of the gearbox
    /// ([`PrepareOptions::link_side_torque`]).
    pub link_side_torque: bool,
    /// The aligned raw run.
    pub raw: Run,
    /// Smoothed velocities at every sample of the raw run (`len × dof`; at the first and last
    /// samples, whose window is incomplete, those of the nearest sample that has one).
    qd_every: Vec<f64>,
    smoother: Smoother,
    kept: Vec<usize>,
}

/// The step [rad or m] of the central difference of [`FitData::offset_slope`].
const OFFSET_STEP: f64 = 1e-6;

/// The model torque `H(q) q̈ + C(q, q̇) q̇ + g(q)` with `formulation`'s C into `out` (`h`:
/// scratch `dof × dof`).
#[allow(clippy::too_many_arguments)]
fn model_torque(model: &Model, ws: &mut Workspace, formulation: Formulation, q: &[f64], qd: &[f64], qdd: &[f64], h: &mut nalgebra::DMatrix<f64>, out: &mut [f64]) {
    mass_matrix_into(model, ws, q, h);
    bias_torques_into(model, ws, q, qd, formulation, out);
    for (i, o) in out.iter_mut().enumerate() {
        *o += (0..q.len()).map(|j| h[(i, j)] * qdd[j]).sum::<f64>();
    }
}

impl FitData {
    /// Prepares an aligned run (see [`align_run`]).
    ///
    /// # Errors
    /// [`Error::Log`] when the run is too short for the smoothing window.
    pub fn new(model: &Model, formulation: Formulation, run: Run, options: &PrepareOptions) -> Result<FitData> {
        let n = model.dof();
        let smoother = Smoother::new(&run.t, options.window);
        let valid = smoother.valid();
        if valid.len() < 20 {
            return Err(Error::Log {
                log: run.source.clone(),
                message: format!(
                    "too short to fit: {} samples over {:.3} s; expected at least {} samples (a {:.3} s smoothing window plus 20 samples)",
                    run.len(),
                    run.duration(),
                    2 * smoother.half() + 20,
                    options.window
                ),
            });
        }
        let stride = valid.len().div_ceil(options.max_samples).max(1);
        let kept: Vec<usize> = valid.clone().step_by(stride).collect();
        let qs = smoother.apply(&run.q, n, 0);
        let mut qds = smoother.apply(&run.q, n, 1);
        // the velocity of every sample, for columns filtered like the torque: at the first and
        // last samples (no full window) that of the nearest sample that has one
        for k in (0..valid.start).chain(valid.end..run.len()) {
            let nearest = k.clamp(valid.start, valid.end - 1);
            qds.copy_within(nearest * n..(nearest + 1) * n, k * n);
        }
        let qdds = smoother.apply(&run.q, n, 2);
        let taus = smoother.apply_zoh(&run.tau, n);
        let taus_measured = if run.tau_measured.len() == run.tau.len() { smoother.apply_zoh(&run.tau_measured, n) } else { Vec::new() };
        let pick = |m: &[f64]| -> Vec<f64> { kept.iter().flat_map(|&k| m[k * n..(k + 1) * n].iter().copied()).collect() };
        let (q, qd, qdd, mut tau) = (pick(&qs), pick(&qds), pick(&qdds), pick(&taus));
        let logged_enable = run.drive.torque_enable.len() == run.len() * n;
        let enabled = if logged_enable { pick(&smoother.apply_zoh(&run.drive.torque_enable, n)) } else { vec![1.0; tau.len()] };
        // en q̇ over every sample interval (its midpoint velocity, see
        // `filtered_velocity_map`), filtered like the torque: the back-EMF torque's velocity
        let en_qd: Vec<f64> = (0..qds.len())
            .map(|i| {
                let en = if logged_enable { run.drive.torque_enable[i] } else { 1.0 };
                en * midpoint_velocity(&qds, n, i / n, i % n)
            })
            .collect();
        let enabled_qd = pick(&smoother.apply_zoh(&en_qd, n));
        // a servo's own back-EMF, en kt²/R q̇, is part of its nominal drive torque
        let mut back_emf = vec![0.0; n];
        if let Some(p) = run.experiment.as_ref().filter(|_| crate::prepare::servo::is_servo(&run)).and_then(|e| simgap_sim::ServoParams::from_experiment(e).ok()) {
            if let (Some(kt), Some(r)) = (&p.kt, &p.r) {
                for (j, b) in back_emf.iter_mut().enumerate() {
                    *b = kt[j] * kt[j] / r[j];
                }
                for i in 0..tau.len() {
                    let j = i % n;
                    tau[i] -= kt[j] * kt[j] / r[j] * enabled_qd[i];
                }
            }
        }
        let tau_measured = if taus_measured.is_empty() { Vec::new() } else { pick(&taus_measured) };
        let t: Vec<f64> = kept.iter().map(|&k| run.t[k]).collect();
        let mut ws = Workspace::new(model);
        let mut h = nalgebra::DMatrix::zeros(n, n);
        let mut b = vec![0.0; n];
        let mut b_other = vec![0.0; n];
        let mut y = nalgebra::DMatrix::zeros(n, PARAMS_PER_LINK * n);
        let m = t.len();
        let mut residual = vec![0.0; m * n];
        let mut coriolis_delta = vec![0.0; m * n];
        let mut regressor = if options.regressor { Vec::with_capacity(m * n * PARAMS_PER_LINK * n) } else { Vec::new() };
        let mut h_max = vec![0.0f64; n];
        let mut offset_slope = vec![vec![0.0; m * n]; n];
        let (mut q_shift, mut id_plus, mut id_minus) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        // per sample: model torque, the other formulation's bias, the regressor, the slopes
        for k in 0..m {
            let (qk, qdk, qddk) = (&q[k * n..(k + 1) * n], &qd[k * n..(k + 1) * n], &qdd[k * n..(k + 1) * n]);
            mass_matrix_into(model, &mut ws, qk, &mut h);
            for (i, hm) in h_max.iter_mut().enumerate() {
                *hm = hm.max(h[(i, i)]);
            }
            bias_torques_into(model, &mut ws, qk, qdk, formulation, &mut b);
            bias_torques_into(model, &mut ws, qk, qdk, formulation.other(), &mut b_other);
            for i in 0..n {
                let hq: f64 = (0..n).map(|j| h[(i, j)] * qddk[j]).sum();
                residual[k * n + i] = tau[k * n + i] - hq - b[i];
                coriolis_delta[k * n + i] = b_other[i] - b[i];
            }
            // the model torque's slope in each joint's position, by central difference
            for (j, slope) in offset_slope.iter_mut().enumerate() {
                for (sign, out) in [(1.0, &mut id_plus), (-1.0, &mut id_minus)] {
                    q_shift.copy_from_slice(qk);
                    q_shift[j] += sign * OFFSET_STEP;
                    model_torque(model, &mut ws, formulation, &q_shift, qdk, qddk, &mut h, out);
                }
                for i in 0..n {
                    slope[k * n + i] = (id_plus[i] - id_minus[i]) / (2.0 * OFFSET_STEP);
                }
            }
            if options.regressor {
                inverse_dynamics_regressor_into(model, &mut ws, qk, qdk, qddk, &mut y);
                for i in 0..n {
                    for c in 0..PARAMS_PER_LINK * n {
                        regressor.push(y[(i, c)]);
                    }
                }
            }
        }
        let mut data = FitData {
            name: run.source.clone(),
            dof: n,
            t,
            q,
            qd,
            qdd,
            tau,
            enabled,
            back_emf,
            enabled_qd,
            tau_measured,
            residual,
            coriolis_delta,
            regressor,
            offset_slope,
            h_max,
            dry_width: Vec::new(),
            recorder_bandwidth: None,
            link_side_torque: options.link_side_torque,
            raw: run,
            qd_every: qds,
            smoother,
            kept,
        };
        let kinds: Vec<simgap_core::JointKind> = model.joints().iter().map(|j| j.kind).collect();
        data.dry_width = crate::prepare::width::dry_friction_widths(&kinds, &[&data.qd]);
        Ok(data)
    }

    /// Number of kept samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True when no sample was kept.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Applies a per-sample map to the raw commanded torque (each value held over its sample),
    /// then the filter of the accelerations; returns the kept samples.
    pub fn smoothed_torque_map(&self, f: impl Fn(usize, &[f64], &mut [f64])) -> Vec<f64> {
        let n = self.dof;
        let raw = &self.raw;
        let mut mapped = vec![0.0; raw.tau.len()];
        for k in 0..raw.len() {
            f(k, &raw.tau[k * n..(k + 1) * n], &mut mapped[k * n..(k + 1) * n]);
        }
        let s = self.smoother.apply_zoh(&mapped, n);
        self.kept.iter().flat_map(|&k| s[k * n..(k + 1) * n].iter().copied()).collect()
    }

    /// `f(q̇_j)` of joint `j`'s velocity at every sample, filtered like the torque, at the kept
    /// samples.
    ///
    /// The torque side of the fit is the command filtered by [`Smoother::apply_zoh`], so a
    /// friction torque `f(q̇)` in it arrives through that kernel: at a velocity reversal the
    /// filtered `fc sign(q̇)` ramps over the whole window. A column `f` of the smoothed velocity
    /// instead steps within the dry-friction width; least squares would fit the ramp with a
    /// smaller fc and make up the loss at speed with a larger viscous b. Filtering the column
    /// like the torque keeps both sides of the equation under one filter.
    ///
    /// The kernel takes each value as held over its sample interval `[t_k, t_k+1)` (as the
    /// command is), so `f` is evaluated at the interval's midpoint velocity
    /// `(q̇_k + q̇_k+1) / 2`: the sample's own velocity would lag the column by half a period,
    /// and a lagged viscous column trades with the inertia.
    pub fn filtered_velocity_map(&self, j: usize, f: impl Fn(f64) -> f64) -> Vec<f64> {
        let x: Vec<f64> = (0..self.raw.len()).map(|k| f(midpoint_velocity(&self.qd_every, self.dof, k, j))).collect();
        self.smoother.apply_zoh_at(&x, &self.kept)
    }

    /// The command of joint `j` held over sample `k` after a delay of `delay` seconds, as the
    /// simulator applies it: with `delay = m T + r`, `(1 − r/T) τ_{k−m} + (r/T) τ_{k−m−1}`
    /// (before the first sample, the first command; see [`simgap_sim::DelayLine`]).
    pub fn delayed_torque(&self, k: usize, delay: f64, period: f64, j: usize) -> f64 {
        DelayLine::new(delay, period).delayed(k, |i| self.raw.tau[i * self.dof + j])
    }
}

impl Samples for FitData {
    fn dof(&self) -> usize {
        self.dof
    }

    fn samples(&self) -> usize {
        self.len()
    }

    fn residual(&self) -> &[f64] {
        &self.residual
    }

    fn tau(&self) -> &[f64] {
        &self.tau
    }
}

/// Joint `j`'s velocity at the middle of sample interval `k`, from the row-major `len × dof`
/// velocities `qd` of every sample (at the last sample, its own).
fn midpoint_velocity(qd: &[f64], dof: usize, k: usize, j: usize) -> f64 {
    let next = (k + 1).min(qd.len() / dof - 1);
    0.5 * (qd[k * dof + j] + qd[next * dof + j])
}
