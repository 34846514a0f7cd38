//! ROS 1 bags (format 2.0): topics and counts from the index at the end, and messages read a
//! chunk at a time (uncompressed, bz2 or lz4), so that memory holds one chunk, not the file.
//!
//! A bag is a sequence of records, each a header (a list of `name=value` fields, one of them
//! the opcode `op`) and data. Chunks hold connection and message records; after them the index
//! section holds every connection and, per chunk, how many messages each connection has there.

use super::error::RecordingError::{self, Damaged, NotThisFormat, Truncated, Unsupported};
use super::{decompress, Compression, Encoding, RawMessage, Topic};
use std::collections::HashMap;
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

/// The first bytes of every ROS 1 bag.
pub const MAGIC: &[u8] = b"#ROSBAG V2.0\n";

const OP_MESSAGE: u8 = 0x02;
const OP_BAG_HEADER: u8 = 0x03;
const OP_CHUNK: u8 = 0x05;
const OP_CHUNK_INFO: u8 = 0x06;
const OP_CONNECTION: u8 = 0x07;

/// Records and chunks larger than this are refused as corrupt (a chunk is rarely over a few
/// MB; the same limit as MCAP's, [`super::mcap::MAX_RECORD_BYTES`]).
const MAX_RECORD: usize = super::mcap::MAX_RECORD_BYTES;

/// One record: its header fields and its data.
struct Record {
    fields: HashMap<String, Vec<u8>>,
    data: Vec<u8>,
}

impl Record {
    fn op(&self) -> Option<u8> {
        self.fields.get("op").and_then(|v| v.first().copied())
    }
    fn u32(&self, name: &str) -> Result<u32, RecordingError> {
        let v = self
            .fields
            .get(name)
            .ok_or_else(|| Damaged(format!("a record has no {name}")))?;
        let b: [u8; 4] = v[..]
            .try_into()
            .map_err(|_| Damaged(format!("{name} is not 4 bytes")))?;
        Ok(u32::from_le_bytes(b))
    }
    fn u64(&self, name: &str) -> Result<u64, RecordingError> {
        let v = self
            .fields
            .get(name)
            .ok_or_else(|| Damaged(format!("a record has no {name}")))?;
        let b: [u8; 8] = v[..]
            .try_into()
            .map_err(|_| Damaged(format!("{name} is not 8 bytes")))?;
        Ok(u64::from_le_bytes(b))
    }
    fn text(&self, name: &str) -> Result<String, RecordingError> {
        let v = self
            .fields
            .get(name)
            .ok_or_else(|| Damaged(format!("a record has no {name}")))?;
        Ok(String::from_utf8_lossy(v).into_owned())
    }
}

/// Parses `name=value` fields, each preceded by its u32 length.
fn parse_fields(mut b: &[u8]) -> Result<HashMap<String, Vec<u8>>, RecordingError> {
    let mut out = HashMap::new();
    while !b.is_empty() {
        let n = read_u32(&mut b)
            .ok_or_else(|| Truncated("a header field's length is cut off".into()))?
            as usize;
        let f = b
            .get(..n)
            .ok_or_else(|| Damaged("a header field runs past its header".into()))?;
        let eq = f
            .iter()
            .position(|&c| c == b'=')
            .ok_or_else(|| Damaged("a header field has no '='".into()))?;
        out.insert(
            String::from_utf8_lossy(&f[..eq]).into_owned(),
            f[eq + 1..].to_vec(),
        );
        b = &b[n..];
    }
    Ok(out)
}

fn read_u32(b: &mut &[u8]) -> Option<u32> {
    let v = u32::from_le_bytes(b.get(..4)?.try_into().ok()?);
    *b = &b[4..];
    Some(v)
}

/// Reads the next record from `r`, or `None` at a clean end of file.
fn next_record(r: &mut impl Read) -> Result<Option<Record>, RecordingError> {
    let mut len = [0u8; 4];
    match r.read(&mut len[..1]) {
        Ok(0) => return Ok(None),
        Ok(_) => r
            .read_exact(&mut len[1..])
            .map_err(|_| Truncated("the file ends inside a record's length".into()))?,
        Err(e) => return Err(e.into()),
    }
    let header = read_block(r, u32::from_le_bytes(len) as usize, "header")?;
    let fields = parse_fields(&header)?;
    r.read_exact(&mut len)
        .map_err(|_| Truncated("the file ends before a record's data".into()))?;
    let data = read_block(r, u32::from_le_bytes(len) as usize, "data")?;
    Ok(Some(Record { fields, data }))
}

fn read_block(r: &mut impl Read, n: usize, what: &str) -> Result<Vec<u8>, RecordingError> {
    if n > MAX_RECORD {
        return Err(Damaged(format!("a record's {what} claims {n} bytes")));
    }
    let mut v = Vec::new();
    r.take(n as u64).read_to_end(&mut v)?;
    if v.len() != n {
        return Err(Truncated(format!("the file ends inside a record's {what}")));
    }
    Ok(v)
}

fn open(path: &Path) -> Result<(BufReader<File>, u64), RecordingError> {
    let mut r = BufReader::new(File::open(path)?);
    let mut magic = [0u8; 13];
    r.read_exact(&mut magic)
        .map_err(|_| NotThisFormat("too short for a bag".into()))?;
    if magic != MAGIC {
        return Err(NotThisFormat("not a ROS 1 bag (format 2.0)".into()));
    }
    let header = next_record(&mut r)?.ok_or_else(|| Damaged("no bag header".into()))?;
    if header.op() != Some(OP_BAG_HEADER) {
        return Err(Damaged("the first record is not the bag header".into()));
    }
    Ok((r, header.u64("index_pos")?))
}

/// A connection record's topic and message type.
fn connection(rec: &Record) -> Result<(u32, String, String), RecordingError> {
    let conn = rec.u32("conn")?;
    let topic = rec.text("topic")?;
    let fields = parse_fields(&rec.data)?;
    let ty = fields
        .get("type")
        .map(|t| String::from_utf8_lossy(t).into_owned())
        .unwrap_or_default();
    Ok((conn, topic, ty))
}

/// The bag's topics with their types and message counts, from its index (or, for a bag whose
/// recording was cut off before the index was written, by reading it through).
pub fn topics(path: &Path) -> Result<Vec<Topic>, RecordingError> {
    let (mut r, index_pos) = open(path)?;
    let mut conns: Vec<(u32, String, String)> = Vec::new();
    let mut counts: HashMap<u32, u64> = HashMap::new();
    if index_pos > 0 {
        r.seek(SeekFrom::Start(index_pos))?;
        while let Some(rec) = next_record(&mut r)? {
            match rec.op() {
                Some(OP_CONNECTION) => conns.push(connection(&rec)?),
                Some(OP_CHUNK_INFO) => {
                    let mut d = &rec.data[..];
                    while let (Some(c), Some(n)) = (read_u32(&mut d), read_u32(&mut d)) {
                        *counts.entry(c).or_default() += n as u64;
                    }
                }
                _ => {}
            }
        }
    } else {
        for item in Messages::new(path, None)? {
            let (conn, _) = item?;
            *counts.entry(conn).or_default() += 1;
        }
        conns = Messages::new(path, None)?.connections_all()?;
    }
    // Several connections may share a topic (one per publisher).
    let mut out: Vec<Topic> = Vec::new();
    for (c, topic, ty) in conns {
        let n = counts.get(&c).copied().unwrap_or(0);
        match out.iter_mut().find(|t| t.name == topic) {
            Some(t) => t.messages += n,
            None => out.push(Topic {
                name: topic,
                type_name: ty,
                messages: n,
            }),
        }
    }
    Ok(out)
}

/// The messages of one topic (or of all, with `None`), in file order.
pub struct Messages {
    reader: BufReader<File>,
    index_pos: u64,
    topic: Option<String>,
    /// Connection ids and their topics, as met.
    conns: HashMap<u32, String>,
    /// The current chunk's records, decompressed, and the read position in it.
    chunk: Vec<u8>,
    at: usize,
}

impl Messages {
    /// Opens `path` for the messages of `topic`.
    pub fn new(path: &Path, topic: Option<&str>) -> Result<Self, RecordingError> {
        let (reader, index_pos) = open(path)?;
        Ok(Messages {
            reader,
            index_pos,
            topic: topic.map(str::to_owned),
            conns: HashMap::new(),
            chunk: Vec::new(),
            at: 0,
        })
    }

    /// Every connection in the bag, reading it through (for a bag without an index).
    fn connections_all(mut self) -> Result<Vec<(u32, String, String)>, RecordingError> {
        let mut out = Vec::new();
        loop {
            while self.at < self.chunk.len() {
                let mut r = &self.chunk[self.at..];
                let before = r.len();
                let rec = next_record(&mut r)?
                    .ok_or_else(|| Truncated("a chunk ends inside a record".into()))?;
                self.at += before - r.len();
                if rec.op() == Some(OP_CONNECTION) {
                    out.push(connection(&rec)?);
                }
            }
            if !self.next_chunk()? {
                return Ok(out);
            }
        }
    }

    /// Loads the next chunk; false at the end of the chunk section.
    fn next_chunk(&mut self) -> Result<bool, RecordingError> {
        loop {
            if self.index_pos > 0 {
                let pos = self.reader.stream_position()?;
                if pos >= self.index_pos {
                    return Ok(false);
                }
            }
            let Some(rec) = next_record(&mut self.reader)? else {
                return Ok(false);
            };
            match rec.op() {
                Some(OP_CHUNK) => {
                    let size = rec.u32("size")? as usize;
                    self.chunk = chunk_records(&rec.text("compression")?, &rec.data, size)?;
                    self.at = 0;
                    return Ok(true);
                }
                // Outside chunks only the index follows; a bag written without an index
                // ends with it too.
                Some(OP_CONNECTION) | Some(OP_CHUNK_INFO) => return Ok(false),
                _ => {}
            }
        }
    }
}

/// A chunk's records: `data` as it is, or decompressed to `size` bytes.
fn chunk_records(kind: &str, data: &[u8], size: usize) -> Result<Vec<u8>, RecordingError> {
    let kind = match kind {
        "none" => return Ok(data.to_vec()),
        "bz2" => Compression::Bz2,
        "lz4" => Compression::Lz4,
        other => {
            return Err(Unsupported(format!(
                "chunk compression {other:?} is not none, bz2 or lz4"
            )))
        }
    };
    decompress(kind, data, size)
}

impl Iterator for Messages {
    /// The connection id and the message.
    type Item = Result<(u32, RawMessage), RecordingError>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            while self.at < self.chunk.len() {
                let mut r = &self.chunk[self.at..];
                let before = r.len();
                let rec = match next_record(&mut r) {
                    Ok(Some(rec)) => rec,
                    Ok(None) => break,
                    Err(e) => {
                        self.chunk.clear();
                        return Some(Err(e));
                    }
                };
                self.at += before - r.len();
                match rec.op() {
                    Some(OP_CONNECTION) => match connection(&rec) {
                        Ok((c, topic, _)) => {
                            self.conns.insert(c, topic);
                        }
                        Err(e) => return Some(Err(e)),
                    },
                    Some(OP_MESSAGE) => {
                        let Ok(conn) = rec.u32("conn") else { continue };
                        let wanted = match (&self.topic, self.conns.get(&conn)) {
                            (None, _) => true,
                            (Some(t), Some(c)) => t == c,
                            (Some(_), None) => false,
                        };
                        if wanted {
                            let time = rec.u64("time").unwrap_or(0);
                            let ns = (time & 0xffff_ffff) * 1_000_000_000 + (time >> 32);
                            return Some(Ok((
                                conn,
                                RawMessage {
                                    start: 0,
                                    data: rec.data,
                                    encoding: Encoding::Ros1,
                                    log_time_ns: ns,
                                },
                            )));
                        }
                    }
                    _ => {}
                }
            }
            match self.next_chunk() {
                Ok(true) => {}
                Ok(false) => return None,
                Err(e) => return Some(Err(e)),
            }
        }
    }
}
