//! Every subcommand and flag the README lists, checked by what it writes: `config`, `demo`,
//! `eval` (trajectories against files and KITTI folders, `--calib`, `--mesh`/`--cloud`,
//! `--build-reference`), `mesh` with `--calib` and with fewer poses than frames, `run --obj`,
//! the window flags and the memory cap (and their refusals), and `bench --preset` (saved maps
//! and `localize`: `tests/map_persistence.rs`). The data
//! is simulated (a street with known surfaces), written to disk as a user's would be.

use crate::common;

use common::{
    scratch, slamesh, slamesh_ok, slamesh_run, slamesh_run_ok, street_drive as drive, write_bin,
    write_scan_folder,
};
use nalgebra::{Point3, Translation3, UnitQuaternion};
use slamesh::formats::ply::{read_ply_mesh, read_ply_points};
use slamesh::formats::trajectory::{self, write_kitti_line, write_tum_line};
use slamesh::run::config_file::{self, PRESETS};
use slamesh_core::{Point, Pose};
use slamesh_sim::{Scene, SurfaceDistance};
use std::path::Path;

/// Poses relative to the first: what slamesh estimates and KITTI files hold.
fn relative(truth: &[Pose]) -> Vec<Pose> {
    truth.iter().map(|p| truth[0].inverse() * p).collect()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

fn json(bytes: &[u8]) -> serde_json::Value {
    serde_json::from_slice(bytes).unwrap_or_else(|e| panic!("{e}: {}", text(bytes)))
}

fn report(out: &Path) -> serde_json::Value {
    json(&std::fs::read(out.join("report.json")).unwrap())
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A LiDAR-to-camera transform that is far from the identity, as KITTI's is.
fn calib_tr() -> Pose {
    Pose::from_parts(
        Translation3::new(0.27, -0.08, -0.06),
        UnitQuaternion::from_euler_angles(-1.57, 0.01, -1.56),
    )
}

/// A KITTI sequence folder: `velodyne/*.bin`, `calib.txt` with [`calib_tr`], and `poses.txt`
/// holding the camera poses of the drive (relative to the first, as KITTI's are).
fn kitti_sequence(dir: &Path, truth: &[Pose], scans: &[Vec<Point>]) {
    let velodyne = dir.join("velodyne");
    std::fs::create_dir_all(&velodyne).unwrap();
    for (i, scan) in scans.iter().enumerate() {
        write_bin(&velodyne.join(format!("{i:06}.bin")), scan);
    }
    let tr = calib_tr();
    let m = tr.to_homogeneous();
    let row: Vec<String> = (0..3)
        .flat_map(|r| (0..4).map(move |c| (r, c)))
        .map(|(r, c)| format!("{:e}", m[(r, c)]))
        .collect();
    std::fs::write(
        dir.join("calib.txt"),
        format!("P0: 1 0 0 0 0 1 0 0 0 0 1 0\nTr: {}\n", row.join(" ")),
    )
    .unwrap();
    let mut b = Vec::new();
    for p in relative(truth) {
        write_kitti_line(&mut b, &(tr * p * tr.inverse())).unwrap();
    }
    std::fs::write(dir.join("poses.txt"), b).unwrap();
}

/// Share of `points` (in the first sensor frame of `truth`) within `d` of the street's surfaces.
fn share_near_surfaces(points: &[Point], truth: &[Pose], d: f64) -> f64 {
    let scene = Scene::street();
    let distance = SurfaceDistance::new(&scene);
    let near = points
        .iter()
        .filter(|p| {
            let w = truth[0] * Point3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            distance.distance(&w.coords) <= d
        })
        .count();
    near as f64 / points.len().max(1) as f64
}

#[test]
fn config_prints_every_preset_as_a_file_that_reads_back_as_that_preset() {
    let dir = scratch("config-presets");
    for preset in PRESETS {
        let o = slamesh_ok(&["config", "--preset", preset]);
        let path = dir.join(format!("{preset}.toml"));
        std::fs::write(&path, &o.stdout).unwrap();
        let settings = config_file::read(&path).unwrap();
        assert_eq!(settings.preset, preset);
        assert_eq!(
            Some(settings.config),
            config_file::preset(preset),
            "{preset}"
        );
        let toml = text(&o.stdout);
        for p in config_file::PARAMETERS {
            assert!(
                toml.lines()
                    .any(|l| l.trim_start().starts_with(&format!("{} =", p.name))),
                "{preset}: no line for [{}] {}",
                p.section,
                p.name
            );
        }
    }
}

#[test]
fn demo_as_a_user_calls_it_writes_its_outputs_and_scores() {
    let dir = scratch("demo-command");
    let out = dir.join("demo-out");
    let o = slamesh_ok(&[
        "demo",
        "--frames",
        "12",
        "--seed",
        "2",
        "--threads",
        "1",
        "--out",
        s(&out),
        "-q",
    ]);
    let stdout = text(&o.stdout);
    assert!(stdout.contains("demo: 12 frames"), "{stdout}");
    let f1: Vec<f64> = stdout
        .lines()
        .filter(|l| l.starts_with("demo: mesh at"))
        .map(|l| l.rsplit("F1 ").next().unwrap().parse().unwrap())
        .collect();
    assert_eq!(f1.len(), 3, "{stdout}");
    // The first 12 frames of seed 2: F1 0.952 / 0.981 / 0.987 at 0.1 / 0.2 / 0.3 m (measured
    // 2026-12-01); the bound leaves 5 % for legitimate change.
    for (got, measured) in f1.iter().zip([0.952, 0.981, 0.987]) {
        assert!(*got >= measured * 0.95, "F1 {f1:?}");
    }
    let estimate = trajectory::read(&out.join("poses_kitti.txt"))
        .unwrap()
        .poses;
    let truth = trajectory::read(&out.join("poses_true_kitti.txt"))
        .unwrap()
        .poses;
    assert_eq!((estimate.len(), truth.len()), (12, 12));
    for (e, t) in estimate.iter().zip(&truth) {
        let d = (e.translation.vector - t.translation.vector).norm();
        assert!(d < 0.02, "{d} m off the truth");
    }
    let reference = read_ply_points(&out.join("reference.ply")).unwrap();
    assert!(
        reference.len() > 10_000,
        "{} reference points",
        reference.len()
    );
    let png = std::fs::read(out.join("topview.png")).unwrap();
    let info = png::Decoder::new(std::io::Cursor::new(png))
        .read_info()
        .unwrap();
    assert!(info.info().width >= 500 && info.info().height >= 500);
}

#[test]
fn eval_reads_kitti_folders_and_calib_files_scores_meshes_and_builds_references() {
    let dir = scratch("eval-modes");
    let (truth, scans) = drive(5);
    let seq = dir.join("seq");
    kitti_sequence(&seq, &truth, &scans);

    // Odometry on the sequence, evaluated against the folder and against poses.txt + calib.txt:
    // the same figures; against poses.txt without its calib, camera poses are compared with
    // LiDAR poses and the error is far larger.
    let run = dir.join("run");
    slamesh_run_ok(&seq, &run, &[]);
    let estimate = run.join("poses_kitti.txt");
    let eval = |extra: &[&str]| {
        let mut args = vec!["eval", "--estimate", s(&estimate), "--json"];
        args.extend_from_slice(extra);
        json(&slamesh_ok(&args).stdout)
    };
    let folder = eval(&["--reference", s(&seq)]);
    // Its plots beside the estimate.
    for plot in [
        "poses_kitti_eval_trajectory.png",
        "poses_kitti_eval_error.png",
    ] {
        assert!(run.join(plot).is_file(), "{plot}");
    }
    let calibrated = eval(&[
        "--reference",
        s(&seq.join("poses.txt")),
        "--calib",
        s(&seq.join("calib.txt")),
    ]);
    let uncalibrated = eval(&["--reference", s(&seq.join("poses.txt"))]);
    assert_eq!(folder["pairs"], 4);
    let t = |v: &serde_json::Value| v["mean_translation_m"].as_f64().unwrap();
    assert!(t(&folder) < 0.01, "{folder}");
    assert!(
        (t(&calibrated) - t(&folder)).abs() < 1e-9,
        "{calibrated} vs {folder}"
    );
    assert!(t(&uncalibrated) > 5.0 * t(&folder), "{uncalibrated}");
    // A folder that is no KITTI sequence is named with what it lacks.
    let o = slamesh(&["eval", "--estimate", s(&estimate), "--reference", s(&run)]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("it has no poses.txt"),
        "{err}"
    );

    // A reference cloud from the scans at the reference poses lies on the true surfaces.
    let reference = dir.join("ref.ply");
    let o = slamesh_ok(&["eval", "--build-reference", s(&seq), s(&reference)]);
    let cloud = read_ply_points(&reference).unwrap();
    assert!(text(&o.stdout).contains(&format!("wrote {} reference points", cloud.len())));
    assert!(cloud.len() > 20_000, "{} points", cloud.len());
    let on_surface = share_near_surfaces(&cloud, &truth, 0.03);
    assert!(
        on_surface > 0.99,
        "{on_surface} of the reference within 3 cm"
    );

    // Meshing at the calibrated poses puts the mesh on the true surfaces; at the camera
    // poses taken as LiDAR poses it does not.
    let (poses_txt, calib_txt) = (seq.join("poses.txt"), seq.join("calib.txt"));
    let mesh_at = |name: &str, calib: bool| {
        let out = dir.join(name);
        let mut args = vec!["mesh", s(&seq), "--poses", s(&poses_txt)];
        if calib {
            args.extend_from_slice(&["--calib", s(&calib_txt)]);
        }
        args.extend_from_slice(&["--out", s(&out), "-q"]);
        slamesh_ok(&args);
        out.join("mesh.ply")
    };
    let good = mesh_at("mesh-calib", true);
    let bad = mesh_at("mesh-raw", false);
    let good_vertices = read_ply_mesh(&good).unwrap().vertices;
    let near = share_near_surfaces(&good_vertices, &truth, 0.1);
    assert!(near > 0.95, "{near} of the vertices within 10 cm");
    let far = share_near_surfaces(&read_ply_mesh(&bad).unwrap().vertices, &truth, 0.1);
    assert!(far < 0.5 * near, "without --calib: {far} within 10 cm");

    // The mesh against the cloud: high scores; against the cloud lifted by 0.5 m, low ones.
    let scores = |cloud: &Path| {
        let o = slamesh_ok(&["eval", "--mesh", s(&good), "--cloud", s(cloud), "--json"]);
        json(&o.stdout)
            .as_array()
            .unwrap()
            .iter()
            .map(|m| {
                (
                    m["threshold_m"].as_f64().unwrap(),
                    m["f1"].as_f64().unwrap(),
                )
            })
            .collect::<Vec<_>>()
    };
    let matched = scores(&reference);
    assert_eq!(
        matched.iter().map(|m| m.0).collect::<Vec<_>>(),
        [0.1, 0.2, 0.3]
    );
    // Measured 2026-12-01: F1 0.904 / 0.975 / 0.983; bound: 5 % below.
    for ((_, f1), measured) in matched.iter().zip([0.904, 0.975, 0.983]) {
        assert!(*f1 >= 0.95 * measured, "{matched:?}");
    }
    let lifted: Vec<Point> = cloud.iter().map(|p| [p[0], p[1], p[2] + 0.5]).collect();
    let lifted_path = dir.join("lifted.ply");
    slamesh::formats::ply::write_points(&lifted_path, &lifted).unwrap();
    let off = scores(&lifted_path);
    assert!(off[0].1 < 0.5 * matched[0].1, "lifted cloud: {off:?}");
}

#[test]
fn mesh_mode_with_fewer_poses_than_frames_meshes_those_and_skips_the_rest() {
    let dir = scratch("few-poses");
    let (truth, scans) = drive(4);
    let scans_dir = write_scan_folder(&dir, &scans);
    let poses = dir.join("two.txt");
    let mut b = Vec::new();
    for (i, p) in relative(&truth).iter().take(2).enumerate() {
        write_tum_line(&mut b, i as f64 * 0.1, p).unwrap();
    }
    std::fs::write(&poses, b).unwrap();
    let out = dir.join("out");
    let o = slamesh_ok(&[
        "mesh",
        s(&scans_dir),
        "--poses",
        s(&poses),
        "--out",
        s(&out),
        "-q",
    ]);
    assert!(
        text(&o.stderr).contains(
            "2 poses for 4 frames, matched to frames by time (within 0.050 s); frames without \
             a pose are skipped"
        ) && text(&o.stderr).contains("frame 2: no given pose within 0.050 s of its time 0.2"),
        "{}",
        text(&o.stderr)
    );
    let r = report(&out);
    assert_eq!(r["summary"]["used"], 2);
    for i in [0, 1] {
        assert_eq!(r["frames"][i]["status"], "Given");
    }
    for i in [2, 3] {
        assert_eq!(r["frames"][i]["status"], "Skipped");
        let e = r["frames"][i]["error"].as_str().unwrap();
        assert!(
            e.contains("no given pose within 0.050 s of its time"),
            "{e}"
        );
    }
    let mesh = read_ply_mesh(&out.join("mesh.ply")).unwrap();
    assert!(share_near_surfaces(&mesh.vertices, &truth, 0.1) > 0.95);
}

/// The RGB pixels of a PNG, with its size.
#[test]
fn run_obj_writes_the_same_mesh_as_the_ply() {
    let dir = scratch("obj");
    let (_, scans) = drive(3);
    let scans_dir = write_scan_folder(&dir, &scans);
    let out = dir.join("out");
    slamesh_run_ok(&scans_dir, &out, &["--obj"]);
    let ply = read_ply_mesh(&out.join("mesh.ply")).unwrap();
    let obj = std::fs::read_to_string(out.join("mesh.obj")).unwrap();
    let numbers = |prefix: &str| -> Vec<Vec<f64>> {
        obj.lines()
            .filter_map(|l| l.strip_prefix(prefix))
            .map(|l| {
                l.split_whitespace()
                    .map(|w| w.split('/').next().unwrap().parse().unwrap())
                    .collect()
            })
            .collect()
    };
    let v = numbers("v ");
    let f = numbers("f ");
    assert!(ply.triangles.len() > 1000);
    assert_eq!(
        (v.len(), f.len()),
        (ply.vertices.len(), ply.triangles.len())
    );
    // A unit normal per vertex, and each face corner names its vertex's normal.
    let vn = numbers("vn ");
    assert_eq!(vn.len(), v.len());
    assert!(vn
        .iter()
        .all(|n| (n.iter().map(|c| c * c).sum::<f64>() - 1.0).abs() < 1e-4));
    assert!(obj
        .lines()
        .filter_map(|l| l.strip_prefix("f "))
        .flat_map(|l| l.split_whitespace())
        .all(|w| w.split_once("//").is_some_and(|(p, n)| p == n)));
    for (a, b) in v.iter().zip(&ply.vertices) {
        assert_eq!(a.iter().map(|x| *x as f32).collect::<Vec<_>>(), b.to_vec());
    }
    for (a, b) in f.iter().zip(&ply.triangles) {
        assert_eq!(
            a.clone(),
            b.iter().map(|i| f64::from(*i) + 1.0).collect::<Vec<_>>()
        );
    }
}

#[test]
fn window_flags_and_the_memory_cap_from_the_command_line() {
    let dir = scratch("window-flags");
    let (_, scans) = drive(10);
    let scans_dir = write_scan_folder(&dir, &scans);
    let run = |name: &str, extra: &[&str]| {
        let out = dir.join(name);
        slamesh_run_ok(&scans_dir, &out, extra);
        let r = report(&out);
        let tris = read_ply_mesh(&out.join("mesh.ply"))
            .unwrap()
            .triangles
            .len();
        (r, tris)
    };
    let count = |r: &serde_json::Value, k: &str| r["summary"][k].as_u64().unwrap();
    let (all, all_tris) = run("all", &[]);
    assert_eq!(count(&all, "evicted_cells"), 0);

    // Cells farther than 12 m go; with --save-evicted their triangles stay in the mesh.
    let (near, near_tris) = run("radius", &["--evict-radius", "12"]);
    let (saved, saved_tris) = run("radius-saved", &["--evict-radius", "12", "--save-evicted"]);
    assert!(count(&near, "evicted_cells") > 100, "{}", near["summary"]);
    assert!(count(&near, "map_cells") < count(&all, "map_cells") / 2);
    assert_eq!(
        count(&saved, "evicted_cells"),
        count(&near, "evicted_cells")
    );
    assert!(near_tris < all_tris / 2 && saved_tris > near_tris);

    // Cells not seen for 2 frames go.
    let (aged, _) = run("age", &["--evict-after", "2"]);
    assert!(count(&aged, "evicted_cells") > 0);

    // A cap below what the capacity needs is refused, naming the minimum; a cap just above it
    // leaves a small layer budget, which the map keeps to by evicting.
    let o = slamesh_run(&scans_dir, &dir.join("tiny"), &["--memory-cap", "1"]);
    assert!(!o.status.success());
    let e = text(&o.stderr);
    let needed: f64 = e
        .split("needs: ")
        .nth(1)
        .and_then(|r| r.split(" MB").next())
        .unwrap_or_else(|| panic!("{e}"))
        .trim()
        .parse()
        .unwrap();
    assert!(e.contains("memory cap 1 MB is below"), "{e}");
    let cap = format!("{}", needed + 1.0);
    let (capped, _) = run("capped", &["--memory-cap", &cap]);
    let budget = count(&capped, "max_layers");
    assert!(
        budget > 0 && count(&capped, "map_layers") <= budget,
        "{}",
        capped["summary"]
    );
    if count(&all, "map_layers") > budget {
        assert!(count(&capped, "evicted_cells") > 0);
    }
    let peak = capped["summary"]["peak_rss_mb"]
        .as_f64()
        .expect("peak RSS (Linux)");
    assert!(peak <= needed + 1.0, "peak {peak} MB over the cap {cap} MB");
    for (flag, value) in [("--evict-radius", "-3"), ("--memory-cap", "0")] {
        let o = slamesh_run(&scans_dir, &dir.join("bad"), &[&format!("{flag}={value}")]);
        assert!(!o.status.success());
        let e = text(&o.stderr);
        assert!(
            e.contains(&format!("{flag}: must be a positive number")),
            "{e}"
        );
    }
}

#[test]
fn bench_takes_a_preset() {
    let dir = scratch("bench-preset");
    let (_, scans) = drive(3);
    for (i, scan) in scans.iter().enumerate() {
        write_bin(&dir.join(format!("{i}.bin")), scan);
    }
    let o = slamesh_ok(&[
        "bench",
        s(&dir),
        "--preset",
        "meshing",
        "--threads",
        "1",
        "--repeat",
        "1",
        "--json",
    ]);
    let b = json(&o.stdout);
    assert_eq!(
        (b["preset"].as_str(), b["threads"].as_u64()),
        (Some("meshing"), Some(1))
    );
    assert_eq!(b["scans_timed"], 3);
    // Each outcome's frames and cost: the three timed scans, the first a FirstScan.
    let outcomes = b["outcomes"].as_array().unwrap();
    let frames: u64 = outcomes.iter().map(|o| o["frames"].as_u64().unwrap()).sum();
    assert_eq!(frames, 3, "{outcomes:?}");
    assert!(outcomes.iter().any(|o| o["status"] == "FirstScan"));
    assert!(outcomes
        .iter()
        .all(|o| o["median_ms"].as_f64().unwrap() > 0.0));
    // --scaling: one row a thread count, 1 first, up to the cores present.
    let o = slamesh_ok(&["bench", s(&dir), "--scaling", "--repeat", "1", "--json"]);
    let rows = json(&o.stdout)["scaling"].as_array().unwrap().clone();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get()) as u64;
    assert_eq!(rows[0]["threads"], 1);
    assert_eq!(rows.last().unwrap()["threads"].as_u64(), Some(cores));
    assert!((rows[0]["speed_vs_one"].as_f64().unwrap() - 1.0).abs() < 1e-12);
    // Each stage's median, reading among them.
    let stages = rows[0]["stage_median_ms"].as_object().unwrap();
    for stage in "read filter bucket reconstruct solve update total".split(' ') {
        assert!(stages.contains_key(stage), "{stage}: {stages:?}");
    }
    let o = slamesh(&["bench", s(&dir), "--preset", "nonsense"]);
    assert!(!o.status.success() && text(&o.stderr).contains("nonsense"));
}

#[test]
fn the_capacity_class_fits_the_first_scans_and_a_scan_too_large_for_it_is_refused() {
    let dir = scratch("capacity");
    let (_, scans) = drive(3);
    let scans_dir = write_scan_folder(&dir, &scans);
    // Points within the default range limits (1.2 to 100 m) in a scan, and the class the rule
    // gives for the largest of the first scans: the smallest of 2 048, 36 000, 72 000, 140 000
    // points that holds them with a quarter to spare.
    let in_range = |scan: &[slamesh_core::Point]| {
        scan.iter()
            .filter(|p| {
                let r = p.iter().map(|c| c * c).sum::<f32>().sqrt();
                (1.2..=100.0).contains(&r)
            })
            .count()
    };
    let class_of = |n: usize| {
        [
            (2_048, "tiny", "tiny"),
            (36_000, "16-beam", "16"),
            (72_000, "32-beam", "32"),
        ]
        .into_iter()
        .find(|(points, _, _)| *points as f64 >= 1.25 * n as f64)
        .map_or(("64-beam", "64"), |(_, name, flag)| (name, flag))
    };
    // The first of the largest.
    let most = |counts: &[usize]| {
        let max = *counts.iter().max().unwrap();
        (counts.iter().position(|&n| n == max).unwrap(), max)
    };
    let counts: Vec<usize> = scans.iter().map(|s| in_range(s)).collect();
    let (frame, most_n) = most(&counts);
    let (name, flag) = class_of(most_n);
    let out = dir.join("auto");
    // Without -q: the choice is an info message.
    let o = slamesh_ok(&["run", s(&scans_dir), "--out", s(&out)]);
    let stderr = text(&o.stderr);
    assert!(
        stderr.contains(&format!(
            "capacity {name} (--capacity {flag}): frame {frame} has {most_n} points within \
             range, the most of the first 3 readable scans"
        )),
        "{most_n} points: {stderr}"
    );
    assert_eq!(report(&out)["summary"]["capacity"], name);

    // One odd first scan (a partial sweep of 64 points) does not choose for the whole run.
    // Both it and a cut-off scan later on are named.
    let mut odd = vec![scans[0][..64].to_vec()];
    odd.extend(scans.iter().cloned());
    odd.push(scans[2][..64].to_vec());
    let odd_dir = write_scan_folder(&dir.join("odd"), &odd);
    let out = dir.join("odd-auto");
    let o = slamesh_ok(&["run", s(&odd_dir), "--out", s(&out), "-q"]);
    let stderr = text(&o.stderr);
    assert!(
        stderr.lines().any(|l| l.contains("000000.bin: frame 0: ")
            && l.contains("points within range, far fewer than frame")),
        "{stderr}"
    );
    assert!(
        stderr.contains("000004.bin: frame 4: 64 points, far fewer than the"),
        "{stderr}"
    );
    let odd_counts: Vec<usize> = odd.iter().map(|s| in_range(s)).collect();
    let (odd_name, _) = class_of(most(&odd_counts).1);
    assert_ne!(odd_name, "tiny");
    assert_eq!(report(&out)["summary"]["capacity"], odd_name);

    let n = counts[0];
    // The tiny class cannot hold these scans: each is refused, naming the class that can.
    let holding = [(36_000, "16"), (72_000, "32"), (140_000, "64")]
        .into_iter()
        .find(|(points, _)| *points >= n)
        .unwrap()
        .1;
    let o = slamesh_run(&scans_dir, &dir.join("tiny"), &["--capacity", "tiny"]);
    assert!(!o.status.success());
    let stderr = text(&o.stderr);
    assert!(
        stderr.contains(&format!(
            "0.bin: frame 0: {n} points within range, more than the tiny capacity holds (2048): run with --capacity {holding}"
        )),
        "{stderr}"
    );
    assert!(stderr.contains("no frame could be used"), "{stderr}");

    let out = dir.join("largest");
    slamesh_run_ok(&scans_dir, &out, &["--capacity", "64"]);
    assert_eq!(report(&out)["summary"]["capacity"], "64-beam");
}
