//! CDR, the serialisation of ROS 2 messages: primitives aligned to their size relative to the
//! end of the 4-byte encapsulation header (`00 01 00 00` little-endian; `00 00` big-endian is
//! read too), strings as a `u32` length including the NUL terminator, sequences as a `u32`
//! count then the elements (aligned only when there is at least one, as Fast-CDR and
//! `mcap_ros2` do).
//!
//! [`JointState`] is encoded by hand here (the writer's hot path); reading any message type is
//! [`crate::mcap::schema`]'s job. Every count read is checked against the bytes that remain
//! before anything is allocated.

/// The byte order of a CDR message from its encapsulation header.
///
/// # Errors
/// [`CdrError`] for a message shorter than the header or another encapsulation than plain CDR.
pub fn encapsulation(data: &[u8]) -> Result<bool, CdrError> {
    if data.len() < 4 {
        return Err(CdrError(format!("message of {} bytes has no CDR encapsulation header", data.len())));
    }
    match (data[0], data[1]) {
        (0x00, 0x01) | (0x00, 0x03) => Ok(true),
        (0x00, 0x00) | (0x00, 0x02) => Ok(false),
        (a, b) => Err(CdrError(format!("unsupported CDR encapsulation {a:#04x} {b:#04x} (expected plain CDR)"))),
    }
}

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
        encode_parts(buf, self.sec, self.nanosec, &self.frame_id, &self.name, &self.position, &self.velocity, &self.effort);
    }

    /// Decodes a CDR message (little- or big-endian) with its encapsulation header.
    ///
    /// # Errors
    /// [`CdrError`] naming the field where the data ended or was invalid.
    pub fn decode_cdr(data: &[u8]) -> std::result::Result<JointState, CdrError> {
        if data.len() < 4 {
            return Err(CdrError(format!("message of {} bytes has no CDR encapsulation header", data.len())));
        }
        let little = encapsulation(data)?;
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

/// Appends a `sensor_msgs/msg/JointState` stamped `ns` [ns since the epoch] (empty frame id)
/// to `buf`, encapsulation header included: the writer's hot path, no allocation once `buf`
/// has grown.
pub(crate) fn encode_joint_state_into(buf: &mut Vec<u8>, ns: i64, names: &[String], position: &[f64], velocity: &[f64], effort: &[f64]) {
    let sec = ns.div_euclid(1_000_000_000) as i32;
    let nanosec = ns.rem_euclid(1_000_000_000) as u32;
    encode_parts(buf, sec, nanosec, "", names, position, velocity, effort);
}

/// The CDR bytes of a `sensor_msgs/msg/JointState` for fixed joint names and array lengths
/// (empty frame id), with where the stamp and the values go: encoding a message is then one copy
/// and the stamp and values written in place, the same bytes as [`encode_joint_state_into`].
#[derive(Clone, Debug)]
pub(crate) struct JointStateTemplate {
    bytes: Vec<u8>,
    /// Offset of each array's first value in `bytes` (position, velocity, effort).
    data: [usize; 3],
    lens: [usize; 3],
}

impl JointStateTemplate {
    /// The template of messages naming `names` with arrays of `lens` values.
    pub(crate) fn new(names: &[String], lens: [usize; 3]) -> Self {
        let zeros: Vec<Vec<f64>> = lens.iter().map(|&l| vec![0.0; l]).collect();
        let mut bytes = Vec::new();
        encode_parts(&mut bytes, 0, 0, "", names, &zeros[0], &zeros[1], &zeros[2]);
        // where the arrays start: after the names, each a u32 count (aligned to 4) and, when not
        // empty, its values aligned to 8, alignment relative to the end of the 4-byte
        // encapsulation header; with empty arrays the message ends with the three counts
        let mut empty = Vec::new();
        encode_parts(&mut empty, 0, 0, "", names, &[], &[], &[]);
        let base = 4;
        let align = |x: usize, n: usize| x.div_ceil(n) * n;
        let mut off = empty.len() - 12 - base;
        let mut data = [0; 3];
        for (i, &l) in lens.iter().enumerate() {
            off = align(off, 4) + 4;
            if l > 0 {
                off = align(off, 8);
                data[i] = base + off;
                off += 8 * l;
            }
        }
        debug_assert_eq!(base + off, bytes.len());
        JointStateTemplate { bytes, data, lens }
    }

    /// The bytes of every message of this template, stamp and values zero.
    pub(crate) fn bytes(&self) -> &[u8] {
        &self.bytes
    }

    /// Offset of the first value of each array (position, velocity, effort) in [`Self::bytes`].
    pub(crate) fn value_offsets(&self) -> [usize; 3] {
        self.data
    }

    /// Whether messages with arrays of `lens` values use this template.
    pub(crate) fn fits(&self, lens: [usize; 3]) -> bool {
        self.lens == lens
    }

    /// Appends the message stamped `ns` [ns since the epoch] with `values` (position, velocity,
    /// effort; lengths as the template's) to `buf`.
    #[cfg(test)]
    pub(crate) fn encode_into(&self, buf: &mut Vec<u8>, ns: i64, values: [&[f64]; 3]) {
        let at = buf.len();
        buf.extend_from_slice(&self.bytes);
        let sec = ns.div_euclid(1_000_000_000) as i32;
        let nanosec = ns.rem_euclid(1_000_000_000) as u32;
        buf[at + 4..at + 8].copy_from_slice(&sec.to_le_bytes());
        buf[at + 8..at + 12].copy_from_slice(&nanosec.to_le_bytes());
        for (i, v) in values.iter().enumerate() {
            let start = at + self.data[i];
            for (x, out) in v.iter().zip(buf[start..start + 8 * v.len()].chunks_exact_mut(8)) {
                out.copy_from_slice(&x.to_le_bytes());
            }
        }
    }
}

#[allow(clippy::too_many_arguments)]
fn encode_parts(buf: &mut Vec<u8>, sec: i32, nanosec: u32, frame_id: &str, names: &[String], position: &[f64], velocity: &[f64], effort: &[f64]) {
    buf.extend_from_slice(&[0x00, 0x01, 0x00, 0x00]);
    let base = buf.len();
    let mut w = CdrWriter { buf, base };
    w.i32(sec);
    w.u32(nanosec);
    w.string(frame_id);
    w.u32(names.len() as u32);
    for s in names {
        w.string(s);
    }
    w.f64_seq(position);
    w.f64_seq(velocity);
    w.f64_seq(effort);
}

/// Appends CDR little-endian values, aligned relative to `base` (the end of the encapsulation
/// header).
struct CdrWriter<'a> {
    buf: &'a mut Vec<u8>,
    base: usize,
}

impl CdrWriter<'_> {
    fn align(&mut self, n: usize) {
        while (self.buf.len() - self.base) % n != 0 {
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

pub(crate) struct CdrReader<'a> {
    data: &'a [u8],
    pos: usize,
    pub(crate) little: bool,
}

impl<'a> CdrReader<'a> {
    /// A reader of a CDR payload after its 4-byte encapsulation header.
    pub(crate) fn new(data: &'a [u8], little: bool) -> Self {
        CdrReader { data, pos: 0, little }
    }

    /// Bytes not read yet.
    pub(crate) fn remaining(&self) -> usize {
        self.data.len().saturating_sub(self.pos)
    }

    pub(crate) fn take(&mut self, n: usize, align: usize, field: &str) -> std::result::Result<&[u8], CdrError> {
        let start = self.pos.div_ceil(align) * align;
        if start > self.data.len() || n > self.data.len() - start {
            return Err(CdrError(format!("message truncated in field '{field}' ({} bytes of CDR payload)", self.data.len())));
        }
        self.pos = start + n;
        Ok(&self.data[start..start + n])
    }
    pub(crate) fn u32(&mut self, field: &str) -> std::result::Result<u32, CdrError> {
        let little = self.little;
        let s = self.take(4, 4, field)?;
        let b = [s[0], s[1], s[2], s[3]];
        Ok(if little { u32::from_le_bytes(b) } else { u32::from_be_bytes(b) })
    }
    pub(crate) fn i32(&mut self, field: &str) -> std::result::Result<i32, CdrError> {
        Ok(self.u32(field)? as i32)
    }
    pub(crate) fn f64(&mut self, field: &str) -> std::result::Result<f64, CdrError> {
        let little = self.little;
        let s = self.take(8, 8, field)?;
        let b = [s[0], s[1], s[2], s[3], s[4], s[5], s[6], s[7]];
        Ok(if little { f64::from_le_bytes(b) } else { f64::from_be_bytes(b) })
    }
    /// A sequence count, checked against the bytes left (`min_size` bytes per element).
    pub(crate) fn count(&mut self, field: &str, min_size: usize) -> std::result::Result<usize, CdrError> {
        let n = self.u32(field)? as usize;
        if n.saturating_mul(min_size.max(1)) > self.remaining() {
            return Err(CdrError(format!("field '{field}' claims {n} elements but the message is shorter")));
        }
        Ok(n)
    }
    pub(crate) fn string(&mut self, field: &str) -> std::result::Result<String, CdrError> {
        let n = self.count(field, 1)?;
        let bytes = self.take(n, 1, field)?;
        let bytes = bytes.strip_suffix(&[0]).unwrap_or(bytes);
        String::from_utf8(bytes.to_vec()).map_err(|_| CdrError(format!("field '{field}' is not UTF-8")))
    }
    pub(crate) fn f64_seq(&mut self, field: &str) -> std::result::Result<Vec<f64>, CdrError> {
        let n = self.count(field, 8)?;
        (0..n).map(|_| self.f64(field)).collect()
    }
}

#[cfg(test)]
mod template_tests {
    use super::{encode_joint_state_into, JointStateTemplate};

    #[test]
    fn template_encoding_gives_the_bytes_of_the_direct_encoding() {
        let name_sets: [&[&str]; 4] = [&["a"], &["shoulder", "elbow"], &["j1", "joint_two", "x", "a_long_joint_name"], &["abc", "de", "f", "ghij", "k", "lm", "nop"]];
        for names in name_sets {
            let names: Vec<String> = names.iter().map(|s| s.to_string()).collect();
            let n = names.len();
            for lens in [[n, n, n], [n, 0, n], [0, 0, n], [n, n, 0], [n, 0, 0]] {
                let t = JointStateTemplate::new(&names, lens);
                for (k, ns) in [0i64, 1_712_345_678_123_456_789, -1_500_000_000, 2_500_000].into_iter().enumerate() {
                    let v: Vec<Vec<f64>> = lens.iter().enumerate().map(|(i, &l)| (0..l).map(|j| (k * 31 + i * 7 + j) as f64 * 0.37 - 1.1).collect()).collect();
                    let mut direct = vec![9u8; 3];
                    encode_joint_state_into(&mut direct, ns, &names, &v[0], &v[1], &v[2]);
                    let mut templated = vec![9u8; 3];
                    t.encode_into(&mut templated, ns, [&v[0], &v[1], &v[2]]);
                    assert_eq!(templated, direct, "names {names:?}, lengths {lens:?}, stamp {ns}");
                }
            }
        }
    }
}
