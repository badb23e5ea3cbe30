//! Writing runs as ROS 2 MCAP: the [`McapSink`] a simulation writes into as it goes, and
//! [`write_mcap`] for a whole run.
//!
//! The sink keeps each sample's stamp and values in a batch of rows ([`BATCH_ROWS`]) and hands
//! every full batch to a writer thread over a bounded channel: the simulation's thread copies
//! numbers and nothing else. The thread encodes the rows' messages (CDR) as MCAP message records
//! into the chunk being filled (256 KiB of records by default), compresses every full chunk in
//! one call, appends it with its message indexes, and writes the summary at the end
//! ([`super::chunked`]). The simulation loop never waits for encoding, compression or the disk
//! unless the thread falls more than [`QUEUED_BATCHES`] batches behind, so memory stays bounded
//! whatever the run's length. The file is always finished (summary and footer) by
//! [`Sink::finish`], and by `Drop` when `finish` was never called (a panic or an early return),
//! so it stays readable after a failed or interrupted run; a process killed outright leaves
//! every chunk the thread completed (each is handed to the operating system whole), which the
//! reader recovers by a linear scan.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender};
use std::thread::JoinHandle;

use mcap::records::{MessageHeader, Metadata};
use simgap_sim::{experiment_to_map, DriveSample, Experiment, Run, RunEnd, Sample, Sink};

use super::cdr::{encode_joint_state_into, JointStateTemplate};
use super::chunked::{ChunkBuf, ChunkCompression, ChunkedWriter, MessageTemplate};
use super::{CDR_ENCODING, EXPERIMENT_METADATA, JOINT_STATE_DEFINITION, JOINT_STATE_SCHEMA, OFFERED_QOS_PROFILES, ROS2MSG_ENCODING, RUN_END_METADATA};
use crate::error::{write_error, Result};
use crate::topics::{
    JOINT_EFFORT_MEASURED_TOPIC, JOINT_REFERENCE_TOPIC, JOINT_STATES_TOPIC, SERVO_DUTY_TOPIC, SERVO_TEMPERATURE_TOPIC, SERVO_TORQUE_ENABLE_TOPIC, SERVO_VOLTAGE_TOPIC,
};

/// Batches of rows the writer thread may hold before [`Sink::record`] waits for it.
pub const QUEUED_BATCHES: usize = 8;
/// Rows (samples) per batch handed to the writer thread.
pub const BATCH_ROWS: usize = 512;
/// Zstandard level of the sink's chunks: -3 (a fast level). Measured in one run (`simgap
/// simulate --duration 300 --out`, CPU time of the process, medians of 11): 91.7 ms at -3, 103.9
/// ms at level 1, 87.3 ms uncompressed (unlogged: 44.6 ms), for files of 6.8, 6.2 and 38.7 MB;
/// levels below -3 are no faster and larger.
const ZSTD_LEVEL: i32 = -3;

/// Chunk compression of written files.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Compression {
    /// No compression (about as fast to write as zstd, whose output is about 6x smaller).
    None,
    /// LZ4 frames.
    Lz4,
    /// Zstandard (the default: measured smaller and faster to write than lz4 through the mcap
    /// writer's streaming compressors).
    #[default]
    Zstd,
}

/// How [`McapSink`] writes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SinkOptions {
    /// Chunk compression (default zstd).
    pub compression: Compression,
    /// Uncompressed bytes per chunk (default 256 KiB: about two seconds of a 400 Hz, 7-joint
    /// run, the most a killed writer loses).
    pub chunk_size: u64,
}

impl Default for SinkOptions {
    fn default() -> Self {
        SinkOptions { compression: Compression::Zstd, chunk_size: 256 * 1024 }
    }
}

/// The channels the sink writes, in the order of [`TOPICS`]: the joint states, reference and
/// measured effort, and a servo's duty, torque enable and supply voltage.
const STATES: u8 = 0;
const REFERENCE: u8 = 1;
const MEASURED: u8 = 2;
const DUTY: u8 = 3;
const ENABLE: u8 = 4;
const VOLTAGE: u8 = 5;
const TOPICS: [&str; 6] = [JOINT_STATES_TOPIC, JOINT_REFERENCE_TOPIC, JOINT_EFFORT_MEASURED_TOPIC, SERVO_DUTY_TOPIC, SERVO_TORQUE_ENABLE_TOPIC, SERVO_VOLTAGE_TOPIC];
/// The first of the servo streams of [`McapWriter::write_run`] (duty, torque enable,
/// temperature, voltage), after the three joint topics.
const SERVO: u8 = 3;
const SERVO_VOLTAGE: u8 = SERVO + 3;
/// The name of the one value of a servo's voltage message.
const VOLTAGE_NAME: &str = "voltage";

/// Rows of one layout, as the sink hands them to the writer thread.
#[derive(Default)]
struct Rows {
    /// Values per row of q, q̇, τ, q_ref, q̇_ref, τ_ff, τ_measured, duty, torque enable (the
    /// joint count or 0) and voltage (1 or 0).
    lens: [usize; 10],
    /// Sequence number of the first row (one per row, shared by its messages).
    sequence: u32,
    /// Stamp of each row [ns since the epoch].
    ns: Vec<i64>,
    /// The values of each row, its arrays one after the other (room for [`BATCH_ROWS`] rows;
    /// as many rows as `ns` holds are filled).
    values: Vec<f64>,
}

/// What the writer thread is told.
enum Command {
    /// Rows to encode (the joint names come with the first).
    Rows(Rows),
    /// The joint names of the messages.
    Joints(Vec<String>),
    /// A metadata record (after the chunk being filled).
    Metadata(String, BTreeMap<String, String>),
}

/// Writes a run as a ROS 2 MCAP file as it goes (see the [module docs](self)).
///
/// The end status goes to the `simgap.run_end` metadata record (`status`, `t`, `joint`).
pub struct McapSink {
    path: PathBuf,
    tx: Option<SyncSender<Command>>,
    thread: Option<JoinHandle<std::result::Result<(), String>>>,
    recycled: Option<Receiver<Rows>>,
    joints: Vec<String>,
    rows: Rows,
    sequence: u32,
    start_ns: i64,
    last_t: Option<f64>,
    began: bool,
}

impl std::fmt::Debug for McapSink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("McapSink").field("path", &self.path).field("joints", &self.joints).field("finished", &self.tx.is_none()).finish()
    }
}

/// The writer thread's encoder: rows into message records of the chunk being filled, full
/// chunks into the file.
struct Encoder {
    w: ChunkedWriter<BufWriter<File>>,
    schema: u16,
    qos: BTreeMap<String, String>,
    joints: Vec<String>,
    chunk: ChunkBuf,
    chunk_size: usize,
    /// Channel id of each slot, once its channel record is written.
    channels: [Option<u16>; 6],
    /// The message layout of each slot (joint names and array lengths fixed).
    templates: [Option<MessageTemplate>; 6],
}

impl Encoder {
    /// The channel id of `slot`, writing its channel record on first use (before any chunk
    /// that holds its messages).
    fn channel(&mut self, slot: u8) -> std::io::Result<u16> {
        if let Some(id) = self.channels[slot as usize] {
            return Ok(id);
        }
        let id = self.w.add_channel(self.schema, TOPICS[slot as usize], CDR_ENCODING, &self.qos)?;
        self.channels[slot as usize] = Some(id);
        Ok(id)
    }

    /// Makes the template of `slot` the one for arrays of `lens` values.
    fn template(&mut self, slot: u8, lens: [usize; 3]) -> std::io::Result<()> {
        if !self.templates[slot as usize].as_ref().is_some_and(|t| t.fits(lens)) {
            let channel = self.channel(slot)?;
            let names = if slot == VOLTAGE { vec![VOLTAGE_NAME.to_string()] } else { self.joints.clone() };
            self.templates[slot as usize] = Some(MessageTemplate::new(channel, JointStateTemplate::new(&names, lens)));
        }
        Ok(())
    }

    /// Encodes every row: `/joint_states` always, `/joint_reference` when the row has `q_ref`,
    /// `/joint_effort_measured` when it has the drives' torque, a servo's topics when it has
    /// its drive signals; a chunk ends after a whole row.
    fn rows(&mut self, rows: &Rows) -> std::io::Result<()> {
        let l = rows.lens;
        let width: usize = l.iter().sum();
        // where each array starts in a row
        let mut o = [0usize; 11];
        for i in 0..10 {
            o[i + 1] = o[i] + l[i];
        }
        // a servo's signals, each the effort of its own message: (slot, the row's array index)
        let drive = [(DUTY, 7), (ENABLE, 8), (VOLTAGE, 9)];
        for (slot, i) in drive {
            if l[i] > 0 {
                self.template(slot, [0, 0, l[i]])?;
            }
        }
        // the batch has one layout: its templates are ready before its rows
        self.template(STATES, [l[0], l[1], l[2]])?;
        if l[3] > 0 {
            self.template(REFERENCE, [l[3], l[4], l[5]])?;
        }
        if l[6] > 0 {
            self.template(MEASURED, [0, 0, l[6]])?;
        }
        let [states, reference, measured, ..] = &self.templates;
        let states = states.as_ref().expect("set above");
        let reference = reference.as_ref().filter(|_| l[3] > 0);
        let measured = measured.as_ref().filter(|_| l[6] > 0);
        let chunk = &mut self.chunk;
        for (r, &ns) in rows.ns.iter().enumerate() {
            let row = &rows.values[r * width..(r + 1) * width];
            let sequence = rows.sequence.wrapping_add(r as u32);
            let time = ns.max(0) as u64;
            let at = states.push(&mut chunk.records, sequence, time, ns, [&row[o[0]..o[1]], &row[o[1]..o[2]], &row[o[2]..o[3]]]);
            chunk.note(states.channel(), time, at);
            if let Some(t) = reference {
                let at = t.push(&mut chunk.records, sequence, time, ns, [&row[o[3]..o[4]], &row[o[4]..o[5]], &row[o[5]..o[6]]]);
                chunk.note(t.channel(), time, at);
            }
            if let Some(t) = measured {
                let at = t.push(&mut chunk.records, sequence, time, ns, [&[], &[], &row[o[6]..o[7]]]);
                chunk.note(t.channel(), time, at);
            }
            for (slot, i) in drive {
                if let (Some(t), true) = (&self.templates[slot as usize], l[i] > 0) {
                    let at = t.push(&mut chunk.records, sequence, time, ns, [&[], &[], &row[o[i]..o[i + 1]]]);
                    chunk.note(t.channel(), time, at);
                }
            }
            if chunk.records.len() >= self.chunk_size {
                let written = self.w.write_chunk(chunk);
                chunk.clear();
                written?;
            }
        }
        Ok(())
    }

    /// Compresses and writes the chunk being filled, if it holds anything.
    fn flush(&mut self) -> std::io::Result<()> {
        if self.chunk.is_empty() {
            return Ok(());
        }
        let result = self.w.write_chunk(&self.chunk);
        self.chunk.clear();
        result
    }
}

/// The writer thread: owns the file, writes what it is sent, finishes the file when the sink
/// hangs up.
fn writer_thread(file: File, options: SinkOptions, rx: Receiver<Command>, recycle: SyncSender<Rows>) -> std::result::Result<(), String> {
    let s = |e: std::io::Error| e.to_string();
    let compression = match options.compression {
        Compression::None => ChunkCompression::None,
        Compression::Lz4 => ChunkCompression::Lz4,
        Compression::Zstd => ChunkCompression::Zstd(ZSTD_LEVEL),
    };
    let mut w = ChunkedWriter::new(BufWriter::with_capacity(1 << 16, file), "ros2", concat!("simgap-log ", env!("CARGO_PKG_VERSION")), compression).map_err(s)?;
    let schema = w.add_schema(JOINT_STATE_SCHEMA, ROS2MSG_ENCODING, JOINT_STATE_DEFINITION.as_bytes()).map_err(s)?;
    let qos: BTreeMap<String, String> = [("offered_qos_profiles".to_string(), OFFERED_QOS_PROFILES.to_string())].into();
    let chunk_size = options.chunk_size.max(1024) as usize;
    let mut e = Encoder { w, schema, qos, joints: Vec::new(), chunk: ChunkBuf::with_capacity(chunk_size + 4096), chunk_size, channels: [None; 6], templates: Default::default() };
    // the states and reference channels come first, as every reader expects them
    e.channel(STATES).map_err(s)?;
    e.channel(REFERENCE).map_err(s)?;
    // keep draining on errors, so the sink never blocks; report the first
    let mut failed: Option<String> = None;
    for command in rx {
        if failed.is_some() {
            continue;
        }
        let result = match command {
            Command::Joints(joints) => {
                e.joints = joints;
                e.templates = Default::default();
                Ok(())
            }
            Command::Metadata(name, map) => e.flush().and_then(|()| e.w.write_metadata(&name, &map)),
            Command::Rows(mut rows) => {
                let result = e.rows(&rows);
                rows.ns.clear();
                let _ = recycle.try_send(rows);
                result
            }
        };
        if let Err(err) = result {
            failed = Some(err.to_string());
        }
    }
    if let Some(err) = failed {
        return Err(err);
    }
    // the sink hung up: the last chunk, summary, footer, flush
    e.flush().map_err(s)?;
    e.w.finish().map(|_| ()).map_err(s)
}

impl McapSink {
    /// Creates (truncates) the file at `path`, with [`SinkOptions::default`].
    ///
    /// # Errors
    /// [`Error::Write`](crate::Error::Write) when the file cannot be created.
    pub fn create(path: &Path) -> Result<McapSink> {
        Self::create_with_options(path, SinkOptions::default())
    }

    /// Creates (truncates) the file at `path` with other options (compression, chunk size).
    ///
    /// # Errors
    /// [`Error::Write`](crate::Error::Write) when the file cannot be created.
    pub fn create_with_options(path: &Path, options: SinkOptions) -> Result<McapSink> {
        // fail here, not in the thread, when the file cannot be created
        let file = File::create(path).map_err(|e| write_error(path, e))?;
        let (tx, rx) = sync_channel(QUEUED_BATCHES);
        let (recycle_tx, recycle_rx) = sync_channel(QUEUED_BATCHES + 2);
        let thread = std::thread::Builder::new()
            .name("simgap-mcap-writer".into())
            .spawn(move || writer_thread(file, options, rx, recycle_tx))
            .map_err(|e| write_error(path, format!("cannot start the writer thread: {e}")))?;
        Ok(McapSink {
            path: path.to_path_buf(),
            tx: Some(tx),
            recycled: Some(recycle_rx),
            thread: Some(thread),
            joints: Vec::new(),
            rows: Rows::default(),
            sequence: 0,
            start_ns: 0,
            last_t: None,
            began: false,
        })
    }

    /// The file being written.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Sets the absolute time of `t = 0` [ns since the Unix epoch] (default 0): stamps are
    /// `start_ns + t`. Call before the first sample.
    pub fn set_start_ns(&mut self, start_ns: i64) {
        self.start_ns = start_ns;
    }

    /// Like [`Sink::begin`], with an optional experiment (no metadata record without one).
    ///
    /// # Errors
    /// [`Error::Write`](crate::Error::Write) when called twice, after finishing, or when the
    /// file cannot be written.
    pub fn begin_with(&mut self, joints: &[String], experiment: Option<&Experiment>) -> Result<()> {
        if self.began {
            return Err(write_error(&self.path, "begin called twice"));
        }
        if let Some(e) = experiment {
            self.send(Command::Metadata(EXPERIMENT_METADATA.into(), experiment_to_map(e)))?;
        }
        self.send(Command::Joints(joints.to_vec()))?;
        self.joints = joints.to_vec();
        self.began = true;
        Ok(())
    }

    /// Hands a command to the writer thread; when the thread has stopped, its error.
    fn send(&mut self, command: Command) -> Result<()> {
        let Some(tx) = &self.tx else { return Err(write_error(&self.path, "write after finish")) };
        if tx.send(command).is_ok() {
            return Ok(());
        }
        self.tx = None;
        let e = self.join().err().unwrap_or_else(|| "the writer thread stopped".into());
        Err(write_error(&self.path, e))
    }

    fn join(&mut self) -> std::result::Result<(), String> {
        match self.thread.take().map(JoinHandle::join) {
            Some(Ok(result)) => result,
            Some(Err(_)) => Err("the writer thread panicked".into()),
            None => Ok(()),
        }
    }

    /// Sends the current batch of rows (if any) and starts a new one, reusing a returned buffer.
    fn flush_rows(&mut self) -> Result<()> {
        if self.rows.ns.is_empty() {
            return Ok(());
        }
        let mut next = self.recycled.as_ref().and_then(|r| r.try_recv().ok()).unwrap_or_default();
        next.lens = self.rows.lens;
        next.sequence = self.sequence;
        let full = std::mem::replace(&mut self.rows, next);
        self.send(Command::Rows(full))
    }

    /// Records one sample with every channel: measured state and commanded effort
    /// (`/joint_states`), reference and feed-forward (`/joint_reference`, when `q_ref` is not
    /// empty), and the drives' torque (`/joint_effort_measured`, when not empty).
    ///
    /// # Errors
    /// [`Error::Write`](crate::Error::Write) before `begin`, after finishing, for arrays of the
    /// wrong length, or when the writer thread failed.
    #[allow(clippy::too_many_arguments)]
    pub fn record_row(&mut self, t: f64, q: &[f64], qd: &[f64], tau: &[f64], q_ref: &[f64], qd_ref: &[f64], tau_ff: &[f64], tau_measured: &[f64]) -> Result<()> {
        self.record_arrays(t, [q, qd, tau, q_ref, qd_ref, tau_ff, tau_measured], None)
    }

    /// [`McapSink::record_row`]'s arrays (q, q̇, τ, q_ref, q̇_ref, τ_ff, τ_measured), with a
    /// servo's drive signals on its topics when given.
    fn record_arrays(&mut self, t: f64, arrays: [&[f64]; 7], drive: Option<&DriveSample<'_>>) -> Result<()> {
        let [q, qd, tau, q_ref, qd_ref, tau_ff, tau_measured] = arrays;
        if !self.began {
            return Err(write_error(&self.path, "record before begin"));
        }
        let dof = self.joints.len();
        let fits = |v: &[f64], may_be_empty: bool| v.len() == dof || (may_be_empty && v.is_empty());
        if !(fits(q, false) && fits(qd, false) && fits(tau, true) && fits(q_ref, true) && fits(qd_ref, true) && fits(tau_ff, true) && fits(tau_measured, true)) {
            let arrays = [("q", q), ("qd", qd), ("tau", tau), ("q_ref", q_ref), ("qd_ref", qd_ref), ("tau_ff", tau_ff), ("tau_measured", tau_measured)];
            let (what, v) = arrays.into_iter().find(|(what, v)| !fits(v, !matches!(*what, "q" | "qd"))).expect("one does not fit");
            return Err(write_error(&self.path, format!("sample at t = {t} s: {what} has {} values for {dof} joints", v.len())));
        }
        let (duty, enable, voltage): (&[f64], &[f64], &[f64]) = match drive {
            Some(d) => (d.duty, d.torque_enable, std::slice::from_ref(&d.voltage)),
            None => (&[], &[], &[]),
        };
        if let Some((what, v)) = [("duty", duty), ("torque_enable", enable)].into_iter().find(|(_, v)| drive.is_some() && v.len() != dof) {
            return Err(write_error(&self.path, format!("sample at t = {t} s: {what} has {} values for {dof} joints", v.len())));
        }
        // a reference without q_ref is not written (as before): its other arrays count as empty
        let with_ref = !q_ref.is_empty();
        let lens = [
            dof,
            dof,
            tau.len(),
            q_ref.len(),
            if with_ref { qd_ref.len() } else { 0 },
            if with_ref { tau_ff.len() } else { 0 },
            tau_measured.len(),
            duty.len(),
            enable.len(),
            voltage.len(),
        ];
        if lens != self.rows.lens {
            self.flush_rows()?;
            self.rows.lens = lens;
            self.rows.sequence = self.sequence;
        }
        let ns = self.start_ns.saturating_add((t * 1e9).round() as i64);
        // the row's values at their place in the batch (the buffer holds BATCH_ROWS rows)
        let width: usize = lens.iter().sum();
        let r = self.rows.ns.len();
        self.rows.ns.push(ns);
        if self.rows.values.len() < (r + 1) * width {
            self.rows.values.resize(BATCH_ROWS * width, 0.0);
        }
        let row = &mut self.rows.values[r * width..(r + 1) * width];
        let reference: [&[f64]; 3] = if with_ref { [q_ref, qd_ref, tau_ff] } else { [&[], &[], &[]] };
        let mut k = 0;
        for part in [q, qd, tau, reference[0], reference[1], reference[2], tau_measured, duty, enable, voltage] {
            for &x in part {
                row[k] = x;
                k += 1;
            }
        }
        self.sequence = self.sequence.wrapping_add(1);
        self.last_t = Some(t);
        if self.rows.ns.len() >= BATCH_ROWS {
            self.flush_rows()?;
        }
        Ok(())
    }

    /// Finishes the file without a [`RunEnd`] status (for logs that are not simulation runs).
    ///
    /// # Errors
    /// [`Error::Write`](crate::Error::Write) when the file cannot be finished.
    pub fn close(&mut self) -> Result<()> {
        self.finish_inner(None)
    }

    fn finish_inner(&mut self, end: Option<&RunEnd>) -> Result<()> {
        if self.tx.is_none() {
            return self.join().map_err(|e| write_error(&self.path, e));
        }
        let mut result = self.flush_rows();
        // end status: a metadata record
        if let (Some(end), true, true) = (end, self.began, result.is_ok()) {
            result = self.send(Command::Metadata(RUN_END_METADATA.into(), run_end_map(end, self.last_t)));
        }
        // hang up: the thread writes the last chunk, the summary and the footer
        self.tx = None;
        let joined = self.join().map_err(|e| write_error(&self.path, e));
        result.and(joined)
    }
}

/// The `simgap.run_end` metadata of a run that ended with `end`, its last sample at `last_t`.
fn run_end_map(end: &RunEnd, last_t: Option<f64>) -> BTreeMap<String, String> {
    let (status, t, joint) = match end {
        RunEnd::Completed => ("completed", last_t, None),
        RunEnd::Interrupted { t } => ("interrupted", Some(*t), None),
        RunEnd::Diverged { t, joint } => ("diverged", Some(*t), Some(joint.clone())),
    };
    let mut map = BTreeMap::from([("status".to_string(), status.to_string())]);
    if let Some(t) = t {
        map.insert("t".into(), format!("{t}"));
    }
    if let Some(j) = joint {
        map.insert("joint".into(), j);
    }
    map
}

impl Sink for McapSink {
    fn begin(&mut self, joints: &[String], experiment: &Experiment) -> simgap_sim::Result<()> {
        Ok(self.begin_with(joints, Some(experiment))?)
    }

    /// Records a sample; a servo's (one with drive signals) as a servo logs it: its duty, torque
    /// enable and voltage on their topics, and no effort in `/joint_states`.
    fn record(&mut self, s: &Sample<'_>) -> simgap_sim::Result<()> {
        let tau = if s.drive.is_some() { &[][..] } else { s.tau };
        Ok(self.record_arrays(s.t, [s.q, s.qd, tau, s.q_ref, s.qd_ref, &[], &[]], s.drive.as_ref())?)
    }

    fn finish(&mut self, end: &RunEnd) -> simgap_sim::Result<()> {
        Ok(self.finish_inner(Some(end))?)
    }
}

impl Drop for McapSink {
    fn drop(&mut self) {
        if self.tx.is_some() {
            let t = self.last_t.unwrap_or(0.0);
            let _ = self.finish_inner(Some(&RunEnd::Interrupted { t }));
        }
    }
}

/// Writes a whole run as an MCAP file (zstd chunks; no run-end status). Stamps are
/// `run.start_ns + t` when the run has a start, else `t`, to the nanosecond, so a log read and
/// written again keeps its stamps exactly. A servo run's drive signals (duty, torque enable,
/// temperature, supply voltage) go on the servo topics of [`RunTopics::default`] (lz4 chunks).
///
/// # Errors
/// [`Error::Write`](crate::Error::Write) when the file cannot be written or the run's matrices
/// have wrong sizes.
pub fn write_mcap(run: &Run, path: &Path) -> Result<()> {
    write_mcap_with_options(run, path, SinkOptions::default())
}

/// [`write_mcap`] with other options.
///
/// # Errors
/// As [`write_mcap`].
pub fn write_mcap_with_options(run: &Run, path: &Path, options: SinkOptions) -> Result<()> {
    write_mcap_rows(run, path, options, None)
}

/// [`write_mcap`] of a simulated run, with how the run ended in the `simgap.run_end` metadata
/// record (as the sink writes it while a run goes).
///
/// # Errors
/// As [`write_mcap`].
pub fn write_mcap_ended(run: &Run, path: &Path, end: &simgap_sim::RunEnd) -> Result<()> {
    write_mcap_rows(run, path, SinkOptions::default(), Some(end))
}

fn write_mcap_rows(run: &Run, path: &Path, options: SinkOptions, end: Option<&simgap_sim::RunEnd>) -> Result<()> {
    if !run.drive.is_empty() {
        // a servo run: every topic through the plain writer, which writes the drive's as well
        let mut w = McapWriter::create(path)?;
        if let Some(e) = &run.experiment {
            w.metadata(EXPERIMENT_METADATA, experiment_to_map(e))?;
        }
        w.write_run(run, &RunTopics::default(), None)?;
        if let Some(end) = end {
            w.metadata(RUN_END_METADATA, run_end_map(end, run.t.last().copied()))?;
        }
        return w.finish();
    }
    let mut sink = McapSink::create_with_options(path, options)?;
    sink.set_start_ns(run.start_ns.unwrap_or(0));
    sink.begin_with(&run.joints, run.experiment.as_ref())?;
    let dof = run.dof();
    let row = |m: &'_ [f64], k: usize| -> std::ops::Range<usize> {
        if m.is_empty() {
            0..0
        } else {
            k * dof..(k + 1) * dof
        }
    };
    for k in 0..run.len() {
        sink.record_row(
            run.t[k],
            &run.q[row(&run.q, k)],
            &run.qd[row(&run.qd, k)],
            &run.tau[row(&run.tau, k)],
            &run.q_ref[row(&run.q_ref, k)],
            &run.qd_ref[row(&run.qd_ref, k)],
            &run.tau_ff[row(&run.tau_ff, k)],
            &run.tau_measured[row(&run.tau_measured, k)],
        )?;
    }
    match end {
        Some(end) => simgap_sim::Sink::finish(&mut sink, end).map_err(|e| crate::Error::Write { path: path.to_path_buf(), message: e.to_string() }),
        None => sink.close(),
    }
}

/// Topics one run is written on by [`McapWriter::write_run`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RunTopics {
    /// Measured (or simulated) state and commanded effort.
    pub states: String,
    /// Reference and feed-forward, when the run has a reference (`None`: not written).
    pub reference: Option<String>,
    /// Torque the drives report, when the run has it (`None`: not written).
    pub measured_effort: Option<String>,
    /// A servo's duty, torque enable and temperature (JointState efforts, one per joint) and
    /// supply voltage (a JointState with the one effort `voltage`), each when the run has it
    /// (`None`: not written).
    pub servo: [Option<String>; 4],
}

impl Default for RunTopics {
    fn default() -> Self {
        RunTopics {
            states: JOINT_STATES_TOPIC.into(),
            reference: Some(JOINT_REFERENCE_TOPIC.into()),
            measured_effort: Some(JOINT_EFFORT_MEASURED_TOPIC.into()),
            servo: [SERVO_DUTY_TOPIC, SERVO_TORQUE_ENABLE_TOPIC, SERVO_TEMPERATURE_TOPIC, SERVO_VOLTAGE_TOPIC].map(|t| Some(t.to_string())),
        }
    }
}

/// A ROS 2 MCAP file holding several runs on topics of the caller's choosing, and metadata
/// records: e.g. measured, nominal and corrected runs side by side for Foxglove. Every channel is
/// a CDR `sensor_msgs/msg/JointState`, like everything simgap writes.
pub struct McapWriter {
    path: PathBuf,
    writer: Option<mcap::Writer<BufWriter<File>>>,
    schema: u16,
    buf: Vec<u8>,
}

impl std::fmt::Debug for McapWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("McapWriter").field("path", &self.path).finish()
    }
}

impl McapWriter {
    /// Creates (truncates) the file (lz4 chunks).
    ///
    /// # Errors
    /// [`Error::Write`](crate::Error::Write) when the file cannot be created.
    pub fn create(path: &Path) -> Result<McapWriter> {
        let err = |e: &dyn std::fmt::Display| write_error(path, e);
        let file = File::create(path).map_err(|e| err(&e))?;
        let mut w = mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!("simgap-log ", env!("CARGO_PKG_VERSION")))
            .compression(Some(mcap::Compression::Lz4))
            .compression_threads(0)
            .create(BufWriter::new(file))
            .map_err(|e| err(&e))?;
        let schema = w.add_schema(JOINT_STATE_SCHEMA, ROS2MSG_ENCODING, JOINT_STATE_DEFINITION.as_bytes()).map_err(|e| err(&e))?;
        Ok(McapWriter { path: path.to_path_buf(), writer: Some(w), schema, buf: Vec::new() })
    }

    fn writer(&mut self) -> Result<&mut mcap::Writer<BufWriter<File>>> {
        let path = &self.path;
        self.writer.as_mut().ok_or_else(|| write_error(path, "write after finish"))
    }

    /// Writes a metadata record.
    ///
    /// # Errors
    /// [`Error::Write`](crate::Error::Write) when the file cannot be written.
    pub fn metadata(&mut self, name: &str, map: BTreeMap<String, String>) -> Result<()> {
        let path = self.path.clone();
        self.writer()?.write_metadata(&Metadata { name: name.into(), metadata: map }).map_err(|e| write_error(&path, e))
    }

    /// Writes a run on `topics`, stamped `start_ns + t` to the nanosecond (`start_ns`: the run's
    /// own, else the one given, else 0).
    ///
    /// # Errors
    /// [`Error::Write`](crate::Error::Write) when the file cannot be written.
    pub fn write_run(&mut self, run: &Run, topics: &RunTopics, start_ns: Option<i64>) -> Result<()> {
        let path = self.path.clone();
        let err = |e: mcap::McapError| write_error(&path, e);
        let start = run.start_ns.or(start_ns).unwrap_or(0);
        let dof = run.dof();
        let row = |m: &[f64], k: usize| -> std::ops::Range<usize> {
            if m.len() >= (k + 1) * dof {
                k * dof..(k + 1) * dof
            } else {
                0..0
            }
        };
        let qos: BTreeMap<String, String> = [("offered_qos_profiles".to_string(), OFFERED_QOS_PROFILES.to_string())].into();
        let schema = self.schema;
        let mut streams: Vec<(u8, &str)> = vec![(STATES, topics.states.as_str())];
        if let (Some(t), false) = (&topics.reference, run.q_ref.is_empty()) {
            streams.push((REFERENCE, t.as_str()));
        }
        if let (Some(t), false) = (&topics.measured_effort, run.tau_measured.is_empty()) {
            streams.push((MEASURED, t.as_str()));
        }
        let d = &run.drive;
        for (i, (topic, signal)) in topics.servo.iter().zip([&d.duty, &d.torque_enable, &d.temperature, &d.voltage]).enumerate() {
            if let (Some(t), false) = (topic, signal.is_empty()) {
                streams.push((SERVO + i as u8, t.as_str()));
            }
        }
        let voltage = [VOLTAGE_NAME.to_string()];
        for (kind, topic) in streams {
            let mut buf = std::mem::take(&mut self.buf);
            let w = self.writer()?;
            let channel = w.add_channel(schema, topic, CDR_ENCODING, &qos).map_err(err)?;
            for k in 0..run.len() {
                let ns = start.saturating_add((run.t[k] * 1e9).round() as i64);
                buf.clear();
                match kind {
                    STATES => encode_joint_state_into(&mut buf, ns, &run.joints, &run.q[row(&run.q, k)], &run.qd[row(&run.qd, k)], &run.tau[row(&run.tau, k)]),
                    REFERENCE => {
                        encode_joint_state_into(&mut buf, ns, &run.joints, &run.q_ref[row(&run.q_ref, k)], &run.qd_ref[row(&run.qd_ref, k)], &run.tau_ff[row(&run.tau_ff, k)])
                    }
                    MEASURED => encode_joint_state_into(&mut buf, ns, &run.joints, &[], &[], &run.tau_measured[row(&run.tau_measured, k)]),
                    SERVO_VOLTAGE => encode_joint_state_into(&mut buf, ns, &voltage, &[], &[], d.voltage.get(k..k + 1).unwrap_or(&[])),
                    _ => {
                        let signal = [&d.duty, &d.torque_enable, &d.temperature][(kind - SERVO) as usize];
                        encode_joint_state_into(&mut buf, ns, &run.joints, &[], &[], &signal[row(signal, k)])
                    }
                }
                let time = ns.max(0) as u64;
                let header = MessageHeader { channel_id: channel, sequence: k as u32, log_time: time, publish_time: time };
                w.write_to_known_channel(&header, &buf).map_err(err)?;
            }
            self.buf = buf;
        }
        Ok(())
    }

    /// Writes the summary and footer, flushes and syncs the file.
    ///
    /// # Errors
    /// [`Error::Write`](crate::Error::Write) when the file cannot be finished.
    pub fn finish(mut self) -> Result<()> {
        let path = self.path.clone();
        let Some(mut w) = self.writer.take() else { return Ok(()) };
        w.finish().map_err(|e| write_error(&path, e))?;
        let mut inner = w.into_inner();
        inner.flush().map_err(|e| write_error(&path, e))?;
        inner.get_ref().sync_all().map_err(|e| write_error(&path, e))
    }
}
