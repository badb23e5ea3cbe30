//! The experiment behind a run: its `simgap.experiment` metadata (controller kind, gains,
//! sample period) and, for a position-controlled servo, its constants. A leaf of the crate:
//! runs, controllers and log readers read it; it reads none of them.

use std::collections::BTreeMap;

/// Metadata key of the controller kind.
pub const KEY_CONTROLLER: &str = "controller";
/// Metadata key of the joint names giving the order of the gains.
pub const KEY_JOINTS: &str = "joints";
/// Metadata key of the proportional gains.
pub const KEY_KP: &str = "kp";
/// Metadata key of the derivative gains.
pub const KEY_KV: &str = "kv";
/// Metadata key of the controller sample period [s].
pub const KEY_SAMPLE_PERIOD: &str = "sample_period";

/// The controller of an experiment.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ControllerKind {
    /// τ = Kp (q_ref − q) + Kv (q̇_ref − q̇).
    Pd,
    /// The same plus the model's g(q).
    PdGravity,
    /// The logged effort applied open-loop.
    Replay,
    /// A position-controlled servo: the firmware's P loop drives a PWM duty
    /// (see [`crate::controller::Servo`]); the log holds no torque.
    Servo,
}

impl ControllerKind {
    /// Whether the drive's torque is held over each sample (zero-order hold of the command or of
    /// the logged effort): every controller but the servo, whose torque follows its back-EMF
    /// within the sample.
    pub fn holds_torque_over_sample(self) -> bool {
        self != ControllerKind::Servo
    }

    /// The metadata spelling: `pd`, `pd_gravity` or `replay`.
    pub fn as_str(self) -> &'static str {
        match self {
            ControllerKind::Pd => "pd",
            ControllerKind::PdGravity => "pd_gravity",
            ControllerKind::Replay => "replay",
            ControllerKind::Servo => "servo",
        }
    }
}

impl std::str::FromStr for ControllerKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "pd" => Ok(ControllerKind::Pd),
            "pd_gravity" => Ok(ControllerKind::PdGravity),
            "replay" => Ok(ControllerKind::Replay),
            "servo" => Ok(ControllerKind::Servo),
            other => Err(format!("unknown controller '{other}'; expected pd, pd_gravity, replay or servo")),
        }
    }
}

/// The `simgap.experiment` metadata of a log.
#[derive(Clone, Debug, PartialEq)]
pub struct Experiment {
    /// Controller kind.
    pub controller: ControllerKind,
    /// Joint names giving the order of `kp` and `kv`.
    pub joints: Vec<String>,
    /// Proportional gains [N·m/rad], aligned with `joints`.
    pub kp: Vec<f64>,
    /// Derivative gains [N·m·s/rad], aligned with `joints`.
    pub kv: Vec<f64>,
    /// Controller sample period [s].
    pub sample_period: f64,
    /// Any other metadata entries, kept as read.
    pub extra: BTreeMap<String, String>,
}

/// The `simgap.experiment` string map of an experiment. Numbers are written in
/// Rust's shortest round-trip form, so [`experiment_from_map`] gives back the same values.
/// Entries of `extra` with a reserved key are left out.
pub fn experiment_to_map(e: &Experiment) -> BTreeMap<String, String> {
    let join = |v: &[f64]| v.iter().map(|x| format!("{x}")).collect::<Vec<_>>().join(",");
    let mut map: BTreeMap<String, String> =
        e.extra.iter().filter(|(k, _)| ![KEY_CONTROLLER, KEY_JOINTS, KEY_KP, KEY_KV, KEY_SAMPLE_PERIOD].contains(&k.as_str())).map(|(k, v)| (k.clone(), v.clone())).collect();
    map.insert(KEY_CONTROLLER.into(), e.controller.as_str().into());
    map.insert(KEY_JOINTS.into(), e.joints.join(","));
    map.insert(KEY_KP.into(), join(&e.kp));
    map.insert(KEY_KV.into(), join(&e.kv));
    map.insert(KEY_SAMPLE_PERIOD.into(), format!("{}", e.sample_period));
    map
}

/// Parses a `simgap.experiment` string map. Unknown keys go to `extra`.
///
/// # Errors
/// A message saying which key is missing or malformed (the caller adds the file).
pub fn experiment_from_map(map: &BTreeMap<String, String>) -> std::result::Result<Experiment, String> {
    let get = |k: &str| map.get(k).ok_or_else(|| format!("key '{k}' is missing"));
    let numbers = |k: &str| -> std::result::Result<Vec<f64>, String> {
        let s = get(k)?;
        if s.trim().is_empty() {
            return Ok(Vec::new());
        }
        s.split(',').map(|x| x.trim().parse::<f64>().map_err(|_| format!("key '{k}': '{}' is not a number (in '{s}')", x.trim()))).collect()
    };
    let controller: ControllerKind = get(KEY_CONTROLLER)?.parse().map_err(|m| format!("key '{KEY_CONTROLLER}': {m}"))?;
    let joints_s = get(KEY_JOINTS)?;
    let joints: Vec<String> = if joints_s.trim().is_empty() { Vec::new() } else { joints_s.split(',').map(|s| s.trim().to_string()).collect() };
    // a replay or a servo has no PD gains; a sample period left out is the log's median
    // spacing (filled in by the reader, which knows the stamps)
    let gainless = matches!(controller, ControllerKind::Replay | ControllerKind::Servo);
    let kp = if gainless && !map.contains_key(KEY_KP) { Vec::new() } else { numbers(KEY_KP)? };
    let kv = if gainless && !map.contains_key(KEY_KV) { Vec::new() } else { numbers(KEY_KV)? };
    let sample_period = match map.get(KEY_SAMPLE_PERIOD) {
        Some(sp) => sp.trim().parse::<f64>().map_err(|_| format!("key '{KEY_SAMPLE_PERIOD}': '{sp}' is not a number"))?,
        None => f64::NAN,
    };
    let extra = map.iter().filter(|(k, _)| ![KEY_CONTROLLER, KEY_JOINTS, KEY_KP, KEY_KV, KEY_SAMPLE_PERIOD].contains(&k.as_str())).map(|(k, v)| (k.clone(), v.clone())).collect();
    let e = Experiment { controller, joints, kp, kv, sample_period, extra };
    check_experiment(&Experiment { sample_period: if sample_period.is_nan() { 1.0 } else { sample_period }, ..e.clone() })?;
    Ok(e)
}

/// Checks an experiment on its own: gains aligned with joints (none for a replay or a servo),
/// finite, positive sample period, a servo's keys (see [`ServoParams`]).
pub(crate) fn check_experiment(e: &Experiment) -> std::result::Result<(), String> {
    if e.joints.iter().any(|j| j.is_empty()) {
        return Err(format!("'{KEY_JOINTS}' has an empty joint name ('{}')", e.joints.join(",")));
    }
    if let Some(j) = e.joints.iter().find(|j| j.contains(',')) {
        return Err(format!("joint name '{j}' contains a comma"));
    }
    let gainless = matches!(e.controller, ControllerKind::Replay | ControllerKind::Servo);
    for (k, v) in [(KEY_KP, &e.kp), (KEY_KV, &e.kv)] {
        if v.len() != e.joints.len() && !(gainless && v.is_empty()) {
            return Err(format!("'{k}' has {} gains for {} joints ({})", v.len(), e.joints.len(), e.joints.join(",")));
        }
        if let Some(x) = v.iter().find(|x| !x.is_finite()) {
            return Err(format!("'{k}' has a gain {x}"));
        }
    }
    if !(e.sample_period.is_finite() && e.sample_period > 0.0) {
        return Err(format!("'{KEY_SAMPLE_PERIOD}' must be a positive number of seconds, got {}", e.sample_period));
    }
    if e.controller == ControllerKind::Servo {
        ServoParams::from_experiment(e)?;
    }
    Ok(())
}

/// Metadata keys of a servo experiment (see [`Servo`](crate::controller::Servo)).
pub mod servo_keys {
    /// Duty per radian of position error [1/rad], per joint.
    pub const DUTY_GAIN: &str = "duty_gain";
    /// Largest duty magnitude, per joint (default 1).
    pub const MAX_DUTY: &str = "max_duty";
    /// Supply voltage [V] where the log has none.
    pub const SUPPLY_VOLTAGE: &str = "supply_voltage";
    /// Motor torque constant through the gearbox [N·m/A], per joint.
    pub const KT: &str = "kt";
    /// Motor winding resistance [Ω], per joint.
    pub const R: &str = "R";
    /// Largest rate of the goal [rad/s or m/s] (absent: none).
    pub const GOAL_RATE_LIMIT: &str = "goal_rate_limit";
}

/// The constants of a position-controlled servo, per joint in the order of the experiment's
/// `joints` (see [`Servo`](crate::controller::Servo)).
#[derive(Clone, Debug, PartialEq)]
pub struct ServoParams {
    /// Duty per unit of position error [1/rad or 1/m].
    pub duty_gain: Vec<f64>,
    /// Largest duty magnitude in (0, 1].
    pub max_duty: Vec<f64>,
    /// Supply voltage [V] used where the log has none.
    pub supply_voltage: f64,
    /// Torque constant [N·m/A or N/A] (`None`: not given).
    pub kt: Option<Vec<f64>>,
    /// Winding resistance [Ω] (`None`: not given).
    pub r: Option<Vec<f64>>,
    /// Largest goal rate [rad/s or m/s] (`None`: none).
    pub goal_rate_limit: Option<f64>,
}

impl ServoParams {
    /// The servo constants of a `servo` experiment's metadata.
    ///
    /// # Errors
    /// A message naming the missing or malformed key (the caller adds the file).
    pub fn from_experiment(exp: &Experiment) -> std::result::Result<ServoParams, String> {
        use servo_keys::*;
        let n = exp.joints.len();
        let numbers = |k: &str| -> std::result::Result<Option<Vec<f64>>, String> {
            let Some(s) = exp.extra.get(k) else { return Ok(None) };
            let v: Vec<f64> = s
                .split(',')
                .map(|x| x.trim().parse::<f64>().map_err(|_| format!("key '{k}': '{}' is not a number (in '{s}')", x.trim())))
                .collect::<std::result::Result<_, _>>()?;
            match v.len() {
                1 => Ok(Some(vec![v[0]; n])),
                m if m == n => Ok(Some(v)),
                m => Err(format!("key '{k}' has {m} values for {n} joints ({}); expected one per joint or one for all", exp.joints.join(","))),
            }
        };
        let positive = |k: &str, v: &[f64], upper: f64| -> std::result::Result<(), String> {
            match v.iter().find(|x| !(x.is_finite() && **x > 0.0 && **x <= upper)) {
                Some(x) if upper.is_finite() => Err(format!("key '{k}' has {x}; expected a number in (0, {upper}]")),
                Some(x) => Err(format!("key '{k}' has {x}; expected a positive number")),
                None => Ok(()),
            }
        };
        let duty_gain = numbers(DUTY_GAIN)?.ok_or_else(|| format!("a servo experiment needs '{DUTY_GAIN}' (duty per radian of position error, one per joint)"))?;
        positive(DUTY_GAIN, &duty_gain, f64::INFINITY)?;
        let max_duty = numbers(MAX_DUTY)?.unwrap_or_else(|| vec![1.0; n]);
        positive(MAX_DUTY, &max_duty, 1.0)?;
        let supply_voltage = match exp.extra.get(SUPPLY_VOLTAGE) {
            Some(s) => s.trim().parse::<f64>().map_err(|_| format!("key '{SUPPLY_VOLTAGE}': '{s}' is not a number of volts"))?,
            None => f64::NAN,
        };
        if exp.extra.contains_key(SUPPLY_VOLTAGE) {
            positive(SUPPLY_VOLTAGE, &[supply_voltage], f64::INFINITY)?;
        }
        let kt = numbers(KT)?;
        let r = numbers(R)?;
        if kt.is_some() != r.is_some() {
            return Err(format!("key '{}' is given without '{}'; expected both motor constants or neither", if kt.is_some() { KT } else { R }, if kt.is_some() { R } else { KT }));
        }
        for (k, v) in [(KT, &kt), (R, &r)] {
            if let Some(v) = v {
                positive(k, v, f64::INFINITY)?;
            }
        }
        let goal_rate_limit = match exp.extra.get(GOAL_RATE_LIMIT) {
            Some(s) => {
                let x = s.trim().parse::<f64>().map_err(|_| format!("key '{GOAL_RATE_LIMIT}': '{s}' is not a number"))?;
                positive(GOAL_RATE_LIMIT, &[x], f64::INFINITY)?;
                Some(x)
            }
            None => None,
        };
        Ok(ServoParams { duty_gain, max_duty, supply_voltage, kt, r, goal_rate_limit })
    }

    /// Writes the constants into an experiment's metadata (`kt`, `R` only when known).
    pub fn write_to(&self, exp: &mut Experiment) {
        use servo_keys::*;
        let join = |v: &[f64]| v.iter().map(|x| format!("{x}")).collect::<Vec<_>>().join(",");
        exp.extra.insert(DUTY_GAIN.into(), join(&self.duty_gain));
        exp.extra.insert(MAX_DUTY.into(), join(&self.max_duty));
        if self.supply_voltage.is_finite() {
            exp.extra.insert(SUPPLY_VOLTAGE.into(), format!("{}", self.supply_voltage));
        }
        if let (Some(kt), Some(r)) = (&self.kt, &self.r) {
            exp.extra.insert(KT.into(), join(kt));
            exp.extra.insert(R.into(), join(r));
        }
        if let Some(g) = self.goal_rate_limit {
            exp.extra.insert(GOAL_RATE_LIMIT.into(), format!("{g}"));
        }
    }
}
