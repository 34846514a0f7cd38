//! Trajectory files on arbitrary text, as `slamesh eval` and `run --poses` read them: an
//! estimate, a reference and a KITTI `calib.txt` (the input's parts between zero bytes). Each
//! reader gives poses or a `FileError`, never a panic; the pairing accounts for every line of
//! the estimate, and the error metrics take any finite poses.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamesh::eval::odometry as eval;
use slamesh::formats::{kitti, trajectory};
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let mut parts = data.splitn(3, |&b| b == 0).map(String::from_utf8_lossy);
    let (estimate, reference, calib) = (
        parts.next().unwrap_or_default(),
        parts.next().unwrap_or_default(),
        parts.next().unwrap_or_default(),
    );
    let read = |name: &str, text: &str| match trajectory::parse(Path::new(name), text) {
        Ok(t) => {
            assert!(!t.poses.is_empty());
            let tum = t.format == trajectory::Format::Tum;
            assert_eq!(t.stamps.as_ref().map(Vec::len), tum.then_some(t.poses.len()));
            Some(t)
        }
        Err(e) => {
            assert!(!e.reason.is_empty());
            None
        }
    };
    let (Some(est), Some(mut reference)) = (read("estimate", &estimate), read("reference", &reference))
    else {
        return;
    };
    if let Ok(tr) = kitti::parse_calib_tr(Path::new("calib.txt"), &calib) {
        reference.poses = kitti::lidar_poses(&reference.poses, &tr);
    }
    let _ = est.tolerance_s();
    let stamp = est.stamps.as_ref().map_or(0.0, |s| s[0]);
    let _ = reference.pose_at(0, stamp);
    let (pairs, missing) = est.pair_with(&reference);
    assert_eq!(pairs.len() + missing.len(), est.poses.len());
    assert!(pairs.iter().all(|&(i, k)| i < est.poses.len() && k < reference.poses.len()));
    let e: Vec<_> = pairs.iter().map(|&(i, _)| est.poses[i]).collect();
    let r: Vec<_> = pairs.iter().map(|&(_, k)| reference.poses[k]).collect();
    let c = eval::consecutive_errors(&e, &r);
    assert_eq!(c.pairs, e.len().saturating_sub(1));
    let _ = eval::end_drift(&e, &r);
    assert!(!(eval::ate_rmse(&e, &r) < 0.0));
    let _ = eval::segment_errors(&e, &r, &eval::KITTI_SEGMENTS);
});
