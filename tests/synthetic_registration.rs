//! Registration against ground truth: a structured synthetic street seen from two poses.

use slamesh::sim::{sensor_pose as pose, Lidar, Scene};
use slamesh_core::{Config, Pipeline, Pose, RegistrationStatus};

/// Registers the scan from `second` against the map of the scan from `first` and returns the
/// translation (m) and rotation (deg) error of the estimated relative pose.
fn register_pair(first: Pose, second: Pose) -> (f64, f64, RegistrationStatus) {
    let scene = Scene::street();
    let lidar = Lidar::hdl64(1024);
    let mut pipeline = Pipeline::<slamesh_core::KittiCapacity>::new(Config::default()).unwrap();
    let a = pipeline.process_scan(&lidar.scan(&scene, &first)).unwrap();
    assert_eq!(a.status, RegistrationStatus::FirstScan);
    let b = pipeline.process_scan(&lidar.scan(&scene, &second)).unwrap();
    let estimated = a.t_world_sensor.inverse() * b.t_world_sensor;
    let truth = first.inverse() * second;
    let e = truth.inverse() * estimated;
    (
        e.translation.vector.norm(),
        e.rotation.angle().to_degrees(),
        b.status,
    )
}

#[test]
fn two_views_half_a_metre_to_one_and_a_half_apart_register_within_2cm_and_a_tenth_degree() {
    let first = pose(0.0, 0.0, 1.73, 0.0);
    let seconds = [
        pose(0.5, 0.0, 1.73, 2.0),
        pose(1.0, 0.3, 1.75, -3.0),
        pose(1.4, -0.4, 1.70, 4.0),
        pose(-0.6, 0.6, 1.73, 5.0),
    ];
    for second in seconds {
        let (t, r, status) = register_pair(first, second);
        println!(
            "motion {:.2} m: error {:.2} cm, {:.4} deg, {:?}",
            (first.inverse() * second).translation.vector.norm(),
            t * 100.0,
            r,
            status
        );
        assert_eq!(status, RegistrationStatus::Converged);
        assert!(t < 0.02, "translation error {:.3} m", t);
        assert!(r < 0.1, "rotation error {:.3} deg", r);
    }
}

#[test]
fn the_same_scans_give_bitwise_identical_poses_and_meshes() {
    let scene = Scene::street();
    let lidar = Lidar::hdl64(512);
    let scans: Vec<_> = (0..4)
        .map(|i| {
            lidar.scan(
                &scene,
                &pose(0.8 * i as f64, 0.1 * i as f64, 1.73, i as f64),
            )
        })
        .collect();
    let run = || {
        let mut p = Pipeline::<slamesh_core::KittiCapacity>::new(Config::default()).unwrap();
        let poses: Vec<Pose> = scans
            .iter()
            .map(|s| p.process_scan(s).unwrap().t_world_sensor)
            .collect();
        let tris: Vec<_> = p.triangles().collect();
        (poses, tris)
    };
    let (p1, t1) = run();
    let (p2, t2) = run();
    assert_eq!(p1, p2);
    assert!(!t1.is_empty());
    assert_eq!(t1, t2);
}
