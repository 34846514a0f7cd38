//! From a captured link-layer frame to the UDP datagram inside it: Ethernet (with VLAN tags),
//! Linux cooked captures (v1 and v2), BSD loopback and raw IP; then IPv4, whose fragments are
//! put back together, and UDP.
//!
//! What it guarantees: a frame is either one whole datagram, or a [`Skip`] saying why not
//! (never a panic, never a datagram cut short); fragments wait in a table of at most
//! [`MAX_PENDING`] datagrams of at most 64 KiB each, the oldest dropped (and counted) first.

/// Link-layer types (pcap's `LINKTYPE_*` numbers) this module reads.
pub mod linktype {
    /// BSD loopback: a 4-byte address family, then IP.
    pub const NULL: i32 = 0;
    /// Ethernet II.
    pub const ETHERNET: i32 = 1;
    /// Raw IP (no link header).
    pub const RAW: i32 = 101;
    /// OpenBSD loopback.
    pub const LOOP: i32 = 108;
    /// Linux cooked capture, version 1.
    pub const LINUX_SLL: i32 = 113;
    /// Raw IPv4.
    pub const IPV4: i32 = 228;
    /// Linux cooked capture, version 2.
    pub const LINUX_SLL2: i32 = 276;
}

/// Datagrams being reassembled at once, at most.
pub const MAX_PENDING: usize = 8;

/// Why a frame gave no datagram.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Skip {
    /// A link type this reader does not know.
    LinkType(i32),
    /// Not IPv4 (IPv6, ARP, ...).
    NotIpv4,
    /// IPv4 but not UDP.
    NotUdp,
    /// Shorter than its headers say (the capture's snap length, or damage).
    Truncated,
    /// A header field that cannot be (a bad IP header length, a UDP length below 8).
    Malformed,
    /// A fragment kept until its datagram is whole.
    Fragment,
}

/// One UDP datagram: its ports and its payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Udp<'a> {
    /// Source port.
    pub src_port: u16,
    /// Destination port.
    pub dst_port: u16,
    /// The payload.
    pub payload: &'a [u8],
}

/// A datagram whose fragments are arriving.
#[derive(Debug)]
struct Pending {
    /// Source, destination, protocol and identification: what ties fragments together.
    key: ([u8; 4], [u8; 4], u16),
    /// The IP payload (UDP header and data) as far as it has come.
    bytes: Vec<u8>,
    /// Bytes received so far (fragments do not overlap in a sane capture; overlaps are
    /// refused).
    received: usize,
    /// The whole payload's length, known once the last fragment came.
    total: Option<usize>,
    /// Which 8-byte units have come.
    have: Vec<bool>,
    /// When it started (frames counted), to drop the oldest first.
    started: u64,
}

/// Turns captured frames into UDP datagrams, reassembling IPv4 fragments.
#[derive(Debug, Default)]
pub struct Network {
    pending: Vec<Pending>,
    /// The last reassembled datagram (its UDP header and payload).
    whole: Vec<u8>,
    frames: u64,
    /// Fragmented datagrams given up (never completed, or pushed out by newer ones).
    pub fragments_dropped: u64,
    /// Datagrams put back together from fragments.
    pub reassembled: u64,
}

fn u16_at(b: &[u8], i: usize) -> Option<u16> {
    Some(u16::from_be_bytes([*b.get(i)?, *b.get(i + 1)?]))
}

impl Network {
    /// The UDP datagram in `frame`, a frame of link type `link`.
    pub fn udp<'a>(&'a mut self, link: i32, frame: &'a [u8]) -> Result<Udp<'a>, Skip> {
        self.frames += 1;
        let ip = ip_packet(link, frame)?;
        // IPv4 header.
        let first = *ip.first().ok_or(Skip::Truncated)?;
        if first >> 4 != 4 {
            return Err(Skip::NotIpv4);
        }
        let header = usize::from(first & 0x0f) * 4;
        let total = usize::from(u16_at(ip, 2).ok_or(Skip::Truncated)?);
        if header < 20 || total < header {
            return Err(Skip::Malformed);
        }
        if ip.len() < total {
            return Err(Skip::Truncated);
        }
        let protocol = ip[9];
        if protocol != 17 {
            return Err(Skip::NotUdp);
        }
        let flags_offset = u16_at(ip, 6).ok_or(Skip::Truncated)?;
        let more = flags_offset & 0x2000 != 0;
        let offset = usize::from(flags_offset & 0x1fff) * 8;
        let body = &ip[header..total];
        if !more && offset == 0 {
            return udp(body);
        }
        let key = (
            [ip[12], ip[13], ip[14], ip[15]],
            [ip[16], ip[17], ip[18], ip[19]],
            u16_at(ip, 4).ok_or(Skip::Truncated)?,
        );
        if self.fragment(key, offset, more, body)? {
            return udp(&self.whole);
        }
        Err(Skip::Fragment)
    }

    /// Adds a fragment; `true` when its datagram is whole (then in `self.whole`).
    fn fragment(
        &mut self,
        key: ([u8; 4], [u8; 4], u16),
        offset: usize,
        more: bool,
        body: &[u8],
    ) -> Result<bool, Skip> {
        const MAX: usize = 65_535;
        let end = offset + body.len();
        if end > MAX || (more && !body.len().is_multiple_of(8)) {
            return Err(Skip::Malformed);
        }
        let i = match self.pending.iter().position(|p| p.key == key) {
            Some(i) => i,
            None => {
                if self.pending.len() >= MAX_PENDING {
                    let oldest = (0..self.pending.len())
                        .min_by_key(|&k| self.pending[k].started)
                        .unwrap_or(0);
                    self.pending.swap_remove(oldest);
                    self.fragments_dropped += 1;
                }
                self.pending.push(Pending {
                    key,
                    bytes: Vec::new(),
                    received: 0,
                    total: None,
                    have: Vec::new(),
                    started: self.frames,
                });
                self.pending.len() - 1
            }
        };
        let p = &mut self.pending[i];
        let units = (offset / 8)..end.div_ceil(8);
        if p.have.len() < units.end {
            p.have.resize(units.end, false);
        }
        if p.have[units.clone()].iter().any(|&h| h) {
            // Overlapping fragments: refuse the datagram rather than guess which bytes win.
            self.pending.swap_remove(i);
            self.fragments_dropped += 1;
            return Err(Skip::Malformed);
        }
        p.have[units].iter_mut().for_each(|h| *h = true);
        if p.bytes.len() < end {
            p.bytes.resize(end, 0);
        }
        p.bytes[offset..end].copy_from_slice(body);
        p.received += body.len();
        if !more {
            p.total = Some(end);
        }
        if p.total.is_some_and(|t| p.received == t) {
            let done = self.pending.swap_remove(i);
            self.whole = done.bytes;
            self.reassembled += 1;
            return Ok(true);
        }
        Ok(false)
    }
}

/// The IP packet in a link-layer frame.
fn ip_packet(link: i32, frame: &[u8]) -> Result<&[u8], Skip> {
    let after = |n: usize| frame.get(n..).ok_or(Skip::Truncated);
    match link {
        linktype::ETHERNET => {
            let mut at = 12;
            let mut ethertype = u16_at(frame, at).ok_or(Skip::Truncated)?;
            // 802.1Q and 802.1ad tags, up to two.
            for _ in 0..2 {
                if ethertype == 0x8100 || ethertype == 0x88a8 {
                    at += 4;
                    ethertype = u16_at(frame, at).ok_or(Skip::Truncated)?;
                }
            }
            if ethertype != 0x0800 {
                return Err(Skip::NotIpv4);
            }
            after(at + 2)
        }
        linktype::LINUX_SLL => {
            if u16_at(frame, 14).ok_or(Skip::Truncated)? != 0x0800 {
                return Err(Skip::NotIpv4);
            }
            after(16)
        }
        linktype::LINUX_SLL2 => {
            if u16_at(frame, 0).ok_or(Skip::Truncated)? != 0x0800 {
                return Err(Skip::NotIpv4);
            }
            after(20)
        }
        linktype::NULL | linktype::LOOP => {
            // The address family, in the capturing host's byte order (NULL) or big-endian
            // (LOOP): AF_INET is 2 everywhere.
            let family = frame.get(..4).ok_or(Skip::Truncated)?;
            if !(family == [2, 0, 0, 0] || family == [0, 0, 0, 2]) {
                return Err(Skip::NotIpv4);
            }
            after(4)
        }
        linktype::RAW | linktype::IPV4 => Ok(frame),
        other => Err(Skip::LinkType(other)),
    }
}

/// The datagram in a UDP header and payload.
fn udp(bytes: &[u8]) -> Result<Udp<'_>, Skip> {
    let len = usize::from(u16_at(bytes, 4).ok_or(Skip::Truncated)?);
    if len < 8 {
        return Err(Skip::Malformed);
    }
    let payload = bytes.get(8..len).ok_or(Skip::Truncated)?;
    Ok(Udp {
        src_port: u16_at(bytes, 0).ok_or(Skip::Truncated)?,
        dst_port: u16_at(bytes, 2).ok_or(Skip::Truncated)?,
        payload,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An Ethernet frame with an IPv4 header (`id`, fragment `offset` in bytes, more
    /// fragments or not) around `body`.
    fn frame(id: u16, offset: usize, more: bool, body: &[u8]) -> Vec<u8> {
        let mut f = vec![0u8; 12];
        f.extend_from_slice(&[0x08, 0x00]);
        let total = (20 + body.len()) as u16;
        let fo = (offset / 8) as u16 | if more { 0x2000 } else { 0 };
        f.extend_from_slice(&[0x45, 0]);
        f.extend_from_slice(&total.to_be_bytes());
        f.extend_from_slice(&id.to_be_bytes());
        f.extend_from_slice(&fo.to_be_bytes());
        f.extend_from_slice(&[64, 17, 0, 0, 10, 0, 0, 1, 10, 0, 0, 2]);
        f.extend_from_slice(body);
        f
    }

    fn datagram(payload: &[u8]) -> Vec<u8> {
        let mut d = Vec::new();
        d.extend_from_slice(&7502u16.to_be_bytes());
        d.extend_from_slice(&7502u16.to_be_bytes());
        d.extend_from_slice(&((8 + payload.len()) as u16).to_be_bytes());
        d.extend_from_slice(&[0, 0]);
        d.extend_from_slice(payload);
        d
    }

    #[test]
    fn a_whole_datagram_comes_out_with_its_ports() {
        let mut n = Network::default();
        let f = frame(1, 0, false, &datagram(b"hello"));
        let u = n.udp(linktype::ETHERNET, &f).unwrap();
        assert_eq!(
            (u.src_port, u.dst_port, u.payload),
            (7502, 7502, &b"hello"[..])
        );
        // Cut short: refused, not read past.
        assert_eq!(
            n.udp(linktype::ETHERNET, &f[..f.len() - 1]),
            Err(Skip::Truncated)
        );
        assert_eq!(n.udp(linktype::ETHERNET, &f[..10]), Err(Skip::Truncated));
        assert_eq!(n.udp(7, &f), Err(Skip::LinkType(7)));
    }

    #[test]
    fn fragments_in_any_order_are_put_back_together() {
        let payload: Vec<u8> = (0..3000u32).map(|i| (i % 251) as u8).collect();
        let d = datagram(&payload);
        let pieces: Vec<(usize, &[u8])> = d
            .chunks(1480)
            .enumerate()
            .map(|(k, c)| (k * 1480, c))
            .collect();
        let last = pieces.len() - 1;
        let mut n = Network::default();
        for &k in &[2, 0, 1] {
            let (off, body) = pieces[k];
            let f = frame(9, off, k != last, body);
            let got = n.udp(linktype::ETHERNET, &f).map(|u| u.payload.to_vec());
            if k == 1 {
                assert_eq!(got.unwrap(), payload);
            } else {
                assert_eq!(got, Err(Skip::Fragment));
            }
        }
        assert_eq!(n.reassembled, 1);
        // An overlap is refused.
        let f = frame(10, 0, true, &d[..1480]);
        assert_eq!(n.udp(linktype::ETHERNET, &f), Err(Skip::Fragment));
        let f = frame(10, 8, true, &d[8..16]);
        assert_eq!(n.udp(linktype::ETHERNET, &f), Err(Skip::Malformed));
        // Many unfinished datagrams: the oldest go, counted.
        for id in 100..100 + MAX_PENDING as u16 + 3 {
            let f = frame(id, 0, true, &d[..8]);
            assert_eq!(n.udp(linktype::ETHERNET, &f), Err(Skip::Fragment));
        }
        assert_eq!(n.fragments_dropped, 1 + 3);
    }
}
