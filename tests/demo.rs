//! The demo through the library: a short drive through the procedural town writes every
//! output, and its accuracy is in the range the README reports for longer drives.

use slamesh::config_file::WindowSettings;
use slamesh::demo::run_demo;
use slamesh::mesh_file::MeshFormat;
use slamesh::session::RunOptions;
use slamesh_core::KittiCapacity;

#[test]
fn a_short_town_drive_writes_everything_and_tracks() {
    let out = std::env::temp_dir().join(format!("slamesh-demo-{}", std::process::id()));
    let opts = RunOptions {
        out: out.clone(),
        config: slamesh::config_file::preset("town").unwrap(),
        preset: "town".into(),
        window: WindowSettings::default(),
        threads: 2,
        mesh_formats: vec![MeshFormat::Ply],
        given_poses: None,
        input: "demo test".into(),
        ..RunOptions::default()
    };
    let r = run_demo::<KittiCapacity>(60, 1, &opts, |_| {}).unwrap();
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
    assert_eq!((r.frames, r.summary.used), (60, 60));
    assert!(r.path_m > 15.0, "the car moved: {} m", r.path_m);
    assert!(
        r.consecutive.mean_translation_m < 0.03,
        "{:?}",
        r.consecutive
    );
    assert!(r.end_drift.0 < 0.3, "{:?}", r.end_drift);
    let at = |t: f64| r.mesh.iter().find(|m| m.threshold_m == t).unwrap();
    assert!(at(0.3).f1 > 0.9 && at(0.1).f1 > 0.6, "{:?}", r.mesh);
    std::fs::remove_dir_all(&out).unwrap();
}
