//! Degenerate scenes from the simulator: a long featureless tunnel, a single plane, and a
//! scan of only far points. Registration must say so (a `Degenerate` or `TooFewResiduals`
//! status, or an empty scan) and keep the motion model's pose where the geometry says
//! nothing, without diverging.

use slamesh::run::FrameSource;
use slamesh_core::{Config, KittiCapacity, Pipeline, Pose, RegistrationStatus, ScanError};
use slamesh_sim::{sensor_pose, Drive, Lidar, OrientedBox, Scene};

fn wall(centre: [f64; 3], half: [f64; 3]) -> OrientedBox {
    OrientedBox {
        centre,
        half,
        yaw: 0.0,
    }
}

/// A drive through `scene` at `step_m` a frame along +x, level, 1.8 m above the ground.
fn drive(scene: Scene, frames: usize, step_m: f64, max_range_m: f64) -> Drive {
    let mut lidar = Lidar::hdl64(600);
    lidar.max_range_m = max_range_m;
    Drive {
        scene,
        lidar,
        poses: (0..frames)
            .map(|i| sensor_pose(step_m * i as f64, 0.0, 1.8, 0.0))
            .collect(),
        noise_m: 0.02,
        dropout: 0.0,
        seed: 11,
        sweep_s: None,
        period_s: 0.1,
        imu: None,
        shake: None,
        traffic: None,
    }
}

/// Runs the pipeline over `d`; per frame, the status (or the scan error) and the estimated
/// pose relative to the first frame.
fn run(d: &mut Drive) -> Vec<(Result<RegistrationStatus, ScanError>, Option<Pose>, f64)> {
    let mut p = Pipeline::<KittiCapacity>::new(Config::default()).unwrap();
    (0..d.frames())
        .map(|i| {
            let scan = d.read(i).unwrap();
            let r = p.process_scan(&scan);
            let c = r.as_ref().map_or(0.0, |o| o.stats.conditioning);
            (r.map(|o| o.status), p.pose(), c)
        })
        .collect()
}

fn position_error(estimate: &Pose, truth: &Pose) -> [f64; 3] {
    let e = estimate.translation.vector - truth.translation.vector;
    [e.x.abs(), e.y.abs(), e.z.abs()]
}

#[test]
fn a_featureless_tunnel_is_degenerate_along_its_axis_and_the_motion_model_carries_on() {
    // A 10 m wide, 6 m high tunnel, 500 m long, closed behind the start, with a few pillars
    // near the entrance: the first frames are well constrained and give the speed; beyond
    // 60 m the scanner (50 m range) sees only walls, floor and ceiling.
    let mut d = drive(tunnel(), 70, TUNNEL_STEP_M, 50.0);
    let out = run(&mut d);
    let truth: Vec<Pose> = d.poses.iter().map(|p| d.poses[0].inverse() * p).collect();
    let mut entered = None;
    for (i, (status, pose, cond)) in out.iter().enumerate() {
        let pose = pose.expect("every frame has a pose");
        let e = position_error(&pose, &truth[i]);
        println!(
            "frame {i:2} {status:?} {cond:.5} error x {:.3} y {:.3} z {:.3}",
            e[0], e[1], e[2]
        );
        // Across the tunnel and vertically the walls hold it throughout.
        assert!(e[1] < 0.1 && e[2] < 0.1, "frame {i}: {e:?}");
        if walls_only(i) {
            assert_eq!(
                *status,
                Ok(RegistrationStatus::Degenerate),
                "frame {i}: only walls in view"
            );
            // Along the tunnel the motion model carries the pose: no divergence, the error
            // grows no faster than a speed 0.3 % off. The speed is the last registered
            // frames': here 0.23 % off (0.052 m over the 22.5 m to frame 64); 0.09 % before
            // layers kept their facing, when seeds 1 to 8 entered the tunnel 0.06 to 7.2 m
            // off (five of them over 0.5 m), and now 0.05 to 0.41 m (docs/journal.md,
            // "Faces").
            let x0 = *entered.get_or_insert(e[0]);
            assert!(
                e[0] < x0 + 0.003 * TUNNEL_STEP_M * (i - 49) as f64 + 0.02,
                "frame {i}: {} m, {x0} m on entering",
                e[0]
            );
        }
    }
    // While a few distant pillars are the only hold along the axis (conditioning about
    // 0.011), a full solve slides on them, 0.7 m in three frames; they count as degenerate.
    assert!(entered.is_some_and(|x0| x0 < 0.1));
}

/// Metres a frame along the tunnel.
const TUNNEL_STEP_M: f64 = 1.5;

/// Once only walls are in view (50 m range past the last pillar and the end wall).
fn walls_only(i: usize) -> bool {
    TUNNEL_STEP_M * i as f64 > 50.0 + 12.0 + 10.0
}

/// The pillars near the tunnel's entrance are 0.8 m thick, both faces in one 1.6 m cell: the
/// far face, seen once the scanner is past, replaces the near one instead of being fused with
/// it (docs/design.md §1.5, "Faces"). Fused, they pulled the last registered frames, and the
/// speed the motion model carries into the tunnel, off: on these seeds the pose entered 6.5,
/// 7.2 and 4.5 m off.
#[test]
fn the_pillars_far_faces_do_not_throw_the_speed_into_the_tunnel() {
    for seed in 4..=6 {
        let mut d = drive(tunnel(), 50, TUNNEL_STEP_M, 50.0);
        d.seed = seed;
        let out = run(&mut d);
        let i = out.len() - 1;
        assert!(walls_only(i));
        let truth = d.poses[0].inverse() * d.poses[i];
        let e = position_error(&out[i].1.expect("a pose"), &truth);
        assert!(e[0] < 0.5, "seed {seed}: {e:?} m on entering");
    }
}

/// A 10 m wide, 6 m high tunnel along x, closed behind the start, with four pillars near it.
fn tunnel() -> Scene {
    let mut boxes = vec![
        wall([-12.0, 0.0, 3.0], [0.5, 6.0, 3.0]),
        wall([240.0, 5.5, 3.0], [252.0, 0.5, 3.0]),
        wall([240.0, -5.5, 3.0], [252.0, 0.5, 3.0]),
        wall([240.0, 0.0, 6.5], [252.0, 6.0, 0.5]),
    ];
    for (x, y) in [(-6.0, 3.5), (-2.0, -3.8), (3.0, 3.6), (7.0, -3.5)] {
        boxes.push(wall([x, y, 1.0], [0.4, 0.4, 1.0]));
    }
    Scene {
        ground_z: 0.0,
        terrain: None,
        boxes,
        spheres: Vec::new(),
    }
}

#[test]
fn a_single_plane_is_degenerate_and_the_pose_stays_finite_and_level() {
    let scene = Scene::default();
    let mut d = drive(scene, 20, 1.0, 60.0);
    let out = run(&mut d);
    for (i, (status, pose, cond)) in out.iter().enumerate() {
        let pose = pose.expect("every frame has a pose");
        let truth = d.poses[0].inverse() * d.poses[i];
        let e = position_error(&pose, &truth);
        let (roll, pitch, _) = (truth.inverse() * pose).rotation.euler_angles();
        println!(
            "frame {i:2} {status:?} {cond:.5} error x {:.3} y {:.3} z {:.3}",
            e[0], e[1], e[2]
        );
        assert!(pose.translation.vector.iter().all(|v| v.is_finite()));
        // Height, roll and pitch are what a plane constrains.
        assert!(e[2] < 0.05, "frame {i}: height error {}", e[2]);
        assert!(roll.abs().max(pitch.abs()).to_degrees() < 0.2, "frame {i}");
        // The first motion cannot be seen, so the motion model holds still: no divergence.
        assert!(
            e[0] <= truth.translation.vector.x.abs() + 0.01 && e[1] < 0.05,
            "frame {i}: {e:?}"
        );
        if i > 0 {
            assert_eq!(*status, Ok(RegistrationStatus::Degenerate), "frame {i}");
        }
    }
}

#[test]
fn a_scan_of_only_far_points_keeps_the_motion_model() {
    // A street gives the speed; then only walls 89 to 130 m away are in view: too sparse for
    // any cell to be reconstructed, or beyond the 100 m range filter.
    let street = Scene::street();
    // The far scene: no ground (a scanner on a mast over water, say), walls far away.
    let far = Scene {
        ground_z: -1.0e4,
        terrain: None,
        boxes: vec![
            wall([90.0, 0.0, 5.0], [1.0, 90.0, 10.0]),
            wall([-90.0, 0.0, 5.0], [1.0, 90.0, 10.0]),
            wall([0.0, 90.0, 5.0], [90.0, 1.0, 10.0]),
        ],
        spheres: Vec::new(),
    };
    let mut near = drive(street, 6, 1.0, 100.0);
    let mut far_drive = drive(far, 6, 1.0, 100.0);
    let mut p = Pipeline::<KittiCapacity>::new(Config::default()).unwrap();
    for i in 0..near.frames() {
        let o = p.process_scan(&near.read(i).unwrap()).unwrap();
        assert!(matches!(
            o.status,
            RegistrationStatus::FirstScan | RegistrationStatus::Converged
        ));
    }
    let before = p.pose().unwrap();
    for i in 0..far_drive.frames() {
        let last = p.pose().unwrap();
        let scan = far_drive.read(i).unwrap();
        match p.process_scan(&scan) {
            Ok(o) => {
                println!(
                    "far frame {i}: {:?}, {} points kept",
                    o.status, o.stats.filter.kept
                );
                assert!(matches!(
                    o.status,
                    RegistrationStatus::TooFewResiduals | RegistrationStatus::Degenerate
                ));
                // The motion model's step: the street drive's metre along x a frame.
                let step = last.inverse() * o.t_world_sensor;
                assert!((step.translation.vector - nalgebra::Vector3::x()).norm() < 0.01);
            }
            Err(e) => println!("far frame {i}: {e}"),
        }
    }
    assert!(p.pose().unwrap().translation.vector.x > before.translation.vector.x);
}
