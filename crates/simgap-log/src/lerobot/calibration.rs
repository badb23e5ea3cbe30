//! LeRobot's calibration file, and the angle of a range-normalised joint.
//!
//! LeRobot keeps one JSON file per robot (`~/.cache/huggingface/lerobot/calibration/robots/
//! <type>/<id>.json`): for each motor `{"id", "drive_mode", "homing_offset", "range_min",
//! "range_max"}`, the last two in encoder counts (4096 per turn on the Feetech STS3215 and the
//! Dynamixel XL330/XL430). Its motor bus writes a position in one of three modes
//! (`lerobot/motors/motors_bus.py`, `MotorsBus._normalize`), with `min`, `max` the calibrated
//! range, `mid = (min + max) / 2` and the raw count clamped into `[min, max]`:
//!
//! - `DEGREES`: `(raw − mid) · 360 / 4095`;
//! - `RANGE_0_100` (the gripper): `100 (raw − min) / (max − min)`, mirrored to `100 − ·` when
//!   `drive_mode` is 1;
//! - `RANGE_M100_100` (arm joints recorded with `use_degrees=False`):
//!   `200 (raw − min) / (max − min) − 100`, negated when `drive_mode` is 1.
//!
//! [`Calibration::angle_deg`] inverts a range mode back to the raw count and applies the
//! `DEGREES` formula to it, so a calibrated range-normalised joint gets the angle LeRobot would
//! have written had the motor been in `DEGREES` mode: 0 at the middle of its calibrated range,
//! the zero every other joint of the dataset has (and SO-ARM100's `new_calib` URDFs).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde_json::Value;

/// Counts per degree's denominator in LeRobot's `DEGREES` mode: the resolution less one
/// (`model_resolution_table[model] − 1` = 4095 for 4096 counts per turn).
pub const MAX_RESOLUTION: f64 = 4095.0;

/// The largest calibration file read [bytes].
const MAX_BYTES: u64 = 1 << 20;

/// How a joint's `.pos` values are normalised by LeRobot's motor bus.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NormMode {
    /// Degrees from the middle of the calibrated range (an angle).
    Degrees,
    /// 0–100 across the calibrated range (LeRobot's grippers).
    Range0To100,
    /// −100…100 across the calibrated range (arm joints written with `use_degrees=False`).
    RangeM100To100,
}

impl NormMode {
    /// The interval a range-normalised value lies in (LeRobot clamps into it).
    pub fn interval(self) -> Option<(f64, f64)> {
        match self {
            NormMode::Degrees => None,
            NormMode::Range0To100 => Some((0.0, 100.0)),
            NormMode::RangeM100To100 => Some((-100.0, 100.0)),
        }
    }

    /// How the mode is written in messages.
    pub fn describe(self) -> &'static str {
        match self {
            NormMode::Degrees => "degrees",
            NormMode::Range0To100 => "range-normalised 0–100",
            NormMode::RangeM100To100 => "range-normalised −100…100",
        }
    }
}

/// One motor's calibration.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MotorCalibration {
    /// The motor's bus id.
    pub id: i64,
    /// 1 when the motor's direction is mirrored.
    pub drive_mode: i64,
    /// The homing offset written to the motor [counts] (already applied to its readings).
    pub homing_offset: i64,
    /// Lower end of the calibrated range [counts].
    pub range_min: i64,
    /// Upper end of the calibrated range [counts].
    pub range_max: i64,
}

/// A LeRobot calibration file: the calibration of each motor, by motor (joint) name.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Calibration {
    /// The file it was read from (for messages).
    pub path: PathBuf,
    /// Motor name → calibration.
    pub motors: BTreeMap<String, MotorCalibration>,
}

impl Calibration {
    /// Reads a calibration file: a JSON object of motor name → `{"id", "drive_mode",
    /// "homing_offset", "range_min", "range_max"}` (integers).
    ///
    /// # Errors
    /// [`Error::Read`](crate::Error::Read) naming the file and the motor: unreadable, not JSON,
    /// a missing or non-integer key, `drive_mode` other than 0 or 1, `range_min ≥ range_max`.
    pub fn read(path: &Path) -> crate::Result<Calibration> {
        let err = |m: String| crate::error::read_error(path, m);
        let len = std::fs::metadata(path).map_err(|e| err(format!("cannot read the calibration file: {e}")))?.len();
        if len > MAX_BYTES {
            return Err(err(format!("{len} bytes; a LeRobot calibration file is a few hundred")));
        }
        let text = std::fs::read_to_string(path).map_err(|e| err(format!("cannot read the calibration file: {e}")))?;
        Calibration::parse(&text, path).map_err(err)
    }

    /// Parses the text of a calibration file (see [`Calibration::read`]); `path` is kept for
    /// messages.
    ///
    /// # Errors
    /// A message naming the motor and the key.
    pub fn parse(text: &str, path: &Path) -> Result<Calibration, String> {
        let value: Value = serde_json::from_str(text).map_err(|e| format!("not valid JSON: {e}"))?;
        let obj = value.as_object().ok_or("expected a JSON object of motor name → {id, drive_mode, homing_offset, range_min, range_max}")?;
        let mut motors = BTreeMap::new();
        for (name, m) in obj {
            let int = |key: &str| -> Result<i64, String> {
                let v = m.get(key).ok_or_else(|| format!("motor '{name}': key '{key}' is missing"))?;
                v.as_i64().filter(|x| x.abs() < 1 << 31).ok_or_else(|| format!("motor '{name}': {key} is {v}; expected an integer"))
            };
            let c = MotorCalibration {
                id: int("id")?,
                drive_mode: int("drive_mode")?,
                homing_offset: int("homing_offset")?,
                range_min: int("range_min")?,
                range_max: int("range_max")?,
            };
            if !matches!(c.drive_mode, 0 | 1) {
                return Err(format!("motor '{name}': drive_mode is {}; expected 0 or 1", c.drive_mode));
            }
            if c.range_min >= c.range_max {
                return Err(format!("motor '{name}': range_min {} is not below range_max {}", c.range_min, c.range_max));
            }
            motors.insert(name.clone(), c);
        }
        Ok(Calibration { path: path.to_path_buf(), motors })
    }

    /// The angle [degrees, 0 at the middle of the calibrated range] of `value` written by
    /// LeRobot in `mode` for `motor` (see the [module docs](self)); `None` when the file has
    /// no such motor.
    pub fn angle_deg(&self, motor: &str, mode: NormMode, value: f64) -> Option<f64> {
        let c = self.motors.get(motor)?;
        Some(angle_deg(c, mode, value))
    }
}

/// The angle [degrees] of a normalised `value` of a motor calibrated as `c` (module docs).
pub fn angle_deg(c: &MotorCalibration, mode: NormMode, value: f64) -> f64 {
    let (min, max) = (c.range_min as f64, c.range_max as f64);
    let mirrored = c.drive_mode == 1;
    let raw = match mode {
        NormMode::Degrees => return value,
        NormMode::Range0To100 => {
            let v = if mirrored { 100.0 - value } else { value };
            min + v / 100.0 * (max - min)
        }
        NormMode::RangeM100To100 => {
            let v = if mirrored { -value } else { value };
            min + (v + 100.0) / 200.0 * (max - min)
        }
    };
    (raw - (min + max) / 2.0) * 360.0 / MAX_RESOLUTION
}

#[cfg(test)]
mod tests {
    use super::*;

    fn motor(drive_mode: i64) -> MotorCalibration {
        MotorCalibration { id: 6, drive_mode, homing_offset: 1000, range_min: 2000, range_max: 3000 }
    }

    #[test]
    fn range_modes_invert_lerobots_normalisation_to_its_degrees() {
        // LeRobot: raw 2500 is the middle (0°), raw 3000 is 100 in 0–100 and 100 in −100…100
        let half_span_deg = 500.0 * 360.0 / 4095.0;
        for (mode, value, expected) in [
            (NormMode::Range0To100, 50.0, 0.0),
            (NormMode::Range0To100, 100.0, half_span_deg),
            (NormMode::Range0To100, 0.0, -half_span_deg),
            (NormMode::RangeM100To100, 0.0, 0.0),
            (NormMode::RangeM100To100, 100.0, half_span_deg),
            (NormMode::Degrees, 12.5, 12.5),
        ] {
            assert!((angle_deg(&motor(0), mode, value) - expected).abs() < 1e-12, "{mode:?} {value}");
        }
        // a mirrored motor: LeRobot wrote 100 − v (0–100) and −v (−100…100)
        assert!((angle_deg(&motor(1), NormMode::Range0To100, 0.0) - half_span_deg).abs() < 1e-12);
        assert!((angle_deg(&motor(1), NormMode::RangeM100To100, 100.0) + half_span_deg).abs() < 1e-12);
    }

    #[test]
    fn a_calibration_file_names_the_motor_at_fault() {
        let ok = r#"{"gripper": {"id": 6, "drive_mode": 0, "homing_offset": 1047, "range_min": 2030, "range_max": 3400}}"#;
        let c = Calibration::parse(ok, Path::new("so101.json")).unwrap();
        assert_eq!(c.motors["gripper"].range_max, 3400);
        for (text, what) in [
            (r#"{"gripper": {"id": 6, "drive_mode": 0, "homing_offset": 1, "range_min": 3400, "range_max": 2030}}"#, "range_min"),
            (r#"{"gripper": {"id": 6, "drive_mode": 2, "homing_offset": 1, "range_min": 1, "range_max": 2}}"#, "drive_mode"),
            (r#"{"gripper": {"id": 6, "drive_mode": 0, "range_min": 1, "range_max": 2}}"#, "homing_offset"),
            (r#"{"gripper": {"id": 6.5, "drive_mode": 0, "homing_offset": 1, "range_min": 1, "range_max": 2}}"#, "id"),
            ("[1, 2]", "JSON object"),
        ] {
            let e = Calibration::parse(text, Path::new("x.json")).unwrap_err();
            assert!(e.contains(what), "{e}");
        }
    }
}
