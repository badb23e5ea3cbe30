//! Writing a run as a CSV log as it goes: [`CsvSink`], the CSV counterpart of
//! [`McapSink`](crate::McapSink).
//!
//! The sink keeps each sample in a batch of rows ([`BATCH_ROWS`] numbers per row) and hands
//! every full batch to a writer thread over a bounded channel ([`QUEUED_BATCHES`]); the thread
//! formats the rows (the generic convention of [`write_csv`](crate::csv::write_csv), numbers in
//! shortest round-trip form) and hands each batch to the operating system whole, ending in a
//! line end. Memory is bounded whatever the run's length.
//!
//! **While the run goes, the file is `NAME.partial.csv`** (`NAME.partial.csv.gz`) beside the
//! requested `NAME.csv`: [`Sink::finish`] (also after a diverged or interrupted run, and `Drop`)
//! renames it to the requested name. A process killed outright leaves the partial file: every
//! row the thread wrote is complete, but a kill inside a write call can cut the last line, so
//! the reader ([`read_log`](crate::read_log)) reads a `*.partial.csv[.gz]` file up to its last
//! line end (and a gzip file up to where it was cut: each batch is one gzip member), with a
//! warning saying how much it recovered. The experiment goes to the sidecar
//! `NAME.experiment.json` when the run begins, so a killed run keeps it too.

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};
use std::thread::JoinHandle;

use simgap_sim::{Experiment, RunEnd, Sample, Sink};

use crate::error::{write_error, Result};
pub use crate::partial::{is_partial, partial_path, PARTIAL};

/// Batches of rows the writer thread may hold before [`Sink::record`] waits for it.
pub const QUEUED_BATCHES: usize = 8;
/// Rows per batch (and per gzip member).
pub const BATCH_ROWS: usize = 1024;

/// Rows as the sink hands them over: per row the time, then q, q̇, τ, q_ref, q̇_ref, and a
/// servo's duty, torque enable and voltage (those present).
#[derive(Default)]
struct Rows {
    values: Vec<f64>,
    rows: usize,
}

enum Command {
    /// The header line (first).
    Header(String),
    /// Rows, `width` numbers each.
    Rows(Rows),
}

/// Writes a simulated run as a CSV log (`.csv`, or gzip-compressed `.csv.gz`) as it goes (see
/// the [module docs](self)).
pub struct CsvSink {
    path: PathBuf,
    partial: PathBuf,
    tx: Option<SyncSender<Command>>,
    thread: Option<JoinHandle<std::result::Result<(), String>>>,
    recycled: Option<Receiver<Rows>>,
    joints: Vec<String>,
    /// Values per row of τ, q_ref, q̇_ref, duty, torque enable (the joint count or 0) and
    /// voltage (1 or 0), fixed by the first sample.
    lens: Option<[usize; 6]>,
    rows: Rows,
    began: bool,
    finished: bool,
}

impl std::fmt::Debug for CsvSink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CsvSink").field("path", &self.path).field("joints", &self.joints).field("finished", &self.tx.is_none()).finish()
    }
}

/// The writer thread: formats the rows and appends each batch whole (a gzip member each for a
/// compressed log).
fn writer_thread(mut file: File, gz: bool, width: usize, rx: Receiver<Command>, recycle: SyncSender<Rows>) -> std::result::Result<(), String> {
    let mut text: Vec<u8> = Vec::with_capacity(1 << 18);
    let mut failed: Option<String> = None;
    let put = |file: &mut File, text: &[u8]| -> std::io::Result<()> {
        if gz {
            let mut e = flate2::write::GzEncoder::new(Vec::with_capacity(text.len() / 3), flate2::Compression::fast());
            e.write_all(text)?;
            file.write_all(&e.finish()?)
        } else {
            file.write_all(text)
        }
    };
    // keep draining on errors, so the sink never blocks; report the first
    for command in rx {
        if failed.is_some() {
            continue;
        }
        text.clear();
        let result = match command {
            Command::Header(h) => {
                text.extend_from_slice(h.as_bytes());
                text.push(b'\n');
                put(&mut file, &text)
            }
            Command::Rows(mut rows) => {
                for row in rows.values.chunks_exact(width.max(1)).take(rows.rows) {
                    for (i, x) in row.iter().enumerate() {
                        if i > 0 {
                            text.push(b',');
                        }
                        let _ = write!(text, "{x}");
                    }
                    text.push(b'\n');
                }
                rows.values.clear();
                rows.rows = 0;
                let _ = recycle.try_send(rows);
                put(&mut file, &text)
            }
        };
        if let Err(e) = result {
            failed = Some(e.to_string());
        }
    }
    match failed {
        Some(e) => Err(e),
        None => file.flush().map_err(|e| e.to_string()),
    }
}

impl CsvSink {
    /// Creates (truncates) `NAME.partial.csv[.gz]` beside `path` (`.csv` or `.csv.gz`); the log
    /// gets its name `path` when the sink is finished.
    ///
    /// # Errors
    /// [`Error::Write`](crate::Error::Write) when `path` is not a CSV name or the file cannot
    /// be created.
    pub fn create(path: &Path) -> Result<CsvSink> {
        let lower = path.to_string_lossy().to_lowercase();
        if !(lower.ends_with(".csv") || lower.ends_with(".csv.gz")) {
            return Err(write_error(path, "a CSV log's name ends in .csv or .csv.gz"));
        }
        let partial = partial_path(path);
        File::create(&partial).map_err(|e| write_error(&partial, e))?;
        Ok(CsvSink {
            path: path.to_path_buf(),
            partial,
            tx: None,
            thread: None,
            recycled: None,
            joints: Vec::new(),
            lens: None,
            rows: Rows::default(),
            began: false,
            finished: false,
        })
    }

    /// The requested path (the log's name once finished).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The file being written (`NAME.partial.csv[.gz]`).
    pub fn partial_path(&self) -> &Path {
        &self.partial
    }

    /// Starts the writer thread with the header of these columns.
    fn start(&mut self, lens: [usize; 6]) -> Result<()> {
        let file = File::options().write(true).truncate(true).open(&self.partial).map_err(|e| write_error(&self.partial, e))?;
        let gz = self.path.to_string_lossy().to_lowercase().ends_with(".gz");
        // the columns of `write_csv`, in its order
        let dof = self.joints.len();
        let blocks = [("q_", dof), ("qd_", dof), ("tau_", lens[0]), ("q_ref_", lens[1]), ("qd_ref_", lens[2]), ("duty_", lens[3]), ("torque_enable_", lens[4])];
        let mut header = vec!["time".to_string()];
        for (prefix, n) in blocks {
            if n > 0 {
                header.extend(self.joints.iter().map(|j| format!("{prefix}{j}")));
            }
        }
        if lens[5] > 0 {
            header.push("voltage".into());
        }
        let width = header.len();
        let (tx, rx) = sync_channel(QUEUED_BATCHES);
        let (recycle_tx, recycle_rx) = sync_channel(QUEUED_BATCHES + 2);
        let thread = std::thread::Builder::new()
            .name("simgap-csv-writer".into())
            .spawn(move || writer_thread(file, gz, width, rx, recycle_tx))
            .map_err(|e| write_error(&self.partial, format!("cannot start the writer thread: {e}")))?;
        self.tx = Some(tx);
        self.thread = Some(thread);
        self.recycled = Some(recycle_rx);
        self.lens = Some(lens);
        self.send(Command::Header(header.join(",")))
    }

    fn send(&mut self, command: Command) -> Result<()> {
        let Some(tx) = &self.tx else { return Err(write_error(&self.partial, "write after finish")) };
        if tx.send(command).is_ok() {
            return Ok(());
        }
        self.tx = None;
        let e = self.join().err().unwrap_or_else(|| "the writer thread stopped".into());
        Err(write_error(&self.partial, e))
    }

    fn join(&mut self) -> std::result::Result<(), String> {
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(result)) => result,
            Some(Err(_)) => Err("the writer thread panicked".into()),
            None => Ok(()),
        }
    }

    fn flush_rows(&mut self) -> Result<()> {
        if self.rows.rows == 0 {
            return Ok(());
        }
        let next = self.recycled.as_ref().and_then(|r| r.try_recv().ok()).unwrap_or_default();
        let full = std::mem::replace(&mut self.rows, next);
        self.send(Command::Rows(full))
    }

    /// Sends the last rows, waits for the thread, renames the file to its requested name.
    fn finish_inner(&mut self) -> Result<()> {
        if self.finished {
            return Ok(());
        }
        self.finished = true;
        if !self.began {
            // nothing was written: no log
            let _ = std::fs::remove_file(&self.partial);
            return Ok(());
        }
        // a run without samples still gets its header
        let mut result = if self.lens.is_none() { self.start([0; 6]) } else { Ok(()) };
        if result.is_ok() {
            result = self.flush_rows();
        }
        self.tx = None;
        let joined = self.join().map_err(|e| write_error(&self.partial, e));
        result = result.and(joined);
        let renamed = std::fs::rename(&self.partial, &self.path).map_err(|e| write_error(&self.path, format!("cannot rename {} to it: {e}", self.partial.display())));
        result.and(renamed)
    }
}

impl Sink for CsvSink {
    fn begin(&mut self, joints: &[String], experiment: &Experiment) -> simgap_sim::Result<()> {
        if self.began || self.finished {
            return Err(write_error(&self.path, "begin called twice or after finishing").into());
        }
        if let Some(j) = joints.iter().find(|j| j.contains(',') || j.contains('"')) {
            return Err(write_error(&self.path, format!("joint name '{j}' cannot be a CSV column")).into());
        }
        crate::experiment::write_experiment_file(experiment, &crate::experiment::sidecar_path(&self.path))?;
        self.joints = joints.to_vec();
        self.began = true;
        Ok(())
    }

    fn record(&mut self, s: &Sample<'_>) -> simgap_sim::Result<()> {
        if !self.began || self.finished {
            return Err(write_error(&self.path, "record before begin or after finishing").into());
        }
        let dof = self.joints.len();
        // a servo logs its drive's duty, enable and voltage, and no torque
        let (tau, duty, enable, voltage): (&[f64], &[f64], &[f64], &[f64]) = match &s.drive {
            Some(d) => (&[], d.duty, d.torque_enable, std::slice::from_ref(&d.voltage)),
            None => (s.tau, &[], &[], &[]),
        };
        let lens = [tau.len(), s.q_ref.len(), if s.q_ref.is_empty() { 0 } else { s.qd_ref.len() }, duty.len(), enable.len(), voltage.len()];
        let lens = match self.lens {
            Some(l) => l,
            None => {
                self.start(lens)?;
                lens
            }
        };
        let arrays = [
            ("q", s.q, dof),
            ("qd", s.qd, dof),
            ("tau", tau, lens[0]),
            ("q_ref", s.q_ref, lens[1]),
            ("qd_ref", s.qd_ref, lens[2]),
            ("duty", duty, lens[3]),
            ("torque_enable", enable, lens[4]),
            ("voltage", voltage, lens[5]),
        ];
        for (what, v, n) in arrays {
            if v.len() != n && !(what == "qd_ref" && n == 0) {
                return Err(write_error(&self.path, format!("sample at t = {} s: {what} has {} values; the log's columns hold {n}", s.t, v.len())).into());
            }
        }
        let r = &mut self.rows;
        r.values.push(s.t);
        for (what, v, n) in arrays {
            r.values.extend_from_slice(if what == "qd_ref" { &v[..n] } else { v });
        }
        r.rows += 1;
        if r.rows >= BATCH_ROWS {
            self.flush_rows()?;
        }
        Ok(())
    }

    fn finish(&mut self, _end: &RunEnd) -> simgap_sim::Result<()> {
        Ok(self.finish_inner()?)
    }
}

impl Drop for CsvSink {
    fn drop(&mut self) {
        let _ = self.finish_inner();
    }
}
