//! No file crashes the reader: seeded byte mutations of simgap's own logs (uncompressed, lz4,
//! zstd, with and without chunk CRCs) and of a rosbag2-style log give a valid read or a clean
//! error every time, with no panic, no abort, and memory within a constant times the file's size;
//! every error names the record and the byte of the file where the reader stopped.
//!
//! One test in its own binary, so the allocation counter sees only the reads.

use std::collections::BTreeMap;
use std::sync::atomic::Ordering;
use std::time::Instant;

use mcap::records::MessageHeader;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use simgap_log::mcap::write::write_mcap_with_options;
use simgap_log::mcap::{JointState, JOINT_STATE_DEFINITION};
use simgap_log::{read_mcap_bytes, Compression, LogOptions, SinkOptions};
use simgap_sim::{ControllerKind, Experiment, Run};

mod counting;
use counting::{LIVE, PEAK};

#[global_allocator]
static ALLOCATOR: counting::Counting = counting::Counting;

/// Mutants per base log.
const MUTANTS_PER_LOG: usize = 2000;

fn sample_run(n: usize) -> Run {
    let joints: Vec<String> = ["shoulder", "elbow", "wrist"].iter().map(|s| s.to_string()).collect();
    let mut run = Run::new(joints.clone());
    run.start_ns = Some(1_733_000_000_000_000_000);
    for k in 0..n {
        run.t.push(k as f64 * 0.0025);
        for j in 0..3 {
            let x = k as f64 * 0.01 + j as f64;
            run.q.push(x.sin());
            run.qd.push(x.cos());
            run.tau.push(-x);
            run.q_ref.push(0.5 * j as f64);
            run.qd_ref.push(0.0);
            run.tau_ff.push(0.1 * x);
            run.tau_measured.push(-0.9 * x);
        }
    }
    run.experiment = Some(Experiment { controller: ControllerKind::Pd, joints, kp: vec![1.0, 2.0, 3.0], kv: vec![0.1, 0.2, 0.3], sample_period: 0.0025, extra: BTreeMap::new() });
    run
}

/// A log as rosbags / rosbag2 write it: uncompressed chunks, one channel per topic, absolute
/// stamps, joints in another order on a second publisher.
fn rosbags_style_log() -> Vec<u8> {
    let mut out = std::io::Cursor::new(Vec::new());
    {
        let mut w = mcap::WriteOptions::new().profile("ros2").compression(None).chunk_size(Some(2048)).create(&mut out).unwrap();
        let s = w.add_schema("sensor_msgs/msg/JointState", "ros2msg", JOINT_STATE_DEFINITION.as_bytes()).unwrap();
        let meta = BTreeMap::from([("offered_qos_profiles".to_string(), String::new())]);
        let c = w.add_channel(s, "/joint_states", "cdr", &meta).unwrap();
        for k in 0..60i64 {
            let t = 1_700_000_000_000_000_000 + k * 2_000_000;
            for (names, x) in [(vec!["b", "a"], vec![1.0, 2.0]), (vec!["c"], vec![3.0])] {
                let mut m = JointState { name: names.iter().map(|s| s.to_string()).collect(), position: x.clone(), velocity: x.clone(), effort: x, ..JointState::default() };
                m.set_stamp_ns(t);
                let h = MessageHeader { channel_id: c, sequence: k as u32, log_time: t as u64, publish_time: t as u64 };
                w.write_to_known_channel(&h, &m.encode_cdr()).unwrap();
            }
        }
        w.finish().unwrap();
    }
    out.into_inner()
}

fn simgap_log(compression: Compression, crcs: bool) -> Vec<u8> {
    let scratch = tempfile::Builder::new().prefix("simgap-log-mutation-").tempdir().unwrap();
    let path = scratch.path().join(format!("{compression:?}.mcap"));
    write_mcap_with_options(&sample_run(60), &path, SinkOptions { compression, chunk_size: 4096 }).unwrap();
    let mut bytes = std::fs::read(&path).unwrap();
    if !crcs {
        zero_chunk_crcs(&mut bytes);
    }
    bytes
}

/// Sets every chunk's CRC to 0 (not checked), so mutations reach the decompressors and decoders.
fn zero_chunk_crcs(bytes: &mut [u8]) {
    let mut pos = 8;
    while pos + 9 <= bytes.len() {
        let op = bytes[pos];
        let len = u64::from_le_bytes(bytes[pos + 1..pos + 9].try_into().unwrap()) as usize;
        if op == 0x06 {
            let crc_at = pos + 9 + 24;
            bytes[crc_at..crc_at + 4].fill(0);
        }
        if op == 0x0F || op == 0x02 {
            break;
        }
        pos += 9 + len;
    }
}

/// One mutation of `base`, drawn from `rng`.
fn mutate(base: &[u8], rng: &mut ChaCha8Rng) -> Vec<u8> {
    let mut b = base.to_vec();
    let n = b.len();
    match rng.random_range(0..7) {
        // a few random bytes
        0 => {
            for _ in 0..rng.random_range(1..=8) {
                let i = rng.random_range(0..n);
                b[i] = rng.random();
            }
        }
        // one bit
        1 => {
            let i = rng.random_range(0..n);
            b[i] ^= 1 << rng.random_range(0..8);
        }
        // a length-sized field set to all ones (a record length of 2^64 - 1 at bytes 9..17 too)
        2 => {
            let i = if rng.random_bool(0.2) { 9 } else { rng.random_range(0..n.saturating_sub(8)) };
            b[i..i + 8].fill(0xFF);
        }
        // a 4- or 8-byte field set to a large or random value
        3 => {
            let i = rng.random_range(0..n.saturating_sub(8));
            let v: u64 = if rng.random_bool(0.5) { rng.random() } else { rng.random_range(0..1u64 << 34) };
            let w = if rng.random_bool(0.5) { 4 } else { 8 };
            b[i..i + w].copy_from_slice(&v.to_le_bytes()[..w]);
        }
        // truncated
        4 => b.truncate(rng.random_range(0..n)),
        // bytes removed
        5 => {
            let i = rng.random_range(0..n);
            let k = rng.random_range(1..=16).min(n - i);
            b.drain(i..i + k);
        }
        // bytes inserted
        _ => {
            let i = rng.random_range(0..n);
            let extra: Vec<u8> = (0..rng.random_range(1..=16)).map(|_| rng.random()).collect();
            b.splice(i..i, extra);
        }
    }
    b
}

#[test]
fn mutated_logs_read_or_fail_cleanly_within_bounded_memory() {
    let bases: Vec<(&str, Vec<u8>)> = vec![
        ("simgap uncompressed", simgap_log(Compression::None, true)),
        ("simgap lz4", simgap_log(Compression::Lz4, false)),
        ("simgap zstd", simgap_log(Compression::Zstd, false)),
        ("simgap lz4 with CRCs", simgap_log(Compression::Lz4, true)),
        ("simgap zstd with CRCs", simgap_log(Compression::Zstd, true)),
        ("rosbags-style", rosbags_style_log()),
    ];
    let options = LogOptions::default();
    // every base reads
    for (name, bytes) in &bases {
        let read = read_mcap_bytes(name, bytes, &options).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(read.run.len() >= 60, "{name}");
    }
    let mut rng = ChaCha8Rng::seed_from_u64(20261130);
    let (mut ok, mut err) = (0usize, 0usize);
    let mut unlocated: Vec<String> = Vec::new();
    let mut worst_ratio = 0.0f64;
    let start = Instant::now();
    for (name, base) in &bases {
        for i in 0..MUTANTS_PER_LOG {
            let mutant = mutate(base, &mut rng);
            let before = LIVE.load(Ordering::Relaxed);
            PEAK.store(before, Ordering::Relaxed);
            let result = std::panic::catch_unwind(|| read_mcap_bytes("mutant.mcap", &mutant, &options));
            let used = PEAK.load(Ordering::Relaxed).saturating_sub(before);
            match result {
                Ok(Ok(_)) => ok += 1,
                Ok(Err(e)) => {
                    let m = e.to_string();
                    assert!(!m.contains("internal error"), "{name} mutant {i}: the reader panicked inside: {m}");
                    // every refusal says where: the record and the byte of the file
                    if !(m.contains("record") || m.contains("magic bytes")) || !m.contains("byte ") {
                        unlocated.push(format!("{name} mutant {i}: {m}"));
                    }
                    err += 1;
                }
                Err(_) => panic!("{name} mutant {i}: read_mcap_bytes unwound a panic into the caller"),
            }
            // memory: within a constant times the file's size (chunks may decompress 1024x)
            let bound = 1100 * mutant.len() + (4 << 20);
            assert!(used <= bound, "{name} mutant {i}: {used} bytes for a file of {} bytes", mutant.len());
            worst_ratio = worst_ratio.max(used as f64 / mutant.len().max(1) as f64);
        }
    }
    let elapsed = start.elapsed();
    let total = ok + err;
    println!(
        "{total} mutants of {} logs in {:.2} s: {ok} read, {err} clean errors, 0 panics; peak memory at most {worst_ratio:.0}x the file's size",
        bases.len(),
        elapsed.as_secs_f64()
    );
    assert!(total >= 10_000);
    // one example of each kind of message (digits aside)
    let mut kinds: BTreeMap<String, &String> = BTreeMap::new();
    for m in &unlocated {
        kinds.entry(m.split_once(": ").map_or(m.as_str(), |x| x.1).chars().filter(|c| !c.is_ascii_digit()).collect()).or_insert(m);
    }
    assert!(unlocated.is_empty(), "{} refusals name no record and byte, e.g.:\n{}", unlocated.len(), kinds.values().take(20).map(|m| m.as_str()).collect::<Vec<_>>().join("\n"));
}
