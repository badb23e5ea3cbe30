//! Servo joints in the MJCF: the firmware's P loop and the motor law as a MuJoCo `<position>`
//! actuator.

use simgap_core::Model;
use simgap_sim::Run;

use super::ExportError;
use crate::report::export_basis::ServoFirmware;
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
    /// firmware settings of the first servo log among `runs` ([`ServoFirmware::of`]; `None`
    /// when none is a servo log).
    ///
    /// # Errors
    /// [`ExportError::Option`] for a servo log whose experiment cannot be read, or that has
    /// neither a `supply_voltage` nor a logged voltage; as [`ServoActuators::with_firmware`].
    pub fn of<'a>(model: &Model, servo: &ServoReport, runs: impl IntoIterator<Item = &'a Run>) -> Result<Option<ServoActuators>, ExportError> {
        match ServoFirmware::of(model, runs).map_err(ExportError::Option)? {
            Some(firmware) => Self::with_firmware(model, servo, &firmware).map(Some),
            None => Ok(None),
        }
    }

    /// The servo actuators of a diagnosis whose report has the `servo` key `servo` (its
    /// effective constants, picked in model order), driven by `firmware`.
    ///
    /// # Errors
    /// [`ExportError::Option`] when the report's servo key lacks one of the model's joints.
    pub fn with_firmware(model: &Model, servo: &ServoReport, firmware: &ServoFirmware) -> Result<ServoActuators, ExportError> {
        // the report's constants in model order
        let names = model.joint_names();
        let order: Vec<usize> = names
            .iter()
            .map(|j| servo.joints.iter().position(|s| s == j).ok_or_else(|| ExportError::Option(format!("servo actuators: the report's servo key has no joint '{j}'"))))
            .collect::<Result<_, _>>()?;
        let pick = |v: &[f64]| order.iter().map(|&i| v[i]).collect::<Vec<f64>>();
        Ok(ServoActuators {
            joints: names.iter().map(|s| s.to_string()).collect(),
            kt: pick(&servo.effective.kt),
            r: pick(&servo.effective.r),
            voltage: firmware.voltage,
            voltage_source: firmware.voltage_source.clone(),
            duty_gain: firmware.duty_gain.clone(),
            max_duty: firmware.max_duty.clone(),
            notes: firmware.notes.clone(),
        })
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
