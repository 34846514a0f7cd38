//! The single-precision reconstruction (`Pipeline<_, f32>`, the firmware's) against the
//! double-precision one on a simulated drive that starts from standstill, accelerates, turns
//! and brakes, 5 km from the world's origin (where world coordinates in `f32` would lose half
//! a millimetre): both track the truth, and they agree with each other. Bounds are the
//! measured values (2026-12-03) with room for legitimate change.

use slamesh_core::{Config, KittiCapacity, Pipeline, Pose, Real, RegistrationStatus};
use slamesh_sim::{sensor_pose as pose, Lidar, Scene};

/// The drive's true poses: from rest to 1.2 m a frame, a left then a right turn of up to 3
/// degrees a frame, then hard braking.
fn drive() -> Vec<Pose> {
    let (mut x, mut y, mut yaw) = (0.0f64, 0.0f64, 0.0f64);
    let mut poses = Vec::new();
    for i in 0..24 {
        let speed = match i {
            0..=7 => 0.15 * i as f64,
            8..=17 => 1.2,
            _ => 1.2 - 0.3 * (i - 17) as f64,
        }
        .max(0.1);
        let turn = match i {
            6..=10 => 3.0,
            13..=16 => -3.0,
            _ => 0.0,
        };
        yaw += turn;
        x += speed * yaw.to_radians().cos();
        y += speed * yaw.to_radians().sin();
        poses.push(pose(x, 0.3 * y, 1.73, yaw));
    }
    poses
}

/// The estimated poses of the drive's scans, seen from `origin` (the world frame's offset).
fn track<R: Real>(origin: &Pose, truth: &[Pose], scans: &[Vec<[f32; 3]>]) -> Vec<Pose> {
    let mut pipeline = Pipeline::<KittiCapacity, R>::new(Config::default()).unwrap();
    // The first scan at its true place in the far-off world frame, the others estimated.
    let first = pipeline
        .integrate_scan(&scans[0], &(*origin * truth[0]))
        .unwrap();
    let mut poses = vec![origin.inverse() * first.t_world_sensor];
    poses.extend(scans[1..].iter().map(|scan| {
        let out = pipeline.process_scan(scan).unwrap();
        assert_eq!(
            out.status,
            RegistrationStatus::Converged,
            "{}: {:?}",
            R::NAME,
            out.status
        );
        origin.inverse() * out.t_world_sensor
    }));
    poses
}

/// Translation (m) and rotation (degrees) between two poses.
fn apart(a: &Pose, b: &Pose) -> (f64, f64) {
    let d = a.inverse() * b;
    (d.translation.vector.norm(), d.rotation.angle().to_degrees())
}

#[test]
fn single_precision_tracks_as_double_precision_does_far_from_the_origin() {
    let (scene, lidar) = (Scene::street(), Lidar::hdl64(1024));
    let truth = drive();
    let scans: Vec<_> = truth.iter().map(|p| lidar.scan(&scene, p)).collect();
    let origin = Pose::translation(4_871.2, -3_305.9, 12.0);
    let double = track::<f64>(&origin, &truth, &scans);
    let single = track::<f32>(&origin, &truth, &scans);
    // Per scalar: the worst pose error and the mean step error against the truth.
    let mut worst = [(0.0f64, 0.0f64); 2];
    let mut steps = [0.0f64; 2];
    for (k, estimate) in [&double, &single].into_iter().enumerate() {
        for i in 0..truth.len() {
            let (t, r) = apart(&truth[i], &estimate[i]);
            worst[k] = (worst[k].0.max(t), worst[k].1.max(r));
            if i > 0 {
                let step = |p: &[Pose]| p[i - 1].inverse() * p[i];
                steps[k] += apart(&step(&truth), &step(estimate)).0 / (truth.len() - 1) as f64;
            }
        }
    }
    let apart_most = (0..truth.len())
        .map(|i| apart(&double[i], &single[i]))
        .fold((0.0f64, 0.0f64), |a, b| (a.0.max(b.0), a.1.max(b.1)));
    for (k, name) in ["f64", "f32"].iter().enumerate() {
        println!(
            "{name}: worst {:.2} cm, {:.4} deg from the truth; mean step error {:.3} cm",
            worst[k].0 * 100.0,
            worst[k].1,
            steps[k] * 100.0
        );
    }
    println!(
        "f32 from f64: {:.2} cm, {:.4} deg at most",
        apart_most.0 * 100.0,
        apart_most.1
    );
    // Measured 2026-12-03: worst 1.92 cm, 0.071 deg (f64) and 1.56 cm, 0.067 deg (f32); mean
    // step errors 0.702 and 0.656 cm; the two 0.74 cm and 0.037 deg apart at most.
    for (k, name) in ["f64", "f32"].iter().enumerate() {
        assert!(
            worst[k].0 < 0.025 && worst[k].1 < 0.1,
            "{name}: {:?} from the truth",
            worst[k]
        );
    }
    assert!(
        steps[1] <= 1.10 * steps[0],
        "f32's mean step error {} m against f64's {} m",
        steps[1],
        steps[0]
    );
    assert!(
        apart_most.0 < 0.01 && apart_most.1 < 0.05,
        "f32 and f64 poses {apart_most:?} apart"
    );
}
