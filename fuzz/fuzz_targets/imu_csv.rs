//! IMU readings on arbitrary bytes: the EuRoC CSV reader keeps what it can read and names
//! the rest, never panics; the core's track takes whatever readings came (any stamps, any
//! values) and counts each, and its rotations, bias corrections and gravity return an answer
//! or a gap, never panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamesh::formats::imu_csv;
use slamesh_core::imu::{ImuCalibration, ImuTrack};
use slamesh_core::Pose;

fuzz_target!(|data: &[u8]| {
    let csv = imu_csv::parse(data);
    let mut track = ImuTrack::new(16, ImuCalibration::default());
    for r in &csv.readings {
        let _ = track.push(r);
    }
    let stamps: Vec<f64> = csv.readings.iter().map(|r| r.stamp).collect();
    for w in stamps.windows(2) {
        let _ = track.rotation(w[0], w[1]);
        if let Ok(gyro) = track.rotation(w[0], w[1]) {
            track.correct_bias(&gyro, w[1] - w[0], &Pose::identity().rotation, 0.2, 0.1);
        }
    }
    if let Some(&t) = stamps.last() {
        if let Ok(f) = track.mean_force(f64::NEG_INFINITY, t) {
            let _ = slamesh_core::gravity::Gravity::judge(&f).map(|g| g.level());
        }
    }
    let c = track.counts();
    assert_eq!(
        c.taken + c.not_finite + c.out_of_order + c.duplicate,
        csv.readings.len()
    );
});
