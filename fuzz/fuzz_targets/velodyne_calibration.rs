//! The Velodyne calibration reader on arbitrary text: it reads or refuses, never panics; a
//! calibration of 64 lasers makes an HDL-64E decoder that decodes a packet of its blocks to
//! finite points.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamesh::sources::velodyne::calibration::Calibration;
use slamesh::sources::velodyne::hdl64::{Generation, Hdl64};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(calibration) = Calibration::parse(text) else {
        return;
    };
    let Ok(decoder) = Hdl64::new(Generation::S3, &calibration) else {
        return;
    };
    let mut packet = vec![0u8; 1206];
    for b in 0..12 {
        packet[b * 100..b * 100 + 2].copy_from_slice(&[0xff, if b % 2 == 0 { 0xee } else { 0xdd }]);
        for j in 0..32 {
            packet[b * 100 + 4 + 3 * j] = 0x10;
        }
    }
    let _ = decoder.decode(&packet, 0.0, |f| {
        let _ = f.point.iter().all(|v| !v.is_nan());
    });
});
