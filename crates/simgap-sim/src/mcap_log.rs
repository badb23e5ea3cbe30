//! ROS 2 MCAP logs (BRIEF §3.1): `sensor_msgs/msg/JointState` in CDR on `/joint_states` and
//! `/joint_reference`, and the `simgap.experiment` metadata record.
//!
//! Writing: [`McapSink`] (a [`Sink`] that writes as the run goes, zstd-chunked, and always
//! leaves a finished, readable file: on [`Sink::finish`], whatever the [`RunEnd`], and on drop).
//! Reading: [`read_mcap`] streams any ROS 2 bag from the file (chunks are decompressed one at a
//! time; zstd, lz4 and uncompressed chunks, or no chunks at all).
//!
//! **CDR.** The JointState encoder/decoder is hand-written here ([`JointState`]): the message is
//! small and fixed, so ~150 lines give exact control over alignment and precise errors
//! ("truncated in field `position`"), with no dependency. The `cdr` crate (serde-based, last
//! released 2021) would need a static Rust type per message and reports errors without the
//! field. Encoding: 4-byte encapsulation header `00 01 00 00` (CDR little-endian; `00 00` big
//! endian is read too), primitives aligned to their size relative to the end of that header,
//! strings as `u32` length including the NUL terminator, sequences as a `u32` count then the
//! elements (aligned only when there is at least one, as Fast-CDR and `mcap_ros2` do).
//!
//! **Time.** A sample's time is its header stamp (sec + nanosec, absolute, quantised to 1 ns);
//! when every stamp of a topic is zero, the MCAP log time is used instead.
//!
//! **Merging.** Messages of a topic are sorted by time; messages with the same time and disjoint
//! joint subsets (several publishers) merge into one sample. A joint given twice at the same
//! time, or whose time goes backwards in file order, is an error. The run's joint order is the
//! first message's order, then joints first seen later, in order of appearance.
//!
//! **Missing arrays.** No velocities in any `/joint_states` message: q̇ by central difference
//! of q (see `run.source`). No efforts: `run.tau` is empty. A reference without velocities
//! gives an empty `qd_ref` (zero). A reference at other times than the states is interpolated
//! linearly onto the state times.

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use mcap::records::{MessageHeader, Metadata, Record};
use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};

use crate::error::{Error, Result};
use crate::log::{central_difference, experiment_from_map, experiment_to_map, interpolate_rows, log_error, validate_run, write_error};
use crate::run::{Experiment, Run, Sample};
use crate::sink::{RunEnd, Sink};

/// Topic of the measured joint states.
pub const JOINT_STATES_TOPIC: &str = "/joint_states";
/// Topic of the joint reference.
pub const JOINT_REFERENCE_TOPIC: &str = "/joint_reference";
/// Topic of the JSON run-end status written by [`McapSink`].
pub const RUN_END_TOPIC: &str = "/simgap/run_end";
/// Name of the experiment metadata record.
pub const EXPERIMENT_METADATA: &str = "simgap.experiment";
/// Name of the run-end metadata record written by [`McapSink`] (`status`, `t`, `joint`).
pub const RUN_END_METADATA: &str = "simgap.run_end";
/// Schema name of `sensor_msgs/msg/JointState`.
pub const JOINT_STATE_SCHEMA: &str = "sensor_msgs/msg/JointState";
/// Schema encoding of ROS 2 message definitions.
pub const ROS2MSG_ENCODING: &str = "ros2msg";
/// Message encoding of ROS 2 messages.
pub const CDR_ENCODING: &str = "cdr";

/// The concatenated definition of `sensor_msgs/msg/JointState` as rosbag2 writes it.
pub const JOINT_STATE_DEFINITION: &str = "\
# This is a message that holds data to describe the state of a set of torque controlled joints.
#
# The state of each joint (revolute or prismatic) is defined by:
#  * the position of the joint (rad or m),
#  * the velocity of the joint (rad/s or m/s) and
#  * the effort that is applied in the joint (Nm or N).
#
# Each joint is uniquely identified by its name
# The header specifies the time at which the joint states were recorded. All the joint states
# in one message have to be recorded at the same time.
#
# This message consists of a multiple arrays, one for each part of the joint state.
# The goal is to make each of the fields optional. When e.g. your joints have no
# effort associated with them, you can leave the effort array empty.
#
# All arrays in this message should have the same size, or be empty.
# This is the only way to uniquely associate the joint name with the correct
# states.

std_msgs/Header header

string[] name
float64[] position
float64[] velocity
float64[] effort

================================================================================
MSG: std_msgs/Header
# Standard metadata for higher-level stamped data types.
# This is generally used to communicate timestamped data
# in a particular coordinate frame.

# Two-integer timestamp that is expressed as seconds and nanoseconds.
builtin_interfaces/Time stamp

# Transform frame with which this data is associated.
string frame_id

================================================================================
MSG: builtin_interfaces/Time
# This message communicates ROS Time defined here:
# https://design.ros2.org/articles/clock_and_time.html

# The seconds component, valid over all int32 values.
int32 sec

# The nanoseconds component, valid in the range [0, 1e9), to be added to the seconds component.
# e.g.
# The time -1.7 seconds is represented as {sec: -2, nanosec: 3e8}
# The time 1.7 seconds is represented as {sec: 1, nanosec: 7e8}
uint32 nanosec
";

/// The `offered_qos_profiles` channel metadata rosbag2 writes for a reliable, volatile topic.
const OFFERED_QOS_PROFILES: &str = "- history: 3
  depth: 0
  reliability: 1
  durability: 2
  deadline:
    sec: 9223372036
    nsec: 854775807
  lifespan:
    sec: 9223372036
    nsec: 854775807
  liveliness: 1
  liveliness_lease_duration:
    sec: 9223372036
    nsec: 854775807
  avoid_ros_namespace_conventions: false";

const RUN_END_SCHEMA: &str = r#"{"type":"object","properties":{"status":{"type":"string","enum":["completed","interrupted","diverged"]},"t":{"type":"number"},"joint":{"type":"string"}},"required":["status"]}"#;

// ---------------------------------------------------------------------------------------------
// CDR

/// A `sensor_msgs/msg/JointState` message.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct JointState {
    /// `header.stamp.sec`.
    pub sec: i32,
    /// `header.stamp.nanosec`, in [0, 1e9).
    pub nanosec: u32,
    /// `header.frame_id`.
    pub frame_id: String,
    /// Joint names.
    pub name: Vec<String>,
    /// Positions (aligned with `name`, or empty).
    pub position: Vec<f64>,
    /// Velocities (aligned with `name`, or empty).
    pub velocity: Vec<f64>,
    /// Efforts (aligned with `name`, or empty).
    pub effort: Vec<f64>,
}

/// A CDR message that could not be decoded.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CdrError(pub String);

impl std::fmt::Display for CdrError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for CdrError {}

impl JointState {
    /// The stamp in nanoseconds.
    pub fn stamp_ns(&self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }

    /// Sets the stamp from nanoseconds (`sec` floor-divided, `nanosec` in [0, 1e9)).
    pub fn set_stamp_ns(&mut self, ns: i64) {
        self.sec = ns.div_euclid(1_000_000_000) as i32;
        self.nanosec = ns.rem_euclid(1_000_000_000) as u32;
    }

    /// Encodes as CDR little-endian with the encapsulation header.
    #[must_use]
    pub fn encode_cdr(&self) -> Vec<u8> {
        let mut buf = Vec::new();
        self.encode_cdr_into(&mut buf);
        buf
    }

    /// Encodes as CDR little-endian into `buf` (cleared first).
    pub fn encode_cdr_into(&self, buf: &mut Vec<u8>) {
        buf.clear();
        buf.extend_from_slice(&[0x00, 0x01, 0x00, 0x00]);
        let mut w = CdrWriter { buf };
        w.i32(self.sec);
        w.u32(self.nanosec);
        w.string(&self.frame_id);
        w.u32(self.name.len() as u32);
        for s in &self.name {
            w.string(s);
        }
        w.f64_seq(&self.position);
        w.f64_seq(&self.velocity);
        w.f64_seq(&self.effort);
    }

    /// Decodes a CDR message (little- or big-endian) with its encapsulation header.
    ///
    /// # Errors
    /// [`CdrError`] naming the field where the data ended or was invalid.
    pub fn decode_cdr(data: &[u8]) -> std::result::Result<JointState, CdrError> {
        if data.len() < 4 {
            return Err(CdrError(format!("message of {} bytes has no CDR encapsulation header", data.len())));
        }
        let little = match (data[0], data[1]) {
            (0x00, 0x01) | (0x00, 0x03) => true,
            (0x00, 0x00) | (0x00, 0x02) => false,
            (a, b) => return Err(CdrError(format!("unsupported CDR encapsulation {a:#04x} {b:#04x} (expected plain CDR)"))),
        };
        let mut r = CdrReader { data: &data[4..], pos: 0, little };
        let sec = r.i32("header.stamp.sec")?;
        let nanosec = r.u32("header.stamp.nanosec")?;
        let frame_id = r.string("header.frame_id")?;
        let count = r.count("name", 4)?;
        let mut name = Vec::with_capacity(count);
        for _ in 0..count {
            name.push(r.string("name")?);
        }
        let position = r.f64_seq("position")?;
        let velocity = r.f64_seq("velocity")?;
        let effort = r.f64_seq("effort")?;
        Ok(JointState { sec, nanosec, frame_id, name, position, velocity, effort })
    }
}

struct CdrWriter<'a> {
    buf: &'a mut Vec<u8>,
}

impl CdrWriter<'_> {
    fn align(&mut self, n: usize) {
        while (self.buf.len() - 4) % n != 0 {
            self.buf.push(0);
        }
    }
    fn u32(&mut self, x: u32) {
        self.align(4);
        self.buf.extend_from_slice(&x.to_le_bytes());
    }
    fn i32(&mut self, x: i32) {
        self.align(4);
        self.buf.extend_from_slice(&x.to_le_bytes());
    }
    fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }
    fn f64_seq(&mut self, v: &[f64]) {
        self.u32(v.len() as u32);
        if !v.is_empty() {
            self.align(8);
            for x in v {
                self.buf.extend_from_slice(&x.to_le_bytes());
            }
        }
    }
}

struct CdrReader<'a> {
    data: &'a [u8],
    pos: usize,
    little: bool,
}

impl CdrReader<'_> {
    fn take(&mut self, n: usize, align: usize, field: &str) -> std::result::Result<&[u8], CdrError> {
        let start = self.pos.div_ceil(align) * align;
        if start + n > self.data.len() {
            return Err(CdrError(format!("message truncated in field '{field}' ({} bytes of CDR payload)", self.data.len())));
        }
        self.pos = start + n;
        Ok(&self.data[start..start + n])
    }
    fn u32(&mut self, field: &str) -> std::result::Result<u32, CdrError> {
        let little = self.little;
        let b: [u8; 4] = self.take(4, 4, field)?.try_into().expect("4 bytes");
        Ok(if little { u32::from_le_bytes(b) } else { u32::from_be_bytes(b) })
    }
    fn i32(&mut self, field: &str) -> std::result::Result<i32, CdrError> {
        Ok(self.u32(field)? as i32)
    }
    fn f64(&mut self, field: &str) -> std::result::Result<f64, CdrError> {
        let little = self.little;
        let b: [u8; 8] = self.take(8, 8, field)?.try_into().expect("8 bytes");
        Ok(if little { f64::from_le_bytes(b) } else { f64::from_be_bytes(b) })
    }
    /// A sequence count, checked against the bytes left (`min_size` bytes per element).
    fn count(&mut self, field: &str, min_size: usize) -> std::result::Result<usize, CdrError> {
        let n = self.u32(field)? as usize;
        if n.saturating_mul(min_size) > self.data.len() - self.pos {
            return Err(CdrError(format!("field '{field}' claims {n} elements but the message is shorter")));
        }
        Ok(n)
    }
    fn string(&mut self, field: &str) -> std::result::Result<String, CdrError> {
        let n = self.count(field, 1)?;
        let bytes = self.take(n, 1, field)?;
        let bytes = bytes.strip_suffix(&[0]).unwrap_or(bytes);
        String::from_utf8(bytes.to_vec()).map_err(|_| CdrError(format!("field '{field}' is not UTF-8")))
    }
    fn f64_seq(&mut self, field: &str) -> std::result::Result<Vec<f64>, CdrError> {
        let n = self.count(field, 8)?;
        (0..n).map(|_| self.f64(field)).collect()
    }
}

// ---------------------------------------------------------------------------------------------
// writing

/// Writes a run as a ROS 2 MCAP file as it goes (see the [module docs](self)).
///
/// The file is always finished (summary and footer written) by [`Sink::finish`], and by `Drop`
/// when `finish` was never called (a panic or an early return), so it stays readable after a
/// failed or interrupted run. The end status goes to the `simgap.run_end` metadata record and
/// the `/simgap/run_end` JSON channel (`{"status": "diverged", "t": …, "joint": …}`).
pub struct McapSink {
    path: PathBuf,
    writer: Option<mcap::Writer<BufWriter<File>>>,
    joints: Vec<String>,
    states_channel: u16,
    reference_channel: u16,
    run_end_channel: u16,
    sequence: u32,
    last_t: Option<f64>,
    began: bool,
    buf: Vec<u8>,
    msg: JointState,
}

impl std::fmt::Debug for McapSink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("McapSink").field("path", &self.path).field("joints", &self.joints).field("finished", &self.writer.is_none()).finish()
    }
}

impl McapSink {
    /// The default writer options: ROS 2 profile, lz4 chunks (measured as cheap as no compression
    /// when writing as the run goes, where zstd cost about 50 % more), single-threaded.
    pub fn default_options() -> mcap::WriteOptions {
        mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!("simgap-sim ", env!("CARGO_PKG_VERSION")))
            .compression(Some(mcap::Compression::Lz4))
            .compression_threads(0)
    }

    /// Creates (truncates) the file at `path`, with [`McapSink::default_options`].
    ///
    /// # Errors
    /// [`Error::Write`] when the file cannot be created.
    pub fn create(path: &Path) -> Result<McapSink> {
        Self::create_with_options(path, Self::default_options())
    }

    /// Creates (truncates) the file at `path` with other MCAP writer options (e.g. lz4 chunks).
    ///
    /// # Errors
    /// [`Error::Write`] when the file cannot be created.
    pub fn create_with_options(path: &Path, options: mcap::WriteOptions) -> Result<McapSink> {
        let file = File::create(path).map_err(|e| write_error(path, e))?;
        let writer = options.create(BufWriter::new(file)).map_err(|e| write_error(path, e))?;
        Ok(McapSink {
            path: path.to_path_buf(),
            writer: Some(writer),
            joints: Vec::new(),
            states_channel: 0,
            reference_channel: 0,
            run_end_channel: 0,
            sequence: 0,
            last_t: None,
            began: false,
            buf: Vec::new(),
            msg: JointState::default(),
        })
    }

    /// The file being written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Like [`Sink::begin`], with an optional experiment (no metadata record without one).
    ///
    /// # Errors
    /// [`Error::Write`] when called twice, after finishing, or when the file cannot be written.
    pub fn begin_with(&mut self, joints: &[String], experiment: Option<&Experiment>) -> Result<()> {
        if self.began {
            return Err(write_error(&self.path, "begin called twice"));
        }
        let path = self.path.clone();
        let w = self.writer.as_mut().ok_or_else(|| write_error(&path, "begin after finish"))?;
        let err = |e: mcap::McapError| write_error(&path, e);
        let schema = w.add_schema(JOINT_STATE_SCHEMA, ROS2MSG_ENCODING, JOINT_STATE_DEFINITION.as_bytes()).map_err(err)?;
        let qos: BTreeMap<String, String> = [("offered_qos_profiles".to_string(), OFFERED_QOS_PROFILES.to_string())].into();
        self.states_channel = w.add_channel(schema, JOINT_STATES_TOPIC, CDR_ENCODING, &qos).map_err(err)?;
        self.reference_channel = w.add_channel(schema, JOINT_REFERENCE_TOPIC, CDR_ENCODING, &qos).map_err(err)?;
        let end_schema = w.add_schema("simgap/RunEnd", "jsonschema", RUN_END_SCHEMA.as_bytes()).map_err(err)?;
        self.run_end_channel = w.add_channel(end_schema, RUN_END_TOPIC, "json", &BTreeMap::new()).map_err(err)?;
        if let Some(e) = experiment {
            w.write_metadata(&Metadata { name: EXPERIMENT_METADATA.into(), metadata: experiment_to_map(e) }).map_err(err)?;
        }
        self.joints = joints.to_vec();
        self.msg.name = joints.to_vec();
        self.began = true;
        Ok(())
    }

    fn write_state(&mut self, channel: u16, ns: i64) -> Result<()> {
        let path = &self.path;
        let w = self.writer.as_mut().ok_or_else(|| write_error(path, "record after finish"))?;
        self.msg.set_stamp_ns(ns);
        self.msg.encode_cdr_into(&mut self.buf);
        let log_time = ns.max(0) as u64;
        let header = MessageHeader { channel_id: channel, sequence: self.sequence, log_time, publish_time: log_time };
        w.write_to_known_channel(&header, &self.buf).map_err(|e| write_error(path, e))
    }

    /// Finishes the file without a [`RunEnd`] status (for logs that are not simulation runs).
    ///
    /// # Errors
    /// [`Error::Write`] when the summary cannot be written.
    pub fn close(&mut self) -> Result<()> {
        self.finish_inner(None)
    }

    fn finish_inner(&mut self, end: Option<&RunEnd>) -> Result<()> {
        let Some(mut w) = self.writer.take() else { return Ok(()) };
        let path = self.path.clone();
        let err = |e: mcap::McapError| write_error(&path, e);
        // end status: metadata record and a JSON message on its channel
        if let (Some(end), true) = (end, self.began) {
            let (status, t, joint) = match end {
                RunEnd::Completed => ("completed", self.last_t, None),
                RunEnd::Interrupted { t } => ("interrupted", Some(*t), None),
                RunEnd::Diverged { t, joint } => ("diverged", Some(*t), Some(joint.clone())),
            };
            let mut map = BTreeMap::from([("status".to_string(), status.to_string())]);
            let mut json = serde_json::json!({ "status": status });
            if let Some(t) = t {
                map.insert("t".into(), format!("{t}"));
                json["t"] = serde_json::json!(t);
            }
            if let Some(j) = joint {
                map.insert("joint".into(), j.clone());
                json["joint"] = serde_json::json!(j);
            }
            let ns = seconds_to_ns(t.or(self.last_t).unwrap_or(0.0)).max(0) as u64;
            let header = MessageHeader { channel_id: self.run_end_channel, sequence: 0, log_time: ns, publish_time: ns };
            w.write_to_known_channel(&header, json.to_string().as_bytes()).map_err(err)?;
            w.write_metadata(&Metadata { name: RUN_END_METADATA.into(), metadata: map }).map_err(err)?;
        }
        // summary, footer, flush
        w.finish().map_err(err)?;
        let mut inner = w.into_inner();
        inner.flush().map_err(|e| write_error(&path, e))?;
        Ok(())
    }
}

impl Sink for McapSink {
    fn begin(&mut self, joints: &[String], experiment: &Experiment) -> Result<()> {
        self.begin_with(joints, Some(experiment))
    }

    fn record(&mut self, s: &Sample<'_>) -> Result<()> {
        if !self.began {
            return Err(write_error(&self.path, "record before begin"));
        }
        let dof = self.joints.len();
        for (what, v, may_be_empty) in
            [("q", s.q, false), ("qd", s.qd, false), ("tau", s.tau, true), ("q_ref", s.q_ref, true), ("qd_ref", s.qd_ref, true)]
        {
            if v.len() != dof && !(may_be_empty && v.is_empty()) {
                return Err(write_error(&self.path, format!("sample at t = {} s: {what} has {} values for {dof} joints", s.t, v.len())));
            }
        }
        let ns = seconds_to_ns(s.t);
        // measured state and commanded effort
        self.msg.position.clear();
        self.msg.position.extend_from_slice(s.q);
        self.msg.velocity.clear();
        self.msg.velocity.extend_from_slice(s.qd);
        self.msg.effort.clear();
        self.msg.effort.extend_from_slice(s.tau);
        self.write_state(self.states_channel, ns)?;
        // reference
        if !s.q_ref.is_empty() {
            self.msg.position.clear();
            self.msg.position.extend_from_slice(s.q_ref);
            self.msg.velocity.clear();
            self.msg.velocity.extend_from_slice(s.qd_ref);
            self.msg.effort.clear();
            self.write_state(self.reference_channel, ns)?;
        }
        self.sequence = self.sequence.wrapping_add(1);
        self.last_t = Some(s.t);
        Ok(())
    }

    fn finish(&mut self, end: &RunEnd) -> Result<()> {
        self.finish_inner(Some(end))
    }
}

impl Drop for McapSink {
    fn drop(&mut self) {
        if self.writer.is_some() {
            let t = self.last_t.unwrap_or(0.0);
            let _ = self.finish_inner(Some(&RunEnd::Interrupted { t }));
        }
    }
}

/// Writes a whole run as an MCAP file (zstd chunks; no run-end status).
///
/// # Errors
/// [`Error::Write`] when the file cannot be written or the run's matrices have wrong sizes.
pub fn write_mcap(run: &Run, path: &Path) -> Result<()> {
    let mut sink = McapSink::create(path)?;
    sink.begin_with(&run.joints, run.experiment.as_ref())?;
    let dof = run.dof();
    fn row(m: &[f64], k: usize, dof: usize) -> &[f64] {
        if m.is_empty() {
            &[]
        } else {
            &m[k * dof..(k + 1) * dof]
        }
    }
    for k in 0..run.len() {
        sink.record(&Sample {
            t: run.t[k],
            q: row(&run.q, k, dof),
            qd: row(&run.qd, k, dof),
            tau: row(&run.tau, k, dof),
            q_ref: row(&run.q_ref, k, dof),
            qd_ref: row(&run.qd_ref, k, dof),
        })?;
    }
    sink.close()
}

fn seconds_to_ns(t: f64) -> i64 {
    (t * 1e9).round() as i64
}

fn ns_to_seconds(ns: i64) -> f64 {
    ns.div_euclid(1_000_000_000) as f64 + ns.rem_euclid(1_000_000_000) as f64 / 1e9
}

// ---------------------------------------------------------------------------------------------
// reading

/// Reads a ROS 2 MCAP log: `/joint_states` (required), `/joint_reference` (optional) and the
/// `simgap.experiment` metadata (optional; `run.experiment = None` without it). The run's
/// joint order is the first `/joint_states` message's (see the [module docs](self) for merging,
/// time and missing arrays).
///
/// # Errors
/// [`Error::Log`] naming the file and the problem: not an MCAP file, truncated file, no
/// `/joint_states` messages, a topic with another schema or encoding, undecodable messages,
/// arrays of the wrong length, non-finite values, a joint missing from a sample or a reference,
/// time going backwards or repeated for a joint, a malformed `simgap.experiment` record.
pub fn read_mcap(path: &Path) -> Result<Run> {
    let mut topics: HashMap<&'static str, TopicData> = HashMap::new();
    let mut channels: HashMap<u16, Option<&'static str>> = HashMap::new();
    let mut schemas: HashMap<u16, (String, String)> = HashMap::new();
    let mut experiment: Option<BTreeMap<String, String>> = None;
    let mut n_messages = 0usize;
    let mut other_topics: Vec<String> = Vec::new();

    stream_records(path, |record| {
        match record {
            Record::Schema { header, .. } => {
                schemas.insert(header.id, (header.name, header.encoding));
            }
            Record::Channel(c) => {
                let topic = match c.topic.as_str() {
                    JOINT_STATES_TOPIC => Some(JOINT_STATES_TOPIC),
                    JOINT_REFERENCE_TOPIC => Some(JOINT_REFERENCE_TOPIC),
                    other => {
                        if !other_topics.iter().any(|t| t == other) {
                            other_topics.push(other.to_string());
                        }
                        None
                    }
                };
                if let Some(topic) = topic {
                    let (sname, sencoding) = schemas.get(&c.schema_id).cloned().unwrap_or_default();
                    if sname != JOINT_STATE_SCHEMA || c.message_encoding != CDR_ENCODING {
                        return Err(format!(
                            "wrong schema on {topic}: found schema '{sname}' (encoding '{sencoding}') with message encoding '{}', expected '{JOINT_STATE_SCHEMA}' ({ROS2MSG_ENCODING}) in '{CDR_ENCODING}'",
                            c.message_encoding
                        ));
                    }
                }
                channels.insert(c.id, topic);
            }
            Record::Message { header, data } => {
                n_messages += 1;
                let Some(topic) = channels.get(&header.channel_id).copied().flatten() else { return Ok(()) };
                let msg = JointState::decode_cdr(&data).map_err(|e| format!("{topic} message {}: {e}", n_messages))?;
                topics.entry(topic).or_default().push(topic, msg, header.log_time as i64, header.channel_id)?;
            }
            Record::Metadata(m) if m.name == EXPERIMENT_METADATA => {
                if experiment.is_some() {
                    return Err(format!("two '{EXPERIMENT_METADATA}' metadata records"));
                }
                experiment = Some(m.metadata);
            }
            _ => {}
        }
        Ok(())
    })?;

    let err = |m: String| log_error(path, m);
    let states = topics.remove(JOINT_STATES_TOPIC).ok_or_else(|| {
        err(format!(
            "no {JOINT_STATES_TOPIC} messages (topics in the file: {})",
            if other_topics.is_empty() { "none".to_string() } else { other_topics.join(", ") }
        ))
    })?;
    let states = states.merge(JOINT_STATES_TOPIC, None).map_err(err)?;
    let joints = states.joints.clone();
    let n = states.t.len();
    let dof = joints.len();
    let mut run = Run::new(joints.clone());
    run.source = path.display().to_string();
    run.t = states.t.iter().map(|&ns| ns_to_seconds(ns)).collect();
    run.q = states.position;
    match states.velocity {
        Some(v) => run.qd = v,
        None => {
            run.qd = central_difference(&run.t, &run.q, dof);
            run.source.push_str(" (velocity by central difference of position: the log has none)");
        }
    }
    run.tau = states.effort.unwrap_or_default();

    // reference: same joints, at the state times
    if let Some(reference) = topics.remove(JOINT_REFERENCE_TOPIC) {
        let r = reference.merge(JOINT_REFERENCE_TOPIC, Some(&joints)).map_err(err)?;
        if r.t == states.t {
            run.q_ref = r.position;
            run.qd_ref = r.velocity.unwrap_or_default();
        } else {
            // interpolate in time relative to the first state: absolute f64 seconds lose ~1e-7 s
            let t0 = states.t[0];
            let rel = |ns: &[i64]| -> Vec<f64> { ns.iter().map(|&x| (x - t0) as f64 * 1e-9).collect() };
            let (tr, ts) = (rel(&r.t), rel(&states.t));
            run.q_ref = interpolate_rows(&tr, &r.position, dof, &ts);
            run.qd_ref = r.velocity.map(|v| interpolate_rows(&tr, &v, dof, &ts)).unwrap_or_default();
        }
    }
    debug_assert_eq!(run.q.len(), n * dof);

    // experiment
    if let Some(map) = experiment {
        run.experiment =
            Some(experiment_from_map(&map).map_err(|m| err(format!("malformed '{EXPERIMENT_METADATA}' metadata: {m}")))?);
    }
    validate_run(&run).map_err(|e| match e {
        Error::Log { message, .. } => err(message),
        other => other,
    })?;
    Ok(run)
}

/// Reads an MCAP log with its joints in `joints` order (a model's order).
///
/// # Errors
/// As [`read_mcap`], and [`Error::JointMismatch`] naming a joint of `joints` missing from the
/// log, or a joint of the log that is not in `joints`.
pub fn read_mcap_for(path: &Path, joints: &[String]) -> Result<Run> {
    crate::log::reorder_joints(&read_mcap(path)?, joints, false)
}

/// Streams the records of an MCAP file (chunks decompressed one at a time).
fn stream_records(path: &Path, mut on_record: impl FnMut(Record<'_>) -> std::result::Result<(), String>) -> Result<()> {
    let err = |m: String| log_error(path, m);
    let mut file = File::open(path).map_err(|e| err(format!("cannot open: {e}")))?;
    let mut reader = LinearReader::new_with_options(LinearReaderOptions::default().with_validate_chunk_crcs(true));
    let mut bytes_read = 0u64;
    let mut records = 0usize;
    while let Some(event) = reader.next_event() {
        let event = event.map_err(|e| err(describe_mcap_error(&e, bytes_read, records)))?;
        match event {
            LinearReadEvent::ReadRequest(need) => {
                let got = file.read(reader.insert(need)).map_err(|e| err(format!("read error: {e}")))?;
                bytes_read += got as u64;
                reader.notify_read(got);
            }
            LinearReadEvent::Record { opcode, data } => {
                records += 1;
                let record = mcap::parse_record(opcode, data)
                    .map_err(|e| err(format!("corrupt record (opcode {opcode:#04x}) at record {records}: {e}")))?;
                on_record(record).map_err(err)?;
            }
        }
    }
    Ok(())
}

fn describe_mcap_error(e: &mcap::McapError, bytes: u64, records: usize) -> String {
    match e {
        mcap::McapError::BadMagic => "not an MCAP file (no MCAP magic bytes at the start)".to_string(),
        mcap::McapError::UnexpectedEof | mcap::McapError::UnexpectedEoc => format!(
            "truncated MCAP file: it ends inside a record after {bytes} bytes and {records} records (the writer did not finish it)"
        ),
        other => format!("invalid MCAP file after {bytes} bytes and {records} records: {other}"),
    }
}

/// The messages of one topic as read: joint names interned, values in flat arrays, so a long
/// bag costs about what the run itself costs.
#[derive(Default)]
struct TopicData {
    names: Vec<String>,
    index: HashMap<String, u32>,
    msgs: Vec<MsgRef>,
    ids: Vec<u32>,
    position: Vec<f64>,
    velocity: Vec<f64>,
    effort: Vec<f64>,
    any_stamp: bool,
}

/// One message: its times and its slice of the flat arrays.
struct MsgRef {
    stamp: i64,
    log: i64,
    channel: u16,
    start: usize,
    len: usize,
    has_velocity: bool,
    has_effort: bool,
}

/// A topic merged into samples.
struct Merged {
    joints: Vec<String>,
    t: Vec<i64>,
    position: Vec<f64>,
    velocity: Option<Vec<f64>>,
    effort: Option<Vec<f64>>,
}

impl TopicData {
    /// Checks and stores a message: array lengths and finite values.
    fn push(&mut self, topic: &str, m: JointState, log_ns: i64, channel: u16) -> std::result::Result<(), String> {
        let stamp = m.stamp_ns();
        let t = ns_to_seconds(if stamp != 0 { stamp } else { log_ns });
        // array lengths
        if m.name.is_empty() {
            return Err(format!("{topic} message at t = {t} s has no joint names"));
        }
        if m.position.len() != m.name.len() {
            return Err(format!("{topic} message at t = {t} s has {} positions for {} joints", m.position.len(), m.name.len()));
        }
        for (what, v) in [("velocities", &m.velocity), ("efforts", &m.effort)] {
            if !v.is_empty() && v.len() != m.name.len() {
                return Err(format!("{topic} message at t = {t} s has {} {what} for {} joints", v.len(), m.name.len()));
            }
        }
        // finite values
        for (i, j) in m.name.iter().enumerate() {
            for (what, v) in [("position", &m.position), ("velocity", &m.velocity), ("effort", &m.effort)] {
                if let Some(x) = v.get(i).filter(|x| !x.is_finite()) {
                    return Err(format!("{topic}: {what} of joint '{j}' is {x} at t = {t} s"));
                }
            }
        }
        // store
        let start = self.ids.len();
        for j in &m.name {
            let id = match self.index.get(j) {
                Some(&id) => id,
                None => {
                    self.names.push(j.clone());
                    self.index.insert(j.clone(), (self.names.len() - 1) as u32);
                    (self.names.len() - 1) as u32
                }
            };
            self.ids.push(id);
        }
        let n = m.name.len();
        self.position.extend_from_slice(&m.position);
        let has_velocity = !m.velocity.is_empty();
        let has_effort = !m.effort.is_empty();
        if has_velocity {
            self.velocity.extend_from_slice(&m.velocity);
        } else {
            self.velocity.extend(std::iter::repeat(0.0).take(n));
        }
        if has_effort {
            self.effort.extend_from_slice(&m.effort);
        } else {
            self.effort.extend(std::iter::repeat(0.0).take(n));
        }
        self.any_stamp |= stamp != 0;
        self.msgs.push(MsgRef { stamp, log: log_ns, channel, start, len: n, has_velocity, has_effort });
        Ok(())
    }

    /// Merges messages into samples (see the module docs); `joints` fixes the joint set.
    fn merge(self, topic: &str, joints: Option<&[String]>) -> std::result::Result<Merged, String> {
        let times: Vec<i64> = self.msgs.iter().map(|m| if self.any_stamp { m.stamp } else { m.log }).collect();
        let time_s = ns_to_seconds;

        // columns: the given joints, or the order of first appearance (first message first)
        let (names, column): (Vec<String>, Vec<usize>) = match joints {
            Some(js) => {
                let mut column = Vec::with_capacity(self.names.len());
                for j in &self.names {
                    let c = js.iter().position(|x| x == j).ok_or_else(|| {
                        format!("joint '{j}' is in {topic} but not in {JOINT_STATES_TOPIC} (joints: {})", js.join(", "))
                    })?;
                    column.push(c);
                }
                (js.to_vec(), column)
            }
            None => (self.names.clone(), (0..self.names.len()).collect()),
        };

        // time strictly increasing per joint and channel (publisher), in file order
        let mut last_time: HashMap<(u16, u32), i64> = HashMap::new();
        for (m, &t) in self.msgs.iter().zip(&times) {
            for &id in &self.ids[m.start..m.start + m.len] {
                if let Some(prev) = last_time.insert((m.channel, id), t) {
                    let j = &self.names[id as usize];
                    if t == prev {
                        return Err(format!("{topic}: joint '{j}' is given twice at the same time t = {} s", time_s(t)));
                    }
                    if t < prev {
                        return Err(format!(
                            "{topic}: time is not monotonic for joint '{j}': t = {} s comes after t = {} s",
                            time_s(t),
                            time_s(prev)
                        ));
                    }
                }
            }
        }

        // group by time; messages with the same time merge
        let dof = names.len();
        let mut order: Vec<usize> = (0..self.msgs.len()).collect();
        order.sort_by_key(|&i| times[i]);
        let has_velocity = self.msgs.iter().any(|m| m.has_velocity);
        let has_effort = self.msgs.iter().any(|m| m.has_effort);
        let mut out = Merged { joints: names.clone(), t: Vec::new(), position: Vec::new(), velocity: None, effort: None };
        let mut velocity = Vec::new();
        let mut effort = Vec::new();
        let mut filled = vec![false; dof];
        let mut g = 0;
        while g < order.len() {
            let t = times[order[g]];
            let row = out.position.len();
            out.position.resize(row + dof, 0.0);
            velocity.resize(row + dof, 0.0);
            effort.resize(row + dof, 0.0);
            filled.fill(false);
            while g < order.len() && times[order[g]] == t {
                let m = &self.msgs[order[g]];
                for (what, any, this) in [("velocity", has_velocity, m.has_velocity), ("effort", has_effort, m.has_effort)] {
                    if any && !this {
                        return Err(format!("{topic}: the message at t = {} s has no {what} while other messages have one", time_s(t)));
                    }
                }
                for i in m.start..m.start + m.len {
                    let id = self.ids[i] as usize;
                    let k = column[id];
                    if filled[k] {
                        return Err(format!("{topic}: joint '{}' is given twice at the same time t = {} s", self.names[id], time_s(t)));
                    }
                    filled[k] = true;
                    out.position[row + k] = self.position[i];
                    velocity[row + k] = self.velocity[i];
                    effort[row + k] = self.effort[i];
                }
                g += 1;
            }
            if let Some(k) = filled.iter().position(|f| !f) {
                return Err(format!(
                    "{topic}: joint '{}' is missing at t = {} s (no message with that joint has this time stamp)",
                    names[k],
                    time_s(t)
                ));
            }
            out.t.push(t);
        }
        out.velocity = has_velocity.then_some(velocity);
        out.effort = has_effort.then_some(effort);
        Ok(out)
    }
}
