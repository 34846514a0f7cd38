//! MCAP files (the `mcap` crate, Foxglove's own): topics and counts from the summary section,
//! and messages streamed in file order a chunk at a time (uncompressed, zstd or lz4). Both
//! message encodings robots record are read: `cdr` (ROS 2) and `ros1` (what `mcap convert`
//! makes of a ROS 1 bag).

use super::{Encoding, RawMessage, Topic};
use mcap::sans_io::{SummaryReadEvent, SummaryReader, SummaryReaderOptions};
use std::fs::File;
use std::io::{BufReader, Read, Seek};
use std::path::Path;

/// The first bytes of every MCAP file.
pub const MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// The topics, their schema names and message counts: from the summary when it has the
/// statistics, otherwise by reading the file through.
pub fn topics(path: &Path) -> Result<Vec<Topic>, String> {
    let mut file = File::open(path).map_err(|e| e.to_string())?;
    let size = file.metadata().map_err(|e| e.to_string())?.len();
    let mut reader =
        SummaryReader::new_with_options(SummaryReaderOptions::default().with_file_size(size));
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
    for m in
        mcap::io::MessageReader::new(BufReader::new(File::open(path).map_err(|e| e.to_string())?))
    {
        let m = m.map_err(|e| e.to_string())?;
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
    Ok(mcap::io::MessageReader::new(file).filter_map(move |m| {
        let m = match m {
            Ok(m) => m,
            Err(e) => return Some(Err(e.to_string())),
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
