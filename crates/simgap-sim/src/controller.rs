//! Controllers: the callback the simulator calls once per sample.

use std::collections::BTreeMap;

use simgap_core::{gravity_torques_into, Model, Workspace};

use crate::error::{Error, Result};
pub use crate::experiment::{servo_keys, ServoParams};
use crate::experiment::{ControllerKind, Experiment};
use crate::run::Run;

/// A sampled controller: the commanded torque from the measurements and the reference.
///
/// Every slice has length `dof` in model joint order. Called once per sample period; the
/// simulator holds the torque until the next sample (zero-order hold).
pub trait Controller {
    /// Writes the commanded torque τ_cmd [N·m or N] into `out`.
    fn torque(&mut self, t: f64, q_meas: &[f64], qd_meas: &[f64], q_ref: &[f64], qd_ref: &[f64], out: &mut [f64]);

    /// Whether the reference's feed-forward torque is added to this controller's command:
    /// true for feedback controllers, false for a replay (its logged effort already holds
    /// everything that was commanded).
    fn adds_feed_forward(&self) -> bool {
        true
    }

    /// The drives over the sample the last [`Controller::torque`] commanded, into `enabled`
    /// and `emf` (length `dof`, overwritten): whether each drive is enabled (1) or its bridge
    /// open (0: no torque at all), and the back-EMF coefficient of the controller's own motor
    /// law [N·m·s/rad or N·s/m], which the simulator applies as `−emf q̇` continuously over the
    /// interval (it is physics, not a sampled command). The default is a torque-controlled
    /// drive: enabled, no back-EMF.
    fn drive(&self, enabled: &mut [f64], emf: &mut [f64]) {
        enabled.fill(1.0);
        emf.fill(0.0);
    }

    /// What the controller's drive logs of the sample the last [`Controller::torque`]
    /// commanded: a position-controlled servo's duty, torque enable and supply voltage. The
    /// default (a torque-controlled drive) logs none.
    fn drive_sample(&self) -> Option<crate::run::DriveSample<'_>> {
        None
    }

    /// The `simgap.experiment` metadata describing this controller, for the sink.
    ///
    /// The default describes a replay (no gains).
    fn experiment(&self, joints: &[String], sample_period: f64) -> Experiment {
        Experiment { controller: ControllerKind::Replay, joints: joints.to_vec(), kp: Vec::new(), kv: Vec::new(), sample_period, extra: BTreeMap::new() }
    }
}

/// Zero torque: free motion.
#[derive(Clone, Copy, Debug, Default)]
pub struct ZeroTorque;

impl Controller for ZeroTorque {
    fn torque(&mut self, _t: f64, _q: &[f64], _qd: &[f64], _q_ref: &[f64], _qd_ref: &[f64], out: &mut [f64]) {
        out.fill(0.0);
    }
}

/// PD control: `τ = Kp (q_ref − q) + Kv (q̇_ref − q̇)`, diagonal gains in model order (the
/// simulator adds the reference's feed-forward torque).
#[derive(Clone, Debug, PartialEq)]
pub struct Pd {
    /// Proportional gains [N·m/rad].
    pub kp: Vec<f64>,
    /// Derivative gains [N·m·s/rad].
    pub kv: Vec<f64>,
}

impl Controller for Pd {
    fn torque(&mut self, _t: f64, q: &[f64], qd: &[f64], q_ref: &[f64], qd_ref: &[f64], out: &mut [f64]) {
        for i in 0..out.len() {
            out[i] = self.kp[i] * (q_ref[i] - q[i]) + self.kv[i] * (qd_ref[i] - qd[i]);
        }
    }

    fn experiment(&self, joints: &[String], sample_period: f64) -> Experiment {
        gains_experiment(ControllerKind::Pd, joints, &self.kp, &self.kv, sample_period)
    }
}

/// PD control with gravity compensation from the controller's own model:
/// `τ = Kp (q_ref − q) + Kv (q̇_ref − q̇) + g_model(q_meas)`.
#[derive(Clone, Debug)]
pub struct PdGravity {
    /// Proportional gains [N·m/rad].
    pub kp: Vec<f64>,
    /// Derivative gains [N·m·s/rad].
    pub kv: Vec<f64>,
    /// The model whose g(q) is compensated (the controller's belief, not the plant).
    pub model: Model,
    ws: Workspace,
    g: Vec<f64>,
}

impl PdGravity {
    /// A PD + gravity controller.
    pub fn new(kp: Vec<f64>, kv: Vec<f64>, model: Model) -> Self {
        let ws = Workspace::new(&model);
        let g = vec![0.0; model.dof()];
        PdGravity { kp, kv, model, ws, g }
    }
}

impl Controller for PdGravity {
    fn torque(&mut self, _t: f64, q: &[f64], qd: &[f64], q_ref: &[f64], qd_ref: &[f64], out: &mut [f64]) {
        gravity_torques_into(&self.model, &mut self.ws, q, &mut self.g);
        for i in 0..out.len() {
            out[i] = self.kp[i] * (q_ref[i] - q[i]) + self.kv[i] * (qd_ref[i] - qd[i]) + self.g[i];
        }
    }

    fn experiment(&self, joints: &[String], sample_period: f64) -> Experiment {
        gains_experiment(ControllerKind::PdGravity, joints, &self.kp, &self.kv, sample_period)
    }
}

fn gains_experiment(kind: ControllerKind, joints: &[String], kp: &[f64], kv: &[f64], sample_period: f64) -> Experiment {
    Experiment { controller: kind, joints: joints.to_vec(), kp: kp.to_vec(), kv: kv.to_vec(), sample_period, extra: BTreeMap::new() }
}

/// Open-loop replay of a logged effort, zero-order hold: at time `t` the torque of the last
/// logged sample with `t_k <= t + tol` (`tol` = half the mean sample spacing, so timestamp
/// jitter does not shift the replay by a sample), the first sample before the log starts.
#[derive(Clone, Debug, PartialEq)]
pub struct Replay {
    /// Sample times [s], increasing.
    pub t: Vec<f64>,
    /// Torques, row-major `t.len() × dof`, model order.
    pub tau: Vec<f64>,
    cursor: usize,
    tol: f64,
}

impl Replay {
    /// A replay of `tau` (row-major, `t.len()` rows).
    ///
    /// # Errors
    /// [`Error::Invalid`] for an empty log or a length mismatch.
    pub fn new(t: Vec<f64>, tau: Vec<f64>) -> Result<Self> {
        if t.is_empty() || tau.len() % t.len() != 0 || tau.is_empty() {
            return Err(Error::Invalid {
                what: "replay".into(),
                message: format!("{} times and {} torque values; expected a non-empty log with one row per time", t.len(), tau.len()),
            });
        }
        let tol = if t.len() > 1 { 0.5 * (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64 } else { 0.0 };
        Ok(Replay { t, tau, cursor: 0, tol: tol.max(1e-9) })
    }
}

impl Controller for Replay {
    fn adds_feed_forward(&self) -> bool {
        false
    }

    fn torque(&mut self, t: f64, _q: &[f64], _qd: &[f64], _q_ref: &[f64], _qd_ref: &[f64], out: &mut [f64]) {
        let n = out.len();
        let tol = self.tol;
        // move the cursor to the last sample at or before t (times are mostly increasing)
        if self.cursor >= self.t.len() || self.t[self.cursor] > t + tol {
            self.cursor = self.t.partition_point(|&tk| tk <= t + tol).saturating_sub(1);
        }
        while self.cursor + 1 < self.t.len() && self.t[self.cursor + 1] <= t + tol {
            self.cursor += 1;
        }
        out.copy_from_slice(&self.tau[self.cursor * n..(self.cursor + 1) * n]);
    }
}

/// A position-controlled servo (Dynamixel, Feetech): the firmware closes a P loop on the goal
/// position and drives a PWM duty; the motor's torque follows the DC-motor law with back-EMF:
///
/// ```text
/// duty = clip(duty_gain · (goal − q), ±max_duty)
/// τ    = en · (kt / R) · (V · duty − kt · q̇)
/// ```
///
/// with `V` the logged supply voltage (else `supply_voltage`), `en` the logged torque enable
/// (1 when absent; 0 opens the bridge: no torque, no back-EMF) and `goal` the reference,
/// moved at most `goal_rate_limit · Δt` per sample when a limit is given. The command is the
/// voltage part `en (kt/R) V duty`, held over the sample; the back-EMF `en kt²/R` is reported
/// through [`Controller::drive`] and applied continuously in q̇ by the simulator. All vectors in
/// model joint order.
#[derive(Clone, Debug)]
pub struct Servo {
    /// Duty per unit of position error [1/rad or 1/m].
    pub duty_gain: Vec<f64>,
    /// Largest duty magnitude.
    pub max_duty: Vec<f64>,
    /// Supply voltage [V] where the log has none.
    pub supply_voltage: f64,
    /// Torque constant [N·m/A].
    pub kt: Vec<f64>,
    /// Winding resistance [Ω].
    pub r: Vec<f64>,
    /// Largest goal rate (`None`: none).
    pub goal_rate_limit: Option<f64>,
    /// Logged sample times, supply voltage (one per sample) and torque enable (row-major, model
    /// order) held between samples; empty: none logged.
    log_t: Vec<f64>,
    log_voltage: Vec<f64>,
    log_enable: Vec<f64>,
    /// Time spans `[from, to)` [s] with every drive disabled (a drop with torque off).
    off: Vec<(f64, f64)>,
    cursor: usize,
    tol: f64,
    goal: Vec<f64>,
    last_t: Option<f64>,
    enabled: Vec<f64>,
    /// The duty applied over the last sample (0 where disabled) and the voltage it saw.
    duty: Vec<f64>,
    volts: f64,
}

impl Servo {
    /// A servo controller with constants in model order, without logged voltage or enable.
    ///
    /// # Errors
    /// [`Error::Invalid`] for vectors of different lengths or a supply voltage that is not a
    /// positive number.
    pub fn new(duty_gain: Vec<f64>, max_duty: Vec<f64>, supply_voltage: f64, kt: Vec<f64>, r: Vec<f64>, goal_rate_limit: Option<f64>) -> Result<Servo> {
        let n = duty_gain.len();
        if [max_duty.len(), kt.len(), r.len()].iter().any(|&m| m != n) {
            return Err(Error::Invalid {
                what: "servo".into(),
                message: format!("{n} duty gains, {} max duties, {} kt, {} R; expected one of each per joint", max_duty.len(), kt.len(), r.len()),
            });
        }
        if let Some(x) = kt.iter().chain(&r).find(|x| !(x.is_finite() && **x > 0.0)) {
            return Err(Error::Invalid { what: "servo".into(), message: format!("motor constant {x}; expected kt and R positive") });
        }
        Ok(Servo {
            duty_gain,
            max_duty,
            supply_voltage,
            kt,
            r,
            goal_rate_limit,
            log_t: Vec::new(),
            log_voltage: Vec::new(),
            log_enable: Vec::new(),
            off: Vec::new(),
            cursor: 0,
            tol: 0.0,
            goal: vec![0.0; n],
            last_t: None,
            enabled: vec![1.0; n],
            duty: vec![0.0; n],
            volts: supply_voltage,
        })
    }

    /// The same servo reading the supply voltage and torque enable a run logged (model order),
    /// held from each sample to the next.
    pub fn with_log(mut self, run: &Run, map: &[usize]) -> Servo {
        let (n, m) = (run.dof(), map.len());
        self.log_t = run.t.clone();
        self.log_voltage = if run.drive.voltage.len() == run.len() { run.drive.voltage.clone() } else { Vec::new() };
        self.log_enable = if run.drive.torque_enable.len() == run.len() * n {
            (0..run.len()).flat_map(|k| map.iter().map(move |&j| (k, j))).map(|(k, j)| run.drive.torque_enable[k * n + j]).collect()
        } else {
            Vec::new()
        };
        debug_assert!(self.log_enable.is_empty() || self.log_enable.len() == run.len() * m);
        self.tol = if run.len() > 1 { (0.5 * run.duration() / (run.len() - 1) as f64).max(1e-9) } else { 1e-9 };
        self
    }

    /// The same servo with every drive disabled over the time spans `[from, to)` [s] (a drop
    /// with torque off), besides any logged torque enable.
    pub fn with_torque_off(mut self, spans: Vec<(f64, f64)>) -> Servo {
        self.off = spans;
        self
    }

    /// The logged sample in force at `t` (the last at or before `t`, within jitter).
    fn logged_sample(&mut self, t: f64) -> usize {
        let tol = self.tol;
        if self.cursor >= self.log_t.len() || self.log_t[self.cursor] > t + tol {
            self.cursor = self.log_t.partition_point(|&tk| tk <= t + tol).saturating_sub(1);
        }
        while self.cursor + 1 < self.log_t.len() && self.log_t[self.cursor + 1] <= t + tol {
            self.cursor += 1;
        }
        self.cursor
    }
}

impl Controller for Servo {
    fn adds_feed_forward(&self) -> bool {
        false
    }

    fn torque(&mut self, t: f64, q: &[f64], _qd: &[f64], q_ref: &[f64], _qd_ref: &[f64], out: &mut [f64]) {
        let n = out.len();
        let k = if self.log_t.is_empty() { 0 } else { self.logged_sample(t) };
        let v = self.log_voltage.get(k).copied().unwrap_or(self.supply_voltage);
        // the goal, rate-limited from the last sample's (a restart in time starts it afresh)
        let dt = self.last_t.map(|t0| t - t0).filter(|d| *d > 0.0);
        for i in 0..n {
            self.goal[i] = match (self.goal_rate_limit, dt) {
                (Some(rate), Some(dt)) => self.goal[i] + (q_ref[i] - self.goal[i]).clamp(-rate * dt, rate * dt),
                _ => q_ref[i],
            };
            let off = self.off.iter().any(|&(from, to)| t >= from && t < to);
            self.enabled[i] = if off { 0.0 } else { self.log_enable.get(k * n + i).map_or(1.0, |e| if *e > 0.5 { 1.0 } else { 0.0 }) };
            let duty = (self.duty_gain[i] * (self.goal[i] - q[i])).clamp(-self.max_duty[i], self.max_duty[i]);
            self.duty[i] = self.enabled[i] * duty;
            out[i] = self.enabled[i] * self.kt[i] / self.r[i] * v * duty;
        }
        self.volts = v;
        self.last_t = Some(t);
    }

    fn drive_sample(&self) -> Option<crate::run::DriveSample<'_>> {
        Some(crate::run::DriveSample { duty: &self.duty, torque_enable: &self.enabled, voltage: self.volts })
    }

    fn drive(&self, enabled: &mut [f64], emf: &mut [f64]) {
        for i in 0..enabled.len() {
            enabled[i] = self.enabled[i];
            emf[i] = self.enabled[i] * self.kt[i] * self.kt[i] / self.r[i];
        }
    }

    fn experiment(&self, joints: &[String], sample_period: f64) -> Experiment {
        let mut e = Experiment { controller: ControllerKind::Servo, joints: joints.to_vec(), kp: Vec::new(), kv: Vec::new(), sample_period, extra: BTreeMap::new() };
        let params = ServoParams {
            duty_gain: self.duty_gain.clone(),
            max_duty: self.max_duty.clone(),
            supply_voltage: self.supply_voltage,
            kt: Some(self.kt.clone()),
            r: Some(self.r.clone()),
            goal_rate_limit: self.goal_rate_limit,
        };
        params.write_to(&mut e);
        e
    }
}

/// Positions of the model's joints among `names`.
///
/// # Errors
/// [`Error::JointMismatch`] naming the first model joint missing from `names`.
pub fn joint_map(model: &Model, names: &[String], source_name: &str) -> Result<Vec<usize>> {
    model
        .joint_names()
        .iter()
        .map(|j| {
            names.iter().position(|n| n == j).ok_or_else(|| Error::JointMismatch {
                source_name: source_name.into(),
                joint: (*j).to_string(),
                problem: "is in the model but not in the log".into(),
            })
        })
        .collect()
}

/// The controller of an experiment, with gains (and replayed efforts) mapped to the model's
/// joints by name. `PdGravity` compensates gravity with `model`. `log` is the logged run: the
/// efforts a replay applies, or the supply voltage and torque enable a servo reads (a servo
/// without it uses `supply_voltage` and stays enabled).
///
/// # Errors
/// [`Error::JointMismatch`] when a model joint has no gain (or no replayed effort);
/// [`Error::Invalid`] for gains of the wrong length, a replay without a run, or a servo
/// experiment without its keys (`duty_gain`, the motor constants `kt` and `R`, a supply
/// voltage or a logged one).
pub fn controller_from_experiment(exp: &Experiment, model: &Model, log: Option<&Run>) -> Result<Box<dyn Controller>> {
    let replay = log;
    match exp.controller {
        ControllerKind::Pd | ControllerKind::PdGravity => {
            if exp.kp.len() != exp.joints.len() || exp.kv.len() != exp.joints.len() {
                return Err(Error::Invalid {
                    what: "experiment gains".into(),
                    message: format!("{} joints, {} kp, {} kv; expected one gain of each per joint", exp.joints.len(), exp.kp.len(), exp.kv.len()),
                });
            }
            let map = joint_map(model, &exp.joints, "experiment")?;
            let kp = map.iter().map(|&i| exp.kp[i]).collect();
            let kv = map.iter().map(|&i| exp.kv[i]).collect();
            Ok(if exp.controller == ControllerKind::Pd { Box::new(Pd { kp, kv }) } else { Box::new(PdGravity::new(kp, kv, model.clone())) })
        }
        ControllerKind::Replay => {
            let run = replay.ok_or_else(|| Error::Invalid { what: "replay".into(), message: "a replay experiment needs the logged run".into() })?;
            let map = joint_map(model, &run.joints, &run.source)?;
            let (n, m) = (run.dof(), model.dof());
            let mut tau = vec![0.0; run.len() * m];
            for k in 0..run.len() {
                for (i, &j) in map.iter().enumerate() {
                    tau[k * m + i] = run.tau[k * n + j];
                }
            }
            Ok(Box::new(Replay::new(run.t.clone(), tau)?))
        }
        ControllerKind::Servo => {
            let invalid = |message: String| Error::Invalid { what: "servo experiment".into(), message };
            let p = ServoParams::from_experiment(exp).map_err(invalid)?;
            let (Some(kt), Some(r)) = (&p.kt, &p.r) else {
                return Err(invalid("no motor constants 'kt' and 'R'; expected both (priors from the datasheet, or the diagnosis's fitted values)".into()));
            };
            let logged_voltage = log.is_some_and(|run| run.drive.voltage.len() == run.len() && !run.is_empty());
            if !p.supply_voltage.is_finite() && !logged_voltage {
                return Err(invalid("no 'supply_voltage' and no logged voltage; expected one of them".into()));
            }
            let map = joint_map(model, &exp.joints, "experiment")?;
            let pick = |v: &[f64]| map.iter().map(|&i| v[i]).collect::<Vec<f64>>();
            let servo = Servo::new(pick(&p.duty_gain), pick(&p.max_duty), p.supply_voltage, pick(kt), pick(r), p.goal_rate_limit)?;
            Ok(Box::new(match log {
                Some(run) => {
                    let run_map = joint_map(model, &run.joints, &run.source)?;
                    servo.with_log(run, &run_map)
                }
                None => servo,
            }))
        }
    }
}
