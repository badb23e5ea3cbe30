//! What an export takes from the logs rather than from the report: the time step, the passive
//! joints and a servo's firmware settings, decided once by the diagnosis
//! ([`Diagnosis::export`](crate::Diagnosis::export)) from the runs the prepare stage validated,
//! so that every front end writes the same files for one diagnosis.

use simgap_core::Model;
use simgap_sim::Run;

use crate::prepare::servo::{is_servo, params};

/// What the exported MJCF takes from the logs, decided once by the diagnosis from the runs the
/// prepare stage validated (the fit runs, then the held-out runs; model-aligned).
///
/// [`corrected_mjcf`](crate::export::corrected_mjcf) reads it with the report, so the CLI's
/// `--export-mjcf` and Python's `report.export_mjcf` write the same file.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportBasis {
    /// The MJCF's `<option timestep>` [s]: the runs' sample period ([`sample_period_of`]);
    /// `None` when no run states one or has two samples (the prepare stage refuses such runs).
    pub timestep: Option<f64>,
    /// The joints that get no motor ([`passive_joints`]): commanded torque zero on every sample
    /// of every run. Names in model order.
    pub passive: Vec<String>,
    /// The firmware settings of the servo runs ([`ServoFirmware::of`]): `None` without servo
    /// runs, an `Err` with what is missing (and in which log) when they cannot be read.
    pub servo: Option<Result<ServoFirmware, String>>,
}

impl ExportBasis {
    /// The export basis of `runs` (model-aligned, in the diagnosis' order: fit, then held out).
    pub(crate) fn of<'a>(model: &Model, runs: impl IntoIterator<Item = &'a Run, IntoIter: Clone>) -> ExportBasis {
        let runs = runs.into_iter();
        ExportBasis { timestep: sample_period_of(runs.clone()), passive: passive_joints(model, runs.clone()), servo: ServoFirmware::of(model, runs).transpose() }
    }
}

/// A position-controlled servo's firmware as its logs show it: the voltage at full duty, the
/// duty per unit of position error and the duty limit, per joint in model order.
#[derive(Clone, Debug, PartialEq)]
pub struct ServoFirmware {
    /// The motor voltage [V] at full duty.
    pub voltage: f64,
    /// Where the voltage comes from (the experiment's `supply_voltage`, or the logs' mean).
    pub voltage_source: String,
    /// Duty per unit of position error [1/rad or 1/m], model order.
    pub duty_gain: Vec<f64>,
    /// Largest duty magnitude, model order.
    pub max_duty: Vec<f64>,
    /// Anything the user must know about these numbers (e.g. logs with other firmware gains).
    pub notes: Vec<String>,
}

impl ServoFirmware {
    /// The firmware settings of the first servo log among `runs` (`None` when none is a servo
    /// log): its `duty_gain` and `max_duty`, and its `supply_voltage`, else the mean voltage
    /// logged by every servo log.
    ///
    /// # Errors
    /// What is missing, naming the log: a servo log whose experiment cannot be read, or that has
    /// neither a `supply_voltage` nor a logged voltage.
    pub fn of<'a>(model: &Model, runs: impl IntoIterator<Item = &'a Run>) -> Result<Option<ServoFirmware>, String> {
        let servo_runs: Vec<&Run> = runs.into_iter().filter(|r| is_servo(r)).collect();
        let Some(first) = servo_runs.first() else { return Ok(None) };
        let read = |r: &Run| params(model, r).map_err(|e| format!("servo actuators: {e}"));
        let p = read(first)?;
        // the voltage: the experiment's, else the mean of every servo log's
        let mut notes = Vec::new();
        let (voltage, voltage_source) = if p.supply_voltage.is_finite() {
            (p.supply_voltage, format!("supply_voltage of {}", first.source))
        } else {
            let logged: Vec<f64> = servo_runs.iter().flat_map(|r| r.drive.voltage.iter().copied()).filter(|v| v.is_finite()).collect();
            if logged.is_empty() {
                return Err(format!("servo actuators: {} has no supply_voltage and no servo log has a logged voltage", first.source));
            }
            let mean = logged.iter().sum::<f64>() / logged.len() as f64;
            let (lo, hi) = logged.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(*v), b.max(*v)));
            notes.push(format!(
                "the servo's voltage V = {mean:.4} V is the mean of the logged voltage ({lo:.4}–{hi:.4} V); simgap simulated each sample with its own logged voltage, MuJoCo's kp and forcerange hold one V"
            ));
            (mean, "mean logged voltage".to_string())
        };
        // logs with other firmware gains, and what MuJoCo cannot hold
        let others: Vec<&str> =
            servo_runs[1..].iter().filter(|r| read(r).is_ok_and(|q| q.duty_gain != p.duty_gain || q.max_duty != p.max_duty)).map(|r| r.source.as_str()).collect();
        if !others.is_empty() {
            notes.push(format!(
                "kp and forcerange are for the firmware gain (duty_gain) and max_duty of {}; logs {others:?} set others: for them set kp = kt/R·V·duty_gain and forcerange = ±kt/R·V·max_duty (MuJoCo: actuator_gainprm[i][0] = kp, actuator_biasprm[i][1] = −kp, actuator_forcerange[i])",
                first.source
            ));
        }
        if p.goal_rate_limit.is_some() {
            notes.push("the firmware's goal rate limit (goal_rate_limit) is not in the MJCF: limit the rate of ctrl before mj_step".into());
        }
        Ok(Some(ServoFirmware { voltage, voltage_source, duty_gain: p.duty_gain, max_duty: p.max_duty, notes }))
    }
}

/// The sample period of logs [s]: their experiment's `sample_period` where one states it,
/// else the median spacing of their stamps; `None` when no run has two samples.
pub fn sample_period_of<'a>(runs: impl IntoIterator<Item = &'a Run, IntoIter: Clone>) -> Option<f64> {
    let runs = runs.into_iter();
    // the first experiment that states a period
    if let Some(dt) = runs.clone().filter_map(|r| r.experiment.as_ref()).map(|e| e.sample_period).find(|dt| dt.is_finite() && *dt > 0.0) {
        return Some(dt);
    }
    // else the median stamp spacing of every run
    let mut steps: Vec<f64> = runs.flat_map(|r| r.t.windows(2).map(|w| w[1] - w[0])).filter(|d| d.is_finite() && *d > 0.0).collect();
    if steps.is_empty() {
        return None;
    }
    steps.sort_by(f64::total_cmp);
    Some(steps[steps.len() / 2])
}

/// The model's joints whose commanded torque is zero on every sample of every run (joints
/// matched by name; a run without the joint or without torques does not count as zero):
/// passive joints, which get no motor in the MJCF. Names in model order.
pub fn passive_joints<'a>(model: &Model, runs: impl IntoIterator<Item = &'a Run, IntoIter: Clone>) -> Vec<String> {
    let runs = runs.into_iter();
    if runs.clone().next().is_none() {
        return Vec::new();
    }
    model
        .joint_names()
        .into_iter()
        .filter(|name| {
            runs.clone().all(|r| match r.joints.iter().position(|j| j == name) {
                Some(j) if !r.tau.is_empty() && r.dof() > 0 => r.tau.iter().skip(j).step_by(r.dof()).all(|v| *v == 0.0),
                _ => false,
            })
        })
        .map(str::to_string)
        .collect()
}
