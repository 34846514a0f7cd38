//! KITTI raw's OXTS packets and timestamps on arbitrary bytes: a packet's line gives a reading
//! or a named fault, a timestamp seconds or a named fault, and a time written back reads back
//! to a microsecond (more for times far from ours, where an f64 keeps less); never a panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamesh::formats::oxts;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    if let Ok((gyro, accel)) = oxts::parse_packet(&text) {
        assert!(gyro.iter().chain(&accel).all(|v| v.is_finite()));
        let back = oxts::parse_packet(&oxts::encode_packet(gyro, accel));
        assert_eq!(back, Ok((gyro, accel)));
    }
    if let Ok(times) = oxts::parse_times(&text) {
        for t in times {
            let back = oxts::parse_time(&oxts::format_time(t)).expect("a written time reads");
            let tolerance = 1e-6 + t.abs() * 1e-15;
            assert!((back - t).abs() <= tolerance, "{t} read back as {back}");
        }
    }
});
