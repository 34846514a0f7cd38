//! The Ouster decoder on arbitrary packets, for every profile and beam count: the first byte
//! picks them, the rest is the packet. A packet is refused whole or decoded to at most a
//! packet's columns times beams times returns finite points, none farther than a 20-bit range
//! can put it.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamesh::sources::ouster::metadata::Metadata;
use slamesh::sources::ouster::packet::Profile;
use slamesh::sources::ouster::{sniff, Sensor};

fuzz_target!(|data: &[u8]| {
    let Some((&pick, packet)) = data.split_first() else {
        return;
    };
    let profile = Profile::ALL[usize::from(pick) % Profile::ALL.len()];
    let beams = [16u16, 32, 64, 128][usize::from(pick / 8) % 4];
    let sensor = Sensor::new(Metadata {
        prod_line: "fuzz".into(),
        profile,
        columns_per_frame: 1024,
        fps: 10,
        columns_per_packet: 16,
        pixels_per_column: beams,
        column_window: (0, 1023),
        altitude_deg: (0..beams).map(|b| f64::from(b) * 0.7 - 22.0).collect(),
        azimuth_deg: (0..beams).map(|b| f64::from(b % 4) * 3.0 - 4.5).collect(),
        beam_to_lidar: [1.0, 0.0, 0.0, 15.8, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        lidar_to_sensor: [-1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 36.18, 0.0, 0.0, 0.0, 1.0],
        udp_port_lidar: None,
        imu_to_sensor: slamesh::sources::ouster::metadata::IDENTITY,
        udp_port_imu: None,
    });
    let _ = sniff(packet);
    let mut n = 0usize;
    let r = sensor.decode(packet, |f| {
        n += 1;
        let r = f.point.iter().map(|v| f64::from(*v).powi(2)).sum::<f64>().sqrt();
        assert!(f.point.iter().all(|v| v.is_finite()) && r < 1_100.0, "{f:?}");
        assert!(f.azimuth < 36_000 && f.column < 1024 && u16::from(f.beam) < beams);
    });
    if r.is_err() {
        assert_eq!(n, 0, "a refused packet gave no point");
    }
    assert!(n <= 16 * usize::from(beams) * profile.returns(), "{n} points");
});
