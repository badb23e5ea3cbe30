//! No dataset crashes the LeRobot reader: seeded byte mutations and truncations of the SAGE
//! SO-101 dataset's Parquet files (its data file and its episode index) give a valid read or a
//! clean error naming the folder and the file every time, with no panic, no abort, no hang, and
//! memory within a bound.
//!
//! One test in its own binary, so the allocation counter sees only the reads. Needs
//! `../shared/data/sage-so101/lerobot`: without it the test skips with a message, and fails when
//! `CI` is set.

use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use simgap_log::{read_logs, LogOptions};

mod common;

mod counting;
use counting::{LIVE, PEAK};

#[global_allocator]
static ALLOCATOR: counting::Counting = counting::Counting;

/// Mutants of each file.
const MUTANTS: usize = 150;
/// The most heap one read of a mutant may add [bytes]: the clean read of episode 0 needs a few
/// MB; a read that believed a hostile count would need gigabytes.
const PEAK_BOUND: usize = 256 << 20;
/// The longest one read may take (the clean one takes milliseconds in a release build).
const TIME_BOUND: Duration = Duration::from_secs(20);

fn sage_lerobot() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/sage-so101/lerobot");
    if dir.join("meta/info.json").is_file() {
        Some(dir)
    } else {
        assert!(std::env::var_os("CI").is_none(), "the SAGE SO-101 dataset is not at {} (CI is set: a test without its data fails)", dir.display());
        eprintln!("SKIP: the SAGE SO-101 dataset is not at {}", dir.display());
        None
    }
}

/// Reads episode 0 of `ds` and checks the outcome: runs, or an error naming the folder.
fn read_checked(ds: &Path, what: &str) -> bool {
    let before = LIVE.load(Ordering::Relaxed);
    PEAK.store(before, Ordering::Relaxed);
    let start = Instant::now();
    let result = read_logs(&PathBuf::from(format!("{}#0", ds.display())), &LogOptions::default());
    let (took, peak) = (start.elapsed(), PEAK.load(Ordering::Relaxed) - before);
    assert!(took < TIME_BOUND, "{what}: the read took {took:?}");
    assert!(peak < PEAK_BOUND, "{what}: the read allocated {} MiB at its peak", peak >> 20);
    match result {
        Ok(runs) => {
            assert_eq!(runs.len(), 1, "{what}");
            false
        }
        Err(e) => {
            let m = e.to_string();
            assert!(m.contains(&ds.display().to_string()), "{what}: error '{m}' does not name the folder");
            assert!(!m.contains("internal error"), "{what}: the reader panicked: {m}");
            true
        }
    }
}

#[test]
fn mutated_parquet_files_give_a_run_or_a_clean_error() {
    let Some(src) = sage_lerobot() else { return };
    let dir = common::folder();
    let ds = dir.path().join("lerobot");
    for rel in ["meta/info.json", "meta/episodes/chunk-000/file-000.parquet", "data/chunk-000/file-000.parquet"] {
        std::fs::create_dir_all(ds.join(rel).parent().unwrap()).unwrap();
        std::fs::write(ds.join(rel), std::fs::read(src.join(rel)).unwrap()).unwrap();
    }
    assert!(!read_checked(&ds, "the clean copy"), "the clean copy reads");
    let mut rng = ChaCha8Rng::seed_from_u64(54);
    let mut errors = 0;
    for rel in ["data/chunk-000/file-000.parquet", "meta/episodes/chunk-000/file-000.parquet"] {
        let path = ds.join(rel);
        let clean = std::fs::read(&path).unwrap();
        // the bytes episode 0 is read from: its row group at the start, and the footer
        let head = clean.len().min(200_000);
        let tail = clean.len().saturating_sub(80_000);
        for m in 0..MUTANTS {
            let mut bytes = clean.clone();
            let what = match m % 5 {
                // a cut file
                0 => {
                    let at = rng.random_range(0..clean.len());
                    bytes.truncate(at);
                    format!("{rel} cut at byte {at}")
                }
                // a few bytes changed, in the episode's row group or in the footer
                _ => {
                    let flips = rng.random_range(1..=8);
                    for _ in 0..flips {
                        let at = if rng.random_bool(0.5) { rng.random_range(0..head) } else { rng.random_range(tail..clean.len()) };
                        bytes[at] = rng.random();
                    }
                    format!("{rel} with {flips} random bytes (mutant {m})")
                }
            };
            std::fs::write(&path, &bytes).unwrap();
            errors += usize::from(read_checked(&ds, &what));
        }
        std::fs::write(&path, &clean).unwrap();
    }
    // most mutants are refused (a change in a value the reader cannot check gives a run)
    assert!(errors > MUTANTS / 2, "only {errors} of {} mutants were refused", 2 * MUTANTS);
}
