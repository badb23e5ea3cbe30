//! ROS 2 MCAP logs: round trips, name mapping, publisher merging, compression, failed runs,
//! and errors that name the file and the problem.

use std::collections::BTreeMap;
use std::path::Path;

use mcap::records::{MessageHeader, Metadata};
use simgap_log::mcap::{JointState, McapSink, EXPERIMENT_METADATA, JOINT_REFERENCE_TOPIC, JOINT_STATES_TOPIC, JOINT_STATE_DEFINITION, JOINT_STATE_SCHEMA, RUN_END_METADATA};
use simgap_log::{read_log_for, write_log, Compression, Error, LogOptions, SinkOptions};
use simgap_sim::{reorder_joints, validate_run, ControllerKind, Experiment, MemorySink, Run, RunEnd, Sample, Sink};

mod common;
use common::tmp;

fn read_mcap(path: &Path) -> simgap_log::Result<Run> {
    simgap_log::read_log(path, &LogOptions::default())
}

fn read_log(path: &Path) -> simgap_log::Result<Run> {
    simgap_log::read_log(path, &LogOptions::default())
}

fn read_mcap_for(path: &Path, joints: &[String]) -> simgap_log::Result<Run> {
    read_log_for(path, joints, false, &LogOptions::default())
}

fn names(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

fn experiment() -> Experiment {
    Experiment {
        controller: ControllerKind::PdGravity,
        joints: names(&["elbow", "shoulder"]),
        kp: vec![32.36, 64.72],
        kv: vec![6.472, 48.54],
        sample_period: 0.0025,
        extra: BTreeMap::from([("robot".to_string(), "paper arm".to_string()), ("note".to_string(), "a=b, c".to_string())]),
    }
}

/// A run with every channel, absolute times and awkward numbers.
fn sample_run(n: usize) -> Run {
    let joints = names(&["shoulder", "elbow", "wrist"]);
    let mut run = Run::new(joints);
    run.start_ns = Some(1_700_000_000_123_456_789);
    for k in 0..n {
        let t = k as f64 * 0.0025;
        run.t.push(t);
        for j in 0..3 {
            let x = k as f64 * 0.01 + j as f64;
            run.q.push(x.sin() / 3.0);
            run.qd.push(x.cos() * 1e-7);
            run.tau.push(-x * 12.345_678_901_234_567);
            run.q_ref.push(std::f64::consts::FRAC_PI_4 * j as f64);
            run.qd_ref.push(if k % 2 == 0 { 0.0 } else { -0.1 / 3.0 });
        }
    }
    run.experiment = Some(experiment());
    run
}

/// Compares runs field by field; times within 1 ns (the stamp resolution), the rest exactly.
fn assert_same_run(a: &Run, b: &Run) {
    assert_eq!(a.joints, b.joints);
    assert_eq!(a.len(), b.len());
    for (x, y) in a.t.iter().zip(&b.t) {
        assert!((x - y).abs() <= 1e-9 * x.abs().max(1.0), "time {x} vs {y}");
    }
    assert_eq!(a.q, b.q, "q");
    assert_eq!(a.qd, b.qd, "qd");
    assert_eq!(a.tau, b.tau, "tau");
    assert_eq!(a.q_ref, b.q_ref, "q_ref");
    assert_eq!(a.qd_ref, b.qd_ref, "qd_ref");
    assert_eq!(a.experiment, b.experiment, "experiment");
}

fn message_text(e: &Error) -> String {
    e.to_string()
}

fn assert_error_names(result: simgap_log::Result<Run>, path: &Path, needle: &str) {
    let e = result.expect_err("expected an error");
    let m = message_text(&e);
    assert!(m.contains(&path.display().to_string()), "error '{m}' does not name the file {}", path.display());
    assert!(m.contains(needle), "error '{m}' does not say '{needle}'");
}

/// A hand-made bag: JointState messages on topics, written with the mcap crate's writer.
struct Bag {
    writer: mcap::Writer<std::io::BufWriter<std::fs::File>>,
    schema: u16,
    channels: BTreeMap<(String, u16), u16>,
}

impl Bag {
    fn new(path: &Path, options: mcap::WriteOptions) -> Bag {
        let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
        let mut writer = options.profile("ros2").create(file).unwrap();
        let schema = writer.add_schema(JOINT_STATE_SCHEMA, "ros2msg", JOINT_STATE_DEFINITION.as_bytes()).unwrap();
        Bag { writer, schema, channels: BTreeMap::new() }
    }

    /// Publisher `publisher` gets its own channel (rosbag2 writes one per topic and type, other
    /// recorders one per publisher: both must work).
    fn publish(&mut self, topic: &str, publisher: u16, stamp_ns: i64, log_ns: u64, msg: JointState) {
        let key = (topic.to_string(), publisher);
        let schema = self.schema;
        let writer = &mut self.writer;
        let id = *self.channels.entry(key).or_insert_with(|| {
            let meta = BTreeMap::from([("offered_qos_profiles".to_string(), String::new()), ("publisher".to_string(), publisher.to_string())]);
            writer.add_channel(schema, topic, "cdr", &meta).unwrap()
        });
        let mut msg = msg;
        msg.set_stamp_ns(stamp_ns);
        let header = MessageHeader { channel_id: id, sequence: 0, log_time: log_ns, publish_time: log_ns };
        self.writer.write_to_known_channel(&header, &msg.encode_cdr()).unwrap();
    }

    fn metadata(&mut self, name: &str, map: BTreeMap<String, String>) {
        self.writer.write_metadata(&Metadata { name: name.into(), metadata: map }).unwrap();
    }

    fn finish(mut self) {
        self.writer.finish().unwrap();
    }
}

fn js(joints: &[&str], position: &[f64], velocity: &[f64], effort: &[f64]) -> JointState {
    JointState { name: names(joints), position: position.to_vec(), velocity: velocity.to_vec(), effort: effort.to_vec(), ..JointState::default() }
}

const T0: i64 = 1_712_345_678_000_000_000;
const DT: i64 = 2_500_000;

// ---------------------------------------------------------------------------------------------
// CDR

#[test]
fn cdr_joint_state_has_the_ros2_byte_layout() {
    let msg = JointState { sec: 1, nanosec: 2, frame_id: String::new(), name: names(&["a"]), position: vec![1.0], ..JointState::default() };
    let bytes = msg.encode_cdr();
    let mut expected = vec![0x00, 0x01, 0x00, 0x00]; // encapsulation: CDR little-endian
    expected.extend_from_slice(&[1, 0, 0, 0, 2, 0, 0, 0]); // stamp
    expected.extend_from_slice(&[1, 0, 0, 0, 0]); // frame_id "" (length 1 with the NUL)
    expected.extend_from_slice(&[0, 0, 0]); // align to 4
    expected.extend_from_slice(&[1, 0, 0, 0]); // one name
    expected.extend_from_slice(&[2, 0, 0, 0, b'a', 0]); // "a"
    expected.extend_from_slice(&[0, 0]); // align to 4
    expected.extend_from_slice(&[1, 0, 0, 0]); // one position (offset 28, already 8-aligned at 32)
    expected.extend_from_slice(&1.0f64.to_le_bytes());
    expected.extend_from_slice(&[0, 0, 0, 0, 0, 0, 0, 0]); // empty velocity, empty effort
    assert_eq!(bytes, expected);
    assert_eq!(JointState::decode_cdr(&bytes).unwrap(), msg);
}

#[test]
fn cdr_round_trips_and_reads_big_endian() {
    let msg = JointState {
        sec: -2,
        nanosec: 300_000_000,
        frame_id: "base_link".into(),
        name: names(&["j1", "joint_two", "x"]),
        position: vec![1.5, -0.0, f64::MAX],
        velocity: vec![0.1, 0.2, 0.3],
        effort: vec![],
    };
    assert_eq!(JointState::decode_cdr(&msg.encode_cdr()).unwrap(), msg);
    // a big-endian message: the same fields, byte-swapped, header 00 00
    let msg = js(&["q"], &[2.0], &[], &[3.0]);
    let mut be = vec![0x00, 0x00, 0x00, 0x00];
    be.extend_from_slice(&[0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0]); // stamp, frame_id "", pad
    be.extend_from_slice(&[0, 0, 0, 1, 0, 0, 0, 2, b'q', 0, 0, 0]); // names
    be.extend_from_slice(&[0, 0, 0, 1]); // positions at 24, 8-aligned
    be.extend_from_slice(&2.0f64.to_be_bytes());
    be.extend_from_slice(&[0, 0, 0, 0, 0, 0, 0, 1]); // velocity empty, effort count (48: aligned)
    be.extend_from_slice(&3.0f64.to_be_bytes());
    assert_eq!(JointState::decode_cdr(&be).unwrap(), msg);
}

#[test]
fn cdr_truncated_message_names_the_field() {
    let bytes = js(&["a", "b"], &[1.0, 2.0], &[3.0, 4.0], &[]).encode_cdr();
    let e = JointState::decode_cdr(&bytes[..bytes.len() - 12]).unwrap_err();
    assert!(e.0.contains("velocity"), "{e}");
}

// ---------------------------------------------------------------------------------------------
// round trips and failed runs

#[test]
fn log_written_and_read_back_is_identical() {
    let run = sample_run(500);
    validate_run(&run).unwrap();
    let path = tmp("roundtrip.mcap");
    write_log(&run, &path).unwrap();
    let back = read_log(&path).unwrap();
    assert_same_run(&run, &back);
    assert_eq!(back.source, path.display().to_string());
    // again through the file: a log of the log is the same log
    let path2 = tmp("roundtrip2.mcap");
    write_log(&back, &path2).unwrap();
    assert_eq!(read_mcap(&path2).unwrap(), back.clone_with_source(&path2));
}

trait WithSource {
    fn clone_with_source(&self, path: &Path) -> Run;
}

impl WithSource for Run {
    fn clone_with_source(&self, path: &Path) -> Run {
        let mut r = self.clone();
        r.source = path.display().to_string();
        r
    }
}

#[test]
fn run_without_reference_effort_or_experiment_round_trips() {
    let mut run = sample_run(50);
    run.q_ref.clear();
    run.qd_ref.clear();
    run.tau.clear();
    run.experiment = None;
    let path = tmp("bare.mcap");
    write_log(&run, &path).unwrap();
    let back = read_mcap(&path).unwrap();
    assert_same_run(&run, &back);
    // reference without velocity: empty qd_ref (zero)
    let mut run = sample_run(20);
    run.qd_ref.clear();
    let path = tmp("ref_no_vel.mcap");
    write_log(&run, &path).unwrap();
    assert_same_run(&run, &read_mcap(&path).unwrap());
}

fn drive(sink: &mut dyn Sink, run: &Run) {
    sink.begin(&run.joints, run.experiment.as_ref().unwrap()).unwrap();
    let n = run.dof();
    for k in 0..run.len() {
        let r = |m: &[f64]| m[k * n..(k + 1) * n].to_vec();
        let (q, qd, tau, q_ref, qd_ref) = (r(&run.q), r(&run.qd), r(&run.tau), r(&run.q_ref), r(&run.qd_ref));
        sink.record(&Sample { t: run.t[k], q: &q, qd: &qd, tau: &tau, q_ref: &q_ref, qd_ref: &qd_ref, drive: None }).unwrap();
    }
}

/// The run-end metadata record, and the topics of the file (every one a CDR JointState).
fn run_end_of(path: &Path) -> (BTreeMap<String, String>, Vec<String>) {
    let bytes = std::fs::read(path).unwrap();
    let summary = mcap::Summary::read(&bytes).unwrap().expect("a finished file has a summary");
    let mut meta = None;
    for index in &summary.metadata_indexes {
        let m = mcap::read::metadata(&bytes, index).unwrap();
        if m.name == RUN_END_METADATA {
            meta = Some(m.metadata);
        }
    }
    let mut topics = Vec::new();
    for c in summary.channels.values() {
        assert_eq!(c.message_encoding, "cdr", "{}", c.topic);
        let s = c.schema.as_ref().expect("a schema");
        assert_eq!((s.name.as_str(), s.encoding.as_str()), (JOINT_STATE_SCHEMA, "ros2msg"), "{}", c.topic);
        topics.push(c.topic.clone());
    }
    topics.sort();
    (meta.expect("run-end metadata"), topics)
}

#[test]
fn mcap_sink_matches_memory_sink_and_records_the_end() {
    let run = sample_run(300);
    let path = tmp("sink.mcap");
    let mut memory = MemorySink::new();
    drive(&mut memory, &run);
    memory.finish(&RunEnd::Completed).unwrap();
    let mut sink = McapSink::create(&path).unwrap();
    drive(&mut sink, &run);
    sink.finish(&RunEnd::Completed).unwrap();
    assert_same_run(&memory.into_run(), &read_mcap(&path).unwrap());
    let (meta, topics) = run_end_of(&path);
    assert_eq!(meta["status"], "completed");
    assert_eq!(topics, vec![JOINT_REFERENCE_TOPIC.to_string(), JOINT_STATES_TOPIC.to_string()], "no channel but the JointStates");
}

#[test]
fn diverged_run_leaves_a_readable_mcap() {
    let run = sample_run(100);
    let path = tmp("diverged.mcap");
    let mut sink = McapSink::create(&path).unwrap();
    drive(&mut sink, &run);
    sink.finish(&RunEnd::Diverged { t: run.t[99], joint: "elbow".into() }).unwrap();
    sink.finish(&RunEnd::Completed).unwrap(); // a second finish is harmless
    drop(sink);
    let back = read_mcap(&path).unwrap();
    assert_same_run(&run, &back);
    let (meta, _) = run_end_of(&path);
    assert_eq!(meta["status"], "diverged");
    assert_eq!(meta["joint"], "elbow");
    let warned = simgap_log::read_log_with_warnings(&path, &LogOptions::default()).unwrap().warnings;
    assert!(warned.iter().any(|w| w.contains("diverged") && w.contains("elbow")), "{warned:?}");
}

#[test]
fn sink_dropped_without_finish_still_leaves_a_readable_mcap() {
    let run = sample_run(80);
    let path = tmp("dropped.mcap");
    {
        let mut sink = McapSink::create(&path).unwrap();
        drive(&mut sink, &run);
        // an early return or a panic: no finish
    }
    let back = read_mcap(&path).unwrap();
    assert_same_run(&run, &back);
    assert_eq!(run_end_of(&path).0["status"], "interrupted");

    // and across a panic
    let path = tmp("panicked.mcap");
    let run2 = run.clone();
    let p = path.to_path_buf();
    let result = std::panic::catch_unwind(move || {
        let mut sink = McapSink::create(&p).unwrap();
        drive(&mut sink, &run2);
        panic!("controller blew up");
    });
    assert!(result.is_err());
    assert_same_run(&run, &read_mcap(&path).unwrap());
}

#[test]
fn lz4_zstd_uncompressed_and_unchunked_files_all_read() {
    let run = sample_run(2000);
    let options = [
        ("zstd", SinkOptions { compression: Compression::Zstd, chunk_size: 16 * 1024 }),
        ("lz4", SinkOptions { compression: Compression::Lz4, chunk_size: 16 * 1024 }),
        ("none", SinkOptions { compression: Compression::None, chunk_size: 16 * 1024 }),
    ];
    for (name, opts) in options {
        let path = tmp(&format!("compression_{name}.mcap"));
        let mut sink = McapSink::create_with_options(&path, opts).unwrap();
        drive(&mut sink, &run);
        sink.finish(&RunEnd::Completed).unwrap();
        drop(sink);
        // the chunks really are compressed as asked
        let bytes = std::fs::read(&path).unwrap();
        let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
        let compressions: Vec<&str> = summary.chunk_indexes.iter().map(|c| c.compression.as_str()).collect();
        match name {
            "zstd" | "lz4" => assert!(compressions.len() > 1 && compressions.iter().all(|c| *c == name), "{name}: {compressions:?}"),
            _ => assert!(compressions.len() > 1 && compressions.iter().all(|c| c.is_empty())),
        }
        assert_same_run(&run, &read_mcap(&path).unwrap());
    }
    // files of other writers: one chunk, or no chunks at all
    for (name, opts) in [("one_chunk", mcap::WriteOptions::new().compression(None)), ("unchunked", mcap::WriteOptions::new().use_chunks(false))] {
        let path = tmp(&format!("compression_{name}.mcap"));
        let mut bag = Bag::new(&path, opts);
        for k in 0..run.len() {
            let r = |m: &[f64]| m[k * 3..(k + 1) * 3].to_vec();
            let msg = JointState { name: run.joints.clone(), position: r(&run.q), velocity: r(&run.qd), effort: r(&run.tau), ..JointState::default() };
            bag.publish(JOINT_STATES_TOPIC, 0, T0 + k as i64 * DT, 0, msg);
        }
        bag.finish();
        assert_eq!(read_mcap(&path).unwrap().len(), run.len(), "{name}");
    }
}

// ---------------------------------------------------------------------------------------------
// other people's bags: names, publishers, stamps

#[test]
fn joints_in_a_different_order_per_message_map_by_name() {
    let path = tmp("shuffled.mcap");
    let mut bag = Bag::new(&path, mcap::WriteOptions::new());
    for k in 0..10i64 {
        let t = T0 + k * DT;
        let x = k as f64;
        // joint value = 10 * joint index + k, whatever the order in the message
        let msg = if k % 2 == 0 {
            js(&["b", "a", "c"], &[10.0 + x, x, 20.0 + x], &[1.0, 0.0, 2.0], &[-1.0, -0.0, -2.0])
        } else {
            js(&["c", "b", "a"], &[20.0 + x, 10.0 + x, x], &[2.0, 1.0, 0.0], &[-2.0, -1.0, -0.0])
        };
        bag.publish(JOINT_STATES_TOPIC, 0, t, 0, msg);
        bag.publish(JOINT_REFERENCE_TOPIC, 0, t, 0, js(&["a", "c", "b"], &[100.0, 120.0, 110.0], &[], &[]));
    }
    bag.finish();
    let run = read_mcap(&path).unwrap();
    assert_eq!(run.joints, names(&["b", "a", "c"]), "order of the first message");
    for k in 0..10 {
        let x = k as f64;
        assert_eq!(run.row(&run.q, k), &[10.0 + x, x, 20.0 + x]);
        assert_eq!(run.row(&run.qd, k), &[1.0, 0.0, 2.0]);
        assert_eq!(run.row(&run.tau, k), &[-1.0, -0.0, -2.0]);
        assert_eq!(run.row(&run.q_ref, k), &[110.0, 100.0, 120.0]);
    }
    assert!(run.qd_ref.is_empty());
    assert_eq!(run.start_ns, Some(T0), "absolute start kept to the nanosecond");
    assert_eq!(run.t[0], 0.0, "t is time since the start");
    assert!((run.duration() - 9.0 * 0.0025).abs() < 1e-6);

    // in a model's order
    let model = names(&["a", "b", "c"]);
    let ordered = read_mcap_for(&path, &model).unwrap();
    assert_eq!(ordered.row(&ordered.q, 3), &[3.0, 13.0, 23.0]);
    assert_eq!(ordered.row(&ordered.q_ref, 3), &[100.0, 110.0, 120.0]);
    match read_mcap_for(&path, &names(&["a", "b", "c", "d"])) {
        Err(Error::Run(simgap_sim::Error::JointMismatch { joint, source_name, problem })) => {
            assert_eq!(joint, "d");
            assert_eq!(source_name, path.display().to_string());
            assert!(problem.contains("not in the log"), "{problem}");
        }
        other => panic!("expected JointMismatch, got {other:?}"),
    }
    match read_mcap_for(&path, &names(&["a", "b"])) {
        Err(Error::Run(simgap_sim::Error::JointMismatch { joint, problem, .. })) => {
            assert_eq!(joint, "c");
            assert!(problem.contains("not in the model"), "{problem}");
        }
        other => panic!("expected JointMismatch, got {other:?}"),
    }
    let arm = reorder_joints(&run, &names(&["c", "a"]), true).unwrap();
    assert_eq!(arm.row(&arm.q, 2), &[22.0, 2.0]);
}

#[test]
fn several_publishers_merge_into_one_run() {
    let path = tmp("publishers.mcap");
    let mut bag = Bag::new(&path, mcap::WriteOptions::new().compression(Some(mcap::Compression::Lz4)));
    // the arm and the wrist publish separately at the same stamps, written out of order
    for k in (0..20i64).rev() {
        let t = T0 + k * DT;
        let x = k as f64;
        bag.publish(JOINT_STATES_TOPIC, 2, t, 5, js(&["wrist"], &[2.0 + x], &[0.2], &[0.02]));
        bag.publish(JOINT_STATES_TOPIC, 1, t, 5, js(&["elbow", "shoulder"], &[1.0 + x, x], &[0.1, 0.0], &[0.01, 0.0]));
    }
    bag.finish();
    // per publisher time goes backwards here: that is "time not monotonic"
    let e = read_mcap(&path).unwrap_err().to_string();
    assert!(e.contains("not monotonic"), "{e}");

    let path = tmp("publishers_ok.mcap");
    let mut bag = Bag::new(&path, mcap::WriteOptions::new().compression(Some(mcap::Compression::Lz4)));
    for k in 0..20i64 {
        let t = T0 + k * DT;
        let x = k as f64;
        // arrival order differs from stamp order between publishers
        if k % 3 == 0 {
            bag.publish(JOINT_STATES_TOPIC, 2, t, 0, js(&["wrist"], &[2.0 + x], &[0.2], &[0.02]));
            bag.publish(JOINT_STATES_TOPIC, 1, t, 0, js(&["elbow", "shoulder"], &[1.0 + x, x], &[0.1, 0.0], &[0.01, 0.0]));
        } else {
            bag.publish(JOINT_STATES_TOPIC, 1, t, 0, js(&["shoulder", "elbow"], &[x, 1.0 + x], &[0.0, 0.1], &[0.0, 0.01]));
            bag.publish(JOINT_STATES_TOPIC, 2, t, 0, js(&["wrist"], &[2.0 + x], &[0.2], &[0.02]));
        }
    }
    bag.finish();
    let run = read_mcap(&path).unwrap();
    assert_eq!(run.joints, names(&["wrist", "elbow", "shoulder"]));
    assert_eq!(run.len(), 20);
    for k in 0..20 {
        let x = k as f64;
        assert_eq!(run.row(&run.q, k), &[2.0 + x, 1.0 + x, x]);
        assert_eq!(run.row(&run.tau, k), &[0.02, 0.01, 0.0]);
    }

    // two publishers of the same joints at interleaved stamps merge into one time line
    let path = tmp("publishers_interleaved.mcap");
    let mut bag = Bag::new(&path, mcap::WriteOptions::new());
    for k in 0..10i64 {
        let t = T0 + 2 * k * DT;
        bag.publish(JOINT_STATES_TOPIC, 1, t + DT, 0, js(&["a"], &[(2 * k + 1) as f64], &[], &[]));
        bag.publish(JOINT_STATES_TOPIC, 2, t, 0, js(&["a"], &[(2 * k) as f64], &[], &[]));
    }
    bag.finish();
    let run = read_mcap(&path).unwrap();
    assert_eq!(run.q, (0..20).map(f64::from).collect::<Vec<_>>());
}

#[test]
fn zero_stamps_fall_back_to_log_time() {
    let path = tmp("log_time.mcap");
    let mut bag = Bag::new(&path, mcap::WriteOptions::new());
    for k in 0..5u64 {
        let mut msg = js(&["a"], &[k as f64], &[], &[]);
        msg.sec = 0;
        let header_stamp = 0;
        bag.publish(JOINT_STATES_TOPIC, 0, header_stamp, 1_000_000_000 + k * 10_000_000, msg);
    }
    bag.finish();
    let run = read_mcap(&path).unwrap();
    assert_eq!(run.start_ns, Some(1_000_000_000));
    for (k, t) in run.t.iter().enumerate() {
        assert!((t - 0.01 * k as f64).abs() < 1e-12, "{:?}", run.t);
    }
    // no velocities in the log: central differences, and the run says so
    assert!(run.qd.iter().all(|v| (v - 100.0).abs() < 1e-9), "{:?}", run.qd);
    assert!(run.source.contains("central difference"), "{}", run.source);
    assert!(run.tau.is_empty(), "no effort in the log: empty tau");
}

// ---------------------------------------------------------------------------------------------
// metadata

#[test]
fn missing_metadata_gives_no_experiment_and_malformed_metadata_is_an_error() {
    let write = |name: &str, meta: Option<BTreeMap<String, String>>| -> common::Scratch {
        let path = tmp(name);
        let mut bag = Bag::new(&path, mcap::WriteOptions::new());
        if let Some(m) = meta {
            bag.metadata(EXPERIMENT_METADATA, m);
        }
        bag.metadata("other", BTreeMap::from([("x".into(), "y".into())]));
        for k in 0..3 {
            bag.publish(JOINT_STATES_TOPIC, 0, T0 + k * DT, 0, js(&["a", "b"], &[0.0, 1.0], &[0.0, 0.0], &[1.0, 2.0]));
        }
        bag.finish();
        path
    };
    assert_eq!(read_mcap(&write("no_meta.mcap", None)).unwrap().experiment, None);

    let good = || -> BTreeMap<String, String> {
        [("controller", "pd"), ("joints", "b,a"), ("kp", "2,1"), ("kv", "0.2, 0.1"), ("sample_period", "0.002"), ("site", "lab 3")]
            .into_iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect()
    };
    let e = read_mcap(&write("meta.mcap", Some(good()))).unwrap().experiment.unwrap();
    assert_eq!(e.controller, ControllerKind::Pd);
    assert_eq!(e.joints, names(&["b", "a"]));
    assert_eq!(e.kp, vec![2.0, 1.0]);
    assert_eq!(e.kv, vec![0.2, 0.1]);
    assert_eq!(e.sample_period, 0.002);
    assert_eq!(e.extra["site"], "lab 3");

    let cases: [(&str, &str, Option<&str>, &str); 6] = [
        ("kp", "2,x", None, "'x' is not a number"),
        ("kv", "0.1", None, "1 gains for 2 joints"),
        ("controller", "pid", None, "unknown controller 'pid'"),
        ("sample_period", "-1", None, "positive"),
        ("joints", "b,z", None, "'z'"),
        ("kp", "", Some("kp"), "key 'kp' is missing"),
    ];
    for (i, (key, value, remove, needle)) in cases.into_iter().enumerate() {
        let mut m = good();
        m.insert(key.into(), value.into());
        if let Some(r) = remove {
            m.remove(r);
        }
        let path = write(&format!("bad_meta_{i}.mcap"), Some(m));
        assert_error_names(read_mcap(&path), &path, needle);
    }
}

// ---------------------------------------------------------------------------------------------
// errors

#[test]
fn truncated_mcap_is_recovered_up_to_its_last_complete_chunk() {
    let path = tmp("whole.mcap");
    let run = sample_run(3000);
    simgap_log::mcap::write::write_mcap_with_options(&run, &path, SinkOptions { chunk_size: 16 * 1024, ..SinkOptions::default() }).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let cut = tmp("half.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let read = simgap_log::read_log_with_warnings(&cut, &LogOptions::default()).unwrap();
    assert!(read.run.len() > 1000 && read.run.len() < 3000, "{}", read.run.len());
    assert_eq!(&read.run.q[..], &run.q[..read.run.q.len()], "what is recovered is what was written");
    let w = read.warnings.join("; ");
    assert!(w.contains("no summary") && w.contains(&format!("of {}", bytes.len() / 2)) && w.contains("samples over"), "{w}");
    // without its last 10 bytes (the footer cut): every message is still there
    let cut = tmp("no_footer.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() - 10]).unwrap();
    assert_eq!(read_mcap(&cut).unwrap().len(), 3000);
    // cut before any message: an error that says so
    let cut = tmp("header_only.mcap");
    std::fs::write(&cut, &bytes[..40]).unwrap();
    assert_error_names(read_log(&cut), &cut, "truncated");
}

#[test]
fn not_an_mcap_is_an_error_naming_the_file() {
    let path = tmp("text.mcap");
    std::fs::write(&path, "time,q_a\n0,1\n").unwrap();
    assert_error_names(read_mcap(&path), &path, "not an MCAP file");
    let path = tmp("missing.mcap");
    assert_error_names(read_mcap(&path), &path, "cannot open");
    let path = tmp("log.txt");
    std::fs::write(&path, "x").unwrap();
    assert_error_names(read_log(&path), &path, "unknown log format");
}

#[test]
fn no_joint_states_or_a_wrong_schema_is_an_error() {
    let path = tmp("no_states.mcap");
    let mut bag = Bag::new(&path, mcap::WriteOptions::new());
    bag.publish(JOINT_REFERENCE_TOPIC, 0, T0, 0, js(&["a"], &[0.0], &[], &[]));
    bag.finish();
    assert_error_names(read_mcap(&path), &path, "no /joint_states messages");

    let path = tmp("wrong_schema.mcap");
    {
        let file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
        let mut w = mcap::WriteOptions::new().create(file).unwrap();
        let s = w.add_schema("std_msgs/msg/String", "ros2msg", b"string data").unwrap();
        let c = w.add_channel(s, JOINT_STATES_TOPIC, "cdr", &BTreeMap::new()).unwrap();
        w.write_to_known_channel(&MessageHeader { channel_id: c, sequence: 0, log_time: 0, publish_time: 0 }, &[0, 1, 0, 0, 1, 0, 0, 0, 0]).unwrap();
        w.finish().unwrap();
    }
    assert_error_names(read_mcap(&path), &path, "/joint_states (std_msgs/String) has no joint names");
}

#[test]
fn nan_values_are_an_error_naming_joint_and_time() {
    let path = tmp("nan.mcap");
    let mut bag = Bag::new(&path, mcap::WriteOptions::new());
    bag.publish(JOINT_STATES_TOPIC, 0, T0, 0, js(&["a", "b"], &[0.0, 0.0], &[0.0, 0.0], &[]));
    bag.publish(JOINT_STATES_TOPIC, 0, T0 + DT, 0, js(&["a", "b"], &[0.0, 0.0], &[0.0, f64::NAN], &[]));
    bag.finish();
    assert_error_names(read_mcap(&path), &path, "velocity of joint 'b' is NaN");

    let mut run = sample_run(5);
    run.tau[7] = f64::INFINITY;
    let e = write_log(&run, &tmp("inf.mcap")).unwrap_err().to_string();
    assert!(e.contains("tau of joint 'elbow' is inf"), "{e}");
}

#[test]
fn non_monotonic_or_repeated_time_is_an_error() {
    let path = tmp("backwards.mcap");
    let mut bag = Bag::new(&path, mcap::WriteOptions::new());
    for k in [0, 1, 3, 2, 4] {
        bag.publish(JOINT_STATES_TOPIC, 0, T0 + k * DT, 0, js(&["a"], &[0.0], &[0.0], &[0.0]));
    }
    bag.finish();
    assert_error_names(read_mcap(&path), &path, "time is not monotonic for joint 'a'");

    let path = tmp("repeated.mcap");
    let mut bag = Bag::new(&path, mcap::WriteOptions::new());
    for k in [0, 1, 1, 2] {
        bag.publish(JOINT_STATES_TOPIC, 0, T0 + k * DT, 0, js(&["a"], &[0.0], &[0.0], &[0.0]));
    }
    bag.finish();
    assert_error_names(read_mcap(&path), &path, "joint 'a' is given twice at the same time");

    // two publishers giving the same joint at the same stamp
    let path = tmp("duplicate_publishers.mcap");
    let mut bag = Bag::new(&path, mcap::WriteOptions::new());
    bag.publish(JOINT_STATES_TOPIC, 1, T0, 0, js(&["a", "b"], &[0.0, 0.0], &[], &[]));
    bag.publish(JOINT_STATES_TOPIC, 2, T0, 0, js(&["b"], &[1.0], &[], &[]));
    bag.finish();
    assert_error_names(read_mcap(&path), &path, "joint 'b' is given twice at the same time");
}

#[test]
fn unknown_or_missing_joints_are_errors() {
    // a joint missing from some samples
    let path = tmp("missing_joint.mcap");
    let mut bag = Bag::new(&path, mcap::WriteOptions::new());
    bag.publish(JOINT_STATES_TOPIC, 0, T0, 0, js(&["a", "b"], &[0.0, 0.0], &[], &[]));
    bag.publish(JOINT_STATES_TOPIC, 0, T0 + DT, 0, js(&["a"], &[0.0], &[], &[]));
    bag.finish();
    assert_error_names(read_mcap(&path), &path, "joint 'b' is missing at t = ");

    // a reference joint that the states do not have, and a reference missing a joint
    let path = tmp("unknown_ref_joint.mcap");
    let mut bag = Bag::new(&path, mcap::WriteOptions::new());
    bag.publish(JOINT_STATES_TOPIC, 0, T0, 0, js(&["a"], &[0.0], &[], &[]));
    bag.publish(JOINT_REFERENCE_TOPIC, 0, T0, 0, js(&["a", "z"], &[0.0, 1.0], &[], &[]));
    bag.finish();
    assert_error_names(read_mcap(&path), &path, "joint 'z' is in /joint_reference but not in /joint_states");
    let path = tmp("short_ref.mcap");
    let mut bag = Bag::new(&path, mcap::WriteOptions::new());
    bag.publish(JOINT_STATES_TOPIC, 0, T0, 0, js(&["a", "b"], &[0.0, 0.0], &[], &[]));
    bag.publish(JOINT_REFERENCE_TOPIC, 0, T0, 0, js(&["a"], &[0.0], &[], &[]));
    bag.finish();
    assert_error_names(read_mcap(&path), &path, "/joint_reference: joint 'b' is missing");

    // arrays of the wrong length
    let path = tmp("ragged.mcap");
    let mut bag = Bag::new(&path, mcap::WriteOptions::new());
    bag.publish(JOINT_STATES_TOPIC, 0, T0, 0, js(&["a", "b"], &[0.0, 0.0], &[1.0], &[]));
    bag.finish();
    assert_error_names(read_mcap(&path), &path, "1 velocities for 2 joints");
}

#[test]
fn reference_at_other_times_is_interpolated_onto_the_states() {
    let path = tmp("ref_interp.mcap");
    let mut bag = Bag::new(&path, mcap::WriteOptions::new());
    for k in 0..11 {
        bag.publish(JOINT_STATES_TOPIC, 0, T0 + k * DT, 0, js(&["a"], &[0.0], &[0.0], &[0.0]));
    }
    for k in 0..3 {
        bag.publish(JOINT_REFERENCE_TOPIC, 0, T0 + 5 * k * DT, 0, js(&["a"], &[k as f64], &[2.0], &[]));
    }
    bag.finish();
    let run = read_mcap(&path).unwrap();
    let expected: Vec<f64> = (0..11).map(|k| k as f64 / 5.0).collect();
    for (a, b) in run.q_ref.iter().zip(&expected) {
        assert!((a - b).abs() < 1e-9, "{:?}", run.q_ref);
    }
    assert_eq!(run.qd_ref, vec![2.0; 11]);
}

/// A file whose JointState channel carries a schema of `name` with `definition`, three samples.
fn schema_named(path: &Path, name: &str, definition: &str) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut w = mcap::WriteOptions::new().profile("ros2").create(file).unwrap();
    let s = w.add_schema(name, "ros2msg", definition.as_bytes()).unwrap();
    let c = w.add_channel(s, JOINT_STATES_TOPIC, "cdr", &BTreeMap::new()).unwrap();
    for k in 0..3i64 {
        let mut m = js(&["a"], &[k as f64], &[0.0], &[0.0]);
        m.set_stamp_ns(T0 + k * DT);
        let h = MessageHeader { channel_id: c, sequence: 0, log_time: (T0 + k * DT) as u64, publish_time: 0 };
        w.write_to_known_channel(&h, &m.encode_cdr()).unwrap();
    }
    w.finish().unwrap();
}

#[test]
fn schema_whose_name_does_not_match_its_fields_is_read_with_a_warning_naming_both() {
    // another name, JointState's fields: read as JointState, with a word
    let path = tmp("renamed_joint_state.mcap");
    schema_named(&path, "my_robot_msgs/msg/ArmState", JOINT_STATE_DEFINITION);
    let read = simgap_log::read_log_with_warnings(&path, &LogOptions::default()).unwrap();
    assert_eq!(read.run.len(), 3);
    let w = read.warnings.join("; ");
    assert!(w.contains("'my_robot_msgs/msg/ArmState'") && w.contains("exactly those of sensor_msgs/msg/JointState") && w.contains("/joint_states"), "{w}");
    // JointState's name, other fields (no effort): read by its fields, with a word
    let path = tmp("joint_state_without_effort.mcap");
    let definition = JOINT_STATE_DEFINITION.replacen("float64[] effort\n", "", 1);
    {
        let file = std::io::BufWriter::new(std::fs::File::create(&path).unwrap());
        let mut w = mcap::WriteOptions::new().profile("ros2").create(file).unwrap();
        let s = w.add_schema(JOINT_STATE_SCHEMA, "ros2msg", definition.as_bytes()).unwrap();
        let c = w.add_channel(s, JOINT_STATES_TOPIC, "cdr", &BTreeMap::new()).unwrap();
        for k in 0..3i64 {
            // the message as the definition says: without the (empty) effort sequence's count
            let mut m = js(&["a"], &[k as f64], &[0.0], &[]);
            m.set_stamp_ns(T0 + k * DT);
            let mut bytes = m.encode_cdr();
            bytes.truncate(bytes.len() - 4);
            let h = MessageHeader { channel_id: c, sequence: 0, log_time: (T0 + k * DT) as u64, publish_time: 0 };
            w.write_to_known_channel(&h, &bytes).unwrap();
        }
        w.finish().unwrap();
    }
    let read = simgap_log::read_log_with_warnings(&path, &LogOptions::default()).unwrap();
    assert_eq!(read.run.len(), 3);
    let w = read.warnings.join("; ");
    assert!(w.contains("named 'sensor_msgs/msg/JointState' but its fields are not that type's") && w.contains("(header, name, position, velocity)"), "{w}");
    assert!(w.contains("sensor_msgs/msg/JointState has (header, name, position, velocity, effort)"), "{w}");
    // the real thing: no warning
    let path = tmp("joint_state.mcap");
    schema_named(&path, JOINT_STATE_SCHEMA, JOINT_STATE_DEFINITION);
    let read = simgap_log::read_log_with_warnings(&path, &LogOptions::default()).unwrap();
    assert!(read.warnings.is_empty(), "{:?}", read.warnings);
}

#[test]
fn a_refused_record_is_named_with_its_byte() {
    // a message whose joint count does not match its positions, inside a chunk
    let path = tmp("bad_message.mcap");
    let mut bag = Bag::new(&path, mcap::WriteOptions::new());
    bag.publish(JOINT_STATES_TOPIC, 0, T0, 0, js(&["a", "b"], &[0.0], &[], &[]));
    bag.finish();
    let e = read_mcap(&path).unwrap_err().to_string();
    assert!(e.contains("message record at offset") && e.contains("of the chunk at byte"), "{e}");
    // a file cut inside a record: that record, its byte and its declared length
    let full = tmp("full.mcap");
    write_log(&sample_run(5), &full).unwrap();
    let bytes = std::fs::read(&full).unwrap();
    let cut = tmp("cut.mcap");
    std::fs::write(&cut, &bytes[..60]).unwrap();
    let e = read_mcap(&cut).unwrap_err().to_string();
    assert!(e.contains("truncated MCAP file") && e.contains("record at byte") && e.contains("declares"), "{e}");
}
