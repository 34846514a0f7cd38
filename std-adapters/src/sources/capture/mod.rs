//! Packet captures: a `.pcap` or `.pcapng` file read as a stream of UDP datagrams, with each
//! one's capture time.
//!
//! The container is read by the `pcap-parser` crate's streaming readers through a buffer of
//! [`BUFFER_BYTES`], grown up to [`MAX_BLOCK_BYTES`] for a larger block (a capture whose
//! blocks are larger is refused by name): memory stays flat whatever the file's size. The
//! network layers ([`network`]) are ours. What it guarantees: every datagram of the file in
//! order; every frame that is not one counted by reason ([`CaptureStats`]); a damaged or cut
//! file ends the stream with an error naming the file and the byte where it broke, after the
//! datagrams before it.

pub mod network;

use crate::io::error::FileError;
use network::{Network, Skip, Udp};
use pcap_parser::pcapng::Block;
use pcap_parser::traits::{PcapNGPacketBlock, PcapReaderIterator};
use pcap_parser::{PcapBlockOwned, PcapError};
use std::fs::File;
use std::path::{Path, PathBuf};

/// The reading buffer's size.
pub const BUFFER_BYTES: usize = 256 * 1024;
/// The largest block the buffer grows for.
pub const MAX_BLOCK_BYTES: usize = 4 * 1024 * 1024;

/// Whether `path` starts like a packet capture (either format, either byte order).
pub fn is_capture(path: &Path) -> bool {
    use std::io::Read;
    let mut magic = [0u8; 4];
    let ok = File::open(path)
        .and_then(|mut f| f.read_exact(&mut magic))
        .is_ok();
    ok && matches!(
        u32::from_le_bytes(magic),
        0xa1b2_c3d4 | 0xd4c3_b2a1 | 0xa1b2_3c4d | 0x4d3c_b2a1 | 0x0a0d_0d0a
    )
}

/// What a capture held besides the datagrams handed out.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize)]
pub struct CaptureStats {
    /// Datagrams handed out.
    pub datagrams: u64,
    /// Frames that were not IPv4 UDP (ARP, IPv6, TCP, ...).
    pub other_traffic: u64,
    /// Frames cut short by the capture's snap length or damaged.
    pub truncated: u64,
    /// Frames of a link type this reader does not know.
    pub unknown_link: u64,
    /// Datagrams put back together from IPv4 fragments.
    pub reassembled: u64,
    /// Fragmented datagrams that never came whole.
    pub fragments_dropped: u64,
}

/// One datagram and when it was captured.
#[derive(Debug, Clone, Copy)]
pub struct Datagram<'a> {
    /// Capture time (seconds since the Unix epoch, as the capturing host's clock had it).
    pub time_s: f64,
    /// Its ports and payload.
    pub udp: Udp<'a>,
}

/// An interface of a pcapng section: its link type and time units.
#[derive(Debug, Clone, Copy)]
struct Interface {
    link: i32,
    units_per_s: u64,
    offset_s: i64,
}

/// What the blocks read so far say of the frames to come, and the last frame's bytes.
#[derive(Debug, Default)]
struct Framing {
    /// Legacy format: its link type and whether times are in nanoseconds.
    legacy: Option<(i32, bool)>,
    /// pcapng: the current section's interfaces.
    interfaces: Vec<Interface>,
    /// pcapng: whether the current section is big-endian (`None` before the first section).
    ng_big_endian: Option<bool>,
    /// The last frame's bytes (copied out of the reading buffer).
    payload: Vec<u8>,
}

impl Framing {
    /// Takes one block: a frame's link type, time and whether it was captured whole (its
    /// bytes copied to `payload`), or `None` for a block that describes the ones to come (or
    /// a frame of an interface never described).
    fn frame(&mut self, block: PcapBlockOwned<'_>) -> Option<(i32, f64, bool)> {
        match block {
            PcapBlockOwned::LegacyHeader(h) => {
                self.legacy = Some((h.network.0, h.is_nanosecond_precision()));
                None
            }
            PcapBlockOwned::Legacy(b) => self.legacy.map(|(link, nanos)| {
                let frac = if nanos { 1e-9 } else { 1e-6 };
                let t = f64::from(b.ts_sec) + f64::from(b.ts_usec) * frac;
                (
                    link,
                    t,
                    copy(&mut self.payload, b.data, b.caplen, b.origlen),
                )
            }),
            PcapBlockOwned::NG(Block::SectionHeader(h)) => {
                self.interfaces.clear();
                self.ng_big_endian = Some(h.big_endian());
                None
            }
            PcapBlockOwned::NG(Block::InterfaceDescription(i)) => {
                self.interfaces.push(Interface {
                    link: i.linktype.0,
                    units_per_s: i.ts_resolution().unwrap_or(1_000_000),
                    offset_s: i.ts_offset(),
                });
                None
            }
            PcapBlockOwned::NG(Block::EnhancedPacket(p)) => {
                let i = usize::try_from(p.if_id).ok();
                i.and_then(|i| self.interfaces.get(i)).copied().map(|i| {
                    let ticks = (u64::from(p.ts_high) << 32) | u64::from(p.ts_low);
                    let t = i.offset_s as f64 + ticks as f64 / i.units_per_s as f64;
                    let whole = !p.truncated();
                    (
                        i.link,
                        t,
                        copy_ng(&mut self.payload, p.packet_data(), whole),
                    )
                })
            }
            PcapBlockOwned::NG(Block::SimplePacket(p)) => {
                // No time of its own: the previous one's stands in (0 first).
                self.interfaces.first().copied().map(|i| {
                    let whole = p.data.len() >= p.origlen as usize;
                    (
                        i.link,
                        0.0,
                        copy_ng(&mut self.payload, p.packet_data(), whole),
                    )
                })
            }
            PcapBlockOwned::NG(_) => None,
        }
    }
}

/// A capture being read.
pub struct Capture {
    path: PathBuf,
    reader: Box<dyn PcapReaderIterator + Send>,
    framing: Framing,
    network: Network,
    /// The last datagram's payload.
    datagram: Vec<u8>,
    stats: CaptureStats,
}

impl std::fmt::Debug for Capture {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Capture")
            .field("path", &self.path)
            .field("stats", &self.stats)
            .finish()
    }
}

impl Capture {
    /// Opens `path`; an error names the file and why it is not a capture.
    pub fn open(path: &Path) -> Result<Self, FileError> {
        let file = File::open(path).map_err(|e| FileError::at(path, e.to_string()))?;
        Self::from_reader(path, file)
    }

    /// A capture read from `reader`, named `path` in messages.
    pub fn from_reader(
        path: &Path,
        reader: impl std::io::Read + Send + 'static,
    ) -> Result<Self, FileError> {
        let reader = pcap_parser::create_reader(BUFFER_BYTES, reader).map_err(|e| {
            FileError::at(
                path,
                match e {
                    PcapError::HeaderNotRecognized => "not a pcap or pcapng capture".to_string(),
                    PcapError::Eof => "empty file".to_string(),
                    other => format!("not a readable capture ({other:?})"),
                },
            )
        })?;
        Ok(Self {
            path: path.to_path_buf(),
            reader,
            framing: Framing::default(),
            network: Network::default(),
            datagram: Vec::new(),
            stats: CaptureStats::default(),
        })
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// What was read so far.
    pub fn stats(&self) -> CaptureStats {
        CaptureStats {
            reassembled: self.network.reassembled,
            fragments_dropped: self.network.fragments_dropped,
            ..self.stats
        }
    }

    /// The next datagram, `None` at the end of the file.
    pub fn next_datagram(&mut self) -> Result<Option<Datagram<'_>>, FileError> {
        loop {
            match self.skip_other_block() {
                Ok(true) => continue,
                Ok(false) => {}
                Err(e) => return Err(e),
            }
            // What the block gave: a frame (its link type and time), or nothing to hand out.
            let (consumed, frame) = match self.reader.next() {
                Ok((consumed, block)) => (consumed, Ok(self.framing.frame(block))),
                Err(PcapError::Eof) => return Ok(None),
                Err(PcapError::Incomplete(_)) => (0, Err(None)),
                Err(e) => (0, Err(Some(format!("{e:?}")))),
            };
            let frame = match frame {
                Ok(frame) => frame,
                Err(None) => {
                    if self.refill()? {
                        continue;
                    }
                    return Ok(None);
                }
                Err(Some(why)) => return Err(self.broken(&why)),
            };
            self.reader.consume(consumed);
            let Some((link, time_s, whole)) = frame else {
                continue;
            };
            if !whole {
                self.stats.truncated += 1;
                continue;
            }
            let ports = self.udp_of(link);
            if let Some((src_port, dst_port)) = ports {
                self.stats.datagrams += 1;
                return Ok(Some(Datagram {
                    time_s,
                    udp: Udp {
                        src_port,
                        dst_port,
                        payload: &self.datagram,
                    },
                }));
            }
        }
    }

    /// The ports of the UDP datagram in the last frame (its payload copied to
    /// `self.datagram`), counting what is not one; `None` also for a fragment the network
    /// holds until the datagram is whole.
    fn udp_of(&mut self, link: i32) -> Option<(u16, u16)> {
        // The frame is in the framing's payload; the datagram may be a reassembled one, in
        // the network's buffer: its payload is copied to `self.datagram`.
        let frame_bytes = std::mem::take(&mut self.framing.payload);
        let ports = match self.network.udp(link, &frame_bytes) {
            Ok(u) => {
                self.datagram.clear();
                self.datagram.extend_from_slice(u.payload);
                Some((u.src_port, u.dst_port))
            }
            Err(Skip::Fragment) => None,
            Err(Skip::Truncated | Skip::Malformed) => {
                self.stats.truncated += 1;
                None
            }
            Err(Skip::LinkType(_)) => {
                self.stats.unknown_link += 1;
                None
            }
            Err(Skip::NotIpv4 | Skip::NotUdp) => {
                self.stats.other_traffic += 1;
                None
            }
        };
        self.framing.payload = frame_bytes;
        ports
    }

    /// In a pcapng section, passes over the next block when it is none of the four this reader
    /// uses (section header, interface description, enhanced and simple packet) without
    /// parsing it: `true` when one was passed over. (The parser's own reading of some of the
    /// other blocks can overflow on a damaged length; found by fuzzing pcap-parser 0.17.0.)
    fn skip_other_block(&mut self) -> Result<bool, FileError> {
        const USED: [u32; 4] = [0x0a0d_0d0a, 0x0000_0001, 0x0000_0006, 0x0000_0003];
        let Some(big) = self.framing.ng_big_endian else {
            return Ok(false);
        };
        let data = self.reader.data();
        let Some(header) = data.get(..8) else {
            return Ok(false);
        };
        let word = |b: &[u8]| {
            let w = [b[0], b[1], b[2], b[3]];
            if big {
                u32::from_be_bytes(w)
            } else {
                u32::from_le_bytes(w)
            }
        };
        // The section header's type reads the same in both orders.
        let (kind, len) = (word(&header[..4]), word(&header[4..8]) as usize);
        if USED.contains(&kind) || kind == 0x0a0d_0d0a {
            return Ok(false);
        }
        if len < 12 || !len.is_multiple_of(4) {
            return Err(self.broken(&format!(
                "a block of type {kind:#x} with a length of {len} bytes"
            )));
        }
        if data.len() >= len {
            self.reader.consume(len);
            return Ok(true);
        }
        // Not all of it is in the buffer yet.
        if self.refill()? {
            return Ok(true);
        }
        Err(self.broken("the file ends inside a block"))
    }

    /// Reads more of the file into the buffer, growing it for a block larger than it; `false`
    /// at the clean end of the file.
    fn refill(&mut self) -> Result<bool, FileError> {
        let before = self.reader.data().len();
        self.reader
            .refill()
            .map_err(|e| FileError::at(&self.path, format!("cannot read: {e:?}")))?;
        let after = self.reader.data().len();
        if after > before {
            return Ok(true);
        }
        if after == 0 {
            return Ok(false);
        }
        if self.reader.reader_exhausted() {
            return Err(self.broken("the file ends inside a block"));
        }
        // Nothing more fit: the block is larger than the buffer.
        let size = after.saturating_mul(2);
        if size > MAX_BLOCK_BYTES || !self.reader.grow(size) {
            return Err(self.broken(&format!(
                "a block larger than {} MB, more than any LiDAR packet",
                MAX_BLOCK_BYTES / (1024 * 1024)
            )));
        }
        Ok(true)
    }

    fn broken(&self, why: &str) -> FileError {
        FileError::at(
            &self.path,
            format!("damaged capture at byte {}: {why}", self.reader.consumed()),
        )
    }
}

/// Copies a legacy frame into `buf`; whether it was captured whole.
fn copy(buf: &mut Vec<u8>, data: &[u8], caplen: u32, origlen: u32) -> bool {
    buf.clear();
    let n = (caplen as usize).min(data.len());
    buf.extend_from_slice(&data[..n]);
    caplen >= origlen
}

/// Copies a pcapng frame into `buf`; passes `whole` on.
fn copy_ng(buf: &mut Vec<u8>, data: &[u8], whole: bool) -> bool {
    buf.clear();
    buf.extend_from_slice(data);
    whole
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Cursor;

    fn block(kind: u32, body: &[u8]) -> Vec<u8> {
        let mut body = body.to_vec();
        body.resize(body.len().div_ceil(4) * 4, 0);
        let n = (12 + body.len()) as u32;
        let mut b = Vec::new();
        b.extend_from_slice(&kind.to_le_bytes());
        b.extend_from_slice(&n.to_le_bytes());
        b.extend_from_slice(&body);
        b.extend_from_slice(&n.to_le_bytes());
        b
    }

    /// A pcapng section with one raw-IPv4 interface, `middle`, then one packet.
    fn pcapng(middle: &[u8]) -> Vec<u8> {
        let mut shb = 0x1a2b_3c4du32.to_le_bytes().to_vec();
        shb.extend_from_slice(&[1, 0, 0, 0]);
        shb.extend_from_slice(&(-1i64).to_le_bytes());
        let mut out = block(0x0a0d_0d0a, &shb);
        let mut idb = (network::linktype::RAW as u16).to_le_bytes().to_vec();
        idb.extend_from_slice(&[0, 0, 0xff, 0xff, 0, 0]);
        out.extend(block(1, &idb));
        out.extend_from_slice(middle);
        // An IPv4 UDP datagram of 4 bytes, port 2368.
        let mut ip = vec![
            0x45, 0, 0, 32, 0, 0, 0, 0, 64, 17, 0, 0, 10, 0, 0, 1, 10, 0, 0, 2,
        ];
        ip.extend_from_slice(&[0x09, 0x40, 0x09, 0x40, 0, 12, 0, 0, 1, 2, 3, 4]);
        let mut epb = vec![0u8; 4];
        epb.extend_from_slice(&0u32.to_le_bytes());
        epb.extend_from_slice(&5_000_000u32.to_le_bytes());
        epb.extend_from_slice(&(ip.len() as u32).to_le_bytes());
        epb.extend_from_slice(&(ip.len() as u32).to_le_bytes());
        epb.extend_from_slice(&ip);
        out.extend(block(6, &epb));
        out
    }

    fn datagrams(bytes: Vec<u8>) -> Result<Vec<(f64, Vec<u8>)>, FileError> {
        let mut cap = Capture::from_reader(Path::new("t.pcapng"), Cursor::new(bytes))?;
        let mut out = Vec::new();
        while let Some(d) = cap.next_datagram()? {
            out.push((d.time_s, d.udp.payload.to_vec()));
        }
        Ok(out)
    }

    #[test]
    fn blocks_it_does_not_use_are_passed_over_and_bad_ones_refused() {
        let plain = datagrams(pcapng(&[])).unwrap();
        assert_eq!(plain, vec![(5.0, vec![1, 2, 3, 4])]);
        // An interface statistics block and a custom one: passed over unparsed.
        let mut others = block(5, &[0; 20]);
        others.extend(block(0x4000_0bad, &[7; 9]));
        assert_eq!(datagrams(pcapng(&others)).unwrap(), plain);
        // A block whose length is shorter than any block: the file is damaged there (the
        // parser itself would overflow on some such blocks).
        let mut bad = 0x8000_0001u32.to_le_bytes().to_vec();
        bad.extend_from_slice(&8u32.to_le_bytes());
        let e = datagrams(pcapng(&bad)).unwrap_err().to_string();
        assert!(e.contains("0x80000001 with a length of 8"), "{e}");
    }
}
