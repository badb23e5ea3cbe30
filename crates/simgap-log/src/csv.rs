//! CSV logs with a column mapping, so that other people's files load unedited.
//!
//! A [`CsvMapping`] names the time column and, per joint, the columns of measured position,
//! velocity, commanded effort and the reference. Presets read the DFKI files in
//! `../shared/data` as they are ([`CsvMapping::dfki_double_pendulum`],
//! [`CsvMapping::dfki_double_pendulum_sysid`], [`CsvMapping::dfki_simple_pendulum`]), with the
//! joint names of the DFKI URDFs so the logs map to those models by name. Anything else follows
//! the generic convention `time,q_<j>…,qd_<j>…,tau_<j>…[,q_ref_<j>…,qd_ref_<j>…]`
//! ([`CsvMapping::generic`]), which [`write_csv`] writes. Files whose name ends in `.gz` (or that
//! start with the gzip magic bytes) are decompressed transparently.
//!
//! The experiment of a CSV log lives in a sidecar file
//! ([`sidecar_path`](crate::experiment::sidecar_path)): JSON or `key = value` lines with the
//! keys of the `simgap.experiment` metadata.
//!
//! Times are seconds in the file. A file whose first time looks like an absolute epoch time
//! (after 1 Jan 2000) gives a run with `start_ns` set and `t` since that start.

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Read, Write};
use std::path::Path;

use simgap_sim::{central_difference, Run};

use crate::error::{check_run, read_error as log_error, write_error, Result};

/// Joint names of the DFKI double pendulum URDFs (`system_identification/identified_parameters/
/// */*/{acrobot,pendubot}.urdf`): the shoulder (motor 1) and the elbow (motor 2).
pub const DFKI_DOUBLE_PENDULUM_JOINTS: [&str; 2] = ["Joint1", "Joint2"];
/// Joint name of the DFKI simple pendulum URDF `urdf/simplependul_dfki_pino_Modi.urdf` (the one
/// whose mass and length match the records; `dfki_simple_pendulum.urdf` calls it `Joint_1`, use
/// [`CsvMapping::with_joint_names`] for that one).
pub const DFKI_SIMPLE_PENDULUM_JOINT: &str = "shoulder";

/// Which CSV columns hold what. Each list holds `(joint, column)` pairs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CsvMapping {
    /// Column of the time [s].
    pub time: String,
    /// Measured positions; gives the joints and their order.
    pub position: Vec<(String, String)>,
    /// Measured velocities (empty: q̇ by central difference of q, noted in `run.source`).
    pub velocity: Vec<(String, String)>,
    /// Commanded efforts (empty: `run.tau` is empty).
    pub effort: Vec<(String, String)>,
    /// Reference positions (empty: no reference).
    pub position_ref: Vec<(String, String)>,
    /// Reference velocities (empty: zero).
    pub velocity_ref: Vec<(String, String)>,
    /// Feed-forward torques (empty: zero).
    pub effort_ff: Vec<(String, String)>,
    /// Torques the drives report (empty: none).
    pub effort_measured: Vec<(String, String)>,
    /// A servo's measured PWM duty in [−1, 1] (empty: none).
    pub duty: Vec<(String, String)>,
    /// A servo's torque enable, 0 or 1 (empty: enabled throughout).
    pub torque_enable: Vec<(String, String)>,
    /// A servo's temperature [°C] (empty: none; reported, not modelled).
    pub temperature: Vec<(String, String)>,
    /// The supply voltage [V], one column for the robot (`None`: none).
    pub voltage: Option<String>,
    /// When true, a file without the reference columns reads without a reference instead of
    /// failing (the DFKI presets: system-identification runs have no reference).
    pub optional_reference: bool,
}

impl CsvMapping {
    /// A mapping with a time column and no joints yet; add them with the builder methods.
    pub fn new(time: &str) -> CsvMapping {
        CsvMapping {
            time: time.into(),
            position: Vec::new(),
            velocity: Vec::new(),
            effort: Vec::new(),
            position_ref: Vec::new(),
            velocity_ref: Vec::new(),
            effort_ff: Vec::new(),
            effort_measured: Vec::new(),
            duty: Vec::new(),
            torque_enable: Vec::new(),
            temperature: Vec::new(),
            voltage: None,
            optional_reference: false,
        }
    }

    /// Adds the measured position column of a joint (this also adds the joint).
    #[must_use]
    pub fn position(mut self, joint: &str, column: &str) -> CsvMapping {
        self.position.push((joint.into(), column.into()));
        self
    }

    /// Adds the measured velocity column of a joint.
    #[must_use]
    pub fn velocity(mut self, joint: &str, column: &str) -> CsvMapping {
        self.velocity.push((joint.into(), column.into()));
        self
    }

    /// Adds the commanded effort column of a joint.
    #[must_use]
    pub fn effort(mut self, joint: &str, column: &str) -> CsvMapping {
        self.effort.push((joint.into(), column.into()));
        self
    }

    /// Adds the reference position column of a joint.
    #[must_use]
    pub fn position_ref(mut self, joint: &str, column: &str) -> CsvMapping {
        self.position_ref.push((joint.into(), column.into()));
        self
    }

    /// Adds the reference velocity column of a joint.
    #[must_use]
    pub fn velocity_ref(mut self, joint: &str, column: &str) -> CsvMapping {
        self.velocity_ref.push((joint.into(), column.into()));
        self
    }

    /// Sets whether missing reference columns mean "no reference" rather than an error.
    #[must_use]
    pub fn optional_reference(mut self, optional: bool) -> CsvMapping {
        self.optional_reference = optional;
        self
    }

    /// A mapping whose columns are `prefix + joint` (or `prefix + suffix` with `suffixes`, see
    /// [`CsvMapping::from_suffixes`]). `None` leaves that quantity out.
    pub fn from_prefixes(
        time: &str,
        joints: &[&str],
        position: &str,
        velocity: Option<&str>,
        effort: Option<&str>,
        position_ref: Option<&str>,
        velocity_ref: Option<&str>,
    ) -> CsvMapping {
        let suffixes: Vec<&str> = joints.to_vec();
        Self::from_suffixes(time, joints, &suffixes, position, velocity, effort, position_ref, velocity_ref)
    }

    /// A mapping whose column of joint `joints[i]` is `prefix + suffixes[i]` (e.g. DFKI's
    /// `pos_meas1` for joint `Joint1`).
    ///
    /// # Panics
    /// If `joints` and `suffixes` differ in length.
    #[allow(clippy::too_many_arguments)]
    pub fn from_suffixes(
        time: &str,
        joints: &[&str],
        suffixes: &[&str],
        position: &str,
        velocity: Option<&str>,
        effort: Option<&str>,
        position_ref: Option<&str>,
        velocity_ref: Option<&str>,
    ) -> CsvMapping {
        assert_eq!(joints.len(), suffixes.len(), "one column suffix per joint");
        let cols = |prefix: Option<&str>| -> Vec<(String, String)> {
            match prefix {
                Some(p) => joints.iter().zip(suffixes).map(|(j, s)| (j.to_string(), format!("{p}{s}"))).collect(),
                None => Vec::new(),
            }
        };
        CsvMapping {
            time: time.into(),
            position: cols(Some(position)),
            velocity: cols(velocity),
            effort: cols(effort),
            position_ref: cols(position_ref),
            velocity_ref: cols(velocity_ref),
            effort_ff: Vec::new(),
            effort_measured: Vec::new(),
            duty: Vec::new(),
            torque_enable: Vec::new(),
            temperature: Vec::new(),
            voltage: None,
            optional_reference: false,
        }
    }

    /// The generic convention for these joints: `time`, `q_<j>`, `qd_<j>`, `tau_<j>`,
    /// `q_ref_<j>`, `qd_ref_<j>` (the reference optional).
    pub fn generic(joints: &[&str]) -> CsvMapping {
        Self::from_prefixes("time", joints, "q_", Some("qd_"), Some("tau_"), Some("q_ref_"), Some("qd_ref_")).optional_reference(true)
    }

    /// Adds the feed-forward torque column of a joint.
    #[must_use]
    pub fn effort_ff(mut self, joint: &str, column: &str) -> CsvMapping {
        self.effort_ff.push((joint.into(), column.into()));
        self
    }

    /// Adds the measured (drive-reported) torque column of a joint.
    #[must_use]
    pub fn effort_measured(mut self, joint: &str, column: &str) -> CsvMapping {
        self.effort_measured.push((joint.into(), column.into()));
        self
    }

    /// DFKI double pendulum records in the documented layout
    /// (`docs/text/software_structure.trajectorydata.rst`; e.g.
    /// `design_C.0/20220914/sys_id/trajectory_0*.csv.gz`): q = `pos_meas1/2`, q̇ = `vel_filt1/2`
    /// (the velocity the controller used; equal to `vel_meas` in sys-id runs), τ = `tau_con1/2`
    /// (commanded, after the software limit), reference `pos_des1/2`, `vel_des1/2` when present;
    /// detection adds the torque the drives report, `tau_meas1/2`, as the measured torque when
    /// the file has it.
    /// Joints `Joint1`, `Joint2` as in the DFKI URDFs.
    pub fn dfki_double_pendulum() -> CsvMapping {
        Self::from_suffixes("time", &DFKI_DOUBLE_PENDULUM_JOINTS, &["1", "2"], "pos_meas", Some("vel_filt"), Some("tau_con"), Some("pos_des"), Some("vel_des"))
            .optional_reference(true)
    }

    /// DFKI double pendulum system-identification records of design A.0
    /// (`design_A.0/20220812/sys_id/*_measured.csv.gz`, header
    /// `time,pos1,pos2,vel1,vel2,tau1,tau2`): q = `pos1/2`, q̇ = `vel1/2`, τ = `tau1/2` (the
    /// commanded PD torque). No reference in the file. Joints `Joint1`, `Joint2`.
    pub fn dfki_double_pendulum_sysid() -> CsvMapping {
        Self::from_suffixes("time", &DFKI_DOUBLE_PENDULUM_JOINTS, &["1", "2"], "pos", Some("vel"), Some("tau"), None, None)
    }

    /// DFKI simple pendulum records (`data_measured.csv.gz`, header
    /// `time,position,velocity,torque`): q = `position`, q̇ = `velocity`, τ = `torque`. Note that
    /// in `data_measured` files `torque` is the torque **reported by the motor**, not the
    /// commanded one (that is in `data_desired` for feedback-only controllers): it is read as
    /// both the effort and the measured torque (so nothing is assumed clamped below what the
    /// motor delivered). Joint `shoulder`.
    pub fn dfki_simple_pendulum() -> CsvMapping {
        CsvMapping::new("time")
            .position(DFKI_SIMPLE_PENDULUM_JOINT, "position")
            .velocity(DFKI_SIMPLE_PENDULUM_JOINT, "velocity")
            .effort(DFKI_SIMPLE_PENDULUM_JOINT, "torque")
            .effort_measured(DFKI_SIMPLE_PENDULUM_JOINT, "torque")
    }

    /// The joints of this mapping, in position-column order.
    pub fn joints(&self) -> Vec<String> {
        self.position.iter().map(|(j, _)| j.clone()).collect()
    }

    /// Renames the joints, in position-column order (e.g. to match another URDF).
    ///
    /// # Panics
    /// If `names` does not have one name per joint.
    #[must_use]
    pub fn with_joint_names(mut self, names: &[&str]) -> CsvMapping {
        let old = self.joints();
        assert_eq!(old.len(), names.len(), "one new name per joint");
        let rename: HashMap<String, String> = old.into_iter().zip(names.iter().map(|s| s.to_string())).collect();
        for list in [
            &mut self.position,
            &mut self.velocity,
            &mut self.effort,
            &mut self.position_ref,
            &mut self.velocity_ref,
            &mut self.effort_ff,
            &mut self.effort_measured,
            &mut self.duty,
            &mut self.torque_enable,
            &mut self.temperature,
        ] {
            for (j, _) in list.iter_mut() {
                if let Some(n) = rename.get(j) {
                    *j = n.clone();
                }
            }
        }
        self
    }
}

/// The mapping for a CSV header: a DFKI layout when the header is one, else the generic
/// convention when the header has `time` and `q_<joint>` columns; `None` otherwise.
pub fn detect_mapping(header: &[String]) -> Option<CsvMapping> {
    let has = |c: &str| header.iter().any(|h| h == c);
    if ["time", "pos_meas1", "pos_meas2", "vel_filt1", "vel_filt2", "tau_con1", "tau_con2"].iter().all(|c| has(c)) {
        let mapping = CsvMapping::dfki_double_pendulum();
        if has("tau_meas1") && has("tau_meas2") {
            return Some(mapping.effort_measured(DFKI_DOUBLE_PENDULUM_JOINTS[0], "tau_meas1").effort_measured(DFKI_DOUBLE_PENDULUM_JOINTS[1], "tau_meas2"));
        }
        return Some(mapping);
    }
    if ["time", "pos1", "pos2", "vel1", "vel2", "tau1", "tau2"].iter().all(|c| has(c)) {
        return Some(CsvMapping::dfki_double_pendulum_sysid());
    }
    if header.len() == 4 && ["time", "position", "velocity", "torque"].iter().all(|c| has(c)) {
        return Some(CsvMapping::dfki_simple_pendulum());
    }
    if !has("time") {
        return None;
    }
    let joints: Vec<&str> = header.iter().filter_map(|h| h.strip_prefix("q_")).filter(|j| !j.starts_with("ref_") && !j.is_empty()).collect();
    if joints.is_empty() {
        return None;
    }
    // a quantity is mapped when any of its columns is there (missing ones then fail clearly)
    let any = |p: &str| joints.iter().any(|j| has(&format!("{p}{j}")));
    let mut mapping = CsvMapping::from_prefixes(
        "time",
        &joints,
        "q_",
        any("qd_").then_some("qd_"),
        any("tau_").then_some("tau_"),
        any("q_ref_").then_some("q_ref_"),
        any("qd_ref_").then_some("qd_ref_"),
    )
    .optional_reference(false);
    for j in &joints {
        if any("tau_ff_") {
            mapping = mapping.effort_ff(j, &format!("tau_ff_{j}"));
        }
        if any("tau_measured_") {
            mapping = mapping.effort_measured(j, &format!("tau_measured_{j}"));
        }
        // a position-controlled servo's signals
        for (prefix, list) in [("duty_", &mut mapping.duty), ("torque_enable_", &mut mapping.torque_enable), ("temperature_", &mut mapping.temperature)] {
            if any(prefix) {
                list.push((j.to_string(), format!("{prefix}{j}")));
            }
        }
    }
    if has("voltage") {
        mapping.voltage = Some("voltage".into());
    }
    Some(mapping)
}

/// What reading a CSV log whose writer did not finish (`*.partial.csv[.gz]`) left out.
#[derive(Debug, Default)]
struct Recovery {
    /// Bytes after the last line end (a cut last line), dropped.
    dropped: usize,
    /// The error that ended a cut gzip stream.
    cut: Option<String>,
}

/// Passes on the bytes of `inner` up to its last line end: a last line without one is dropped,
/// and an error (a gzip stream cut inside a member) ends the data; both are noted in
/// `recovery`. For the logs of a writer that was killed ([`crate::csv_sink`]).
struct CompleteLines<R> {
    inner: R,
    pending: Vec<u8>,
    /// `pending[start..ready]` is passed on; `pending[ready..]` waits for a line end.
    start: usize,
    ready: usize,
    eof: bool,
    recovery: std::rc::Rc<std::cell::RefCell<Recovery>>,
}

impl<R: Read> Read for CompleteLines<R> {
    fn read(&mut self, out: &mut [u8]) -> std::io::Result<usize> {
        loop {
            if self.start < self.ready {
                let n = out.len().min(self.ready - self.start);
                out[..n].copy_from_slice(&self.pending[self.start..self.start + n]);
                self.start += n;
                return Ok(n);
            }
            if self.eof {
                return Ok(0);
            }
            // refill: keep what waits for a line end
            self.pending.drain(..self.ready);
            self.start = 0;
            self.ready = 0;
            let mut buf = [0u8; 1 << 14];
            let end = match self.inner.read(&mut buf) {
                Ok(0) => None,
                Ok(n) => {
                    self.pending.extend_from_slice(&buf[..n]);
                    self.ready = self.pending.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
                    continue;
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => Some(e.to_string()),
            };
            let mut r = self.recovery.borrow_mut();
            r.dropped = self.pending.len();
            r.cut = end;
            self.pending.clear();
            self.eof = true;
        }
    }
}

/// Opens a possibly gzip-compressed file; a CSV log whose writer did not finish is read up to
/// its last line end ([`CompleteLines`]).
fn open_maybe_gz(path: &Path, recovery: &std::rc::Rc<std::cell::RefCell<Recovery>>) -> Result<Box<dyn Read>> {
    let file = File::open(path).map_err(|e| log_error(path, format!("cannot open: {e}")))?;
    let mut reader = BufReader::new(file);
    let magic = reader.fill_buf().map_err(|e| log_error(path, format!("cannot read: {e}")))?;
    let decoded: Box<dyn Read> = if magic.starts_with(&[0x1f, 0x8b]) { Box::new(flate2::read::MultiGzDecoder::new(reader)) } else { Box::new(reader) };
    if !crate::csv_sink::is_partial(path) {
        return Ok(decoded);
    }
    Ok(Box::new(CompleteLines { inner: decoded, pending: Vec::new(), start: 0, ready: 0, eof: false, recovery: recovery.clone() }))
}

fn csv_reader(path: &Path, recovery: &std::rc::Rc<std::cell::RefCell<Recovery>>) -> Result<csv::Reader<Box<dyn Read>>> {
    Ok(csv::ReaderBuilder::new().has_headers(true).trim(csv::Trim::All).comment(Some(b'#')).from_reader(open_maybe_gz(path, recovery)?))
}

/// The header of a CSV file (gzip handled).
///
/// # Errors
/// [`Error::Read`](crate::Error::Read) when the file cannot be read or has no header.
pub fn read_header(path: &Path) -> Result<Vec<String>> {
    let mut r = csv_reader(path, &Default::default())?;
    let h = r.headers().map_err(|e| log_error(path, format!("cannot read the CSV header: {e}")))?;
    Ok(h.iter().map(str::to_string).collect())
}

/// Reads a CSV log with a column mapping.
///
/// # Errors
/// [`Error::Read`](crate::Error::Read) naming the file and the problem: a mapped column missing from the header, a
/// cell that is not a number (with its line), joints mapped inconsistently, non-finite values,
/// time not strictly increasing.
pub fn read_csv(path: &Path, mapping: &CsvMapping) -> Result<Run> {
    let mut warnings = Vec::new();
    let run = read_csv_warned(path, mapping, &mut warnings)?;
    for w in &warnings {
        log::warn!("{}: {w}", path.display());
    }
    Ok(run)
}

/// [`read_csv`], with the warnings (a log whose writer did not finish) pushed to `warnings`.
pub(crate) fn read_csv_warned(path: &Path, mapping: &CsvMapping, warnings: &mut Vec<String>) -> Result<Run> {
    let err = |m: String| log_error(path, m);
    let joints = mapping.joints();
    if joints.is_empty() {
        return Err(err("the column mapping has no position column".into()));
    }
    let recovery = std::rc::Rc::new(std::cell::RefCell::new(Recovery::default()));
    let mut reader = csv_reader(path, &recovery)?;
    let header: Vec<String> = reader.headers().map_err(|e| err(format!("cannot read the CSV header: {e}")))?.iter().map(str::to_string).collect();
    let column = |name: &str, what: &str| -> Result<usize> {
        header.iter().position(|h| h == name).ok_or_else(|| err(format!("column '{name}' ({what}) is not in the header (columns: {})", header.join(","))))
    };
    // columns of each quantity, in joint order
    let t_col = column(&mapping.time, "time")?;
    let columns_of = |list: &[(String, String)], what: &str| -> Result<Vec<usize>> {
        if list.is_empty() {
            return Ok(Vec::new());
        }
        joints
            .iter()
            .map(|j| {
                let (_, c) = list.iter().find(|(lj, _)| lj == j).ok_or_else(|| err(format!("the column mapping gives a position but no {what} for joint '{j}'")))?;
                column(c, &format!("{what} of joint '{j}'"))
            })
            .collect()
    };
    let q_cols = columns_of(&mapping.position, "position")?;
    let qd_cols = columns_of(&mapping.velocity, "velocity")?;
    let tau_cols = columns_of(&mapping.effort, "effort")?;
    let ref_present = mapping.position_ref.iter().any(|(_, c)| header.contains(c));
    let (qr_cols, qdr_cols) = if mapping.optional_reference && !ref_present {
        (Vec::new(), Vec::new())
    } else {
        (columns_of(&mapping.position_ref, "reference position")?, columns_of(&mapping.velocity_ref, "reference velocity")?)
    };
    let ff_cols = columns_of(&mapping.effort_ff, "feed-forward effort")?;
    let measured_cols = columns_of(&mapping.effort_measured, "measured effort")?;
    let duty_cols = columns_of(&mapping.duty, "duty")?;
    let enable_cols = columns_of(&mapping.torque_enable, "torque enable")?;
    let temperature_cols = columns_of(&mapping.temperature, "temperature")?;
    let voltage_col = mapping.voltage.as_deref().map(|c| column(c, "supply voltage")).transpose()?;
    for list in [
        &mapping.velocity,
        &mapping.effort,
        &mapping.position_ref,
        &mapping.velocity_ref,
        &mapping.effort_ff,
        &mapping.effort_measured,
        &mapping.duty,
        &mapping.torque_enable,
        &mapping.temperature,
    ] {
        if let Some((j, _)) = list.iter().find(|(j, _)| !joints.contains(j)) {
            return Err(err(format!("the column mapping names joint '{j}', which has no position column")));
        }
    }

    // rows
    let dof = joints.len();
    let mut run = Run::new(joints);
    run.source = path.display().to_string();
    let mut record = csv::StringRecord::new();
    let mut t_ns: Vec<Option<i64>> = Vec::new();
    loop {
        match reader.read_record(&mut record) {
            Ok(true) => {}
            Ok(false) => break,
            Err(e) => return Err(err(format!("cannot read CSV: {e}"))),
        }
        let line = record.position().map_or(0, |p| p.line());
        let value = |i: usize| -> Result<f64> {
            let s = record.get(i).unwrap_or("");
            s.parse::<f64>().map_err(|_| err(format!("line {line}, column '{}': '{s}' is not a number", header[i])))
        };
        run.t.push(value(t_col)?);
        t_ns.push(record.get(t_col).and_then(decimal_ns));
        for (cols, out) in [
            (&q_cols, &mut run.q),
            (&qd_cols, &mut run.qd),
            (&tau_cols, &mut run.tau),
            (&qr_cols, &mut run.q_ref),
            (&qdr_cols, &mut run.qd_ref),
            (&ff_cols, &mut run.tau_ff),
            (&measured_cols, &mut run.tau_measured),
            (&duty_cols, &mut run.drive.duty),
            (&enable_cols, &mut run.drive.torque_enable),
            (&temperature_cols, &mut run.drive.temperature),
        ] {
            for &c in cols.iter() {
                out.push(value(c)?);
            }
        }
        if let Some(c) = voltage_col {
            run.drive.voltage.push(value(c)?);
        }
    }
    if crate::csv_sink::is_partial(path) {
        let r = recovery.borrow();
        let span = match (run.t.first(), run.t.last()) {
            (Some(a), Some(b)) => format!(" ({a:.4} s to {b:.4} s)"),
            _ => String::new(),
        };
        let mut w = format!("its writer did not finish (a killed `simgap simulate --out` leaves NAME.partial.csv): {} complete rows recovered{span}", run.len());
        if r.dropped > 0 {
            w.push_str(&format!("; a cut last line of {} bytes dropped", r.dropped));
        }
        if let Some(e) = &r.cut {
            w.push_str(&format!("; the compressed data end inside a gzip member ({e})"));
        }
        warnings.push(w);
    }
    if run.is_empty() {
        return Err(err("no data rows".into()));
    }
    absolute_to_relative(&mut run, &t_ns);
    if qd_cols.is_empty() {
        if let Some(i) = run.t.iter().position(|t| !t.is_finite()) {
            return Err(err(format!("time of sample {i} is {}", run.t[i])));
        }
        run.qd = central_difference(&run.t, &run.q, dof);
        run.source.push_str(" (velocity by central difference of position: the log has none)");
    }
    check_run(&run, path)?;
    Ok(run)
}

/// Epoch times after 1 Jan 2000 [s]: a CSV time column this large is absolute.
const EPOCH_2000_S: f64 = 946_684_800.0;

/// Turns absolute epoch times into `start_ns` and time since the start, exactly to the
/// nanosecond when the cells are plain decimals (`t_ns`), else to what f64 seconds hold.
fn absolute_to_relative(run: &mut Run, t_ns: &[Option<i64>]) {
    let Some(&t0) = run.t.first() else { return };
    if !(t0.is_finite() && t0 > EPOCH_2000_S && t0 < 1e11) {
        return;
    }
    match t_ns.iter().copied().collect::<Option<Vec<i64>>>() {
        Some(ns) => {
            let start = ns[0];
            for (t, n) in run.t.iter_mut().zip(&ns) {
                *t = (n - start) as f64 * 1e-9;
            }
            run.start_ns = Some(start);
        }
        None => {
            let start_ns = (t0 * 1e6).round() as i64 * 1000;
            let start_s = start_ns as f64 * 1e-9;
            for t in &mut run.t {
                *t -= start_s;
            }
            run.start_ns = Some(start_ns);
        }
    }
}

/// A plain decimal number of seconds (`123.456`, no exponent) as exact nanoseconds (digits
/// past the ninth decimal are cut).
fn decimal_ns(s: &str) -> Option<i64> {
    let (neg, s) = match s.strip_prefix('-') {
        Some(rest) => (true, rest),
        None => (false, s),
    };
    let (int, frac) = s.split_once('.').unwrap_or((s, ""));
    if int.is_empty() || int.len() > 11 || !int.bytes().all(|b| b.is_ascii_digit()) || !frac.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let mut ns: i64 = int.parse::<i64>().ok()? * 1_000_000_000;
    let mut scale = 100_000_000;
    for b in frac.bytes().take(9) {
        ns += i64::from(b - b'0') * scale;
        scale /= 10;
    }
    Some(if neg { -ns } else { ns })
}

/// The time cell of sample `k`: seconds since the run's start, or the absolute time written
/// exactly from nanoseconds when the run has `start_ns`.
fn time_cell(run: &Run, k: usize) -> String {
    match run.start_ns {
        Some(start) => {
            let ns = start + (run.t[k] * 1e9).round() as i64;
            let (s, frac) = (ns.div_euclid(1_000_000_000), ns.rem_euclid(1_000_000_000));
            format!("{s}.{frac:09}")
        }
        None => format!("{}", run.t[k]),
    }
}

/// Reads a CSV log whose mapping is detected from the header ([`detect_mapping`]), with the
/// experiment of its sidecar file when there is one
/// ([`sidecar_path`](crate::experiment::sidecar_path)).
///
/// # Errors
/// As [`read_csv`], and [`Error::Read`](crate::Error::Read) when the header matches no known layout or the sidecar
/// is malformed.
pub fn read_csv_auto(path: &Path) -> Result<Run> {
    let mut warnings = Vec::new();
    let run = read_csv_auto_warned(path, &mut warnings)?;
    for w in &warnings {
        log::warn!("{}: {w}", path.display());
    }
    Ok(run)
}

/// [`read_csv_auto`], with the warnings pushed to `warnings`.
pub(crate) fn read_csv_auto_warned(path: &Path, warnings: &mut Vec<String>) -> Result<Run> {
    let header = read_header(path)?;
    let mapping = detect_mapping(&header).ok_or_else(|| {
        log_error(
            path,
            format!(
                "cannot tell what the columns are: header '{}' is no DFKI layout and does not follow the generic convention \
                 (time, q_<joint>…, qd_<joint>…, tau_<joint>…, q_ref_<joint>…, qd_ref_<joint>…); pass a CsvMapping",
                header.join(",")
            ),
        )
    })?;
    let mut run = read_csv_warned(path, &mapping, warnings)?;
    if let Some(e) = crate::experiment::read_sidecar(path)? {
        run.experiment = Some(e);
        simgap_sim::fill_sample_period(&mut run);
        check_run(&run, path)?;
    }
    Ok(run)
}

/// Writes a run as CSV in the generic convention (gzip-compressed when the name ends in
/// `.gz`), a servo's drive signals included (`duty_<joint>`, `torque_enable_<joint>`,
/// `temperature_<joint>`, `voltage`). Numbers are written in shortest round-trip form, so
/// reading gives back the same values. Absolute runs (`start_ns` set) get absolute times in the file. The experiment is
/// not written (see [`write_experiment_file`](crate::experiment::write_experiment_file)).
///
/// # Errors
/// [`Error::Write`](crate::Error::Write) when the file cannot be written or a joint name contains a comma.
pub fn write_csv(run: &Run, path: &Path) -> Result<()> {
    let werr = |e: &dyn std::fmt::Display| write_error(path, e);
    if let Some(j) = run.joints.iter().find(|j| j.contains(',') || j.contains('"')) {
        return Err(werr(&format!("joint name '{j}' cannot be a CSV column")));
    }
    let file = File::create(path).map_err(|e| werr(&e))?;
    let gz = path.to_string_lossy().to_lowercase().ends_with(".gz");
    let out: Box<dyn Write> = if gz { Box::new(flate2::write::GzEncoder::new(BufWriter::new(file), flate2::Compression::default())) } else { Box::new(BufWriter::new(file)) };
    let mut w = csv::WriterBuilder::new().from_writer(out);
    let dof = run.dof();
    // header
    let blocks: Vec<(&str, &[f64])> = [
        ("q_", &run.q[..]),
        ("qd_", &run.qd[..]),
        ("tau_", &run.tau[..]),
        ("q_ref_", &run.q_ref[..]),
        ("qd_ref_", &run.qd_ref[..]),
        ("tau_ff_", &run.tau_ff[..]),
        ("tau_measured_", &run.tau_measured[..]),
        ("duty_", &run.drive.duty[..]),
        ("torque_enable_", &run.drive.torque_enable[..]),
        ("temperature_", &run.drive.temperature[..]),
    ]
    .into_iter()
    .filter(|(_, m)| !m.is_empty())
    .collect();
    let voltage = (!run.drive.voltage.is_empty()).then_some(&run.drive.voltage);
    let mut header = vec!["time".to_string()];
    for (p, _) in &blocks {
        header.extend(run.joints.iter().map(|j| format!("{p}{j}")));
    }
    if voltage.is_some() {
        header.push("voltage".into());
    }
    w.write_record(&header).map_err(|e| werr(&e))?;
    // rows
    let mut row: Vec<String> = Vec::with_capacity(header.len());
    for k in 0..run.len() {
        row.clear();
        row.push(time_cell(run, k));
        for (_, m) in &blocks {
            row.extend(m[k * dof..(k + 1) * dof].iter().map(|x| format!("{x}")));
        }
        if let Some(v) = voltage {
            row.push(format!("{}", v[k]));
        }
        w.write_record(&row).map_err(|e| werr(&e))?;
    }
    let out = w.into_inner().map_err(|e| werr(&e.error().to_string()))?;
    finish_writer(out).map_err(|e| werr(&e))
}

fn finish_writer(mut out: Box<dyn Write>) -> std::io::Result<()> {
    // flushing the GzEncoder writes the stream so far; dropping it writes the trailer
    out.flush()?;
    drop(out);
    Ok(())
}
