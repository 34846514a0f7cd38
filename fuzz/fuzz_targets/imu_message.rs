//! `sensor_msgs/Imu` messages on arbitrary bytes, as a recording's reader hands them: the
//! ROS 1 and CDR decoders return a reading or an error, never panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamesh::formats::imu_message::{parse_cdr, parse_ros1};

fuzz_target!(|data: &[u8]| {
    // The frame's name is read lossily: a byte that is not UTF-8 becomes one character.
    if let Ok(m) = parse_ros1(data) {
        assert!(m.frame_id.chars().count() <= data.len());
    }
    if let Ok(m) = parse_cdr(data) {
        assert!(m.frame_id.chars().count() <= data.len());
    }
});
