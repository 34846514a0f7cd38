//! The demo through the library: the first 100 frames through the procedural town write every
//! output, track, and mesh the town to the mesh targets (F1 at least 0.95 at 0.1 m and 0.99
//! at 0.3 m against the true surfaces, with the estimated poses), and track within 15 % of
//! the measured errors (dated below; update them with a change that legitimately moves them).

use slamesh::demo::run_demo;
use slamesh::outputs::mesh_spool::MeshFormat;
use slamesh::run::config_file::WindowSettings;
use slamesh::run::RunOptions;
use slamesh_core::KittiCapacity;

/// Measured 2026-12-01 (seed 1, preset town, 100 frames): mean consecutive-frame translation
/// error (m), end-point error (m), ATE (m).
const MEASURED_STEP_M: f64 = 0.00599;
const MEASURED_END_M: f64 = 0.0385;
const MEASURED_ATE_M: f64 = 0.0069;
const MARGIN: f64 = 1.15;

#[test]
fn the_first_100_town_frames_write_everything_track_and_reach_the_mesh_targets() {
    let out = crate::common::scratch("demo");
    let opts = RunOptions {
        out: out.to_path_buf(),
        config: slamesh::run::config_file::preset("town").unwrap(),
        preset: "town".into(),
        window: WindowSettings::default(),
        threads: 2,
        mesh_formats: vec![MeshFormat::Ply],
        given_poses: None,
        input: "demo test".into(),
        ..RunOptions::default()
    };
    let r = run_demo::<KittiCapacity>(100, 1, &opts, |_| {}).unwrap();
    for f in [
        "poses_kitti.txt",
        "poses_tum.txt",
        "poses_true_kitti.txt",
        "mesh.ply",
        "reference.ply",
        "report.json",
        "topview.png",
    ] {
        assert!(out.join(f).metadata().unwrap().len() > 0, "{f}");
    }
    assert_eq!((r.frames, r.summary.used), (100, 100));
    assert!(r.path_m > 15.0, "the car moved: {} m", r.path_m);
    println!(
        "mean step {:.5} m, end {:.4} m, ATE {:.4} m, mesh {:?}",
        r.consecutive.mean_translation_m, r.end_drift.0, r.ate_m, r.mesh
    );
    assert!(
        r.consecutive.mean_translation_m <= MEASURED_STEP_M * MARGIN,
        "{:?}",
        r.consecutive
    );
    assert!(
        r.end_drift.0 <= MEASURED_END_M * MARGIN,
        "{:?}",
        r.end_drift
    );
    assert!(r.ate_m <= MEASURED_ATE_M * MARGIN, "ATE {} m", r.ate_m);
    let at = |t: f64| r.mesh.iter().find(|m| m.threshold_m == t).unwrap();
    assert!(at(0.1).f1 >= 0.95 && at(0.3).f1 >= 0.99, "{:?}", r.mesh);
}
