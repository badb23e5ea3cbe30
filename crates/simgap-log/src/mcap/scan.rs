//! A bounded linear scan of an MCAP file's data section.
//!
//! Every record is `opcode (u8) | length (u64) | body`; chunks hold more records, compressed
//! (`lz4`, `zstd`) or not. The scan trusts no length: a record is read only when its length fits
//! in the bytes the file still has, a chunk is decompressed only into a buffer of its declared
//! size, and that size must be within [`MAX_CHUNK_RATIO`] of its compressed size (the zstd
//! decoder writes into that buffer and nowhere else). So memory stays within a constant times
//! the file's size whatever the bytes say, and every loop advances through the file.
//!
//! The scan stops at the data-end record (the summary after it repeats what the data section
//! holds). A file that ends before it, at a record boundary or inside a record (a recorder that
//! was killed), is not an error here: [`ScanEnd`] says how far the data went, and the reader
//! decides what it can recover.

use std::collections::BTreeMap;
use std::io::Read;

/// The magic bytes that open (and close) an MCAP file.
pub const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

/// Largest accepted ratio of a chunk's declared uncompressed size to its compressed size.
/// Joint-state chunks compress 2–10× with lz4 or zstd; a corrupt size asking for more is
/// refused before any allocation.
pub const MAX_CHUNK_RATIO: u64 = 1024;

/// A record of the data section, as the reader needs it.
pub(crate) enum Record<'a> {
    /// A schema: id, name, encoding, definition bytes.
    Schema { id: u16, name: String, encoding: String, data: &'a [u8] },
    /// A channel: id, schema id, topic, message encoding.
    Channel { id: u16, schema_id: u16, topic: String, message_encoding: String },
    /// A message: channel, log time [ns], payload.
    Message { channel_id: u16, log_time: u64, data: &'a [u8] },
    /// A metadata record: name and string map.
    Metadata { name: String, map: BTreeMap<String, String> },
}

/// Where a record is in the file: at a byte of the file, or at an offset within the
/// decompressed records of the chunk that starts at a byte of the file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Location {
    /// The record's opcode.
    pub opcode: u8,
    /// Byte of the file where the record (or the chunk holding it) starts.
    pub byte: u64,
    /// Offset of the record within its chunk's decompressed records, for a record in a chunk.
    pub in_chunk: Option<u64>,
}

impl std::fmt::Display for Location {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let kind = record_name(self.opcode);
        match self.in_chunk {
            Some(offset) => write!(f, "{kind} record at offset {offset} of the chunk at byte {}", self.byte),
            None => write!(f, "{kind} record at byte {}", self.byte),
        }
    }
}

/// The name of a record type (MCAP specification).
pub(crate) fn record_name(opcode: u8) -> String {
    match opcode {
        0x01 => "header".into(),
        0x02 => "footer".into(),
        0x03 => "schema".into(),
        0x04 => "channel".into(),
        0x05 => "message".into(),
        0x06 => "chunk".into(),
        0x07 => "message index".into(),
        0x08 => "chunk index".into(),
        0x09 => "attachment".into(),
        0x0A => "attachment index".into(),
        0x0B => "statistics".into(),
        0x0C => "metadata".into(),
        0x0D => "metadata index".into(),
        0x0E => "summary offset".into(),
        0x0F => "data end".into(),
        op => format!("opcode 0x{op:02X}"),
    }
}

/// How a scan ended.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct ScanEnd {
    /// True when the data section ended with its data-end record (a finished file).
    pub complete: bool,
    /// Bytes of the file up to the end of the last complete record.
    pub valid_bytes: u64,
    /// Size of the file.
    pub total_bytes: u64,
    /// The record the file ends inside, when it does: opcode and declared length (`None`: the
    /// file ends at a record boundary or inside a record's 9-byte header).
    pub cut: Option<(u8, u64)>,
}

impl ScanEnd {
    /// Where the data section stops, in words: the record the file ends in (or the record
    /// boundary) and the byte.
    pub(crate) fn describe(&self) -> String {
        match self.cut {
            Some((op, len)) => format!(
                "the {} record at byte {} declares {len} bytes but the file ends {} bytes after its header (at byte {})",
                record_name(op),
                self.valid_bytes,
                self.total_bytes - self.valid_bytes - 9,
                self.total_bytes
            ),
            None => format!("the records end at byte {} of {} without a data end record", self.valid_bytes, self.total_bytes),
        }
    }
}

/// Reads exactly `n` bytes into `buf` (resized; `n` was checked against the file's size).
fn read_into(r: &mut impl Read, buf: &mut Vec<u8>, n: usize) -> Result<(), String> {
    buf.clear();
    buf.resize(n, 0);
    r.read_exact(buf).map_err(|e| format!("read error: {e}"))
}

/// Scans the data section of an MCAP stream of `total` bytes, calling `on_record` for every
/// schema, channel, message and metadata record, in file order, with where the record is.
///
/// # Errors
/// A message saying what is wrong, in which record and at which byte: not an MCAP file, a
/// record whose fields overrun it, a chunk that does not decompress to its declared size or
/// fails its CRC, a read error; or the error `on_record` returned, after the record's
/// [`Location`].
pub(crate) fn scan(mut input: impl Read, total: u64, mut on_record: impl FnMut(Record<'_>, Location) -> Result<(), String>) -> Result<ScanEnd, String> {
    let mut magic = [0u8; 8];
    if total < 8 || input.read_exact(&mut magic).is_err() || &magic != MAGIC {
        return Err("not an MCAP file (the magic bytes that open an MCAP file are not at byte 0)".into());
    }
    let mut pos = 8u64;
    let mut body = Vec::new();
    let mut chunk = Vec::new();
    let incomplete = |pos: u64, cut: Option<(u8, u64)>| Ok(ScanEnd { complete: false, valid_bytes: pos, total_bytes: total, cut });
    loop {
        // record header: opcode and length, both within the file
        if total - pos < 9 {
            return incomplete(pos, None);
        }
        let mut head = [0u8; 9];
        input.read_exact(&mut head).map_err(|e| format!("record at byte {pos}: read error: {e}"))?;
        let opcode = head[0];
        let len = u64::from_le_bytes([head[1], head[2], head[3], head[4], head[5], head[6], head[7], head[8]]);
        if len > total - pos - 9 {
            return incomplete(pos, Some((opcode, len)));
        }
        read_into(&mut input, &mut body, len as usize).map_err(|e| format!("{} record at byte {pos}: {e}", record_name(opcode)))?;
        let at = pos;
        pos += 9 + len;
        match opcode {
            // footer or data end: the data section is over
            0x02 | 0x0F => return Ok(ScanEnd { complete: true, valid_bytes: pos, total_bytes: total, cut: None }),
            0x06 => {
                decompress_chunk(&body, &mut chunk).map_err(|e| format!("chunk record at byte {at}: {e}"))?;
                let mut c = Cursor::new(&chunk);
                while !c.is_empty() {
                    let inner_at = c.pos;
                    let head = |e: String| format!("record at offset {inner_at} of the chunk at byte {at}: {e}");
                    let op = c.u8().map_err(head)?;
                    let n = c.u64().map_err(head)?;
                    let rec = c.bytes(n).map_err(head)?;
                    let location = Location { opcode: op, byte: at, in_chunk: Some(inner_at as u64) };
                    dispatch(op, rec, location, &mut on_record).map_err(|e| format!("{location}: {e}"))?;
                }
            }
            op => {
                let location = Location { opcode: op, byte: at, in_chunk: None };
                dispatch(op, &body, location, &mut on_record).map_err(|e| format!("{location}: {e}"))?
            }
        }
    }
}

/// Parses one record and hands it over (records the reader does not need are skipped).
fn dispatch(opcode: u8, body: &[u8], location: Location, on_record: &mut impl FnMut(Record<'_>, Location) -> Result<(), String>) -> Result<(), String> {
    let mut c = Cursor::new(body);
    let record = match opcode {
        0x03 => {
            let id = c.u16()?;
            let name = c.string()?;
            let encoding = c.string()?;
            let n = c.u32()?;
            Record::Schema { id, name, encoding, data: c.bytes(u64::from(n))? }
        }
        0x04 => {
            let id = c.u16()?;
            let schema_id = c.u16()?;
            let topic = c.string()?;
            let message_encoding = c.string()?;
            c.map()?;
            Record::Channel { id, schema_id, topic, message_encoding }
        }
        0x05 => {
            let channel_id = c.u16()?;
            let _sequence = c.u32()?;
            let log_time = c.u64()?;
            let _publish_time = c.u64()?;
            Record::Message { channel_id, log_time, data: c.rest() }
        }
        0x0C => {
            let name = c.string()?;
            let map = c.map()?;
            Record::Metadata { name, map }
        }
        _ => return Ok(()),
    };
    on_record(record, location)
}

/// Decompresses a chunk record's records into `out`, checking size and CRC.
fn decompress_chunk(body: &[u8], out: &mut Vec<u8>) -> Result<(), String> {
    let mut c = Cursor::new(body);
    let _start = c.u64()?;
    let _end = c.u64()?;
    let size = c.u64()?;
    let crc = c.u32()?;
    let compression = c.string()?;
    let n = c.u64()?;
    let data = c.bytes(n)?;
    let compressed = data.len() as u64;
    if size > compressed.saturating_mul(MAX_CHUNK_RATIO).saturating_add(4096) {
        return Err(format!("declares {size} uncompressed bytes for {compressed} compressed ones (corrupt size)"));
    }
    out.clear();
    match compression.as_str() {
        "" => {
            if size != compressed {
                return Err(format!("uncompressed chunk declares {size} bytes but holds {compressed}"));
            }
            out.extend_from_slice(data);
        }
        "zstd" => {
            // decodes into a buffer of exactly the declared size, nothing else
            let got = zstd::bulk::decompress(data, size as usize).map_err(|e| format!("zstd data does not decompress: {e}"))?;
            *out = got;
        }
        "lz4" => {
            out.reserve_exact(size as usize);
            let decoder = lz4::Decoder::new(data).map_err(|e| format!("lz4 data does not decompress: {e}"))?;
            decoder.take(size + 1).read_to_end(out).map_err(|e| format!("lz4 data does not decompress: {e}"))?;
        }
        other => return Err(format!("unsupported chunk compression '{other}' (expected lz4, zstd or none)")),
    }
    if out.len() as u64 != size {
        return Err(format!("decompresses to {} bytes, declared {size}", out.len()));
    }
    if crc != 0 && crc32fast::hash(out) != crc {
        return Err("CRC of the decompressed records does not match (corrupt chunk)".into());
    }
    Ok(())
}

/// Reads little-endian fields from a record body, every length checked against what remains.
struct Cursor<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn new(data: &'a [u8]) -> Self {
        Cursor { data, pos: 0 }
    }

    fn is_empty(&self) -> bool {
        self.pos >= self.data.len()
    }

    fn bytes(&mut self, n: u64) -> Result<&'a [u8], String> {
        let left = (self.data.len() - self.pos) as u64;
        if n > left {
            return Err(format!("a field of {n} bytes overruns its record ({left} bytes left)"));
        }
        let s = &self.data[self.pos..self.pos + n as usize];
        self.pos += n as usize;
        Ok(s)
    }

    fn rest(&mut self) -> &'a [u8] {
        let s = &self.data[self.pos..];
        self.pos = self.data.len();
        s
    }

    fn u8(&mut self) -> Result<u8, String> {
        Ok(self.bytes(1)?[0])
    }

    fn u16(&mut self) -> Result<u16, String> {
        let b = self.bytes(2)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }

    fn u32(&mut self) -> Result<u32, String> {
        let b = self.bytes(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    fn u64(&mut self) -> Result<u64, String> {
        let b = self.bytes(8)?;
        Ok(u64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]))
    }

    fn string(&mut self) -> Result<String, String> {
        let n = self.u32()?;
        let b = self.bytes(u64::from(n))?;
        String::from_utf8(b.to_vec()).map_err(|_| "a string is not UTF-8".to_string())
    }

    fn map(&mut self) -> Result<BTreeMap<String, String>, String> {
        let n = self.u32()?;
        let mut inner = Cursor::new(self.bytes(u64::from(n))?);
        let mut map = BTreeMap::new();
        while !inner.is_empty() {
            let k = inner.string()?;
            let v = inner.string()?;
            map.insert(k, v);
        }
        Ok(map)
    }
}
