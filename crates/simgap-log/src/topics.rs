//! Which topic of a bag holds what: the topic map.
//!
//! The roles, some with a default topic:
//!
//! | role | default topic | fills |
//! |---|---|---|
//! | `states` | `/joint_states` | `t`, `q`, `qd`, and `tau` from its effort |
//! | `reference` | `/joint_reference` | `q_ref`, `qd_ref`, `tau_ff` (feed-forward) from its effort |
//! | `effort` | none | `tau` (commanded effort), replacing the effort of `states` |
//! | `measured_effort` | `/joint_effort_measured` | `tau_measured` |
//! | `duty` | `/servo/duty` | a servo's measured PWM duty in [−1, 1] (`drive.duty`), held per message |
//! | `torque_enable` | `/servo/torque_enable` | a servo's torque enable, 0 or 1 (`drive.torque_enable`), held |
//! | `temperature` | `/servo/temperature` | a servo's temperature [°C] (`drive.temperature`), reported only |
//! | `voltage` | `/servo/voltage` | a servo's supply voltage [V] (`drive.voltage`, one value per sample), interpolated |
//!
//! A role whose topic the file does not have is not logged (the servo topics are where simgap
//! writes a servo run's signals; a bag without them is not a servo log unless mapped).
//!
//! The per-joint servo roles read a `sensor_msgs/msg/JointState`'s `effort` (or a
//! `Float64MultiArray`'s `data` with the joint names in brackets), one value per joint. The
//! voltage is one value for the whole robot: a `std_msgs/msg/Float64`'s `data`, or a message of
//! the other types with exactly one value (a one-element `Float64MultiArray`, a JointState with
//! one effort, whatever its name); it needs no joint names.
//!
//! Real bags name topics after the robot; a map such as
//! `states=/arm/joint_states,reference=/arm_controller/controller_state,effort=/effort_controller/commands[j1;j2]`
//! ([`TopicMap::parse`]) points each role at its topic. A message type without joint names
//! (`std_msgs/msg/Float64MultiArray`) gets them in brackets, `;`-separated, in the order of its
//! `data`.

use std::fmt;

/// Default topic of the measured joint states.
pub const JOINT_STATES_TOPIC: &str = "/joint_states";
/// Default topic of the joint reference.
pub const JOINT_REFERENCE_TOPIC: &str = "/joint_reference";
/// Default topic of the torque the drives report.
pub const JOINT_EFFORT_MEASURED_TOPIC: &str = "/joint_effort_measured";
/// Default topic of a servo's measured PWM duty (a `sensor_msgs/msg/JointState`'s effort).
pub const SERVO_DUTY_TOPIC: &str = "/servo/duty";
/// Default topic of a servo's torque enable, 0 or 1 (a JointState's effort).
pub const SERVO_TORQUE_ENABLE_TOPIC: &str = "/servo/torque_enable";
/// Default topic of a servo's temperature [°C] (a JointState's effort).
pub const SERVO_TEMPERATURE_TOPIC: &str = "/servo/temperature";
/// Default topic of a servo's supply voltage [V] (a JointState with one effort).
pub const SERVO_VOLTAGE_TOPIC: &str = "/servo/voltage";

/// The role a topic plays in a run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Role {
    /// Measured positions, velocities, and the commanded effort.
    States,
    /// Reference positions and velocities, and the feed-forward torque.
    Reference,
    /// Commanded effort (when not in the states).
    Effort,
    /// Torque the drives report.
    MeasuredEffort,
    /// A servo's measured PWM duty.
    Duty,
    /// A servo's torque enable.
    TorqueEnable,
    /// A servo's temperature.
    Temperature,
    /// A servo's supply voltage (one value per sample, not per joint).
    Voltage,
}

impl Role {
    /// Every role, in map order.
    pub const ALL: [Role; 8] = [Role::States, Role::Reference, Role::Effort, Role::MeasuredEffort, Role::Duty, Role::TorqueEnable, Role::Temperature, Role::Voltage];

    /// The role's key in a topic map: `states`, `reference`, `effort`, `measured_effort`, `duty`,
    /// `torque_enable`, `temperature`, `voltage`.
    pub fn key(self) -> &'static str {
        match self {
            Role::States => "states",
            Role::Reference => "reference",
            Role::Effort => "effort",
            Role::MeasuredEffort => "measured_effort",
            Role::Duty => "duty",
            Role::TorqueEnable => "torque_enable",
            Role::Temperature => "temperature",
            Role::Voltage => "voltage",
        }
    }
}

/// A topic and, for message types without joint names, the names of its values.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TopicSpec {
    /// The topic, e.g. `/arm/joint_states`.
    pub topic: String,
    /// Joint names of the values, in order, for messages without names (empty otherwise).
    pub joints: Vec<String>,
}

impl TopicSpec {
    /// A topic whose messages name their joints.
    pub fn new(topic: &str) -> TopicSpec {
        TopicSpec { topic: topic.to_string(), joints: Vec::new() }
    }

    /// A topic whose values belong to `joints`, in order.
    pub fn with_joints(topic: &str, joints: &[&str]) -> TopicSpec {
        TopicSpec { topic: topic.to_string(), joints: joints.iter().map(|s| s.to_string()).collect() }
    }

    /// Parses `/topic` or `/topic[j1;j2]`.
    ///
    /// # Errors
    /// A message for an empty topic, an unclosed bracket or an empty joint name.
    pub fn parse(s: &str) -> Result<TopicSpec, String> {
        let s = s.trim();
        let (topic, joints) = match s.split_once('[') {
            Some((t, rest)) => {
                let inner = rest.strip_suffix(']').ok_or_else(|| format!("'{s}': expected joint names in brackets, '/topic[j1;j2]'"))?;
                let joints: Vec<String> = inner.split(';').map(|j| j.trim().to_string()).collect();
                if joints.iter().any(String::is_empty) {
                    return Err(format!("'{s}': an empty joint name in the brackets"));
                }
                (t.trim(), joints)
            }
            None => (s, Vec::new()),
        };
        if topic.is_empty() {
            return Err(format!("'{s}': no topic"));
        }
        Ok(TopicSpec { topic: topic.to_string(), joints })
    }
}

impl fmt::Display for TopicSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.topic)?;
        if !self.joints.is_empty() {
            write!(f, "[{}]", self.joints.join(";"))?;
        }
        Ok(())
    }
}

/// Which topic plays which [`Role`] (see the [module docs](self)).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TopicMap {
    /// Measured states (default `/joint_states`).
    pub states: TopicSpec,
    /// Reference and feed-forward (default `/joint_reference`).
    pub reference: TopicSpec,
    /// Commanded effort, when not in the states (default none).
    pub effort: Option<TopicSpec>,
    /// Torque the drives report (default `/joint_effort_measured`).
    pub measured_effort: TopicSpec,
    /// A servo's measured duty (default [`SERVO_DUTY_TOPIC`]).
    pub duty: Option<TopicSpec>,
    /// A servo's torque enable (default [`SERVO_TORQUE_ENABLE_TOPIC`]).
    pub torque_enable: Option<TopicSpec>,
    /// A servo's temperature (default [`SERVO_TEMPERATURE_TOPIC`]).
    pub temperature: Option<TopicSpec>,
    /// A servo's supply voltage (default [`SERVO_VOLTAGE_TOPIC`]).
    pub voltage: Option<TopicSpec>,
}

impl Default for TopicMap {
    fn default() -> Self {
        TopicMap {
            states: TopicSpec::new(JOINT_STATES_TOPIC),
            reference: TopicSpec::new(JOINT_REFERENCE_TOPIC),
            effort: None,
            measured_effort: TopicSpec::new(JOINT_EFFORT_MEASURED_TOPIC),
            duty: Some(TopicSpec::new(SERVO_DUTY_TOPIC)),
            torque_enable: Some(TopicSpec::new(SERVO_TORQUE_ENABLE_TOPIC)),
            temperature: Some(TopicSpec::new(SERVO_TEMPERATURE_TOPIC)),
            voltage: Some(TopicSpec::new(SERVO_VOLTAGE_TOPIC)),
        }
    }
}

impl TopicMap {
    /// The defaults with some roles mapped: `states=/a,reference=/b,effort=/c[j1;j2],...`
    /// (the keys of [`Role::key`]; a role not given keeps its default).
    ///
    /// # Errors
    /// A message naming an unknown role, a role given twice, or a malformed topic.
    pub fn parse(s: &str) -> Result<TopicMap, String> {
        let mut map = TopicMap::default();
        let mut seen = Vec::new();
        for entry in split_outside_brackets(s) {
            let entry = entry.trim();
            if entry.is_empty() {
                continue;
            }
            let (key, value) = entry.split_once('=').ok_or_else(|| format!("'{entry}': expected role=topic"))?;
            let key = key.trim();
            if seen.contains(&key.to_string()) {
                return Err(format!("role '{key}' is given twice"));
            }
            seen.push(key.to_string());
            map.set(key, TopicSpec::parse(value)?)?;
        }
        Ok(map)
    }

    /// Points a role (by its [`Role::key`]) at a topic.
    ///
    /// # Errors
    /// A message for an unknown role.
    pub fn set(&mut self, role: &str, spec: TopicSpec) -> Result<(), String> {
        match role {
            "states" => self.states = spec,
            "reference" => self.reference = spec,
            "effort" => self.effort = Some(spec),
            "measured_effort" => self.measured_effort = spec,
            "duty" => self.duty = Some(spec),
            "torque_enable" => self.torque_enable = Some(spec),
            "temperature" => self.temperature = Some(spec),
            "voltage" => self.voltage = Some(spec),
            other => {
                return Err(format!("unknown role '{other}': expected states, reference, effort, measured_effort, duty, torque_enable, temperature or voltage"));
            }
        }
        Ok(())
    }

    /// The spec of a role, if the role is mapped.
    pub fn get(&self, role: Role) -> Option<&TopicSpec> {
        match role {
            Role::States => Some(&self.states),
            Role::Reference => Some(&self.reference),
            Role::Effort => self.effort.as_ref(),
            Role::MeasuredEffort => Some(&self.measured_effort),
            Role::Duty => self.duty.as_ref(),
            Role::TorqueEnable => self.torque_enable.as_ref(),
            Role::Temperature => self.temperature.as_ref(),
            Role::Voltage => self.voltage.as_ref(),
        }
    }

    /// The roles a topic plays (one topic may play several, e.g. a controller state that holds
    /// both the reference and the commanded effort).
    pub fn roles_of(&self, topic: &str) -> Vec<Role> {
        Role::ALL.into_iter().filter(|r| self.get(*r).is_some_and(|s| s.topic == topic)).collect()
    }
}

impl fmt::Display for TopicMap {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let parts: Vec<String> = Role::ALL.iter().filter_map(|r| self.get(*r).map(|s| format!("{}={s}", r.key()))).collect();
        f.write_str(&parts.join(","))
    }
}

/// Splits at commas that are not inside brackets.
fn split_outside_brackets(s: &str) -> Vec<&str> {
    let mut out = Vec::new();
    let mut depth = 0i32;
    let mut start = 0;
    for (i, c) in s.char_indices() {
        match c {
            '[' => depth += 1,
            ']' => depth -= 1,
            ',' if depth == 0 => {
                out.push(&s[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    out.push(&s[start..]);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn topic_map_parses_roles_and_bracketed_joint_names() {
        let m = TopicMap::parse("states=/arm/joint_states, effort=/effort_controller/commands[j1;j2],reference=/ctrl/state").unwrap();
        assert_eq!(m.states.topic, "/arm/joint_states");
        assert_eq!(m.reference.topic, "/ctrl/state");
        assert_eq!(m.effort.as_ref().unwrap().joints, vec!["j1".to_string(), "j2".to_string()]);
        assert_eq!(m.measured_effort.topic, JOINT_EFFORT_MEASURED_TOPIC);
        assert_eq!(TopicMap::parse(&m.to_string()).unwrap(), m);
        assert!(TopicMap::parse("state=/x").unwrap_err().contains("unknown role 'state'"));
        assert!(TopicMap::parse("states=/x,states=/y").unwrap_err().contains("twice"));
        assert!(TopicMap::parse("effort=/x[a;").is_err());
    }
}
