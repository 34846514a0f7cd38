//! An Ouster's IMU packets on arbitrary bytes: after a first byte (odd: the next 128 bytes are
//! an `imu_to_sensor_transform` of sixteen f64, any values; even: the identity) the input is
//! cut into 48-byte datagrams (the last one shorter, refused by size), each decoded and turned
//! into a reading, and the readings go to the core's track, whose gravity and rotations answer
//! or name why not: nothing panics.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamesh::sources::ouster::imu_packet::{ImuPacket, ImuPacketError, IMU_PACKET_BYTES};
use slamesh::sources::ouster::metadata::IDENTITY;
use slamesh_core::gravity::Gravity;
use slamesh_core::imu::{ImuCalibration, ImuTrack};

fuzz_target!(|data: &[u8]| {
    let (transform, packets): ([f64; 16], &[u8]) = match data.split_first() {
        Some((&flag, rest)) if flag & 1 == 1 && rest.len() >= 128 => (
            std::array::from_fn(|k| {
                f64::from_le_bytes(rest[8 * k..8 * k + 8].try_into().unwrap_or([0; 8]))
            }),
            &rest[128..],
        ),
        Some((_, rest)) => (IDENTITY, rest),
        None => return,
    };
    let mut track = ImuTrack::new(64, ImuCalibration::default());
    let mut last = None;
    for chunk in packets.chunks(IMU_PACKET_BYTES) {
        match ImuPacket::decode(chunk) {
            Ok(p) => {
                let s = p.sample(&transform);
                assert_eq!(s.stamp, p.gyro_ts as f64 / 1e9);
                let _ = track.push(&s);
                last = Some(s.stamp);
            }
            Err(ImuPacketError::Size(n)) => assert!(n != IMU_PACKET_BYTES && n == chunk.len()),
        }
    }
    if let Some(t) = last {
        if let Ok(f) = track.mean_force(t - 0.5, t) {
            let _ = Gravity::judge(&f).map(|g| g.level());
        }
        let _ = track.rotation(t - 0.1, t);
    }
});
