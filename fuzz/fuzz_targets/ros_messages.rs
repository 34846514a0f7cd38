//! The ROS 2 messages the node takes (`initialpose`, `imu`, `/clock`, `~/save_map`'s
//! request), decoded from arbitrary CDR in both byte orders as the node's DDS reader decodes
//! them: a message or an error, never a panic, and a pose made from a decoded one is finite
//! or refused.
#![no_main]

use byteorder::{BigEndian, ByteOrder, LittleEndian};
use libfuzzer_sys::fuzz_target;
use slamesh::formats::ros_messages::{Clock, Imu, PoseWithCovarianceStamped, TriggerRequest};

fn decode<B: ByteOrder>(data: &[u8]) {
    if let Ok((m, _)) = cdr_encoding::from_bytes::<PoseWithCovarianceStamped, B>(data) {
        if let Some(p) = m.pose.pose.to_pose() {
            assert!(p.translation.vector.iter().all(|v| v.is_finite()));
            assert!(p.rotation.coords.iter().all(|v| v.is_finite()));
        }
    }
    let _ = cdr_encoding::from_bytes::<Imu, B>(data);
    let _ = cdr_encoding::from_bytes::<Clock, B>(data);
    let _ = cdr_encoding::from_bytes::<TriggerRequest, B>(data);
}

fuzz_target!(|data: &[u8]| {
    decode::<LittleEndian>(data);
    decode::<BigEndian>(data);
});
