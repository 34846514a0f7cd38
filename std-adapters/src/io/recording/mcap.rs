//! MCAP files (the `mcap` crate, Foxglove's own): topics and counts from the summary section,
//! and messages streamed in file order a chunk at a time (uncompressed, zstd or lz4). Both
//! message encodings robots record are read: `cdr` (ROS 2) and `ros1` (what `mcap convert`
//! makes of a ROS 1 bag).

use super::{Encoding, RawMessage, Topic};
use mcap::sans_io::{LinearReaderOptions, SummaryReadEvent, SummaryReader, SummaryReaderOptions};
use std::fs::File;
use std::io::{BufReader, Read, Seek};
use std::path::Path;

/// The first bytes of every MCAP file.
pub const MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// The longest record (and decompressed chunk) read: a corrupt length is refused rather than
/// allocated. A 128-beam cloud of 2 048 columns is about 13 MB.
pub const MAX_RECORD_BYTES: usize = 256 << 20;

/// A streaming reader of `file` that refuses records, and chunks decompressing to more than
/// [`MAX_RECORD_BYTES`] ([`LengthGuard`]).
fn message_reader<R: Read>(file: R) -> mcap::io::MessageReader<LengthGuard<R>> {
    let mut options = LinearReaderOptions::default();
    options.record_length_limit = Some(MAX_RECORD_BYTES);
    mcap::io::MessageReader::new_with_options(LengthGuard::new(file), options)
}

/// An error with the reader's own inside: the `mcap` crate shows a reader's error only as
/// "I/O error ...".
fn describe(e: &mcap::McapError) -> String {
    match e {
        mcap::McapError::Io(io) => format!("{e}: {io}"),
        _ => e.to_string(),
    }
}

const OP_FOOTER: u8 = 0x02;
const OP_CHUNK: u8 = 0x06;
/// Opcode and length, then a chunk's start time, end time and uncompressed size.
const CHUNK_HEAD: usize = 9 + 24;

/// Passes an MCAP byte stream through, checking each record's length and each chunk's
/// uncompressed size against [`MAX_RECORD_BYTES`] before the `mcap` crate sees them: it would
/// allocate a corrupt chunk's claimed size whole (a fuzzed file asked for 3.5 GB), and a
/// robot's process must not die of one bad file.
pub struct LengthGuard<R> {
    inner: R,
    /// File offset of the next byte read.
    offset: u64,
    /// Offset of the next record.
    next: u64,
    /// The head of the record at `next`, as it arrives.
    head: [u8; CHUNK_HEAD],
    have: usize,
    /// Past the footer: the end magic follows, and nothing more to check.
    done: bool,
}

impl<R> LengthGuard<R> {
    fn new(inner: R) -> Self {
        LengthGuard {
            inner,
            offset: 0,
            next: MAGIC.len() as u64,
            head: [0; CHUNK_HEAD],
            have: 0,
            done: false,
        }
    }

    /// Checks the bytes `b`, read at `self.offset`.
    fn check(&mut self, b: &[u8]) -> std::io::Result<()> {
        let too_long = |what: &str, n: u64| {
            std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("{what} of {n} bytes, over the {MAX_RECORD_BYTES}-byte limit"),
            )
        };
        let mut i = 0;
        while i < b.len() && !self.done {
            let at = self.offset + i as u64;
            if at < self.next {
                i += (self.next - at).min((b.len() - i) as u64) as usize;
                continue;
            }
            self.head[self.have] = b[i];
            self.have += 1;
            i += 1;
            let op = self.head[0];
            let want = if op == OP_CHUNK { CHUNK_HEAD } else { 9 };
            if self.have < want {
                continue;
            }
            let len = u64::from_le_bytes(self.head[1..9].try_into().expect("8 bytes"));
            if len > MAX_RECORD_BYTES as u64 {
                return Err(too_long("a record", len));
            }
            if op == OP_CHUNK {
                let size = u64::from_le_bytes(self.head[25..33].try_into().expect("8 bytes"));
                if size > MAX_RECORD_BYTES as u64 {
                    return Err(too_long("a chunk decompressing", size));
                }
            }
            self.done = op == OP_FOOTER;
            self.next = self.next.saturating_add(9 + len);
            self.have = 0;
        }
        self.offset += b.len() as u64;
        Ok(())
    }
}

impl<R: Read> Read for LengthGuard<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.check(&buf[..n])?;
        Ok(n)
    }
}

/// The topics, their schema names and message counts: from the summary when it has the
/// statistics, otherwise by reading the file through.
pub fn topics(path: &Path) -> Result<Vec<Topic>, String> {
    let mut file = File::open(path).map_err(|e| e.to_string())?;
    let size = file.metadata().map_err(|e| e.to_string())?.len();
    // The summary is small and its records are checked against the same limit.
    let mut reader = SummaryReader::new_with_options(
        SummaryReaderOptions::default()
            .with_file_size(size)
            .with_record_length_limit(MAX_RECORD_BYTES),
    );
    while let Some(event) = reader.next_event() {
        match event.map_err(|e| format!("its summary does not read: {e}"))? {
            SummaryReadEvent::ReadRequest(n) => {
                let read = file.read(reader.insert(n)).map_err(|e| e.to_string())?;
                reader.notify_read(read);
            }
            SummaryReadEvent::SeekRequest(to) => {
                let pos = file.seek(to).map_err(|e| e.to_string())?;
                reader.notify_seeked(pos);
            }
        }
    }
    let mut out: Vec<Topic> = Vec::new();
    let mut add = |topic: &str, ty: &str, n: u64| match out.iter_mut().find(|t| t.name == topic) {
        Some(t) => t.messages += n,
        None => out.push(Topic {
            name: topic.to_owned(),
            type_name: ty.to_owned(),
            messages: n,
        }),
    };
    let schema_name =
        |c: &mcap::Channel| c.schema.as_ref().map_or("", |s| s.name.as_str()).to_owned();
    if let Some(summary) = reader.finish() {
        if let Some(stats) = &summary.stats {
            let mut ids: Vec<_> = summary.channels.keys().copied().collect();
            ids.sort_unstable();
            for id in ids {
                let c = &summary.channels[&id];
                let n = stats.channel_message_counts.get(&id).copied().unwrap_or(0);
                add(&c.topic, &schema_name(c), n);
            }
            return Ok(out);
        }
    }
    for m in message_reader(BufReader::new(File::open(path).map_err(|e| e.to_string())?)) {
        let m = m.map_err(|e| describe(&e))?;
        add(&m.channel.topic, &schema_name(&m.channel), 1);
    }
    Ok(out)
}

/// The messages of `topic`, in file order.
pub fn messages(
    path: &Path,
    topic: &str,
) -> Result<impl Iterator<Item = Result<RawMessage, String>>, String> {
    let file = BufReader::with_capacity(1 << 16, File::open(path).map_err(|e| e.to_string())?);
    let topic = topic.to_owned();
    Ok(message_reader(file).filter_map(move |m| {
        let m = match m {
            Ok(m) => m,
            Err(e) => return Some(Err(describe(&e))),
        };
        if m.channel.topic != topic {
            return None;
        }
        let encoding = match m.channel.message_encoding.as_str() {
            "cdr" => Encoding::Cdr,
            "ros1" => Encoding::Ros1,
            other => {
                return Some(Err(format!(
                    "message encoding {other:?} is neither cdr nor ros1"
                )))
            }
        };
        Some(Ok(RawMessage {
            data: m.data.into_owned(),
            encoding,
            log_time_ns: m.log_time,
        }))
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fixture's bytes with its first chunk claiming to decompress to 1 TB.
    fn with_a_huge_chunk() -> Vec<u8> {
        let path = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../tests/fixtures/recordings/mcap/cdr-zstd.mcap");
        let mut b = std::fs::read(path).unwrap();
        let mut at = MAGIC.len();
        while b[at] != OP_CHUNK {
            at += 9 + u64::from_le_bytes(b[at + 1..at + 9].try_into().unwrap()) as usize;
        }
        b[at + 25..at + 33].copy_from_slice(&(1u64 << 40).to_le_bytes());
        b
    }

    #[test]
    fn a_chunk_claiming_a_terabyte_is_refused_not_allocated() {
        let b = with_a_huge_chunk();
        let first = message_reader(&b[..])
            .find_map(|m| m.err())
            .expect("an error");
        let e = describe(&first);
        assert!(
            e.contains("a chunk decompressing of 1099511627776 bytes, over the"),
            "{e}"
        );
    }
}
