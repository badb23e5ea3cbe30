//! Servo joints in the MJCF: the firmware's P loop and the motor law as a MuJoCo `<position>`
//! actuator.

use simgap_core::Model;
use simgap_sim::Run;

use super::ExportError;
use crate::ServoReport;

/// The position-controlled servos of a diagnosis of servo runs, as MuJoCo position actuators
/// (see [`export_mjcf`](super::export_mjcf)): per joint in model order, the motor constants the
/// corrected model simulates with, the voltage, and the firmware's gain and duty limit.
///
/// The servo law `τ = (kt/R)(V·clip(duty_gain·(goal − q), ±max_duty) − kt·q̇)` is written as
/// `kp = kt/R·V·duty_gain`, `kv = kt²/R` (the back-EMF) and `forcerange = ±kt/R·V·max_duty`,
/// with `ctrl` the goal position.
#[derive(Clone, Debug, PartialEq)]
pub struct ServoActuators {
    /// Joint names, model order.
    pub joints: Vec<String>,
    /// Torque constants [N·m/A or N/A]: the report's effective ones (selected torque gain and
    /// back-EMF folded in).
    pub kt: Vec<f64>,
    /// Winding resistances [Ω], effective likewise.
    pub r: Vec<f64>,
    /// The motor voltage [V] at full duty.
    pub voltage: f64,
    /// Where the voltage comes from (the experiment's `supply_voltage`, or the logs' mean).
    pub voltage_source: String,
    /// Duty per unit of position error [1/rad or 1/m].
    pub duty_gain: Vec<f64>,
    /// Largest duty magnitude.
    pub max_duty: Vec<f64>,
    /// Anything the user must know about these numbers (e.g. logs with other firmware gains).
    pub notes: Vec<String>,
}

impl ServoActuators {
    /// The servo actuators of a diagnosis whose report has the `servo` key `servo`, with the
    /// firmware settings of the first servo log among `runs` (`None` when none is a servo log).
    ///
    /// # Errors
    /// [`ExportError::Option`] for a servo log whose experiment cannot be read, or that has
    /// neither a `supply_voltage` nor a logged voltage.
    pub fn of(model: &Model, servo: &ServoReport, runs: &[Run]) -> Result<Option<ServoActuators>, ExportError> {
        let servo_runs: Vec<&Run> = runs.iter().filter(|r| crate::prepare::servo::is_servo(r)).collect();
        let Some(first) = servo_runs.first() else { return Ok(None) };
        let params = |r: &Run| crate::prepare::servo::params(model, r).map_err(|e| ExportError::Option(format!("servo actuators: {e}")));
        let p = params(first)?;
        let names = model.joint_names();
        let order: Vec<usize> = names
            .iter()
            .map(|j| servo.joints.iter().position(|s| s == j).ok_or_else(|| ExportError::Option(format!("servo actuators: the report's servo key has no joint '{j}'"))))
            .collect::<Result<_, _>>()?;
        let pick = |v: &[f64]| order.iter().map(|&i| v[i]).collect::<Vec<f64>>();
        let mut notes = Vec::new();
        let (voltage, voltage_source) = if p.supply_voltage.is_finite() {
            (p.supply_voltage, format!("supply_voltage of {}", first.source))
        } else {
            let logged: Vec<f64> = servo_runs.iter().flat_map(|r| r.drive.voltage.iter().copied()).filter(|v| v.is_finite()).collect();
            if logged.is_empty() {
                return Err(ExportError::Option(format!("servo actuators: {} has no supply_voltage and no servo log has a logged voltage", first.source)));
            }
            let mean = logged.iter().sum::<f64>() / logged.len() as f64;
            let (lo, hi) = logged.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(*v), b.max(*v)));
            notes.push(format!(
                "the servo's voltage V = {mean:.4} V is the mean of the logged voltage ({lo:.4}–{hi:.4} V); simgap simulated each sample with its own logged voltage, MuJoCo's kp and forcerange hold one V"
            ));
            (mean, "mean logged voltage".to_string())
        };
        let others: Vec<&str> =
            servo_runs[1..].iter().filter(|r| params(r).is_ok_and(|q| q.duty_gain != p.duty_gain || q.max_duty != p.max_duty)).map(|r| r.source.as_str()).collect();
        if !others.is_empty() {
            notes.push(format!(
                "kp and forcerange are for the firmware gain (duty_gain) and max_duty of {}; logs {others:?} set others: for them set kp = kt/R·V·duty_gain and forcerange = ±kt/R·V·max_duty (MuJoCo: actuator_gainprm[i][0] = kp, actuator_biasprm[i][1] = −kp, actuator_forcerange[i])",
                first.source
            ));
        }
        if p.goal_rate_limit.is_some() {
            notes.push("the firmware's goal rate limit (goal_rate_limit) is not in the MJCF: limit the rate of ctrl before mj_step".into());
        }
        Ok(Some(ServoActuators {
            joints: names.iter().map(|s| s.to_string()).collect(),
            kt: pick(&servo.effective.kt),
            r: pick(&servo.effective.r),
            voltage,
            voltage_source,
            duty_gain: p.duty_gain,
            max_duty: p.max_duty,
            notes,
        }))
    }

    /// The index of joint `name`, if it is a servo joint.
    pub(super) fn index(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j == name)
    }

    /// Position gain `kt/R·V·duty_gain` [N·m/rad or N/m] of servo joint `i`.
    pub fn kp(&self, i: usize) -> f64 {
        self.kt[i] / self.r[i] * self.voltage * self.duty_gain[i]
    }

    /// Back-EMF damping `kt²/R` [N·m·s/rad or N·s/m] of servo joint `i`.
    pub fn kv(&self, i: usize) -> f64 {
        self.kt[i] * self.kt[i] / self.r[i]
    }

    /// Largest force `kt/R·V·max_duty` [N·m or N] of servo joint `i` (the stall torque at full
    /// duty).
    pub fn force_limit(&self, i: usize) -> f64 {
        self.kt[i] / self.r[i] * self.voltage * self.max_duty[i]
    }
}
