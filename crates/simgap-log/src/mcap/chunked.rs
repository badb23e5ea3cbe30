//! An MCAP file written from whole chunks (the [MCAP specification](https://mcap.dev/spec)):
//! the writer thread of [`McapSink`](super::McapSink) receives a chunk's message records already
//! encoded, compresses the whole chunk in one call and appends it with its message indexes, so
//! that the cost per message is a copy, not a call into a streaming compressor.
//!
//! Layout: magic, header, then in the data section schema, channel and metadata records at the
//! top level (a channel before the first chunk that uses it) and chunks each followed by their
//! message index records; then data end, the summary (schemas, channels, statistics, chunk
//! indexes, metadata indexes), summary offsets, footer and magic. The file only ever grows by
//! whole records, so a writer killed at any instant leaves every complete chunk readable by a
//! linear scan. CRCs: every chunk's uncompressed records; data section and summary CRCs are
//! written as 0 (not computed, as the specification allows).

use std::collections::BTreeMap;
use std::io::Write;

use super::cdr::JointStateTemplate;

/// Record opcodes.
mod op {
    pub(super) const HEADER: u8 = 0x01;
    pub(super) const FOOTER: u8 = 0x02;
    pub(super) const SCHEMA: u8 = 0x03;
    pub(super) const CHANNEL: u8 = 0x04;
    pub(super) const MESSAGE: u8 = 0x05;
    pub(super) const CHUNK: u8 = 0x06;
    pub(super) const MESSAGE_INDEX: u8 = 0x07;
    pub(super) const CHUNK_INDEX: u8 = 0x08;
    pub(super) const STATISTICS: u8 = 0x0B;
    pub(super) const METADATA: u8 = 0x0C;
    pub(super) const METADATA_INDEX: u8 = 0x0D;
    pub(super) const SUMMARY_OFFSET: u8 = 0x0E;
    pub(super) const DATA_END: u8 = 0x0F;
}

/// Chunk compression as the file names it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ChunkCompression {
    None,
    Lz4,
    /// Zstandard at this level.
    Zstd(i32),
}

/// Little-endian record fields into a buffer.
#[derive(Default)]
pub(crate) struct Fields(pub(crate) Vec<u8>);

impl Fields {
    fn u8(&mut self, v: u8) -> &mut Self {
        self.0.push(v);
        self
    }
    fn u16(&mut self, v: u16) -> &mut Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn u32(&mut self, v: u32) -> &mut Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn u64(&mut self, v: u64) -> &mut Self {
        self.0.extend_from_slice(&v.to_le_bytes());
        self
    }
    fn string(&mut self, s: &str) -> &mut Self {
        self.u32(s.len() as u32);
        self.0.extend_from_slice(s.as_bytes());
        self
    }
    fn map(&mut self, m: &BTreeMap<String, String>) -> &mut Self {
        let mut inner = Fields::default();
        for (k, v) in m {
            inner.string(k).string(v);
        }
        self.u32(inner.0.len() as u32);
        self.0.extend_from_slice(&inner.0);
        self
    }
}

/// A message record of one channel whose data is a `sensor_msgs/msg/JointState` of fixed
/// layout: appending one is one copy of the record's bytes and the sequence, times, stamp and
/// values written in place (the bytes of the CDR encoder, see the template test in `cdr`).
pub(crate) struct MessageTemplate {
    /// The whole record: opcode, record length, channel, sequence, log time, publish time (31
    /// bytes), then the CDR message.
    bytes: Vec<u8>,
    /// Offset of each array's first value in `bytes`.
    values: [usize; 3],
    cdr: JointStateTemplate,
}

/// Offset of the CDR message in a message record.
const MESSAGE_DATA: usize = 31;

impl MessageTemplate {
    /// The records of `channel` carrying `cdr` messages.
    pub(crate) fn new(channel: u16, cdr: JointStateTemplate) -> Self {
        let mut bytes = vec![0u8; MESSAGE_DATA];
        bytes[0] = op::MESSAGE;
        bytes[1..9].copy_from_slice(&((MESSAGE_DATA - 9 + cdr.bytes().len()) as u64).to_le_bytes());
        bytes[9..11].copy_from_slice(&channel.to_le_bytes());
        bytes.extend_from_slice(cdr.bytes());
        let values = cdr.value_offsets().map(|o| o + MESSAGE_DATA);
        MessageTemplate { bytes, values, cdr }
    }

    /// Whether messages with arrays of `lens` values use this template.
    pub(crate) fn fits(&self, lens: [usize; 3]) -> bool {
        self.cdr.fits(lens)
    }

    /// The channel of the records.
    pub(crate) fn channel(&self) -> u16 {
        u16::from_le_bytes([self.bytes[9], self.bytes[10]])
    }

    /// Appends the message record (log and publish time `time`, stamp `ns`) to `records`;
    /// returns its offset.
    pub(crate) fn push(&self, records: &mut Vec<u8>, sequence: u32, time: u64, ns: i64, values: [&[f64]; 3]) -> u64 {
        let at = records.len();
        records.extend_from_slice(&self.bytes);
        let rec = &mut records[at..];
        rec[11..15].copy_from_slice(&sequence.to_le_bytes());
        rec[15..23].copy_from_slice(&time.to_le_bytes());
        rec[23..31].copy_from_slice(&time.to_le_bytes());
        // the stamp, after the 4-byte encapsulation header
        let sec = ns.div_euclid(1_000_000_000) as i32;
        let nanosec = ns.rem_euclid(1_000_000_000) as u32;
        rec[MESSAGE_DATA + 4..MESSAGE_DATA + 8].copy_from_slice(&sec.to_le_bytes());
        rec[MESSAGE_DATA + 8..MESSAGE_DATA + 12].copy_from_slice(&nanosec.to_le_bytes());
        for (v, &o) in values.iter().zip(&self.values) {
            for (x, out) in v.iter().zip(rec[o..o + 8 * v.len()].chunks_exact_mut(8)) {
                out.copy_from_slice(&x.to_le_bytes());
            }
        }
        at as u64
    }
}

/// One chunk as it is filled: its message records, and per channel the entries of its message
/// index (log time, offset of the record within `records`, little-endian) as they were noted.
#[derive(Default)]
pub(crate) struct ChunkBuf {
    pub(crate) records: Vec<u8>,
    /// Per channel id: message index entries, 16 bytes each.
    entries: Vec<Vec<u8>>,
    /// Per channel id: the last log time noted, and whether the entries are in order of it.
    order: Vec<(u64, bool)>,
    /// Earliest and latest log time noted.
    span: Option<(u64, u64)>,
}

impl ChunkBuf {
    /// A chunk whose records may grow to `capacity` bytes without reallocating.
    pub(crate) fn with_capacity(capacity: usize) -> Self {
        ChunkBuf { records: Vec::with_capacity(capacity), ..ChunkBuf::default() }
    }

    /// Notes the message record of `channel` at `offset` in `records`, logged at `time`.
    pub(crate) fn note(&mut self, channel: u16, time: u64, offset: u64) {
        let c = channel as usize;
        if self.entries.len() <= c {
            self.entries.resize_with(c + 1, Vec::new);
            self.order.resize(c + 1, (0, true));
        }
        let (last, sorted) = &mut self.order[c];
        if time < *last && !self.entries[c].is_empty() {
            *sorted = false;
        }
        *last = time;
        let mut entry = [0u8; 16];
        entry[..8].copy_from_slice(&time.to_le_bytes());
        entry[8..].copy_from_slice(&offset.to_le_bytes());
        self.entries[c].extend_from_slice(&entry);
        self.span = Some(self.span.map_or((time, time), |(a, b)| (a.min(time), b.max(time))));
    }

    /// Whether no message was noted.
    pub(crate) fn is_empty(&self) -> bool {
        self.span.is_none()
    }

    pub(crate) fn clear(&mut self) {
        self.records.clear();
        for e in &mut self.entries {
            e.clear();
        }
        self.order.iter_mut().for_each(|o| *o = (0, true));
        self.span = None;
    }
}

struct ChunkIndex {
    start: u64,
    end: u64,
    offset: u64,
    length: u64,
    index_offsets: BTreeMap<u16, u64>,
    index_length: u64,
    compressed: u64,
    uncompressed: u64,
}

/// A channel as written: id, schema id, topic, message encoding, metadata.
type ChannelRecord = (u16, u16, String, String, BTreeMap<String, String>);

/// Writes an MCAP file record by record (see the [module docs](self)).
pub(crate) struct ChunkedWriter<W: Write> {
    out: W,
    pos: u64,
    compression: ChunkCompression,
    schemas: Vec<(u16, String, String, Vec<u8>)>,
    channels: Vec<ChannelRecord>,
    metadata: Vec<(u64, u64, String)>,
    chunks: Vec<ChunkIndex>,
    counts: BTreeMap<u16, u64>,
    span: Option<(u64, u64)>,
    compressed: Vec<u8>,
    zstd: Option<zstd::bulk::Compressor<'static>>,
    record: Fields,
}

impl<W: Write> ChunkedWriter<W> {
    /// Starts the file: magic and header record.
    pub(crate) fn new(out: W, profile: &str, library: &str, compression: ChunkCompression) -> std::io::Result<Self> {
        let mut w = ChunkedWriter {
            out,
            pos: 0,
            compression,
            schemas: Vec::new(),
            channels: Vec::new(),
            metadata: Vec::new(),
            chunks: Vec::new(),
            counts: BTreeMap::new(),
            span: None,
            compressed: Vec::new(),
            zstd: None,
            record: Fields::default(),
        };
        w.raw(super::scan::MAGIC)?;
        let mut f = Fields::default();
        f.string(profile).string(library);
        w.write_record(op::HEADER, &f.0)?;
        Ok(w)
    }

    fn raw(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.out.write_all(bytes)?;
        self.pos += bytes.len() as u64;
        Ok(())
    }

    /// Writes one record (opcode, length, body); returns its offset in the file.
    fn write_record(&mut self, opcode: u8, body: &[u8]) -> std::io::Result<u64> {
        let at = self.pos;
        let mut head = [0u8; 9];
        head[0] = opcode;
        head[1..].copy_from_slice(&(body.len() as u64).to_le_bytes());
        self.raw(&head)?;
        self.raw(body)?;
        Ok(at)
    }

    fn schema_body(id: u16, name: &str, encoding: &str, data: &[u8]) -> Vec<u8> {
        let mut f = Fields::default();
        f.u16(id).string(name).string(encoding).u32(data.len() as u32);
        f.0.extend_from_slice(data);
        f.0
    }

    fn channel_body(id: u16, schema: u16, topic: &str, encoding: &str, metadata: &BTreeMap<String, String>) -> Vec<u8> {
        let mut f = Fields::default();
        f.u16(id).u16(schema).string(topic).string(encoding).map(metadata);
        f.0
    }

    /// Writes a schema record (ids from 1); returns the id.
    pub(crate) fn add_schema(&mut self, name: &str, encoding: &str, data: &[u8]) -> std::io::Result<u16> {
        let id = self.schemas.len() as u16 + 1;
        self.write_record(op::SCHEMA, &Self::schema_body(id, name, encoding, data))?;
        self.schemas.push((id, name.into(), encoding.into(), data.to_vec()));
        Ok(id)
    }

    /// Writes a channel record (ids from 0); returns the id.
    pub(crate) fn add_channel(&mut self, schema: u16, topic: &str, encoding: &str, metadata: &BTreeMap<String, String>) -> std::io::Result<u16> {
        let id = self.channels.len() as u16;
        self.write_record(op::CHANNEL, &Self::channel_body(id, schema, topic, encoding, metadata))?;
        self.channels.push((id, schema, topic.into(), encoding.into(), metadata.clone()));
        Ok(id)
    }

    /// Writes a metadata record.
    pub(crate) fn write_metadata(&mut self, name: &str, map: &BTreeMap<String, String>) -> std::io::Result<()> {
        let mut f = Fields::default();
        f.string(name).map(map);
        let at = self.write_record(op::METADATA, &f.0)?;
        self.metadata.push((at, 9 + f.0.len() as u64, name.into()));
        Ok(())
    }

    /// Compresses and writes one chunk, then its message index records.
    pub(crate) fn write_chunk(&mut self, chunk: &ChunkBuf) -> std::io::Result<()> {
        let Some((start, end)) = chunk.span else { return Ok(()) };
        let crc = crc32fast::hash(&chunk.records);
        // compress the whole chunk at once
        let (name, data): (&str, &[u8]) = match self.compression {
            ChunkCompression::None => ("", &chunk.records),
            ChunkCompression::Zstd(level) => {
                // one compression context for the file; the output buffer only ever grows
                let bound = zstd::zstd_safe::compress_bound(chunk.records.len());
                if self.compressed.len() < bound {
                    self.compressed.resize(bound, 0);
                }
                if self.zstd.is_none() {
                    self.zstd = Some(zstd::bulk::Compressor::new(level)?);
                }
                let z = self.zstd.as_mut().expect("created above");
                let n = z.compress_to_buffer(&chunk.records, &mut self.compressed[..])?;
                ("zstd", &self.compressed[..n])
            }
            ChunkCompression::Lz4 => {
                self.compressed.clear();
                let mut e = lz4::EncoderBuilder::new().level(0).build(std::mem::take(&mut self.compressed))?;
                e.write_all(&chunk.records)?;
                let (buf, result) = e.finish();
                result?;
                self.compressed = buf;
                ("lz4", &self.compressed[..])
            }
        };
        let mut head = Fields(std::mem::take(&mut self.record.0));
        head.0.clear();
        head.u64(start).u64(end).u64(chunk.records.len() as u64).u32(crc).string(name).u64(data.len() as u64);
        let offset = self.pos;
        let body_len = head.0.len() + data.len();
        let mut rec = [0u8; 9];
        rec[0] = op::CHUNK;
        rec[1..].copy_from_slice(&(body_len as u64).to_le_bytes());
        let compressed = data.len() as u64;
        // write: record header, chunk header, compressed records
        self.out.write_all(&rec)?;
        self.out.write_all(&head.0)?;
        match self.compression {
            ChunkCompression::None => self.out.write_all(&chunk.records)?,
            _ => self.out.write_all(&self.compressed[..compressed as usize])?,
        }
        self.pos += 9 + body_len as u64;
        let length = self.pos - offset;
        // message indexes, one record per channel (in order of id), in order of log time
        let index_start = self.pos;
        let mut index_offsets = BTreeMap::new();
        for (c, bytes) in chunk.entries.iter().enumerate().filter(|(_, e)| !e.is_empty()) {
            let c = c as u16;
            let mut sorted: Option<Vec<u8>> = None;
            if !chunk.order[c as usize].1 {
                // stable, as the entries were noted
                let mut entries: Vec<[u8; 16]> = bytes.chunks_exact(16).map(|e| e.try_into().expect("16 bytes")).collect();
                entries.sort_by_key(|e| u64::from_le_bytes(e[..8].try_into().expect("8 bytes")));
                sorted = Some(entries.concat());
            }
            let bytes = sorted.as_deref().unwrap_or(bytes);
            *self.counts.entry(c).or_insert(0) += (bytes.len() / 16) as u64;
            let at = self.pos;
            let mut head = [0u8; 15];
            head[0] = op::MESSAGE_INDEX;
            head[1..9].copy_from_slice(&(6 + bytes.len() as u64).to_le_bytes());
            head[9..11].copy_from_slice(&c.to_le_bytes());
            head[11..15].copy_from_slice(&(bytes.len() as u32).to_le_bytes());
            self.raw(&head)?;
            self.raw(bytes)?;
            index_offsets.insert(c, at);
        }
        self.record = head;
        self.span = Some(self.span.map_or((start, end), |(a, b)| (a.min(start), b.max(end))));
        self.chunks.push(ChunkIndex { start, end, offset, length, index_offsets, index_length: self.pos - index_start, compressed, uncompressed: chunk.records.len() as u64 });
        // hand the whole chunk to the operating system: a killed process loses no complete chunk
        self.out.flush()
    }

    /// Data end, summary, summary offsets, footer and the closing magic; flushes.
    pub(crate) fn finish(mut self) -> std::io::Result<W> {
        self.write_record(op::DATA_END, &0u32.to_le_bytes())?;
        let summary_start = self.pos;
        let mut groups: Vec<(u8, u64, u64)> = Vec::new();
        // schemas and channels
        let group = self.pos;
        let schemas = std::mem::take(&mut self.schemas);
        for (id, name, encoding, data) in &schemas {
            self.write_record(op::SCHEMA, &Self::schema_body(*id, name, encoding, data))?;
        }
        if self.pos > group {
            groups.push((op::SCHEMA, group, self.pos - group));
        }
        let group = self.pos;
        let channels = std::mem::take(&mut self.channels);
        for (id, schema, topic, encoding, metadata) in &channels {
            self.write_record(op::CHANNEL, &Self::channel_body(*id, *schema, topic, encoding, metadata))?;
        }
        if self.pos > group {
            groups.push((op::CHANNEL, group, self.pos - group));
        }
        // statistics
        let (start, end) = self.span.unwrap_or((0, 0));
        let mut f = Fields::default();
        f.u64(self.counts.values().sum())
            .u16(schemas.len() as u16)
            .u32(channels.len() as u32)
            .u32(0)
            .u32(self.metadata.len() as u32)
            .u32(self.chunks.len() as u32)
            .u64(start)
            .u64(end);
        let mut counts = Fields::default();
        for (c, n) in &self.counts {
            counts.u16(*c).u64(*n);
        }
        f.u32(counts.0.len() as u32);
        f.0.extend_from_slice(&counts.0);
        let group = self.pos;
        self.write_record(op::STATISTICS, &f.0)?;
        groups.push((op::STATISTICS, group, self.pos - group));
        // chunk indexes
        let group = self.pos;
        for c in std::mem::take(&mut self.chunks) {
            let mut f = Fields::default();
            f.u64(c.start).u64(c.end).u64(c.offset).u64(c.length);
            let mut offsets = Fields::default();
            for (ch, at) in &c.index_offsets {
                offsets.u16(*ch).u64(*at);
            }
            f.u32(offsets.0.len() as u32);
            f.0.extend_from_slice(&offsets.0);
            let name = match self.compression {
                ChunkCompression::None => "",
                ChunkCompression::Lz4 => "lz4",
                ChunkCompression::Zstd(_) => "zstd",
            };
            f.u64(c.index_length).string(name).u64(c.compressed).u64(c.uncompressed);
            self.write_record(op::CHUNK_INDEX, &f.0)?;
        }
        if self.pos > group {
            groups.push((op::CHUNK_INDEX, group, self.pos - group));
        }
        // metadata indexes
        let group = self.pos;
        for (offset, length, name) in std::mem::take(&mut self.metadata) {
            let mut f = Fields::default();
            f.u64(offset).u64(length).string(&name);
            self.write_record(op::METADATA_INDEX, &f.0)?;
        }
        if self.pos > group {
            groups.push((op::METADATA_INDEX, group, self.pos - group));
        }
        // summary offsets, footer
        let offsets_start = self.pos;
        for (opcode, start, length) in groups {
            let mut f = Fields::default();
            f.u8(opcode).u64(start).u64(length);
            self.write_record(op::SUMMARY_OFFSET, &f.0)?;
        }
        let mut f = Fields::default();
        f.u64(summary_start).u64(offsets_start).u32(0);
        self.write_record(op::FOOTER, &f.0)?;
        self.raw(super::scan::MAGIC)?;
        self.out.flush()?;
        Ok(self.out)
    }
}
