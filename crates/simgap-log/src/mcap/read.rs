//! Reading ROS 2 MCAP files and rosbag2 bag folders into a run.
//!
//! Each channel whose topic plays a role of the [`TopicMap`] is decoded with the `ros2msg`
//! schema stored in the file ([`Schema`]), and its fields are found by name:
//!
//! - joint names: `name` (`sensor_msgs/msg/JointState`) or `joint_names`
//!   (`control_msgs/msg/JointTrajectoryControllerState`), else the names given in the map
//!   (`std_msgs/msg/Float64MultiArray`);
//! - stamp: `header.stamp` when the type has a header and any message of the topic a non-zero
//!   stamp, else the MCAP log time;
//! - values: `position`/`positions`, `velocity`/`velocities`, `effort` of the message, or of its
//!   trajectory point for controller states (`feedback` or `actual` for the states and the
//!   measured effort, `reference` or `desired` for the reference, `output` for the commanded
//!   effort; the states take their effort from `output`), or `data` for arrays;
//! - the supply voltage (role `voltage`): one value per message, a `std_msgs/msg/Float64`'s
//!   `data`, or the single value of an array message (no joint names needed).
//!
//! Assembling the run: the states give the times (`start_ns` = the first, `t` = time since it);
//! the reference, feed-forward and measured torque are interpolated linearly onto the state
//! times when logged at others; a separate commanded effort is held from one command to the
//! next (zero-order hold); a servo's duty and torque enable are held, its temperature and supply
//! voltage interpolated. No velocities in the states: q̇ by central difference of q (see
//! `run.source`).

use std::collections::{BTreeMap, HashMap};
use std::io::Read;
use std::path::Path;
use std::sync::Arc;

use simgap_sim::{central_difference, experiment_from_map, hold_rows, interpolate_rows, Experiment, Run};

use super::merge::{Extracted, Merged, TopicData};
use super::scan::{scan, Location, Record, ScanEnd};
use super::schema::{Arity, ElemType, Primitive, Schema, Value};
use super::{CDR_ENCODING, EXPERIMENT_METADATA, FLOAT64_MULTI_ARRAY_DEFINITION, JOINT_STATE_DEFINITION, ROS2MSG_ENCODING, RUN_END_METADATA};
use crate::error::{check_run, read_error, Result};
use crate::topics::{Role, TopicMap};
use crate::LogRead;

/// One input of a read: a name for messages, the bytes, and their length.
pub(crate) struct Source<'a> {
    /// File name for messages.
    pub name: String,
    /// The bytes.
    pub input: Box<dyn Read + 'a>,
    /// Their length.
    pub len: u64,
}

/// How a role's values are found in a message type.
#[derive(Clone)]
struct Extractor {
    names: Option<Vec<usize>>,
    fixed_names: Vec<String>,
    stamp: Option<Vec<usize>>,
    columns: [Option<Vec<usize>>; 3],
    /// One value per message for the whole robot (the supply voltage), not one per joint.
    one_value: bool,
}

/// A channel that plays one or more roles.
struct ChannelPlan {
    topic: String,
    schema: Arc<Schema>,
    roles: Vec<(Role, Extractor)>,
}

/// Column names of each role in messages (plural, singular).
fn columns_of(role: Role) -> [(&'static str, &'static str); 3] {
    match role {
        Role::States | Role::Reference => [("positions", "position"), ("velocities", "velocity"), ("efforts", "effort")],
        Role::Effort | Role::MeasuredEffort | Role::Duty | Role::TorqueEnable | Role::Temperature | Role::Voltage => [("efforts", "effort"), ("-", "-"), ("-", "-")],
    }
}

/// A float array field at `path`, if there is one.
fn float_array(schema: &Schema, path: &str) -> Option<Vec<usize>> {
    let (p, f) = schema.path(path)?;
    match (f.elem, f.arity) {
        (ElemType::Primitive(Primitive::F64 | Primitive::F32), Arity::Sequence | Arity::Fixed(_)) => Some(p),
        _ => None,
    }
}

/// The first of `candidates` that is a float array, with `prefix.` before it.
fn first_array(schema: &Schema, prefix: Option<&str>, candidates: &[&str]) -> Option<Vec<usize>> {
    candidates.iter().find_map(|c| float_array(schema, &prefix.map_or_else(|| c.to_string(), |p| format!("{p}.{c}"))))
}

/// Works out where a role's values are in a schema.
fn plan_role(schema: &Schema, role: Role, topic: &str, fixed_names: &[String]) -> std::result::Result<Extractor, String> {
    let ty = schema.name().to_string();
    if role == Role::Voltage {
        // one value for the whole robot: a scalar `data` (std_msgs/msg/Float64), else the one
        // value of an array (effort of a JointState, data of a Float64MultiArray)
        let scalar = schema.path("data").and_then(|(p, f)| (matches!(f.elem, ElemType::Primitive(Primitive::F64 | Primitive::F32)) && f.arity == Arity::Single).then_some(p));
        let column = scalar.or_else(|| first_array(schema, None, &["effort", "efforts"])).or_else(|| float_array(schema, "data"));
        if column.is_none() {
            return Err(format!("cannot map {ty} on {topic} as voltage: it has no float field data (std_msgs/msg/Float64), effort or data array"));
        }
        let stamp = schema.message_at("header.stamp").and_then(|_| schema.path("header.stamp").map(|(p, _)| p));
        return Ok(Extractor { names: None, fixed_names: vec!["voltage".to_string()], stamp, columns: [column, None, None], one_value: true });
    }
    // joint names
    let names = ["name", "joint_names"].iter().find_map(|n| {
        let (p, f) = schema.path(n)?;
        (f.elem == ElemType::Primitive(Primitive::String) && f.arity != Arity::Single).then_some(p)
    });
    if names.is_none() && fixed_names.is_empty() {
        return Err(format!("{topic} ({ty}) has no joint names: give them in the topic map, e.g. {}={topic}[joint1;joint2]", role.key()));
    }
    // stamp
    let stamp = schema.message_at("header.stamp").and_then(|_| schema.path("header.stamp").map(|(p, _)| p));
    // a trajectory point inside a controller state, by role
    let point = |candidates: &[&'static str]| -> Option<&'static str> {
        candidates.iter().copied().find(|c| schema.message_at(c).is_some_and(|d| d.fields.iter().any(|f| f.name == "positions" || f.name == "effort")))
    };
    let data = float_array(schema, "data");
    let (position, velocity, effort) = (["position", "positions"], ["velocity", "velocities"], ["effort", "efforts"]);
    let columns: [Option<Vec<usize>>; 3] = match role {
        Role::States | Role::Reference => {
            let base = if role == Role::States { point(&["feedback", "actual"]) } else { point(&["reference", "desired"]) };
            let q = first_array(schema, base, &position).or_else(|| data.clone());
            let effort_base = if role == Role::States && base.is_some() { point(&["output"]) } else { base };
            [q, first_array(schema, base, &velocity), first_array(schema, effort_base, &effort)]
        }
        Role::Effort => {
            let base = point(&["output"]);
            [first_array(schema, base, &effort).or_else(|| data.clone()), None, None]
        }
        Role::MeasuredEffort => {
            let base = point(&["feedback", "actual"]);
            [first_array(schema, base, &effort).or_else(|| data.clone()), None, None]
        }
        // a servo's signals: one value per joint in a JointState's effort or an array's data
        Role::Duty | Role::TorqueEnable | Role::Temperature => [first_array(schema, None, &effort).or_else(|| data.clone()), None, None],
        Role::Voltage => unreachable!("planned above"),
    };
    if columns[0].is_none() {
        let want = if matches!(role, Role::States | Role::Reference) { "positions" } else { "efforts" };
        return Err(format!("cannot map {ty} on {topic} as {}: it has no {want} (no field position, positions, effort or data)", role.key()));
    }
    Ok(Extractor { names, fixed_names: fixed_names.to_vec(), stamp, columns, one_value: false })
}

impl Extractor {
    fn extract(&self, v: &Value, topic: &str) -> std::result::Result<Extracted, String> {
        let names = match &self.names {
            Some(p) => match v.at(p) {
                Some(Value::List(items)) => items.iter().map(|s| if let Value::Str(s) = s { s.clone() } else { String::new() }).collect(),
                _ => Vec::new(),
            },
            None => self.fixed_names.clone(),
        };
        let stamp = self.stamp.as_ref().and_then(|p| match v.at(p) {
            Some(Value::Message(f)) => match (f.first(), f.get(1)) {
                (Some(Value::Int(sec)), Some(Value::UInt(nsec))) => Some(sec.saturating_mul(1_000_000_000).saturating_add(i64::try_from(*nsec).unwrap_or(i64::MAX))),
                _ => None,
            },
            _ => None,
        });
        let column = |c: &Option<Vec<usize>>| -> Vec<f64> {
            match c.as_ref().and_then(|p| v.at(p)) {
                Some(Value::Floats(x)) => x.clone(),
                Some(Value::Float(x)) => vec![*x],
                _ => Vec::new(),
            }
        };
        if self.one_value {
            let values = column(&self.columns[0]);
            if values.len() != 1 {
                return Err(format!("{topic}: a voltage message holds one value (the supply voltage [V]), this one {}", values.len()));
            }
            return Ok(Extracted { stamp, names: self.fixed_names.clone(), values: [values, Vec::new(), Vec::new()] });
        }
        Ok(Extracted { stamp, names, values: [column(&self.columns[0]), column(&self.columns[1]), column(&self.columns[2])] })
    }
}

/// Per-file state of the scan: schemas and channels are numbered per file.
#[derive(Default)]
struct FileState {
    schemas: HashMap<u16, (String, String, Arc<[u8]>)>,
    channels: HashMap<u16, Option<Arc<ChannelPlan>>>,
}

/// Reads the sources (one MCAP file, or the files of a bag folder in order) into a run.
pub(crate) fn read_sources(label: &Path, sources: Vec<Source<'_>>, topics: &TopicMap, fallback: Option<&Experiment>) -> Result<LogRead> {
    let err = |m: String| read_error(label, m);
    let multi = sources.len() > 1;
    let mut data: BTreeMap<Role, TopicData> = BTreeMap::new();
    let mut experiment: Option<BTreeMap<String, String>> = None;
    let mut run_end: Option<BTreeMap<String, String>> = None;
    let mut other_topics: Vec<(String, Location)> = Vec::new();
    let mut experiment_at: Option<Location> = None;
    let mut schema_cache: HashMap<(String, Arc<[u8]>), Arc<Schema>> = HashMap::new();
    let mut warnings = Vec::new();
    let mut n_messages = 0usize;
    for (file_index, source) in sources.into_iter().enumerate() {
        let mut state = FileState::default();
        let where_ = |m: String| if multi { format!("{}: {m}", source.name) } else { m };
        let end: ScanEnd = scan(source.input, source.len, |record, at| {
            match record {
                Record::Schema { id, name, encoding, data } => {
                    state.schemas.insert(id, (name, encoding, Arc::from(data)));
                }
                Record::Channel { id, schema_id, topic, message_encoding } => {
                    let roles = topics.roles_of(&topic);
                    if roles.is_empty() {
                        if !other_topics.iter().any(|(t, _)| *t == topic) {
                            other_topics.push((topic, at));
                        }
                        state.channels.insert(id, None);
                        return Ok(());
                    }
                    let (sname, sencoding, sdata) = state.schemas.get(&schema_id).cloned().unwrap_or_else(|| (String::new(), String::new(), Arc::from(&[][..])));
                    if message_encoding != CDR_ENCODING || (sencoding != ROS2MSG_ENCODING && !sdata.is_empty()) || sname.is_empty() {
                        return Err(format!(
                            "wrong schema on {topic}: found schema '{sname}' (encoding '{sencoding}') with message encoding '{message_encoding}', expected a ROS 2 message ({ROS2MSG_ENCODING}) in '{CDR_ENCODING}'"
                        ));
                    }
                    // definitions missing from old recorders: the known ones
                    let text: Arc<[u8]> = if sdata.is_empty() {
                        match super::normalised_type(&sname).as_str() {
                            "sensor_msgs/JointState" => Arc::from(JOINT_STATE_DEFINITION.as_bytes()),
                            "std_msgs/Float64MultiArray" => Arc::from(FLOAT64_MULTI_ARRAY_DEFINITION.as_bytes()),
                            _ => return Err(format!("{topic}: schema '{sname}' has no definition in the file")),
                        }
                    } else {
                        sdata
                    };
                    let schema = match schema_cache.get(&(sname.clone(), text.clone())) {
                        Some(s) => s.clone(),
                        None => {
                            let s = std::str::from_utf8(&text).map_err(|_| format!("{topic}: the definition of '{sname}' is not UTF-8"))?;
                            let s = Arc::new(Schema::parse(&sname, s).map_err(|e| format!("{topic}: {e}"))?);
                            schema_cache.insert((sname.clone(), text.clone()), s.clone());
                            s
                        }
                    };
                    if let Some(w) = schema_name_mismatch(&schema, &sname, &topic) {
                        if !warnings.contains(&w) {
                            warnings.push(w);
                        }
                    }
                    let mut planned = Vec::new();
                    for role in roles {
                        let spec = topics.get(role).expect("role of this topic");
                        planned.push((role, plan_role(&schema, role, &topic, &spec.joints)?));
                    }
                    state.channels.insert(id, Some(Arc::new(ChannelPlan { topic, schema, roles: planned })));
                }
                Record::Message { channel_id, log_time, data: payload } => {
                    n_messages += 1;
                    let Some(Some(plan)) = state.channels.get(&channel_id) else { return Ok(()) };
                    let value = plan.schema.decode(payload).map_err(|e| format!("{} message {n_messages}: {e}", plan.topic))?;
                    let log_ns = i64::try_from(log_time).unwrap_or(i64::MAX);
                    let channel_key = (file_index as u32) << 16 | u32::from(channel_id);
                    for (role, extractor) in &plan.roles {
                        let m = extractor.extract(&value, &plan.topic)?;
                        data.entry(*role)
                            .or_insert_with(|| TopicData::new(columns_of(*role), &topics.states.topic))
                            .push(&plan.topic, m, log_ns, channel_key, at)?;
                    }
                }
                Record::Metadata { name, map } => {
                    if name == EXPERIMENT_METADATA {
                        if experiment.is_some() {
                            return Err(format!("two '{EXPERIMENT_METADATA}' metadata records"));
                        }
                        experiment = Some(map);
                        experiment_at = Some(at);
                    } else if name == RUN_END_METADATA {
                        run_end = Some(map);
                    }
                }
            }
            Ok(())
        })
        .map_err(|m| err(where_(m)))?;
        if !end.complete {
            let states = data.get(&Role::States).map_or(0, TopicData::len);
            if states == 0 {
                return Err(err(where_(format!(
                    "truncated MCAP file: it ends at byte {} of {} before any complete {} message (the writer did not finish it): {}",
                    end.valid_bytes,
                    end.total_bytes,
                    topics.states.topic,
                    end.describe()
                ))));
            }
            warnings.push(where_(format!(
                "the file has no summary (the recorder did not finish it); a linear scan recovered every complete record up to byte {} of {}",
                end.valid_bytes, end.total_bytes
            )));
        }
    }

    // the states
    let states_topic = topics.states.topic.as_str();
    let states = data.remove(&Role::States).ok_or_else(|| {
        let found = if other_topics.is_empty() {
            "no channel record".to_string()
        } else {
            format!("topics in the file: {}", other_topics.iter().map(|(t, at)| format!("{t} ({at})")).collect::<Vec<_>>().join(", "))
        };
        err(format!("no {states_topic} messages ({found})"))
    })?;
    let n_state_messages = states.len();
    let states = states.merge(states_topic, None).map_err(err)?;
    let joints = states.joints.clone();
    let dof = joints.len();
    let start = states.t[0];
    let mut run = Run::new(joints.clone());
    run.source = label.display().to_string();
    run.start_ns = Some(start);
    run.t = states.t.iter().map(|&ns| ns.saturating_sub(start) as f64 * 1e-9).collect();
    run.q = states.position;
    match states.velocity {
        Some(v) => run.qd = v,
        None => {
            run.qd = central_difference(&run.t, &run.q, dof);
            run.source.push_str(" (velocity by central difference of position: the log has none)");
        }
    }
    run.tau = states.effort.unwrap_or_default();

    // the other roles, on the state times
    let rel = |ns: &[i64]| -> Vec<f64> { ns.iter().map(|&x| x.saturating_sub(start) as f64 * 1e-9).collect() };
    let onto = |m: &Merged, col: &[f64], hold: bool| -> Vec<f64> {
        if m.t == states.t {
            col.to_vec()
        } else if hold {
            hold_rows(&rel(&m.t), col, dof, &run.t)
        } else {
            interpolate_rows(&rel(&m.t), col, dof, &run.t)
        }
    };
    if let Some(r) = data.remove(&Role::Reference) {
        let r = r.merge(&topics.reference.topic, Some(&joints)).map_err(err)?;
        run.q_ref = onto(&r, &r.position, false);
        run.qd_ref = r.velocity.as_ref().map(|v| onto(&r, v, false)).unwrap_or_default();
        run.tau_ff = r.effort.as_ref().map(|v| onto(&r, v, false)).unwrap_or_default();
    }
    if let (Some(e), Some(spec)) = (data.remove(&Role::Effort), topics.effort.as_ref()) {
        let e = e.merge(&spec.topic, Some(&joints)).map_err(err)?;
        run.tau = onto(&e, &e.position, true);
    }
    if let Some(m) = data.remove(&Role::MeasuredEffort) {
        let m = m.merge(&topics.measured_effort.topic, Some(&joints)).map_err(err)?;
        run.tau_measured = onto(&m, &m.position, false);
    }
    // a servo's signals: the duty and the enable held from message to message, the temperature
    // interpolated
    for (role, hold) in [(Role::Duty, true), (Role::TorqueEnable, true), (Role::Temperature, false)] {
        if let (Some(d), Some(spec)) = (data.remove(&role), topics.get(role)) {
            let d = d.merge(&spec.topic, Some(&joints)).map_err(err)?;
            let values = onto(&d, &d.position, hold);
            match role {
                Role::Duty => run.drive.duty = values,
                Role::TorqueEnable => run.drive.torque_enable = values.iter().map(|e| if *e > 0.5 { 1.0 } else { 0.0 }).collect(),
                _ => run.drive.temperature = values,
            }
        }
    }
    // the supply voltage: one value per sample, interpolated
    if let (Some(d), Some(spec)) = (data.remove(&Role::Voltage), topics.voltage.as_ref()) {
        let d = d.merge(&spec.topic, None).map_err(err)?;
        run.drive.voltage = if d.t == states.t { d.position } else { interpolate_rows(&rel(&d.t), &d.position, 1, &run.t) };
    }

    // experiment: the file's, else the caller's (a sidecar is looked for by the caller)
    if let Some(map) = experiment {
        let at = experiment_at.map(|a| format!("{a}: ")).unwrap_or_default();
        let e = experiment_from_map(&map).map_err(|m| err(format!("{at}malformed '{EXPERIMENT_METADATA}' metadata: {m}")))?;
        if let Some(j) = e.joints.iter().find(|j| !run.joints.contains(j)) {
            return Err(err(format!("{at}the experiment names joint '{j}', which is not in the run (joints: {})", run.joints.join(", "))));
        }
        run.experiment = Some(e);
    } else if let Some(e) = fallback {
        run.experiment = Some(e.clone());
    }
    if let Some(end) = run_end {
        if let Some(status) = end.get("status").filter(|s| s.as_str() != "completed") {
            let at = end.get("t").map(|t| format!(" at t = {t} s")).unwrap_or_default();
            let joint = end.get("joint").map(|j| format!(" (joint '{j}')")).unwrap_or_default();
            warnings.push(format!("the run did not complete: {status}{at}{joint}"));
        }
    }
    if let Some(w) = warnings.iter_mut().find(|w| w.contains("linear scan recovered")) {
        w.push_str(&format!(": {n_state_messages} {states_topic} messages, {} samples over {:.3} s", run.len(), run.duration()));
    }
    check_run(&run, label)?;
    Ok(LogRead { run, warnings })
}

/// A warning when a schema's name (`stored_name`, as the file has it) and fields disagree about
/// its type: a schema named after a
/// known type (`sensor_msgs/msg/JointState`, `std_msgs/msg/Float64MultiArray`) whose fields are
/// not that type's, or a schema of another name whose fields are exactly a known type's. Field
/// names, types and arities are compared, down through nested messages; nested type names are
/// not.
fn schema_name_mismatch(schema: &Schema, stored_name: &str, topic: &str) -> Option<String> {
    use std::sync::OnceLock;
    static KNOWN: OnceLock<Vec<(&'static str, String)>> = OnceLock::new();
    let known = KNOWN.get_or_init(|| {
        [("sensor_msgs/msg/JointState", JOINT_STATE_DEFINITION), ("std_msgs/msg/Float64MultiArray", FLOAT64_MULTI_ARRAY_DEFINITION)]
            .into_iter()
            .filter_map(|(name, text)| Schema::parse(name, text).ok().map(|s| (name, fields_signature(&s, 0))))
            .collect()
    });
    let name = super::normalised_type(schema.name());
    let fields = fields_signature(schema, 0);
    for (known_name, signature) in known {
        let same_name = super::normalised_type(known_name) == name;
        if same_name && fields != *signature {
            return Some(format!(
                "{topic}: the schema is named '{stored_name}' but its fields are not that type's: it has ({}), {known_name} has ({}); read by its fields",
                field_names(schema),
                signature_names(known_name)
            ));
        }
        if !same_name && fields == *signature {
            return Some(format!("{topic}: the schema is named '{stored_name}' but its fields are exactly those of {known_name} ({}); read as {known_name}", field_names(schema)));
        }
    }
    None
}

/// The fields of message `def` of `schema` with their types and arities, nested messages
/// expanded (their type names left out).
fn fields_signature(schema: &Schema, def: usize) -> String {
    fn go(schema: &Schema, def: usize, depth: usize, out: &mut String) {
        for f in &schema.defs[def].fields {
            out.push_str(&f.name);
            out.push(':');
            match f.elem {
                ElemType::Primitive(p) => out.push_str(&format!("{p:?}")),
                // definitions are acyclic (the parser refuses recursion); the depth bound is a guard
                ElemType::Message(m) if depth < 32 => {
                    out.push('(');
                    go(schema, m, depth + 1, out);
                    out.push(')');
                }
                ElemType::Message(_) => out.push_str("(...)"),
            }
            out.push_str(&format!("{:?};", f.arity));
        }
    }
    let mut out = String::new();
    go(schema, def, 0, &mut out);
    out
}

/// The top-level field names of a schema, comma-separated.
fn field_names(schema: &Schema) -> String {
    schema.defs[0].fields.iter().map(|f| f.name.as_str()).collect::<Vec<_>>().join(", ")
}

/// The top-level field names of a known type.
fn signature_names(known: &str) -> String {
    let text = if known.ends_with("JointState") { JOINT_STATE_DEFINITION } else { FLOAT64_MULTI_ARRAY_DEFINITION };
    Schema::parse(known, text).map(|s| field_names(&s)).unwrap_or_default()
}
