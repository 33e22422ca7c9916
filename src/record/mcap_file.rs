//! The MCAP file writer of the planar sink's writer thread: the records of the `mcap` crate's
//! `Writer` with its default options (chunks, message indexes, a summary with schemas,
//! channels, statistics, chunk and metadata indexes and summary offsets, CRCs of the chunks,
//! the data section and the summary), so the same calls give the same file: byte for byte
//! without compression (unit test `the_same_bytes_as_the_mcap_crate`), and the same records
//! with zstd, compressed whole at the end of each chunk instead of as a stream.
//!
//! Why not the crate's writer: it sends each message through zstd's streaming interface as
//! seven small writes (the record's opcode and length, the header's four fields, the data),
//! each a pass through the stream's machinery and a copy into its buffer. At the two-prong
//! grasp's 18 000 messages that was ~15 % of the MCAP writer thread's instructions (callgrind:
//! 552 M in all, `write_to_known_channel` 350 M of which the block compression ~270 M). Here a
//! message is appended to the chunk's buffer, and the buffer is compressed in one call when the
//! chunk ends. The crate still reads every file (`gripsim replay`, the tests).

use ::mcap::records::{MessageHeader, Metadata};
use std::collections::BTreeMap;
use std::io::{self, Write};

/// The file's first and last bytes.
const MAGIC: &[u8] = b"\x89MCAP0\r\n";
/// A chunk is ended before a message once it holds more than this (the crate's default).
const CHUNK_SIZE: usize = 1024 * 1024;

mod op {
    pub const HEADER: u8 = 0x01;
    pub const FOOTER: u8 = 0x02;
    pub const SCHEMA: u8 = 0x03;
    pub const CHANNEL: u8 = 0x04;
    pub const MESSAGE: u8 = 0x05;
    pub const CHUNK: u8 = 0x06;
    pub const MESSAGE_INDEX: u8 = 0x07;
    pub const CHUNK_INDEX: u8 = 0x08;
    pub const STATISTICS: u8 = 0x0B;
    pub const METADATA: u8 = 0x0C;
    pub const METADATA_INDEX: u8 = 0x0D;
    pub const SUMMARY_OFFSET: u8 = 0x0E;
    pub const DATA_END: u8 = 0x0F;
}

/// Little-endian fields, MCAP strings (u32 length + bytes) and maps (u32 byte length +
/// entries), appended to a buffer.
trait Put {
    fn u8(&mut self, v: u8);
    fn u16(&mut self, v: u16);
    fn u32(&mut self, v: u32);
    fn u64(&mut self, v: u64);
    fn string(&mut self, s: &str);
    fn string_map(&mut self, m: &BTreeMap<String, String>);
    fn record(&mut self, op: u8, body: &[u8]);
}

impl Put for Vec<u8> {
    fn u8(&mut self, v: u8) {
        self.push(v);
    }
    fn u16(&mut self, v: u16) {
        self.extend_from_slice(&v.to_le_bytes());
    }
    fn u32(&mut self, v: u32) {
        self.extend_from_slice(&v.to_le_bytes());
    }
    fn u64(&mut self, v: u64) {
        self.extend_from_slice(&v.to_le_bytes());
    }
    fn string(&mut self, s: &str) {
        self.u32(s.len() as u32);
        self.extend_from_slice(s.as_bytes());
    }
    fn string_map(&mut self, m: &BTreeMap<String, String>) {
        let len: usize = m.iter().map(|(k, v)| 8 + k.len() + v.len()).sum();
        self.u32(len as u32);
        for (k, v) in m {
            self.string(k);
            self.string(v);
        }
    }
    fn record(&mut self, op: u8, body: &[u8]) {
        self.u8(op);
        self.u64(body.len() as u64);
        self.extend_from_slice(body);
    }
}

/// How the chunks are compressed: zstd's level, and the parameters set over the level's.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Zstd {
    pub level: i32,
    pub min_match: Option<u32>,
    pub hash_log: Option<u32>,
}

impl Zstd {
    /// One compression context, reused from chunk to chunk, on the calling thread (zstd's
    /// output then depends on nothing but the input).
    fn compressor(self) -> io::Result<zstd::bulk::Compressor<'static>> {
        use zstd::zstd_safe::CParameter;
        let mut z = zstd::bulk::Compressor::new(self.level)?;
        if let Some(m) = self.min_match {
            z.set_parameter(CParameter::MinMatch(m))?;
        }
        if let Some(h) = self.hash_log {
            z.set_parameter(CParameter::HashLog(h))?;
        }
        Ok(z)
    }
}

/// A channel: id, schema id, topic, message encoding, metadata.
type ChannelRecord = (u16, u16, String, String, BTreeMap<String, String>);

/// A chunk's entry in the summary.
struct ChunkIndex {
    start_time: u64,
    end_time: u64,
    offset: u64,
    length: u64,
    message_indexes: BTreeMap<u16, u64>,
    message_index_length: u64,
    compression: &'static str,
    compressed_size: u64,
    uncompressed_size: u64,
}

/// The chunk being filled.
#[derive(Default)]
struct OpenChunk {
    /// Its records, uncompressed.
    records: Vec<u8>,
    /// (first, last) log time of its messages.
    bounds: Option<(u64, u64)>,
    /// Per channel: (log time, offset in `records`) of each message.
    indexes: BTreeMap<u16, Vec<(u64, u64)>>,
}

/// The output with its position and the CRC of what was written since the last `restart`.
struct Out<W: Write> {
    w: W,
    pos: u64,
    crc: crc32fast::Hasher,
}

impl<W: Write> Out<W> {
    fn put(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.w.write_all(bytes)?;
        self.crc.update(bytes);
        self.pos += bytes.len() as u64;
        Ok(())
    }

    /// The CRC so far; the next bytes start a new one.
    fn restart(&mut self) -> u32 {
        std::mem::take(&mut self.crc).finalize()
    }
}

/// An MCAP file being written (see the module's documentation).
pub(crate) struct McapFile<W: Write> {
    out: Out<W>,
    /// zstd at this level (None: chunks without compression).
    zstd: Option<zstd::bulk::Compressor<'static>>,
    chunk: Option<OpenChunk>,
    /// Buffers reused from chunk to chunk.
    spare: Vec<u8>,
    compressed: Vec<u8>,
    schemas: Vec<(u16, String, String, Vec<u8>)>,
    channels: Vec<ChannelRecord>,
    chunk_indexes: Vec<ChunkIndex>,
    /// (offset, length, name) of each metadata record.
    metadata_indexes: Vec<(u64, u64, String)>,
    message_counts: BTreeMap<u16, u64>,
    bounds: Option<(u64, u64)>,
}

fn widen(b: Option<(u64, u64)>, t: u64) -> Option<(u64, u64)> {
    Some(b.map_or((t, t), |(a, z)| (a.min(t), z.max(t))))
}

impl<W: Write> McapFile<W> {
    /// Start the file (magic, header) in `w`; chunks compressed with zstd at `zstd.level`, or
    /// not at all.
    pub(crate) fn new(w: W, profile: &str, library: &str, zstd: Option<Zstd>) -> io::Result<Self> {
        let zstd = zstd.map(Zstd::compressor).transpose()?;
        let mut f = Self {
            out: Out {
                w,
                pos: 0,
                crc: crc32fast::Hasher::new(),
            },
            zstd,
            chunk: None,
            spare: Vec::new(),
            compressed: Vec::new(),
            schemas: Vec::new(),
            channels: Vec::new(),
            chunk_indexes: Vec::new(),
            metadata_indexes: Vec::new(),
            message_counts: BTreeMap::new(),
            bounds: None,
        };
        f.out.put(MAGIC)?;
        let mut body = Vec::new();
        body.string(profile);
        body.string(library);
        let mut rec = Vec::new();
        rec.record(op::HEADER, &body);
        f.out.put(&rec)?;
        Ok(f)
    }

    fn open_chunk(&mut self) -> &mut OpenChunk {
        let spare = &mut self.spare;
        self.chunk.get_or_insert_with(|| OpenChunk {
            records: std::mem::take(spare),
            ..OpenChunk::default()
        })
    }

    fn schema_record(buf: &mut Vec<u8>, id: u16, name: &str, encoding: &str, data: &[u8]) {
        let mut body = Vec::with_capacity(14 + name.len() + encoding.len() + data.len());
        body.u16(id);
        body.string(name);
        body.string(encoding);
        body.u32(data.len() as u32);
        body.extend_from_slice(data);
        buf.record(op::SCHEMA, &body);
    }

    fn channel_record(buf: &mut Vec<u8>, (id, schema, topic, encoding, meta): &ChannelRecord) {
        let mut body = Vec::new();
        body.u16(*id);
        body.u16(*schema);
        body.string(topic);
        body.string(encoding);
        body.string_map(meta);
        buf.record(op::CHANNEL, &body);
    }

    /// Add a schema (written into the chunk); the same content again gives the same id.
    pub(crate) fn add_schema(&mut self, name: &str, encoding: &str, data: &[u8]) -> u16 {
        if let Some(s) = self
            .schemas
            .iter()
            .find(|s| s.1 == name && s.2 == encoding && s.3 == data)
        {
            return s.0;
        }
        let id = self.schemas.len() as u16 + 1;
        Self::schema_record(&mut self.open_chunk().records, id, name, encoding, data);
        self.schemas
            .push((id, name.into(), encoding.into(), data.to_vec()));
        id
    }

    /// Add a channel (written into the chunk); the same content again gives the same id.
    pub(crate) fn add_channel(
        &mut self,
        schema: u16,
        topic: &str,
        encoding: &str,
        metadata: &BTreeMap<String, String>,
    ) -> u16 {
        if let Some(c) = self
            .channels
            .iter()
            .find(|c| c.1 == schema && c.2 == topic && c.3 == encoding && &c.4 == metadata)
        {
            return c.0;
        }
        let c = (
            self.channels.len() as u16 + 1,
            schema,
            topic.to_string(),
            encoding.to_string(),
            metadata.clone(),
        );
        Self::channel_record(&mut self.open_chunk().records, &c);
        let id = c.0;
        self.channels.push(c);
        id
    }

    /// Append a message on a channel added before.
    pub(crate) fn write_to_known_channel(
        &mut self,
        header: &MessageHeader,
        data: &[u8],
    ) -> io::Result<()> {
        if self
            .chunk
            .as_ref()
            .is_some_and(|c| c.records.len() > CHUNK_SIZE)
        {
            self.end_chunk()?;
        }
        self.bounds = widen(self.bounds, header.log_time);
        *self.message_counts.entry(header.channel_id).or_insert(0) += 1;
        let c = self.open_chunk();
        c.bounds = widen(c.bounds, header.log_time);
        c.indexes
            .entry(header.channel_id)
            .or_default()
            .push((header.log_time, c.records.len() as u64));
        let r = &mut c.records;
        r.u8(op::MESSAGE);
        r.u64(22 + data.len() as u64);
        r.u16(header.channel_id);
        r.u32(header.sequence);
        r.u64(header.log_time);
        r.u64(header.publish_time);
        r.extend_from_slice(data);
        Ok(())
    }

    /// Write a metadata record (after ending the chunk).
    pub(crate) fn write_metadata(&mut self, m: &Metadata) -> io::Result<()> {
        self.end_chunk()?;
        let mut body = Vec::new();
        body.string(&m.name);
        body.string_map(&m.metadata);
        let mut rec = Vec::new();
        rec.record(op::METADATA, &body);
        self.metadata_indexes
            .push((self.out.pos, rec.len() as u64, m.name.clone()));
        self.out.put(&rec)
    }

    /// End the chunk and hand what was written to the operating system.
    pub(crate) fn flush(&mut self) -> io::Result<()> {
        self.end_chunk()?;
        self.out.w.flush()
    }

    /// Write the open chunk (compressed) and its message indexes.
    fn end_chunk(&mut self) -> io::Result<()> {
        let Some(mut c) = self.chunk.take() else {
            return Ok(());
        };
        let crc = crc32fast::hash(&c.records);
        let (name, payload): (&'static str, &[u8]) = match self.zstd.as_mut() {
            Some(z) => {
                self.compressed.clear();
                self.compressed
                    .reserve(zstd::zstd_safe::compress_bound(c.records.len()));
                z.compress_to_buffer(&c.records[..], &mut self.compressed)?;
                ("zstd", &self.compressed)
            }
            None => ("", &c.records),
        };
        let (start, end) = c.bounds.unwrap_or((0, 0));
        let mut head = Vec::with_capacity(64);
        head.u8(op::CHUNK);
        head.u64(8 + 8 + 8 + 4 + 4 + name.len() as u64 + 8 + payload.len() as u64);
        head.u64(start);
        head.u64(end);
        head.u64(c.records.len() as u64);
        head.u32(crc);
        head.string(name);
        head.u64(payload.len() as u64);
        let offset = self.out.pos;
        let length = (head.len() + payload.len()) as u64;
        let compressed_size = payload.len() as u64;
        self.out.put(&head)?;
        self.out.put(payload)?;
        let mut message_indexes = BTreeMap::new();
        let indexes_start = self.out.pos;
        let mut rec = Vec::new();
        for (channel, entries) in &c.indexes {
            let mut body = Vec::with_capacity(6 + 16 * entries.len());
            body.u16(*channel);
            body.u32(16 * entries.len() as u32);
            for &(t, at) in entries {
                body.u64(t);
                body.u64(at);
            }
            rec.clear();
            rec.record(op::MESSAGE_INDEX, &body);
            message_indexes.insert(*channel, self.out.pos);
            self.out.put(&rec)?;
        }
        self.chunk_indexes.push(ChunkIndex {
            start_time: start,
            end_time: end,
            offset,
            length,
            message_indexes,
            message_index_length: self.out.pos - indexes_start,
            compression: name,
            compressed_size,
            uncompressed_size: c.records.len() as u64,
        });
        c.records.clear();
        self.spare = c.records;
        Ok(())
    }

    /// End the data section and write the summary and the footer.
    pub(crate) fn finish(&mut self) -> io::Result<()> {
        self.end_chunk()?;
        let data_crc = self.out.restart();
        let mut rec = Vec::new();
        rec.record(op::DATA_END, &data_crc.to_le_bytes());
        self.out.put(&rec)?;
        self.out.restart();
        let summary_start = self.out.pos;
        let mut groups = Vec::new();
        let mut group = |out: &mut Out<W>, op: u8, bytes: &[u8]| -> io::Result<()> {
            if !bytes.is_empty() {
                groups.push((op, out.pos, bytes.len() as u64));
                out.put(bytes)?;
            }
            Ok(())
        };
        let mut buf = Vec::new();
        for (id, name, encoding, data) in &self.schemas {
            Self::schema_record(&mut buf, *id, name, encoding, data);
        }
        group(&mut self.out, op::SCHEMA, &buf)?;
        buf.clear();
        for c in &self.channels {
            Self::channel_record(&mut buf, c);
        }
        group(&mut self.out, op::CHANNEL, &buf)?;
        buf.clear();
        buf.record(op::STATISTICS, &self.statistics());
        group(&mut self.out, op::STATISTICS, &buf)?;
        buf.clear();
        for c in &self.chunk_indexes {
            buf.record(op::CHUNK_INDEX, &chunk_index(c));
        }
        group(&mut self.out, op::CHUNK_INDEX, &buf)?;
        buf.clear();
        for (offset, length, name) in &self.metadata_indexes {
            let mut body = Vec::new();
            body.u64(*offset);
            body.u64(*length);
            body.string(name);
            buf.record(op::METADATA_INDEX, &body);
        }
        group(&mut self.out, op::METADATA_INDEX, &buf)?;
        let offsets_start = self.out.pos;
        buf.clear();
        for (op, start, length) in groups {
            let mut body = Vec::new();
            body.u8(op);
            body.u64(start);
            body.u64(length);
            buf.record(op::SUMMARY_OFFSET, &body);
        }
        self.out.put(&buf)?;
        buf.clear();
        buf.u8(op::FOOTER);
        buf.u64(20);
        buf.u64(summary_start);
        buf.u64(offsets_start);
        self.out.put(&buf)?;
        let summary_crc = self.out.restart();
        self.out.put(&summary_crc.to_le_bytes())?;
        self.out.put(MAGIC)?;
        self.out.w.flush()
    }

    fn statistics(&self) -> Vec<u8> {
        let (start, end) = self.bounds.unwrap_or((0, 0));
        let mut b = Vec::new();
        b.u64(self.message_counts.values().sum());
        b.u16(self.schemas.len() as u16);
        b.u32(self.channels.len() as u32);
        b.u32(0); // attachments
        b.u32(self.metadata_indexes.len() as u32);
        b.u32(self.chunk_indexes.len() as u32);
        b.u64(start);
        b.u64(end);
        b.u32(10 * self.message_counts.len() as u32);
        for (&k, &v) in &self.message_counts {
            b.u16(k);
            b.u64(v);
        }
        b
    }

    /// The output, after [`McapFile::finish`].
    pub(crate) fn into_inner(self) -> W {
        self.out.w
    }
}

fn chunk_index(c: &ChunkIndex) -> Vec<u8> {
    let mut b = Vec::new();
    b.u64(c.start_time);
    b.u64(c.end_time);
    b.u64(c.offset);
    b.u64(c.length);
    b.u32(10 * c.message_indexes.len() as u32);
    for (&k, &v) in &c.message_indexes {
        b.u16(k);
        b.u64(v);
    }
    b.u64(c.message_index_length);
    b.string(c.compression);
    b.u64(c.compressed_size);
    b.u64(c.uncompressed_size);
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One call to a writer.
    enum Call {
        Schema(&'static str, &'static str, Vec<u8>),
        /// schema (its position among the `Schema` calls), topic, encoding, metadata.
        Channel(
            usize,
            &'static str,
            &'static str,
            Vec<(&'static str, &'static str)>,
        ),
        /// channel (its position among the `Channel` calls), sequence, log time, data.
        Message(usize, u32, u64, Vec<u8>),
        Metadata(&'static str, Vec<(&'static str, &'static str)>),
        Flush,
    }

    fn calls() -> Vec<Call> {
        use Call::*;
        let desc: Vec<u8> = (0..300u32).map(|i| (i * 7 % 256) as u8).collect();
        let mut c = vec![
            Schema("gripsim.Step", "protobuf", desc.clone()),
            Schema(
                "gripsim.Meta",
                "jsonschema",
                b"{\"type\":\"object\"}".to_vec(),
            ),
            // The same content again: the same id, no second record.
            Schema("gripsim.Step", "protobuf", desc),
            Channel(0, "/sim/step", "protobuf", vec![]),
            Channel(1, "/sim/meta", "json", vec![("a", "1"), ("bb", "")]),
            // A channel without messages.
            Channel(2, "/scene", "protobuf", vec![]),
            // Metadata first: the chunk with only schemas and channels ends.
            Metadata("gripsim.start", vec![("k", "v")]),
            Message(1, 0, 0, b"{}".to_vec()),
            Message(0, 0, 5, vec![]),
            Message(0, 1, 5, vec![1, 2, 3]),
            // Log times out of order.
            Message(1, 1, 3, b"{\"x\":1}".to_vec()),
            Flush,
            Flush,
        ];
        // More than a chunk's worth without a flush: the chunk ends before the message that
        // finds it over 1 MiB.
        for k in 0..40u32 {
            let data: Vec<u8> = (0..40_000u32).map(|i| ((i ^ k) % 253) as u8).collect();
            c.push(Message(0, 2 + k, 10 + u64::from(k), data));
            if k == 20 {
                c.push(Metadata("gripsim.middle", vec![]));
            }
        }
        c.push(Message(1, 2, 100, b"{\"end\":true}".to_vec()));
        c
    }

    fn map(kv: &[(&str, &str)]) -> BTreeMap<String, String> {
        kv.iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect()
    }

    fn header(channel: u16, sequence: u32, log_time: u64) -> MessageHeader {
        MessageHeader {
            channel_id: channel,
            sequence,
            log_time,
            publish_time: log_time,
        }
    }

    /// The calls a test makes, on either writer.
    trait Calls {
        fn schema(&mut self, name: &str, encoding: &str, data: &[u8]) -> u16;
        fn channel(
            &mut self,
            schema: u16,
            topic: &str,
            encoding: &str,
            meta: &[(&str, &str)],
        ) -> u16;
        fn message(&mut self, header: &MessageHeader, data: &[u8]);
        fn metadata(&mut self, m: &Metadata);
        fn flush(&mut self);
    }

    impl Calls for McapFile<Vec<u8>> {
        fn schema(&mut self, name: &str, encoding: &str, data: &[u8]) -> u16 {
            self.add_schema(name, encoding, data)
        }
        fn channel(
            &mut self,
            schema: u16,
            topic: &str,
            encoding: &str,
            meta: &[(&str, &str)],
        ) -> u16 {
            self.add_channel(schema, topic, encoding, &map(meta))
        }
        fn message(&mut self, header: &MessageHeader, data: &[u8]) {
            self.write_to_known_channel(header, data).unwrap();
        }
        fn metadata(&mut self, m: &Metadata) {
            self.write_metadata(m).unwrap();
        }
        fn flush(&mut self) {
            McapFile::flush(self).unwrap();
        }
    }

    impl Calls for ::mcap::Writer<std::io::Cursor<Vec<u8>>> {
        fn schema(&mut self, name: &str, encoding: &str, data: &[u8]) -> u16 {
            self.add_schema(name, encoding, data).unwrap()
        }
        fn channel(
            &mut self,
            schema: u16,
            topic: &str,
            encoding: &str,
            meta: &[(&str, &str)],
        ) -> u16 {
            self.add_channel(schema, topic, encoding, &map(meta))
                .unwrap()
        }
        fn message(&mut self, header: &MessageHeader, data: &[u8]) {
            self.write_to_known_channel(header, data).unwrap();
        }
        fn metadata(&mut self, m: &Metadata) {
            self.write_metadata(m).unwrap();
        }
        fn flush(&mut self) {
            ::mcap::Writer::flush(self).unwrap();
        }
    }

    /// Make every call of [`calls`] on `w`.
    fn drive(w: &mut impl Calls) {
        let (mut schemas, mut channels) = (Vec::new(), Vec::new());
        for call in calls() {
            match call {
                Call::Schema(n, e, d) => schemas.push(w.schema(n, e, &d)),
                Call::Channel(s, t, e, m) => channels.push(w.channel(schemas[s], t, e, &m)),
                Call::Message(c, q, t, d) => w.message(&header(channels[c], q, t), &d),
                Call::Metadata(n, m) => w.metadata(&Metadata {
                    name: n.into(),
                    metadata: map(&m),
                }),
                Call::Flush => w.flush(),
            }
        }
    }

    fn ours(zstd: Option<u32>) -> Vec<u8> {
        let zstd = zstd.map(|level| Zstd {
            level: level as i32,
            min_match: None,
            hash_log: None,
        });
        let mut w = McapFile::new(Vec::new(), "", "gripsim test", zstd).unwrap();
        drive(&mut w);
        w.finish().unwrap();
        w.into_inner()
    }

    fn the_crates(zstd: Option<u32>) -> Vec<u8> {
        let mut w = ::mcap::WriteOptions::new()
            .profile("")
            .library("gripsim test")
            .compression(zstd.map(|_| ::mcap::Compression::Zstd))
            .compression_threads(0)
            .compression_level(zstd.unwrap_or(0))
            .create(std::io::Cursor::new(Vec::new()))
            .unwrap();
        drive(&mut w);
        w.finish().unwrap();
        w.into_inner().into_inner()
    }

    /// Without compression the same calls give the crate's bytes: every record, index, CRC
    /// and offset of the data section, the summary and the footer.
    #[test]
    fn the_same_bytes_as_the_mcap_crate() {
        let (a, b) = (ours(None), the_crates(None));
        assert!(a.len() > 1_600_000);
        assert_eq!(a.len(), b.len());
        assert!(
            a == b,
            "first difference at byte {:?}",
            a.iter().zip(&b).position(|(x, y)| x != y)
        );
    }

    /// With zstd the chunks are compressed whole (other bytes than the crate's stream): the
    /// crate reads back the same messages, with the chunks' CRCs checked, and the same summary.
    #[test]
    fn with_zstd_the_crate_reads_the_same_file() {
        let (a, b) = (ours(Some(1)), the_crates(Some(1)));
        assert!(a.len() < 1_000_000, "compressed: {} bytes", a.len());
        let messages = |bytes: &[u8]| -> Vec<(String, u32, u64, Vec<u8>)> {
            ::mcap::MessageStream::new(bytes)
                .unwrap()
                .map(|m| {
                    let m = m.unwrap();
                    (
                        m.channel.topic.clone(),
                        m.sequence,
                        m.log_time,
                        m.data.to_vec(),
                    )
                })
                .collect()
        };
        let (ma, mb) = (messages(&a), messages(&b));
        assert_eq!(ma.len(), 45);
        assert!(ma == mb);
        let sa = ::mcap::Summary::read(&a).unwrap().unwrap();
        let sb = ::mcap::Summary::read(&b).unwrap().unwrap();
        assert_eq!(sa.stats, sb.stats);
        assert_eq!(sa.chunk_indexes.len(), sb.chunk_indexes.len());
        // The same metadata records (at other offsets: the chunks before differ in size).
        let names = |s: &::mcap::Summary| -> Vec<(String, u64)> {
            s.metadata_indexes
                .iter()
                .map(|m| (m.name.clone(), m.length))
                .collect()
        };
        assert_eq!(names(&sa), names(&sb));
        for (x, y) in sa.chunk_indexes.iter().zip(&sb.chunk_indexes) {
            assert_eq!(
                (
                    x.message_start_time,
                    x.message_end_time,
                    x.uncompressed_size
                ),
                (
                    y.message_start_time,
                    y.message_end_time,
                    y.uncompressed_size
                )
            );
            assert_eq!(x.compression, "zstd");
        }
    }
}
