//! The packet capture reader on arbitrary bytes (pcap or pcapng, any link type): every
//! datagram it hands out is decoded as each Velodyne model's packet and cut into sweeps. A
//! damaged file ends with an error, never a panic, and memory stays bounded.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamesh::sources::capture::Capture;
use slamesh::sources::sweep::Sweeps;
use slamesh::sources::velodyne::{self, tables::MODELS, Decoder};
use std::io::Cursor;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let Ok(mut cap) = Capture::from_reader(Path::new("fuzz.pcap"), Cursor::new(data.to_vec())) else {
        return;
    };
    let decoders: Vec<Decoder> = MODELS.iter().map(Decoder::new).collect();
    let mut sweeps = Sweeps::new(0.0);
    let mut n = 0;
    while let Ok(Some(d)) = cap.next_datagram() {
        assert!(d.udp.payload.len() <= data.len() + 65_536);
        let t = velodyne::packet_time(d.udp.payload, d.time_s).unwrap_or(0.0);
        for dec in &decoders {
            let _ = dec.decode(d.udp.payload, t, |f| {
                let _ = sweeps.push(f.point, f.time_s, f.azimuth);
            });
        }
        n += 1;
        if n > 10_000 {
            break;
        }
    }
    sweeps.finish();
});
