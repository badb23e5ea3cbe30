//! Bags as ROS 2 users record them: rosbag2 folders of split MCAP files, topics named after the
//! robot, controller topics of other message types decoded from the schema in the file,
//! per-log experiments, and absolute stamps kept to the nanosecond.

use std::collections::BTreeMap;
use std::path::Path;

use mcap::records::MessageHeader;
use simgap_log::experiment::write_experiment_file;
use simgap_log::mcap::{JointState, FLOAT64_MULTI_ARRAY_DEFINITION, JOINT_STATE_DEFINITION};
use simgap_log::{read_log, read_log_with_warnings, write_log, LogOptions, TopicMap};
use simgap_sim::{ControllerKind, Experiment, Run};

mod common;
use common::tmp;

fn names(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

fn experiment(controller: ControllerKind) -> Experiment {
    Experiment { controller, joints: names(&["a", "b"]), kp: vec![10.0, 5.0], kv: vec![1.0, 0.5], sample_period: 0.002, extra: BTreeMap::new() }
}

/// `control_msgs/msg/JointTrajectoryControllerState` as ros2_control (Humble) records it,
/// constants and comments included.
const JTCS_DEFINITION: &str = "\
# This message presents current controller state of JTC
std_msgs/Header header
string[] joint_names
# The set point, that is, desired state.
trajectory_msgs/JointTrajectoryPoint reference
# Current value of the process (ie: latest sensor measurement on the controlled value).
trajectory_msgs/JointTrajectoryPoint feedback
# The error of the controlled value
trajectory_msgs/JointTrajectoryPoint error
# Current output of the controller.
trajectory_msgs/JointTrajectoryPoint output

================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id

================================================================================
MSG: trajectory_msgs/JointTrajectoryPoint
# Each trajectory point specifies either positions[, velocities[, accelerations]]
float64[] positions
float64[] velocities
float64[] accelerations
float64[] effort
builtin_interfaces/Duration time_from_start
int8 SOME_CONSTANT = 3
";

/// A little CDR encoder for the test's own messages.
struct Cdr(Vec<u8>);

impl Cdr {
    fn new() -> Cdr {
        Cdr(vec![0, 1, 0, 0])
    }
    fn align(&mut self, n: usize) {
        while (self.0.len() - 4) % n != 0 {
            self.0.push(0);
        }
    }
    fn u32(&mut self, x: u32) -> &mut Self {
        self.align(4);
        self.0.extend_from_slice(&x.to_le_bytes());
        self
    }
    fn string(&mut self, s: &str) -> &mut Self {
        self.u32(s.len() as u32 + 1);
        self.0.extend_from_slice(s.as_bytes());
        self.0.push(0);
        self
    }
    fn strings(&mut self, v: &[&str]) -> &mut Self {
        self.u32(v.len() as u32);
        for s in v {
            self.string(s);
        }
        self
    }
    fn f64s(&mut self, v: &[f64]) -> &mut Self {
        self.u32(v.len() as u32);
        if !v.is_empty() {
            self.align(8);
        }
        for x in v {
            self.0.extend_from_slice(&x.to_le_bytes());
        }
        self
    }
    fn header(&mut self, ns: i64) -> &mut Self {
        self.u32(ns.div_euclid(1_000_000_000) as u32).u32(ns.rem_euclid(1_000_000_000) as u32).string("base")
    }
    fn point(&mut self, positions: &[f64], velocities: &[f64], effort: &[f64]) -> &mut Self {
        self.f64s(positions).f64s(velocities).f64s(&[]).f64s(effort).u32(0).u32(0)
    }
}

/// One MCAP file of a bag, written like rosbag2 does (one channel per topic).
struct BagFile {
    w: mcap::Writer<std::io::BufWriter<std::fs::File>>,
    channels: BTreeMap<String, u16>,
    sequence: u32,
}

impl BagFile {
    fn new(path: &Path) -> BagFile {
        let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
        let w = mcap::WriteOptions::new().profile("ros2").compression(Some(mcap::Compression::Zstd)).create(file).unwrap();
        BagFile { w, channels: BTreeMap::new(), sequence: 0 }
    }

    fn publish(&mut self, topic: &str, ty: &str, definition: &str, log_ns: i64, data: &[u8]) {
        let id = match self.channels.get(topic) {
            Some(&id) => id,
            None => {
                let s = self.w.add_schema(ty, "ros2msg", definition.as_bytes()).unwrap();
                let meta = BTreeMap::from([("offered_qos_profiles".to_string(), String::new())]);
                let id = self.w.add_channel(s, topic, "cdr", &meta).unwrap();
                self.channels.insert(topic.into(), id);
                id
            }
        };
        self.sequence += 1;
        let h = MessageHeader { channel_id: id, sequence: self.sequence, log_time: log_ns as u64, publish_time: log_ns as u64 };
        self.w.write_to_known_channel(&h, data).unwrap();
    }

    fn finish(mut self) {
        self.w.finish().unwrap();
    }
}

const T0: i64 = 1_733_000_000_123_456_789;
const DT: i64 = 2_000_000;

/// A teleop bag as recorded on a real arm: states named after the robot (joints in another
/// order than the controller's), the trajectory controller's state with reference and
/// feed-forward, effort commands as a Float64MultiArray at their own times, and the drives'
/// torque; split into two files listed by metadata.yaml.
fn teleop_bag(dir: &Path, samples: i64) {
    std::fs::create_dir_all(dir).unwrap();
    let files = ["teleop_0.mcap", "teleop_1.mcap"];
    let yaml = format!(
        "rosbag2_bagfile_information:\n  version: 8\n  storage_identifier: mcap\n  duration:\n    nanoseconds: {}\n  relative_file_paths:\n    - {}\n    - {}\n",
        samples * DT,
        files[0],
        files[1]
    );
    std::fs::write(dir.join("metadata.yaml"), yaml).unwrap();
    for (f, name) in files.iter().enumerate() {
        let mut bag = BagFile::new(&dir.join(name));
        let range = if f == 0 { 0..samples / 2 } else { samples / 2..samples };
        for k in range {
            let t = T0 + k * DT;
            let x = k as f64;
            let js = JointState { name: names(&["b", "a"]), position: vec![10.0 + x, x], velocity: vec![1.0, 0.1], effort: vec![], ..JointState::default() };
            let mut js = js;
            js.set_stamp_ns(t);
            bag.publish("/robot/arm/joint_states", "sensor_msgs/msg/JointState", JOINT_STATE_DEFINITION, t + 1000, &js.encode_cdr());
            let mut c = Cdr::new();
            c.header(t).strings(&["a", "b"]);
            c.point(&[x + 0.5, 10.5 + x], &[0.2, 2.0], &[0.3, 3.0]); // reference (effort = feed-forward)
            c.point(&[x, 10.0 + x], &[0.1, 1.0], &[]); // feedback
            c.point(&[0.5, 0.5], &[], &[]); // error
            c.point(&[], &[], &[7.0 + x, 8.0 + x]); // output
            bag.publish("/arm_controller/controller_state", "control_msgs/msg/JointTrajectoryControllerState", JTCS_DEFINITION, t + 2000, &c.0);
            if k % 2 == 0 {
                // commands: no header, log time half a period after the state
                let mut c = Cdr::new();
                c.u32(0).u32(0).f64s(&[-x, -10.0 - x]);
                bag.publish("/effort_controller/commands", "std_msgs/msg/Float64MultiArray", FLOAT64_MULTI_ARRAY_DEFINITION, t + DT / 2, &c.0);
            }
            let mut m = JointState { name: names(&["a", "b"]), effort: vec![0.9 * x, 1.1 * x], ..JointState::default() };
            m.set_stamp_ns(t);
            bag.publish("/robot/effort", "sensor_msgs/msg/JointState", JOINT_STATE_DEFINITION, t + 3000, &m.encode_cdr());
        }
        bag.finish();
    }
}

fn teleop_topics() -> TopicMap {
    TopicMap::parse("states=/robot/arm/joint_states,reference=/arm_controller/controller_state,effort=/effort_controller/commands[a;b],measured_effort=/robot/effort").unwrap()
}

#[test]
fn bag_folder_with_controller_topics_maps_every_role_by_name() {
    let dir = tmp("teleop");
    teleop_bag(&dir, 40);
    let options = LogOptions { topics: teleop_topics(), ..LogOptions::default() };
    let run = read_log(&dir, &options).unwrap();
    assert_eq!(run.joints, names(&["b", "a"]), "the states' order");
    assert_eq!(run.len(), 40, "both files of the split bag");
    assert_eq!(run.start_ns, Some(T0));
    assert_eq!(run.t[0], 0.0);
    assert!((run.t[39] - 39.0 * 0.002).abs() < 1e-12);
    for k in 0..40 {
        let x = k as f64;
        assert_eq!(run.row(&run.q, k), &[10.0 + x, x]);
        assert_eq!(run.row(&run.q_ref, k), &[10.5 + x, x + 0.5], "reference by name from joint_names");
        assert_eq!(run.row(&run.qd_ref, k), &[2.0, 0.2]);
        assert_eq!(run.row(&run.tau_ff, k), &[3.0, 0.3], "feed-forward is the reference's effort");
        // the command published half a period after an even sample holds until the next one
        let cmd = if k % 2 == 0 { (k as f64 - 2.0).max(0.0) } else { k as f64 - 1.0 };
        assert_eq!(run.row(&run.tau, k), &[-10.0 - cmd, -cmd], "zero-order hold of the commands at sample {k}");
        assert_eq!(run.row(&run.tau_measured, k), &[1.1 * x, 0.9 * x]);
    }
    // the controller state's output as the commanded effort
    let mut topics = teleop_topics();
    topics.effort = Some(simgap_log::TopicSpec::new("/arm_controller/controller_state"));
    let run = read_log(&dir, &LogOptions { topics, ..LogOptions::default() }).unwrap();
    assert_eq!(run.row(&run.tau, 3), &[11.0, 10.0]);
    // the controller state as the states: feedback positions, output effort
    let topics = TopicMap::parse("states=/arm_controller/controller_state").unwrap();
    let run = read_log(&dir, &LogOptions { topics, ..LogOptions::default() }).unwrap();
    assert_eq!(run.joints, names(&["a", "b"]));
    assert_eq!((run.row(&run.q, 2), run.row(&run.tau, 2)), (&[2.0, 12.0][..], &[9.0, 10.0][..]));
}

#[test]
fn unmapped_or_unnamed_topics_are_errors_that_say_what_to_do() {
    let dir = tmp("teleop_errors");
    teleop_bag(&dir, 6);
    let e = read_log(&dir, &LogOptions::default()).unwrap_err().to_string();
    assert!(e.contains("no /joint_states messages") && e.contains("/robot/arm/joint_states"), "{e}");
    let topics = TopicMap::parse("states=/robot/arm/joint_states,effort=/effort_controller/commands").unwrap();
    let e = read_log(&dir, &LogOptions { topics, ..LogOptions::default() }).unwrap_err().to_string();
    assert!(e.contains("has no joint names") && e.contains("effort=/effort_controller/commands[joint1;joint2]"), "{e}");
    // a sqlite3 bag
    let db = tmp("sqlite_bag");
    std::fs::create_dir_all(&db).unwrap();
    std::fs::write(db.join("metadata.yaml"), "rosbag2_bagfile_information:\n  storage_identifier: sqlite3\n  relative_file_paths:\n  - x.db3\n").unwrap();
    let e = read_log(&db, &LogOptions::default()).unwrap_err().to_string();
    assert!(e.contains("sqlite3") && e.contains("convert"), "{e}");
}

#[test]
fn every_log_carries_its_own_experiment_and_the_fallback_fills_the_rest() {
    let fallback = experiment(ControllerKind::Replay);
    let options = LogOptions { topics: teleop_topics(), experiment: Some(fallback.clone()), ..LogOptions::default() };
    // every log beside its sidecar, in one folder
    let folder = common::folder();
    let tmp = |name: &str| folder.path().join(name);
    // a bag folder with a sidecar beside it
    let dir = tmp("with_sidecar");
    teleop_bag(&dir, 6);
    write_experiment_file(&experiment(ControllerKind::Pd), &tmp("with_sidecar.experiment.json")).unwrap();
    assert_eq!(read_log(&dir, &options).unwrap().experiment.unwrap().controller, ControllerKind::Pd);
    // a bag without: the fallback
    let dir = tmp("without_sidecar");
    teleop_bag(&dir, 6);
    assert_eq!(read_log(&dir, &options).unwrap().experiment, Some(fallback.clone()));
    // an MCAP file: metadata first, then its sidecar, then the fallback
    let options = LogOptions { experiment: Some(fallback.clone()), ..LogOptions::default() };
    let mut run = Run::new(names(&["a", "b"]));
    run.t = vec![0.0, 0.002];
    run.q = vec![0.0; 4];
    run.qd = vec![0.0; 4];
    run.experiment = Some(experiment(ControllerKind::PdGravity));
    let with_meta = tmp("with_meta.mcap");
    write_log(&run, &with_meta).unwrap();
    write_experiment_file(&experiment(ControllerKind::Pd), &tmp("with_meta.experiment.json")).unwrap();
    assert_eq!(read_log(&with_meta, &options).unwrap().experiment.unwrap().controller, ControllerKind::PdGravity);
    run.experiment = None;
    let sidecar_only = tmp("sidecar_only.mcap");
    write_log(&run, &sidecar_only).unwrap();
    write_experiment_file(&experiment(ControllerKind::Pd), &tmp("sidecar_only.experiment.json")).unwrap();
    assert_eq!(read_log(&sidecar_only, &options).unwrap().experiment.unwrap().controller, ControllerKind::Pd);
    let bare = tmp("bare.mcap");
    write_log(&run, &bare).unwrap();
    assert_eq!(read_log(&bare, &options).unwrap().experiment, Some(fallback));
}

#[test]
fn absolute_stamps_survive_read_and_write_to_the_nanosecond() {
    // the logs written are read again below: one folder
    let folder = common::folder();
    let tmp = |name: &str| folder.path().join(name);
    let dir = tmp("stamps");
    teleop_bag(&dir, 30);
    let options = LogOptions { topics: teleop_topics(), ..LogOptions::default() };
    let run = read_log(&dir, &options).unwrap();
    // written again (every channel) and read back: the same stamps, values and torques
    for name in ["again.mcap", "again.csv"] {
        let path = tmp(name);
        write_log(&run, &path).unwrap();
        let back = read_log(&path, &LogOptions::default()).unwrap();
        assert_eq!(back.start_ns, Some(T0), "{name}");
        let ns = |r: &Run| -> Vec<i64> { r.t.iter().map(|t| r.start_ns.unwrap() + (t * 1e9).round() as i64).collect() };
        assert_eq!(ns(&back), (0..30).map(|k| T0 + k * DT).collect::<Vec<_>>(), "{name}: stamps to the nanosecond");
        assert_eq!((&back.q, &back.q_ref, &back.tau_ff, &back.tau_measured, &back.tau), (&run.q, &run.q_ref, &run.tau_ff, &run.tau_measured, &run.tau), "{name}");
    }
    // the stamps in the written file are the originals, as integers
    let bytes = std::fs::read(tmp("again.mcap")).unwrap();
    let stamps: Vec<u64> = mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(Result::unwrap)
        .filter(|m| m.channel.topic == "/joint_states")
        .map(|m| {
            let s = JointState::decode_cdr(&m.data).unwrap();
            assert_eq!(s.stamp_ns() as u64, m.log_time);
            m.log_time
        })
        .collect();
    assert_eq!(stamps, (0..30).map(|k| (T0 + k * DT) as u64).collect::<Vec<_>>());
    let topics: std::collections::BTreeSet<String> = mcap::MessageStream::new(&bytes).unwrap().map(|m| m.unwrap().channel.topic.clone()).collect();
    assert_eq!(topics.into_iter().collect::<Vec<_>>(), names(&["/joint_effort_measured", "/joint_reference", "/joint_states"]));
}

#[test]
fn a_recovered_bag_warns_with_what_it_recovered() {
    let dir = tmp("recovered_bag");
    teleop_bag(&dir, 40);
    // the recorder was killed while writing the second file: cut it before its summary
    let second = dir.join("teleop_1.mcap");
    let bytes = std::fs::read(&second).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    let data_end = summary.chunk_indexes.iter().map(|c| c.chunk_start_offset + c.chunk_length).max().unwrap();
    std::fs::write(&second, &bytes[..data_end as usize]).unwrap();
    let read = read_log_with_warnings(&dir, &LogOptions { topics: teleop_topics(), ..LogOptions::default() }).unwrap();
    assert_eq!(read.run.len(), 40, "every complete chunk is kept");
    let w = read.warnings.join("; ");
    assert!(w.contains("teleop_1.mcap") && w.contains("no summary") && w.contains("40 samples over 0.078 s"), "{w}");
}

#[test]
fn a_servo_bag_maps_its_duty_torque_enable_and_temperature_topics_by_role() {
    // a servo's signals on topics of their own: JointState efforts (duty, temperature) and a
    // Float64MultiArray without names (the torque enable, named in the map)
    let path = tmp("servo.mcap");
    let mut bag = BagFile::new(&path);
    for k in 0..20i64 {
        let t = T0 + k * DT;
        let x = k as f64;
        let mut js = JointState { name: names(&["a", "b"]), position: vec![0.01 * x, -0.01 * x], velocity: vec![0.5, -0.5], ..JointState::default() };
        js.set_stamp_ns(t);
        bag.publish("/servo/states", "sensor_msgs/msg/JointState", JOINT_STATE_DEFINITION, t, &js.encode_cdr());
        let mut duty = JointState { name: names(&["b", "a"]), effort: vec![-0.02 * x, 0.03 * x], ..JointState::default() };
        duty.set_stamp_ns(t);
        bag.publish("/servo/pwm", "sensor_msgs/msg/JointState", JOINT_STATE_DEFINITION, t, &duty.encode_cdr());
        let mut temp = JointState { name: names(&["a", "b"]), effort: vec![30.0 + 0.1 * x, 31.0], ..JointState::default() };
        temp.set_stamp_ns(t);
        bag.publish("/servo/temperature", "sensor_msgs/msg/JointState", JOINT_STATE_DEFINITION, t, &temp.encode_cdr());
        let mut c = Cdr::new();
        c.u32(0).u32(0).f64s(&[if k < 10 { 1.0 } else { 0.0 }, 1.0]);
        bag.publish("/servo/torque_enable", "std_msgs/msg/Float64MultiArray", FLOAT64_MULTI_ARRAY_DEFINITION, t, &c.0);
    }
    bag.finish();
    let topics = TopicMap::parse("states=/servo/states,duty=/servo/pwm,torque_enable=/servo/torque_enable[a;b],temperature=/servo/temperature").unwrap();
    let run = read_log(&path, &LogOptions { topics, ..LogOptions::default() }).unwrap();
    for k in 0..20 {
        let x = k as f64;
        assert_eq!(run.row(&run.drive.duty, k), &[0.03 * x, -0.02 * x], "duty by joint name at sample {k}");
        assert_eq!(run.row(&run.drive.torque_enable, k), &[if k < 10 { 1.0 } else { 0.0 }, 1.0]);
        assert_eq!(run.row(&run.drive.temperature, k), &[30.0 + 0.1 * x, 31.0]);
    }
    assert!(run.tau.is_empty(), "a servo logs no torque");
    assert!(run.drive.voltage.is_empty(), "no voltage role mapped: the experiment's supply voltage drives it");
}

#[test]
fn a_servo_bag_maps_its_supply_voltage_by_role_from_any_one_value_message() {
    // the voltage on a topic of its own, at half the state rate (interpolated onto the state
    // stamps), as a std_msgs/msg/Float64, a one-element Float64MultiArray, or a JointState with
    // one effort; a message with two values is refused
    const FLOAT64_DEFINITION: &str = "float64 data\n";
    let volts = |k: i64| 5.0 - 0.01 * k as f64;
    for (kind, n_values) in [("float64", 1), ("array", 1), ("joint_state", 1), ("array", 2)] {
        let path = tmp(&format!("servo_voltage_{kind}_{n_values}.mcap"));
        let mut bag = BagFile::new(&path);
        for k in 0..20i64 {
            let t = T0 + k * DT;
            let mut js = JointState { name: names(&["a", "b"]), position: vec![0.0, 0.0], velocity: vec![0.0, 0.0], ..JointState::default() };
            js.set_stamp_ns(t);
            bag.publish("/servo/states", "sensor_msgs/msg/JointState", JOINT_STATE_DEFINITION, t, &js.encode_cdr());
            if k % 2 != 0 {
                continue;
            }
            let values = vec![volts(k); n_values];
            match kind {
                "float64" => {
                    let mut c = Cdr::new();
                    c.align(8);
                    c.0.extend_from_slice(&volts(k).to_le_bytes());
                    bag.publish("/servo/voltage", "std_msgs/msg/Float64", FLOAT64_DEFINITION, t, &c.0);
                }
                "array" => {
                    let mut c = Cdr::new();
                    c.u32(0).u32(0).f64s(&values);
                    bag.publish("/servo/voltage", "std_msgs/msg/Float64MultiArray", FLOAT64_MULTI_ARRAY_DEFINITION, t, &c.0);
                }
                _ => {
                    let mut v = JointState { name: names(&["bus"]), effort: values, ..JointState::default() };
                    v.set_stamp_ns(t);
                    bag.publish("/servo/voltage", "sensor_msgs/msg/JointState", JOINT_STATE_DEFINITION, t, &v.encode_cdr());
                }
            }
        }
        bag.finish();
        let topics = TopicMap::parse("states=/servo/states,voltage=/servo/voltage").unwrap();
        assert_eq!(TopicMap::parse(&topics.to_string()).unwrap(), topics);
        let read = read_log(&path, &LogOptions { topics, ..LogOptions::default() });
        if n_values != 1 {
            let e = read.unwrap_err().to_string();
            assert!(e.contains("/servo/voltage") && e.contains("one value") && e.contains("this one 2"), "{e}");
            continue;
        }
        let run = read.unwrap_or_else(|e| panic!("{kind}: {e}"));
        assert_eq!(run.drive.voltage.len(), 20, "{kind}: one voltage per state sample");
        for (k, v) in run.drive.voltage.iter().enumerate() {
            // the last state is past the last voltage message: held
            let want = volts((k as i64).min(18));
            assert!((v - want).abs() < 1e-12, "{kind}: voltage at sample {k} is {v}, expected {want}");
        }
    }
}
