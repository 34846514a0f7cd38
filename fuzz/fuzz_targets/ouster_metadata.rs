//! The Ouster metadata reader on arbitrary text: it reads or refuses, never panics, and what
//! it reads makes a decoder whose packet size is a profile's and which decodes a packet of
//! zeros to no point.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamesh::sources::ouster::metadata::Metadata;
use slamesh::sources::ouster::Sensor;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(meta) = Metadata::parse(text) else {
        return;
    };
    let sensor = Sensor::new(meta);
    let zeros = vec![0u8; sensor.packet_bytes()];
    let mut n = 0;
    // A packet of zeros is refused (a profiled packet's type is 0) or has no valid column.
    let _ = sensor.decode(&zeros, |_| n += 1);
    assert_eq!(n, 0);
    assert!(sensor.packet_period_s() > 0.0 && sensor.frame_start_deg() < 360.0);
});
