//! MCAP files: topics and counts from the summary section, and messages streamed in file order
//! a record at a time, a chunk at a time (uncompressed, zstd or lz4). Both message encodings
//! robots record are read: `cdr` (ROS 2) and `ros1` (what `mcap convert` makes of a ROS 1 bag).
//!
//! The reader is our own, over the records this needs (schema, channel, message, chunk,
//! statistics, footer; the rest are skipped): every length in the file is checked against what
//! holds it before anything is allocated, and a record or chunk over [`MAX_RECORD_BYTES`] is
//! refused. The `mcap` crate, tried first, allocated whatever a corrupt length claimed (the
//! fuzzer asked it for 2.5 and 3.5 GB), which aborts a process on a small computer.
//! CRCs are not checked; a corrupt chunk gives a decompression or parse error.

use super::error::RecordingError::{self, Damaged, NotThisFormat, Truncated, Unsupported};
use super::{decompress, Compression, Encoding, RawMessage, Topic};
use std::collections::HashMap;
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

/// The first (and last) bytes of every MCAP file.
pub const MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// The longest record (and decompressed chunk) read: a corrupt length is refused rather than
/// allocated. A 128-beam cloud of 2 048 columns is about 13 MB.
pub const MAX_RECORD_BYTES: usize = 256 << 20;

const OP_FOOTER: u8 = 0x02;
const OP_SCHEMA: u8 = 0x03;
const OP_CHANNEL: u8 = 0x04;
const OP_MESSAGE: u8 = 0x05;
const OP_CHUNK: u8 = 0x06;
const OP_STATISTICS: u8 = 0x0B;

/// Little-endian fields off a record's body, every length checked against what is left.
struct Fields<'a> {
    b: &'a [u8],
}

impl<'a> Fields<'a> {
    fn bytes(&mut self, n: usize, what: &str) -> Result<&'a [u8], RecordingError> {
        if n > self.b.len() {
            return Err(Damaged(format!("{what} runs past its record")));
        }
        let (head, rest) = self.b.split_at(n);
        self.b = rest;
        Ok(head)
    }
    fn u16(&mut self, what: &str) -> Result<u16, RecordingError> {
        Ok(u16::from_le_bytes(
            self.bytes(2, what)?.try_into().expect("2"),
        ))
    }
    fn u32(&mut self, what: &str) -> Result<u32, RecordingError> {
        Ok(u32::from_le_bytes(
            self.bytes(4, what)?.try_into().expect("4"),
        ))
    }
    fn u64(&mut self, what: &str) -> Result<u64, RecordingError> {
        Ok(u64::from_le_bytes(
            self.bytes(8, what)?.try_into().expect("8"),
        ))
    }
    /// A string or byte array with a u32 length.
    fn prefixed(&mut self, what: &str) -> Result<&'a [u8], RecordingError> {
        let n = self.u32(what)? as usize;
        self.bytes(n, what)
    }
    fn string(&mut self, what: &str) -> Result<String, RecordingError> {
        Ok(String::from_utf8_lossy(self.prefixed(what)?).into_owned())
    }
}

/// A channel: its topic, message encoding and schema name.
#[derive(Debug, Clone)]
struct Channel {
    topic: String,
    encoding: String,
    schema: String,
}

/// Schemas (id to name) and channels met so far.
#[derive(Debug, Default)]
struct Registry {
    schemas: HashMap<u16, String>,
    channels: HashMap<u16, Channel>,
}

impl Registry {
    fn schema(&mut self, body: &[u8]) -> Result<(), RecordingError> {
        let mut f = Fields { b: body };
        let id = f.u16("a schema id")?;
        let name = f.string("a schema name")?;
        self.schemas.insert(id, name);
        Ok(())
    }

    fn channel(&mut self, body: &[u8]) -> Result<(), RecordingError> {
        let mut f = Fields { b: body };
        let id = f.u16("a channel id")?;
        let schema_id = f.u16("a channel's schema id")?;
        let topic = f.string("a channel topic")?;
        let encoding = f.string("a channel's message encoding")?;
        let schema = self.schemas.get(&schema_id).cloned().unwrap_or_default();
        self.channels.insert(
            id,
            Channel {
                topic,
                encoding,
                schema,
            },
        );
        Ok(())
    }
}

/// Handles one record: a schema or channel goes into `registry`; a message is returned, its
/// data copied out of `body` (in a chunk) or taken with it (`owned`, a record of its own).
fn record(
    registry: &mut Registry,
    op: u8,
    body: &[u8],
    owned: Option<Vec<u8>>,
) -> Result<Option<Message>, RecordingError> {
    match op {
        OP_SCHEMA => registry.schema(body)?,
        OP_CHANNEL => registry.channel(body)?,
        OP_MESSAGE => {
            let mut f = Fields { b: body };
            let channel = f.u16("a message's channel")?;
            let _sequence = f.u32("a message's sequence")?;
            let log_time = f.u64("a message's log time")?;
            let _publish = f.u64("a message's publish time")?;
            let (data, start) = match owned {
                Some(v) => (v, MESSAGE_HEAD),
                None => (f.b.to_vec(), 0),
            };
            return Ok(Some(Message {
                channel,
                log_time,
                data,
                start,
            }));
        }
        _ => {}
    }
    Ok(None)
}

/// Reads the next record (opcode and body) of `r`; `None` at a clean end of file.
fn next_record(r: &mut impl Read) -> Result<Option<(u8, Vec<u8>)>, RecordingError> {
    let mut head = [0u8; 9];
    match r.read(&mut head[..1]) {
        Ok(0) => return Ok(None),
        Ok(_) => {}
        Err(e) => return Err(e.into()),
    }
    r.read_exact(&mut head[1..])
        .map_err(|_| Truncated("the file ends inside a record's length".into()))?;
    let len = u64::from_le_bytes(head[1..].try_into().expect("8"));
    if len > MAX_RECORD_BYTES as u64 {
        return Err(Damaged(format!(
            "a record of {len} bytes, over the {MAX_RECORD_BYTES}-byte limit"
        )));
    }
    let mut body = Vec::with_capacity((len as usize).min(16 << 20));
    r.take(len).read_to_end(&mut body)?;
    if body.len() as u64 != len {
        return Err(Truncated("the file ends inside a record".into()));
    }
    Ok(Some((head[0], body)))
}

/// A chunk's records, decompressed, in the returned range (an uncompressed chunk's body is
/// kept as it is, its records in place).
fn chunk_records(body: Vec<u8>) -> Result<(Vec<u8>, std::ops::Range<usize>), RecordingError> {
    let mut f = Fields { b: &body };
    let _start = f.u64("a chunk's start time")?;
    let _end = f.u64("a chunk's end time")?;
    let size = f.u64("a chunk's uncompressed size")?;
    let _crc = f.u32("a chunk's CRC")?;
    let compression = f.string("a chunk's compression")?;
    let len = f.u64("a chunk's records length")?;
    let data = f.bytes(
        usize::try_from(len).unwrap_or(usize::MAX),
        "a chunk's records",
    )?;
    // A size over the limit is refused by `decompress`; here it must not wrap either.
    let size = usize::try_from(size).unwrap_or(usize::MAX);
    let kind = match compression.as_str() {
        "" => {
            if data.len() != size {
                return Err(Damaged(format!(
                    "an uncompressed chunk holds {} bytes, not the {size} its header says",
                    data.len()
                )));
            }
            let start = body.len() - f.b.len() - data.len();
            return Ok((body, start..start + size));
        }
        "zstd" => Compression::Zstd,
        "lz4" => Compression::Lz4,
        other => {
            return Err(Unsupported(format!(
                "chunk compression {other:?} is not none, zstd or lz4"
            )))
        }
    };
    let out = decompress(kind, data, size)?;
    let n = out.len();
    Ok((out, 0..n))
}

/// Every message in file order, with the schemas and channels needed to name it.
pub struct Messages<R> {
    reader: R,
    registry: Registry,
    /// The current chunk's records (up to `chunk_end`) and the read position in them.
    chunk: Vec<u8>,
    at: usize,
    chunk_end: usize,
    done: bool,
}

/// One message and its channel: `data[start..]`.
struct Message {
    channel: u16,
    log_time: u64,
    data: Vec<u8>,
    start: usize,
}

/// The header of a message record: channel, sequence, log time, publish time.
const MESSAGE_HEAD: usize = 2 + 4 + 8 + 8;

impl<R: Read> Messages<R> {
    /// Reads `reader` from its start (the magic).
    fn new(mut reader: R) -> Result<Self, RecordingError> {
        let mut magic = [0u8; 8];
        reader
            .read_exact(&mut magic)
            .map_err(|_| NotThisFormat("too short for an MCAP file".into()))?;
        if magic != MAGIC {
            return Err(NotThisFormat("not an MCAP file".into()));
        }
        Ok(Messages {
            reader,
            registry: Registry::default(),
            chunk: Vec::new(),
            at: 0,
            chunk_end: 0,
            done: false,
        })
    }

    fn next_message(&mut self) -> Result<Option<Message>, RecordingError> {
        loop {
            while self.at < self.chunk_end {
                let mut f = Fields {
                    b: &self.chunk[self.at..self.chunk_end],
                };
                let op = f.bytes(1, "a chunk's record")?[0];
                let len = f.u64("a chunk's record length")?;
                let body = f.bytes(
                    usize::try_from(len).unwrap_or(usize::MAX),
                    "a record in a chunk",
                )?;
                let body_at = self.at + 9;
                self.at = body_at + body.len();
                if op == OP_MESSAGE && self.at == self.chunk_end && body.len() >= MESSAGE_HEAD {
                    // The chunk's last record (a large cloud often fills a chunk alone): the
                    // message takes the chunk's buffer instead of a copy.
                    let head = body[..MESSAGE_HEAD].to_vec();
                    let mut m = record(&mut self.registry, op, &head, Some(Vec::new()))?
                        .expect("a message record");
                    m.data = std::mem::take(&mut self.chunk);
                    m.start = body_at + MESSAGE_HEAD;
                    self.chunk_end = 0;
                    self.at = 0;
                    return Ok(Some(m));
                }
                if let Some(m) = record(&mut self.registry, op, body, None)? {
                    return Ok(Some(m));
                }
            }
            if self.done {
                return Ok(None);
            }
            let Some((op, body)) = next_record(&mut self.reader)? else {
                self.done = true;
                return Ok(None);
            };
            match op {
                OP_CHUNK => {
                    let (records, range) = chunk_records(body)?;
                    self.chunk = records;
                    (self.at, self.chunk_end) = (range.start, range.end);
                }
                OP_FOOTER => self.done = true,
                OP_MESSAGE => {
                    let head = body.get(..MESSAGE_HEAD).unwrap_or(&body).to_vec();
                    if let Some(m) = record(&mut self.registry, op, &head, Some(body))? {
                        return Ok(Some(m));
                    }
                }
                _ => {
                    if let Some(m) = record(&mut self.registry, op, &body, None)? {
                        return Ok(Some(m));
                    }
                }
            }
        }
    }
}

/// A message with its channel's topic, encoding and schema.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Named {
    /// The channel's topic.
    pub topic: String,
    /// The channel's message encoding (`cdr`, `ros1`, ...).
    pub encoding: String,
    /// The channel's schema name.
    pub schema: String,
    /// When it was recorded (ns).
    pub log_time: u64,
    /// The message is `data[start..]`.
    pub data: Vec<u8>,
    /// See `data`.
    pub start: usize,
}

impl<R: Read> Iterator for Messages<R> {
    type Item = Result<Named, RecordingError>;

    fn next(&mut self) -> Option<Self::Item> {
        match self.next_message() {
            Ok(Some(m)) => {
                let Some(c) = self.registry.channels.get(&m.channel) else {
                    return Some(Err(Damaged(format!(
                        "a message on unknown channel {}",
                        m.channel
                    ))));
                };
                Some(Ok(Named {
                    topic: c.topic.clone(),
                    encoding: c.encoding.clone(),
                    schema: c.schema.clone(),
                    log_time: m.log_time,
                    data: m.data,
                    start: m.start,
                }))
            }
            Ok(None) => None,
            Err(e) => {
                // A corrupt file ends the stream: nothing after the error can be trusted.
                self.done = true;
                self.chunk_end = 0;
                Some(Err(e))
            }
        }
    }
}

/// Every message of `bytes` (a whole MCAP file), for tests and the fuzz target.
pub fn messages_of(bytes: &[u8]) -> Result<Messages<&[u8]>, RecordingError> {
    Messages::new(bytes)
}

/// The topics, their schema names and message counts: from the summary section's statistics
/// when the file has them, otherwise by reading it through.
pub fn topics(path: &Path) -> Result<Vec<Topic>, RecordingError> {
    let mut out: Vec<Topic> = Vec::new();
    let mut add = |topic: &str, ty: &str, n: u64| match out.iter_mut().find(|t| t.name == topic) {
        Some(t) => t.messages += n,
        None => out.push(Topic {
            name: topic.to_owned(),
            type_name: ty.to_owned(),
            messages: n,
        }),
    };
    if let Some((registry, counts)) = summary(path)? {
        let mut ids: Vec<_> = registry.channels.keys().copied().collect();
        ids.sort_unstable();
        for id in ids {
            let c = &registry.channels[&id];
            add(&c.topic, &c.schema, counts.get(&id).copied().unwrap_or(0));
        }
        return Ok(out);
    }
    let file = File::open(path)?;
    for m in Messages::new(BufReader::new(file))? {
        let m = m?;
        add(&m.topic, &m.schema, 1);
    }
    Ok(out)
}

/// Messages per channel id.
type ChannelCounts = HashMap<u16, u64>;

/// The summary section's schemas, channels and per-channel message counts, if the footer
/// points at a summary with statistics.
fn summary(path: &Path) -> Result<Option<(Registry, ChannelCounts)>, RecordingError> {
    let mut file = File::open(path)?;
    let size = file.metadata()?.len();
    // The footer (opcode, length 20, summary start, summary offset start, CRC) and the magic.
    let footer_at = match size.checked_sub(8 + 9 + 20) {
        Some(at) if at >= 8 => at,
        _ => return Ok(None),
    };
    file.seek(SeekFrom::Start(footer_at))?;
    let mut tail = [0u8; 37];
    file.read_exact(&mut tail)?;
    if tail[0] != OP_FOOTER || tail[29..] != *MAGIC {
        return Ok(None);
    }
    let start = u64::from_le_bytes(tail[9..17].try_into().expect("8"));
    if start == 0 || start >= footer_at || footer_at - start > MAX_RECORD_BYTES as u64 {
        return Ok(None);
    }
    file.seek(SeekFrom::Start(start))?;
    let mut section = (&mut file).take(footer_at - start);
    let mut registry = Registry::default();
    let mut counts = None;
    while let Some((op, body)) = next_record(&mut section)? {
        match op {
            OP_SCHEMA => registry.schema(&body)?,
            OP_CHANNEL => registry.channel(&body)?,
            OP_STATISTICS => {
                let mut f = Fields { b: &body };
                f.bytes(8 + 2 + 4 + 4 + 4 + 4 + 8 + 8, "the statistics")?;
                let mut map = Fields {
                    b: f.prefixed("the statistics' channel counts")?,
                };
                let mut c = HashMap::new();
                while !map.b.is_empty() {
                    let id = map.u16("a channel count")?;
                    c.insert(id, map.u64("a channel count")?);
                }
                counts = Some(c);
            }
            _ => {}
        }
    }
    Ok(counts.map(|c| (registry, c)))
}

/// The messages of `topic`, in file order.
pub fn messages(
    path: &Path,
    topic: &str,
) -> Result<impl Iterator<Item = Result<RawMessage, RecordingError>>, RecordingError> {
    let file = BufReader::new(File::open(path)?);
    let topic = topic.to_owned();
    Ok(Messages::new(file)?.filter_map(move |m| {
        let m = match m {
            Ok(m) => m,
            Err(e) => return Some(Err(e)),
        };
        if m.topic != topic {
            return None;
        }
        let encoding = match m.encoding.as_str() {
            "cdr" => Encoding::Cdr,
            "ros1" => Encoding::Ros1,
            other => {
                return Some(Err(Unsupported(format!(
                    "message encoding {other:?} is neither cdr nor ros1"
                ))))
            }
        };
        Some(Ok(RawMessage {
            data: m.data,
            start: m.start,
            encoding,
            log_time_ns: m.log_time,
        }))
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixture(name: &str) -> Vec<u8> {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../tests/fixtures/recordings/mcap")
            .join(name);
        std::fs::read(path).unwrap()
    }

    /// The offset of the first chunk record in `b`.
    fn first_chunk(b: &[u8]) -> usize {
        let mut at = MAGIC.len();
        while b[at] != OP_CHUNK {
            at += 9 + u64::from_le_bytes(b[at + 1..at + 9].try_into().unwrap()) as usize;
        }
        at
    }

    #[test]
    fn a_chunk_claiming_a_terabyte_is_refused_not_allocated() {
        let mut b = fixture("cdr-zstd.mcap");
        let at = first_chunk(&b);
        b[at + 25..at + 33].copy_from_slice(&(1u64 << 40).to_le_bytes());
        let e = messages_of(&b)
            .unwrap()
            .find_map(|m| m.err())
            .expect("an error");
        assert_eq!(
            e,
            Damaged(
                "a chunk decompressing to 1099511627776 bytes, over the 268435456-byte limit"
                    .into()
            )
        );
    }

    #[test]
    fn a_string_longer_than_its_record_is_an_error() {
        let mut b = fixture("cdr-none.mcap");
        // The first chunk (uncompressed) starts with the schema: its name's length.
        let chunk = first_chunk(&b);
        let compression = u32::from_le_bytes(b[chunk + 37..chunk + 41].try_into().unwrap());
        let at = chunk + 41 + compression as usize + 8;
        assert_eq!(b[at], OP_SCHEMA);
        b[at + 11..at + 15].copy_from_slice(&u32::MAX.to_le_bytes());
        let e = messages_of(&b)
            .unwrap()
            .find_map(|m| m.err())
            .expect("an error");
        assert_eq!(e, Damaged("a schema name runs past its record".into()));
    }

    #[test]
    fn every_compression_gives_the_same_messages() {
        let all = |name: &str| -> Vec<_> {
            messages_of(&fixture(name))
                .unwrap()
                .map(|m| {
                    let m = m.unwrap();
                    (
                        m.topic,
                        m.encoding,
                        m.schema,
                        m.log_time,
                        m.data[m.start..].to_vec(),
                    )
                })
                .collect()
        };
        let none = all("cdr-none.mcap");
        assert_eq!(none.len(), 6, "three clouds and three IMU messages");
        assert_eq!(none, all("cdr-zstd.mcap"));
        assert_eq!(none, all("cdr-lz4.mcap"));
    }
}
