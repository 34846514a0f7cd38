//! The core's per-scan entry points on arbitrary points: several scans through one pipeline
//! (odometry, then meshing at a given pose), with raw `f32` bit patterns (NaN, infinities,
//! huge values) or centimetre-quantised coordinates that land in real cells.
//!
//! Invariants: no panic; every estimated pose is finite; the map stays within its capacity.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamesh_core::{Capacity, Config, Pipeline, Point, Pose, SmallCapacity};

/// Splits the input into scans at each `0xfe` byte; the first byte picks the
/// coordinate encoding and the preset.
fn scans(data: &[u8]) -> (u8, Vec<Vec<Point>>) {
    let Some((&mode, rest)) = data.split_first() else {
        return (0, Vec::new());
    };
    let scans = rest
        .split(|&b| b == 0xfe)
        .take(6)
        .map(|chunk| {
            if mode & 1 == 0 {
                chunk
                    .chunks_exact(12)
                    .map(|c| {
                        let f = |i: usize| f32::from_le_bytes([c[i], c[i + 1], c[i + 2], c[i + 3]]);
                        [f(0), f(4), f(8)]
                    })
                    .collect()
            } else {
                chunk
                    .chunks_exact(6)
                    .map(|c| {
                        let f = |i: usize| f32::from(i16::from_le_bytes([c[i], c[i + 1]])) * 0.01;
                        [f(0), f(2), f(4)]
                    })
                    .collect()
            }
        })
        .collect();
    (mode, scans)
}

fuzz_target!(|data: &[u8]| {
    let (mode, scans) = scans(data);
    let config = if mode & 2 == 0 {
        Config::kitti()
    } else {
        Config::meshing()
    };
    let Ok(mut pipeline) = Pipeline::<SmallCapacity>::new(config) else {
        return;
    };
    for (i, scan) in scans.iter().enumerate() {
        if mode & 4 != 0 && i == 1 {
            let _ = pipeline.integrate_scan(scan, &Pose::translation(0.3, -0.2, 0.1));
            continue;
        }
        if let Ok(out) = pipeline.process_scan(scan) {
            let p = out.t_world_sensor;
            assert!(p.translation.vector.iter().all(|v| v.is_finite()));
            assert!(p.rotation.coords.iter().all(|v| v.is_finite()));
        }
        assert!(pipeline.map().cell_count() <= SmallCapacity::MAP_CELLS);
        assert!(pipeline.map().layer_count() <= SmallCapacity::MAP_LAYERS);
    }
    let _ = pipeline.triangles().count();
});
