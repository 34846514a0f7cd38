//! The `slamesh` command on simulated scans written to disk (no data needed): bad inputs are
//! reported and skipped, meshing with given poses, configuration files, evaluation.

use crate::common;

use common::{scratch, slamesh_ok, slamesh_run, slamesh_run_ok, write_bin};
use slamesh::formats::pcd::encode_pcd;
use slamesh::formats::trajectory::{self, write_tum_line};
use slamesh_core::{Point, Pose};
use slamesh_sim::{sensor_pose, Lidar, Scene, SurfaceDistance};
use std::path::Path;

/// True poses and scans of a slow drive down the simulated street (0.3 m a frame).
fn drive(frames: usize) -> (Vec<Pose>, Vec<Vec<Point>>) {
    let (scene, lidar) = (Scene::street(), Lidar::hdl64(900));
    let poses: Vec<Pose> = (0..frames)
        .map(|i| sensor_pose(0.3 * i as f64, 0.02 * i as f64, 1.73, 0.5 * i as f64))
        .collect();
    let scans = poses.iter().map(|p| lidar.scan(&scene, p)).collect();
    (poses, scans)
}

fn write_tum(path: &Path, poses: &[Pose]) {
    let mut b = Vec::new();
    for (i, p) in poses.iter().enumerate() {
        write_tum_line(&mut b, i as f64 * 0.1, p).unwrap();
    }
    std::fs::write(path, b).unwrap();
}

/// A PLY point cloud written by hand (not by slamesh's writer): ASCII, or binary big-endian
/// with a double-precision `x` and an extra `intensity` property.
fn write_ply(path: &Path, points: &[Point], ascii: bool) {
    let n = points.len();
    let mut b = if ascii {
        format!(
            "ply\nformat ascii 1.0\nelement vertex {n}\nproperty float x\nproperty float y\n\
             property float z\nend_header\n"
        )
        .into_bytes()
    } else {
        format!(
            "ply\nformat binary_big_endian 1.0\ncomment by hand\nelement vertex {n}\n\
             property double x\nproperty float y\nproperty float z\nproperty uchar intensity\n\
             end_header\n"
        )
        .into_bytes()
    };
    for p in points {
        if ascii {
            b.extend_from_slice(format!("{} {} {}\n", p[0], p[1], p[2]).as_bytes());
        } else {
            b.extend_from_slice(&f64::from(p[0]).to_be_bytes());
            b.extend_from_slice(&p[1].to_be_bytes());
            b.extend_from_slice(&p[2].to_be_bytes());
            b.push(7);
        }
    }
    std::fs::write(path, b).unwrap();
}

/// Share of `vertices` (in the frame of `first`) within `d` of the street's true surfaces.
fn share_on_the_street(vertices: &[Point], first: &Pose, d: f64) -> f64 {
    let scene = Scene::street();
    let distance = SurfaceDistance::new(&scene);
    let near = vertices
        .iter()
        .filter(|v| {
            let w = first * nalgebra::Point3::new(v[0] as f64, v[1] as f64, v[2] as f64);
            distance.distance(&w.coords) <= d
        })
        .count();
    near as f64 / vertices.len().max(1) as f64
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

#[test]
fn bad_frames_are_reported_and_skipped_and_the_run_completes() {
    let dir = scratch("bad-frames");
    let scans_dir = dir.join("scans");
    std::fs::create_dir_all(&scans_dir).unwrap();
    let (truth, scans) = drive(7);
    for i in [0, 2, 4, 6] {
        write_bin(&scans_dir.join(format!("{i:06}.bin")), &scans[i]);
    }
    std::fs::write(scans_dir.join("000001.bin"), []).unwrap();
    write_bin(&scans_dir.join("000003.bin"), &scans[3]);
    let truncated = std::fs::read(scans_dir.join("000003.bin")).unwrap();
    std::fs::write(
        scans_dir.join("000003.bin"),
        &truncated[..truncated.len() - 7],
    )
    .unwrap();
    std::fs::write(
        scans_dir.join("000005.pcd"),
        b"this is not a PCD header\nDATA ascii\n",
    )
    .unwrap();
    std::fs::write(scans_dir.join("notes.txt"), b"not a scan, not a frame").unwrap();

    let out = dir.join("out");
    let o = slamesh_run_ok(&scans_dir, &out, &[]);
    let err = text(&o.stderr);
    for (file, reason) in [
        ("000001.bin", "empty file"),
        ("000003.bin", "not a whole number of 16-byte points"),
        ("000005.pcd", "not a PCD header line"),
    ] {
        assert!(
            err.lines().any(|l| l.contains(file) && l.contains(reason)),
            "no message for {file} ({reason}) in:\n{err}"
        );
    }
    assert!(
        text(&o.stdout).contains("7 frames (4 used, 3 skipped)"),
        "{}",
        text(&o.stdout)
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["summary"]["skipped"].as_array().unwrap().len(), 3);
    assert_eq!(report["frames"].as_array().unwrap().len(), 7);
    assert_eq!(report["frames"][5]["status"], "Skipped");
    // What each outcome cost: the 4 used frames, the skipped ones left out.
    let outcomes = report["summary"]["cost_by_outcome"].as_array().unwrap();
    let counted: u64 = outcomes.iter().map(|o| o["frames"].as_u64().unwrap()).sum();
    assert_eq!(counted, 4, "{outcomes:?}");
    // A converged frame ran its rounds and no recovery guess; the first scan ran none.
    for o in outcomes {
        let (rounds, guesses) = (
            o["rounds"].as_f64().unwrap(),
            o["recovery_attempts"].as_f64().unwrap(),
        );
        match o["status"].as_str().unwrap() {
            "Converged" => assert!(rounds >= 1.0 && guesses == 0.0, "{o:?}"),
            "FirstScan" => assert_eq!((rounds, guesses), (0.0, 0.0), "{o:?}"),
            _ => {}
        }
    }
    assert!(report["frames"][2]["rounds"].as_u64().unwrap() >= 1);
    // One KITTI line per frame (skipped frames repeat the last pose); TUM: used frames only.
    let kitti = trajectory::read(&out.join("poses_kitti.txt"))
        .unwrap()
        .poses;
    let tum = trajectory::read(&out.join("poses_tum.txt")).unwrap();
    assert_eq!((kitti.len(), tum.poses.len()), (7, 4));
    assert_eq!(tum.stamps.unwrap(), vec![0.0, 0.2, 0.4, 0.6]);
    // The used frames are still tracked, across the gaps.
    for (k, i) in [0, 2, 4, 6].into_iter().enumerate() {
        let e =
            (truth[0].inverse() * truth[i]).translation.vector - tum.poses[k].translation.vector;
        assert!(e.norm() < 0.05, "frame {i}: {:.3} m off", e.norm());
    }
    assert!(out.join("mesh.ply").is_file());
}

#[test]
fn inputs_that_cannot_run_are_clear_errors() {
    let dir = scratch("no-scans");
    std::fs::write(dir.join("readme.txt"), b"nothing here").unwrap();
    let out = dir.join("out");
    let o = slamesh_run(&dir, &out, &[]);
    assert!(!o.status.success());
    assert!(
        text(&o.stderr).contains("no scans in this folder"),
        "{}",
        text(&o.stderr)
    );

    let missing = dir.join("missing");
    let o = slamesh_run(&missing, &out, &[]);
    assert!(!o.status.success() && text(&o.stderr).contains("no such file or folder"));

    // Every frame bad: the run ends with an error, and says why for each.
    std::fs::write(dir.join("0.bin"), []).unwrap();
    let o = slamesh_run(&dir, &out, &[]);
    assert!(!o.status.success());
    assert!(text(&o.stderr).contains("0.bin: empty file"));
    assert!(text(&o.stderr).contains("no frame could be used"));
    // Its report says why; no empty trajectory or mesh is left behind.
    assert!(out.join("report.json").is_file());
    for empty in [
        "poses_kitti.txt",
        "poses_tum.txt",
        "mesh.ply",
        "topview.png",
    ] {
        assert!(!out.join(empty).exists(), "{empty} left behind");
    }

    let cfg = dir.join("bad.toml");
    std::fs::write(&cfg, "[grid]\ncell_size = 2\n").unwrap();
    let o = slamesh_run(&dir, &out, &["--config", cfg.to_str().unwrap()]);
    assert!(!o.status.success());
    let e = text(&o.stderr);
    assert!(
        e.contains("bad.toml") && e.contains("[grid] cell_size: unknown parameter"),
        "{e}"
    );
}

#[test]
fn pcd_and_ply_folders_run_and_mesh_mode_uses_the_given_poses() {
    let dir = scratch("formats");
    let (truth, scans) = drive(4);
    let rel: Vec<Pose> = truth.iter().map(|p| truth[0].inverse() * p).collect();
    let pcd_dir = dir.join("pcd");
    std::fs::create_dir_all(&pcd_dir).unwrap();
    for (i, s) in scans.iter().enumerate() {
        let enc = ["ascii", "binary", "binary_compressed", "binary"][i];
        // Natural order: 9 < 10 < 11 < 12.
        std::fs::write(
            pcd_dir.join(format!("scan{}.pcd", 9 + i)),
            encode_pcd(s, enc),
        )
        .unwrap();
    }
    let poses = dir.join("truth_tum.txt");
    write_tum(&poses, &rel);

    let ply_dir = dir.join("ply");
    std::fs::create_dir_all(&ply_dir).unwrap();
    for (i, scan) in scans.iter().enumerate() {
        write_ply(&ply_dir.join(format!("{i}.ply")), scan, i % 2 == 0);
    }

    // Odometry on each folder, then evaluation against the truth.
    for (name, folder) in [("pcd", &pcd_dir), ("ply", &ply_dir)] {
        let out = dir.join(format!("run-{name}"));
        slamesh_run_ok(folder, &out, &[]);
        let o = slamesh_ok(&[
            "eval",
            "--estimate",
            out.join("poses_kitti.txt").to_str().unwrap(),
            "--reference",
            poses.to_str().unwrap(),
            "--json",
        ]);
        let m: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(m["pairs"], 3, "{name}");
        assert!(
            m["mean_translation_m"].as_f64().unwrap() < 0.01,
            "{name}: {m}"
        );
    }

    // Meshing at the given poses: the vertices lie on the street's true surfaces, OBJ on
    // request. At poses moved 2 m along x and 0.5 m up, the mesh moves with them: the poses
    // are used.
    let mesh_at = |name: &str, poses: &Path, extra: &[&str]| {
        let out = dir.join(name);
        let mut args = vec![
            "mesh",
            pcd_dir.to_str().unwrap(),
            "--poses",
            poses.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "-q",
        ];
        args.extend_from_slice(extra);
        slamesh_ok(&args);
        out
    };
    let out = mesh_at("mesh", &poses, &["--obj"]);
    let vertices = slamesh::formats::ply::read_ply_points(&out.join("mesh.ply")).unwrap();
    assert!(vertices.len() > 1000, "{} vertices", vertices.len());
    let on_street = share_on_the_street(&vertices, &truth[0], 0.1);
    assert!(on_street > 0.95, "{on_street} of the vertices within 10 cm");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["preset"], "meshing");
    assert_eq!(report["frames"][2]["status"], "Given");
    let obj = std::fs::read_to_string(out.join("mesh.obj")).unwrap();
    assert_eq!(
        obj.lines().filter(|l| l.starts_with("v ")).count(),
        vertices.len()
    );
    let shift = Pose::from_parts(
        nalgebra::Translation3::new(2.0, 0.0, 0.5),
        nalgebra::UnitQuaternion::identity(),
    );
    let moved_poses = dir.join("moved_tum.txt");
    write_tum(
        &moved_poses,
        &rel.iter().map(|p| shift * p).collect::<Vec<_>>(),
    );
    let moved = mesh_at("mesh-moved", &moved_poses, &[]);
    let moved = slamesh::formats::ply::read_ply_points(&moved.join("mesh.ply")).unwrap();
    // The mesh moved with the poses: on the street once the shift is undone, not before.
    let undone = share_on_the_street(&moved, &(truth[0] * shift.inverse()), 0.1);
    assert!(undone > 0.95, "{undone} of the moved vertices within 10 cm");
    assert!(share_on_the_street(&moved, &truth[0], 0.1) < 0.5 * on_street);
}

#[test]
fn bench_times_every_stage_with_a_configuration_file() {
    let dir = scratch("bench");
    let (_, scans) = drive(4);
    for (i, s) in scans.iter().enumerate() {
        write_bin(&dir.join(format!("{i:06}.bin")), s);
    }
    let cfg = dir.join("full.toml");
    std::fs::write(
        &cfg,
        "preset = \"kitti\"\n[register]\ncoarse_half_cells = false\n",
    )
    .unwrap();
    let args = |config: &Path| {
        let config = config.to_str().unwrap().to_string();
        let input = dir.to_str().unwrap().to_string();
        [
            "bench".to_string(),
            input,
            "--config".into(),
            config,
            "--threads".into(),
            "1".into(),
            "--repeat".into(),
            "2".into(),
            "--json".into(),
        ]
    };
    let a = args(&cfg);
    let o = slamesh_ok(&a.iter().map(String::as_str).collect::<Vec<_>>());
    let b: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(b["preset"], "kitti", "{b}");
    assert_eq!(b["threads"], 1);
    assert_eq!(b["scans_timed"], 8, "two passes over four scans: {b}");
    // Each stage but reading takes part of every frame's total, so its median and 95th
    // percentile are at most the total's; the rate is the total's median's.
    let ms = |stage: &str, q: &str| b["stages"][stage][q].as_f64().unwrap();
    let stages = slamesh::run::timing::StageMs::NAMES;
    for stage in stages
        .into_iter()
        .filter(|n| !matches!(*n, "read" | "total"))
    {
        for q in ["median_ms", "p95_ms"] {
            assert!(ms(stage, q) <= ms("total", q), "{stage} {q}: {b}");
        }
    }
    assert!(ms("reconstruct", "median_ms") > 0.0 && ms("filter", "median_ms") > 0.0);
    let hz = b["hz"].as_f64().unwrap();
    assert!((hz * ms("total", "median_ms") - 1000.0).abs() < 1e-6, "{b}");

    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "[register]\ncoarse_half_cells = 3\n").unwrap();
    let a = args(&bad);
    let o = common::slamesh(&a.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(!o.status.success());
    let e = text(&o.stderr);
    assert!(
        e.contains("bad.toml") && e.contains("coarse_half_cells"),
        "{e}"
    );
}
