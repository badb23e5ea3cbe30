//! A killed `simgap simulate --out RUN.mcap` leaves a log the reader recovers: the CLI writes its
//! MCAP log as the run goes (writer thread, zstd chunks), so a process killed with SIGKILL at
//! any instant leaves every chunk it completed at the requested path. The reader recovers all of
//! them, with the warning it gives for a killed recorder, and the recovered samples are exactly
//! the simulation's (compared with the same run simulated in this process).
//!
//! The chunks a killed file holds are counted here independently of the reader, by walking the
//! records of the data section (`opcode u8 | length u64 | body`): a chunk is complete when its
//! whole record is in the file; its header says the stamp of its last message.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use simgap::core::{Formulation, Model};
use simgap::log::{read_log_with_warnings, LogOptions};
use simgap::sim::{simulate, MemorySink, Pd, Plant, SimParams, Step};

mod common;
use common::bin;

/// Complete chunk records of a (possibly truncated) MCAP file: how many, and the largest
/// `message_end_time` [ns] of their headers.
fn complete_chunks(bytes: &[u8]) -> (usize, Option<u64>) {
    let (mut pos, mut count, mut last) = (8usize, 0usize, None);
    while bytes.len() - pos >= 9 {
        let op = bytes[pos];
        let len = u64::from_le_bytes(bytes[pos + 1..pos + 9].try_into().unwrap());
        if len > (bytes.len() - pos - 9) as u64 {
            break;
        }
        let body = &bytes[pos + 9..pos + 9 + len as usize];
        if op == 0x06 {
            count += 1;
            let end = u64::from_le_bytes(body[8..16].try_into().unwrap());
            last = Some(last.map_or(end, |l: u64| l.max(end)));
        }
        if op == 0x0F || op == 0x02 {
            break;
        }
        pos += 9 + len as usize;
    }
    (count, last)
}

/// The CLI's default run (the paper's experiment) simulated here for `duration` seconds.
fn reference_run(duration: f64) -> simgap::sim::Run {
    let model = Model::paper_arm();
    let plant = Plant::new(&model, Formulation::EulerLagrange, &[]).unwrap();
    let mut pd = Pd { kp: simgap::sim::paper::KP.to_vec(), kv: simgap::sim::paper::KV.to_vec() };
    let mut sink = MemorySink::new();
    let params = SimParams { duration, ..SimParams::default() };
    simulate(&plant, &mut pd, &Step { target: simgap::sim::paper::Q_DESIRED.to_vec() }, &params, &mut sink, None).unwrap();
    sink.into_run()
}

#[test]
fn simulate_killed_at_random_instants_leaves_every_complete_chunk_readable() {
    let dir = std::env::temp_dir().join(format!("simgap-killed-simulate-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(20261201);
    let mut recovered_runs = 0;
    for kill in 0..6 {
        let path = dir.join(format!("day-{kill}.mcap"));
        // a day of the paper's experiment: far longer than the test waits
        let mut child = Command::new(bin())
            .args(["simulate", "--duration", "86400", "--out", path.to_str().unwrap()])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("simgap runs");
        // (hundreds of chunks by then; longer runs only make the reference run longer)
        let after = Duration::from_millis(rng.random_range(150..800));
        let start = Instant::now();
        while start.elapsed() < after {
            assert!(child.try_wait().unwrap().is_none(), "kill {kill}: simulate ended before it was killed");
            std::thread::sleep(Duration::from_millis(5));
        }
        child.kill().unwrap(); // SIGKILL: no handler, no destructor, no summary
        child.wait().unwrap();
        let bytes = std::fs::read(&path).unwrap_or_default();
        let (chunks, last_ns) = complete_chunks(&bytes);
        let read = read_log_with_warnings(&path, &LogOptions::default());
        println!("kill {kill} after {after:?}: {} bytes, {chunks} complete chunks, last stamp {last_ns:?} ns", bytes.len());
        let Some(last_ns) = last_ns else {
            // killed before the first chunk was complete: a clean error naming the truncation
            let e = read.expect_err("a file without a complete chunk cannot be read");
            assert!(e.to_string().contains("truncated") || e.to_string().contains("not an MCAP file"), "kill {kill}: {e}");
            continue;
        };
        let read = read.unwrap_or_else(|e| panic!("kill {kill}: {} complete chunks but the read failed: {e}", chunks));
        let w = read.warnings.join("; ");
        assert!(w.contains("no summary") && w.contains(&format!("of {}", bytes.len())), "kill {kill}: warning {w}");
        // every complete chunk recovered: the run reaches the last stamp of the last complete chunk
        let run = read.run;
        let t_last_ns = (run.t[run.len() - 1] * 1e9).round() as u64;
        assert_eq!(t_last_ns, last_ns, "kill {kill}: the recovered run ends at {t_last_ns} ns, the last complete chunk at {last_ns} ns");
        assert!(run.experiment.is_some(), "kill {kill}: the experiment record is written first");
        // and the samples are the simulation's, bit for bit
        let expected = reference_run(run.duration());
        assert_eq!(run.len(), expected.len(), "kill {kill}");
        assert_eq!(run.q, expected.q, "kill {kill}: q");
        assert_eq!(run.qd, expected.qd, "kill {kill}: qd");
        assert_eq!(run.tau, expected.tau, "kill {kill}: tau");
        recovered_runs += 1;
    }
    assert!(recovered_runs >= 4, "only {recovered_runs} of 6 killed runs had a complete chunk");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The file a killed run leaves is the one asked for: no hidden temporary beside it.
#[test]
fn simulate_writes_at_the_requested_path_as_it_goes() {
    let dir = std::env::temp_dir().join(format!("simgap-streaming-simulate-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("run.mcap");
    let mut child = Command::new(bin()).args(["simulate", "--duration", "86400", "--out", path.to_str().unwrap()]).stdout(Stdio::null()).stderr(Stdio::null()).spawn().unwrap();
    let deadline = Instant::now() + Duration::from_secs(30);
    while std::fs::metadata(&path).map_or(0, |m| m.len()) < 200_000 {
        assert!(Instant::now() < deadline, "nothing written at {} within 30 s", path.display());
        std::thread::sleep(Duration::from_millis(10));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let names: Vec<String> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().to_string()).collect();
    assert_eq!(names, ["run.mcap"], "files in {}", Path::new(&dir).display());
    let _ = std::fs::remove_dir_all(&dir);
}
