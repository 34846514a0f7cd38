//! Maps that outlive a run: a map saved by one run is loaded by another, which localizes in
//! it from an unknown start (or a wrong one) or maps on from it; a map file reads back to the
//! same bytes, and every damaged one is refused by name.

use crate::common;

use common::{kitti_mini, scratch};
use nalgebra::{Translation3, UnitQuaternion};
use slamesh::formats::map_file::{MapFile, MapWriter};
use slamesh::formats::trajectory;
use slamesh::run::session::InitialPose;
use slamesh::run::{run, FrameSource, Input, RunOptions, Summary};
use slamesh_core::map::MeshMap;
use slamesh_core::math::rotation_angle;
use slamesh_core::{Config, KittiCapacity, Pose};
use slamesh_sim::Drive;
use std::path::{Path, PathBuf};

fn options(out: &Path, config: Config) -> RunOptions {
    common::test_run_options(out, config)
}

fn run_ok(source: &mut impl FrameSource, opts: &RunOptions) -> Summary {
    match run::<KittiCapacity>(source, opts, |_| {}) {
        Ok(s) => s,
        Err(e) => panic!("{e}"),
    }
}

/// Runs `drive` with the default configuration into `dir/out`, saving its map to
/// `dir/map.slamesh`; returns the summary and the map file.
fn map_and_save(drive: &mut Drive, dir: &Path, extra: RunOptions) -> (Summary, PathBuf) {
    let file = dir.join("map.slamesh");
    let s = run_ok(
        drive,
        &RunOptions {
            save_map: Some(file.clone()),
            picture: false,
            ..extra
        },
    );
    (s, file)
}

/// The largest translation (m) and rotation (degrees) error of consecutive-frame motions.
fn worst_step(est: &[Pose], truth: &[Pose]) -> (f64, f64) {
    let mut worst = (0.0f64, 0.0f64);
    for i in 1..est.len() {
        let e = (est[i - 1].inverse() * est[i]).inverse() * (truth[i - 1].inverse() * truth[i]);
        worst.0 = worst.0.max(e.translation.vector.norm());
        worst.1 = worst.1.max(rotation_angle(&e).to_degrees());
    }
    worst
}

/// Root mean square of the position errors, no alignment (both in the map's frame).
fn ate(est: &[Pose], truth: &[Pose]) -> f64 {
    let sum: f64 = est
        .iter()
        .zip(truth)
        .map(|(e, t)| (e.translation.vector - t.translation.vector).norm_squared())
        .sum();
    (sum / est.len() as f64).sqrt()
}

/// The simulated town: the first `MAPPED` frames of the loop are mapped and saved; a second
/// drive through the same streets (another noise seed, a lane 1 m to the left, starting
/// `START` frames in) localizes in that map with no pose given, and again from a pose 5 m and
/// 30 degrees off.
#[test]
fn a_second_drive_localizes_in_a_saved_town_map_from_an_unknown_start() {
    const MAPPED: usize = 180;
    const START: usize = 90;
    const FRAMES: usize = 60;
    let dir = scratch("map-town");
    let map_file = dir.join("town.slamesh");
    let mut first = Drive::town(MAPPED, 5);
    let mapping = RunOptions {
        save_map: Some(map_file.clone()),
        picture: false,
        ..options(&dir.join("mapping"), Config::default())
    };
    let mapped = run_ok(&mut first, &mapping);
    assert_eq!(mapped.used, MAPPED);

    // The map's frame is the first true pose's.
    let to_map = first.poses[0].inverse();
    let mut second = first.clone();
    second.seed = 1_000;
    let left = Translation3::new(0.0, 1.0, 0.0);
    second.poses = first.poses[START..START + FRAMES]
        .iter()
        .map(|p| p * left)
        .collect();
    let truth: Vec<Pose> = second.poses.iter().map(|p| to_map * p).collect();
    // Where the map puts the second drive's places: the mapping run's pose of the same
    // frame of the loop, a lane to the left. Against the truth, the map's own drift adds in.
    let placed: Vec<Pose> = mapped.poses[START..START + FRAMES]
        .iter()
        .map(|(_, p)| p * left)
        .collect();
    let drift = ate(&placed, &truth);

    let wrong = truth[0]
        * Pose::from_parts(
            Translation3::new(3.0, -4.0, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 30f64.to_radians()),
        );
    let mut unknown = Vec::new();
    for (name, initial) in [("unknown", None), ("wrong", Some(InitialPose::Near(wrong)))] {
        let out = dir.join(name);
        let opts = RunOptions {
            map: Some(map_file.clone()),
            localize_only: true,
            initial_pose: initial,
            picture: false,
            ..options(&out, Config::default())
        };
        let s = run_ok(&mut second, &opts);
        assert_eq!(s.used, FRAMES, "{name}: every frame localized");
        let est: Vec<Pose> = s.poses.iter().map(|(_, p)| *p).collect();
        let (dt, dr) = worst_step(&est, &truth);
        let to_truth = ate(&est, &truth);
        let in_map = ate(&est, &placed);
        println!(
            "town, {name} start: worst step {:.1} cm, {dr:.3} deg; ATE against where the map \
             puts the same places {in_map:.3} m; against the truth {to_truth:.3} m (the map's \
             own drift there: {drift:.3} m)",
            dt * 100.0
        );
        assert!(dt < 0.05 && dr < 0.5, "{name}: worst step {dt} m, {dr} deg");
        assert!(in_map < 0.1, "{name}: ATE {in_map} m in the map");
        // The map was not changed: the mesh written is the saved map's.
        assert_eq!(s.map_cells, mapped.map_cells, "{name}: the map is fixed");
        if initial.is_none() {
            unknown = s.poses;
        }
    }
    // Under a memory cap the map is paged in by tile around the sensor: the same poses, and
    // the process (the command, alone) stays under the cap.
    const PAGED: usize = 30;
    let scans: Vec<_> = (0..PAGED).map(|i| second.read(i).unwrap()).collect();
    let input = common::write_scan_folder(&dir.join("paged-scans"), &scans);
    let out = dir.join("paged");
    common::slamesh_ok(&[
        "localize",
        input.to_str().unwrap(),
        "--map",
        map_file.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--memory-cap",
        "48",
        "--capacity",
        "32",
        "--threads",
        "2",
        "--no-picture",
        "-q",
    ]);
    let paged = trajectory::read_kitti(&out.join("poses_kitti.txt")).unwrap();
    assert_eq!(paged.len(), PAGED);
    for (k, p) in paged.iter().enumerate() {
        let d = (p.translation.vector - unknown[k].1.translation.vector).norm();
        assert!(
            d < 1e-6,
            "paged, frame {k}: {d} m from the whole map's pose"
        );
    }
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let cells = report["summary"]["map_cells"].as_u64().unwrap() as usize;
    assert!(
        cells < mapped.map_cells,
        "only a part is resident: {cells} cells"
    );
    if let Some(peak) = report["summary"]["peak_rss_mb"].as_f64() {
        println!("paged under --memory-cap 48: peak {peak:.1} MB, {cells} cells resident");
        assert!(peak < 48.0, "peak {peak} MB");
    }
}

/// A KITTI sequence's scans in `order`, linked into a folder of their own.
fn linked(seq: &Path, order: &[usize], dir: &Path) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    for (k, i) in order.iter().enumerate() {
        let from = seq.join("velodyne").join(format!("{i:06}.bin"));
        std::fs::copy(&from, dir.join(format!("{k:06}.bin"))).unwrap();
    }
    dir.to_path_buf()
}

fn kitti_config() -> Config {
    slamesh::run::config_file::preset("kitti").unwrap()
}

/// Each kitti-mini sequence mapped and saved, then its scans localized in reverse order with
/// no pose given: every pose within 2 cm of the mapping run's.
#[test]
fn kitti_scans_in_reverse_localize_where_they_were_mapped() {
    let Some(root) = kitti_mini() else { return };
    for seq in ["00", "01", "02", "03", "04"] {
        let dir = scratch(&format!("map-kitti-reverse-{seq}"));
        let path = root.join(seq);
        let map_file = dir.join("map.slamesh");
        let mut input = Input::open(&path, None, Default::default()).unwrap();
        let n = input.frames();
        let mapped = run_ok(
            &mut input,
            &RunOptions {
                save_map: Some(map_file.clone()),
                picture: false,
                ..options(&dir.join("mapping"), kitti_config())
            },
        );
        let reversed: Vec<usize> = (0..n).rev().collect();
        let mut back = Input::open(
            &linked(&path, &reversed, &dir.join("reversed")),
            None,
            Default::default(),
        )
        .unwrap();
        let s = run_ok(
            &mut back,
            &RunOptions {
                map: Some(map_file),
                localize_only: true,
                picture: false,
                ..options(&dir.join("localized"), kitti_config())
            },
        );
        assert_eq!(s.used, n, "{seq}: every scan localized");
        let worst = s
            .poses
            .iter()
            .map(|(k, p)| {
                let m = mapped.poses[n - 1 - k].1;
                (p.translation.vector - m.translation.vector).norm()
            })
            .fold(0.0, f64::max);
        println!(
            "kitti {seq}: reversed, worst position difference {:.2} cm",
            worst * 100.0
        );
        assert!(worst < 0.02, "{seq}: {worst} m from the mapping run");
    }
}

/// A run over the first half of a sequence that saves its map, then a run over the second
/// half from that map (`--initial-pose end`), gives the poses and the mesh of one run over
/// all the scans, bit for bit; the two map files differ only in the path's times (each
/// session's input starts its clock at zero).
#[test]
fn mapping_on_from_a_saved_map_equals_one_run() {
    let Some(root) = kitti_mini() else { return };
    let dir = scratch("map-kitti-on");
    let path = root.join("00");
    let mut all = Input::open(&path, None, Default::default()).unwrap();
    let n = all.frames();
    let whole = run_ok(
        &mut all,
        &RunOptions {
            save_map: Some(dir.join("whole.slamesh")),
            picture: false,
            ..options(&dir.join("whole"), kitti_config())
        },
    );
    let half = n / 2;
    let first: Vec<usize> = (0..half).collect();
    let second: Vec<usize> = (half..n).collect();
    let mut a = Input::open(
        &linked(&path, &first, &dir.join("a")),
        None,
        Default::default(),
    )
    .unwrap();
    run_ok(
        &mut a,
        &RunOptions {
            save_map: Some(dir.join("a.slamesh")),
            picture: false,
            ..options(&dir.join("a-out"), kitti_config())
        },
    );
    let mut b = Input::open(
        &linked(&path, &second, &dir.join("b")),
        None,
        Default::default(),
    )
    .unwrap();
    let on = run_ok(
        &mut b,
        &RunOptions {
            map: Some(dir.join("a.slamesh")),
            initial_pose: Some(InitialPose::MapEnd),
            save_map: Some(dir.join("b.slamesh")),
            picture: false,
            ..options(&dir.join("b-out"), kitti_config())
        },
    );
    for (k, (_, p)) in on.poses.iter().enumerate() {
        assert_eq!(*p, whole.poses[half + k].1, "frame {}", half + k);
    }
    let mesh = |d: &str| std::fs::read(dir.join(d).join("mesh.ply")).unwrap();
    assert!(mesh("b-out") == mesh("whole"), "the meshes differ");
    let (w, b) = (
        MapFile::open(&dir.join("whole.slamesh")).unwrap(),
        MapFile::open(&dir.join("b.slamesh")).unwrap(),
    );
    assert_eq!(w.index, b.index);
    assert_eq!(w.info, b.info);
    let poses = |f: &MapFile| f.poses.iter().map(|(_, p)| *p).collect::<Vec<_>>();
    assert_eq!(poses(&w), poses(&b));
}

/// A map read back and written again gives the same bytes.
#[test]
fn save_load_save_gives_the_same_bytes() {
    let dir = scratch("map-resave");
    let out = options(&dir.join("out"), Config::default());
    let (_, file) = map_and_save(&mut Drive::town(12, 2), &dir, out);
    let mut f = MapFile::open(&file).unwrap();
    let c = Config::default();
    let mut map = MeshMap::with_capacity(1 << 16, 1 << 17, c.lattice());
    f.load_all(&mut map).unwrap();
    let again = dir.join("again.slamesh");
    let mut w = MapWriter::create(&again, &f.info).unwrap();
    w.add_map(&map).unwrap();
    let stats = w.finish(&f.poses).unwrap();
    assert_eq!(stats.bytes, f.bytes);
    assert!(std::fs::read(&file).unwrap() == std::fs::read(&again).unwrap());
    assert!(stats.cells > 100 && stats.poses == 12, "{stats:?}");
}

/// Every truncation, a bit flip anywhere, another version, an empty file and a foreign file
/// are refused with the file's name and what is wrong, never half-loaded.
#[test]
fn damaged_map_files_are_refused_by_name() {
    let dir = scratch("map-damaged");
    let mut drive = Drive::town(4, 2);
    let (_, file) = map_and_save(
        &mut drive,
        &dir,
        options(&dir.join("out"), Config::default()),
    );
    let good = std::fs::read(&file).unwrap();
    let c = Config::default();
    let bad = dir.join("bad.slamesh");
    let refused = |bytes: &[u8]| -> String {
        std::fs::write(&bad, bytes).unwrap();
        let mut map = MeshMap::with_capacity(1 << 16, 1 << 17, c.lattice());
        let e = match MapFile::open(&bad).and_then(|mut f| f.load_all(&mut map)) {
            Ok(_) => panic!("a damaged map file was read ({} bytes)", bytes.len()),
            Err(e) => e,
        };
        assert_eq!(e.path, bad);
        e.to_string()
    };
    let step = (good.len() / 150).max(1);
    for cut in (0..good.len()).step_by(step) {
        let e = refused(&good[..cut]);
        assert!(cut < 16 || e.contains("truncated"), "cut at {cut}: {e}");
    }
    for i in (0..good.len())
        .step_by(step / 2 + 1)
        .chain([good.len() - 1])
    {
        let mut b = good.clone();
        b[i] ^= 0x10;
        let e = refused(&b);
        assert!(e.contains("not a usable map file"), "{e}");
    }
    let mut v3 = good.clone();
    v3[8] = 3;
    let e = refused(&v3);
    assert!(
        e.contains("version 3") && e.contains("versions 1 to 2"),
        "{e}"
    );
    assert!(refused(&[]).contains("empty"));
    assert!(refused(b"ply\nformat ascii 1.0\n").contains("not a slamesh map file"));
    // A block the index names, corrupted: named with its offset.
    let f = MapFile::open(&file).unwrap();
    let at = f.index[f.index.len() / 2].offset as usize;
    let mut b = good.clone();
    b[at + 40] ^= 1;
    let e = refused(&b);
    assert!(
        e.contains(&format!("at byte {at}")) && e.contains("checksum"),
        "{e}"
    );
    // Another lattice: refused naming both.
    let mut other = Config::default();
    other.grid.cell_size_m *= 2.0;
    let mut map = MeshMap::with_capacity(1 << 16, 1 << 17, other.lattice());
    let e = MapFile::open(&file)
        .and_then(|mut f| f.load_all(&mut map))
        .unwrap_err();
    assert!(e.reason.contains("cells of"), "{e}");
    // Through the command: the run refuses to start, naming the file and the block.
    let scans: Vec<_> = (0..2).map(|i| drive.read(i).unwrap()).collect();
    let input = common::write_scan_folder(&dir, &scans);
    std::fs::write(&bad, &good[..good.len() - 7]).unwrap();
    let out = common::slamesh(&[
        "localize",
        input.to_str().unwrap(),
        "--map",
        bad.to_str().unwrap(),
        "--out",
        dir.join("cli").to_str().unwrap(),
        "-q",
    ]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("bad.slamesh") && stderr.contains("not a usable map file"),
        "{stderr}"
    );
}

/// The fuzz corpus's map file, written by `fuzz/seeds/make_seeds.py` from the format's table
/// (not by slamesh, and with Python's zlib CRC-32), reads as that script wrote it.
#[test]
fn a_map_file_written_by_another_program_reads() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz/corpus/map_file/two_cells");
    let mut f = MapFile::open(&path).unwrap();
    assert_eq!((f.info.frames, f.info.frame_id.as_str()), (2, "map"));
    assert_eq!(f.poses.len(), 2);
    assert_eq!(f.poses[1].1.translation.vector.x, 1.0);
    let mut map = MeshMap::with_capacity(16, 16, f.info.lattice);
    assert_eq!(f.load_all(&mut map).unwrap(), 3);
    let key = slamesh_core::cell::CellKey::new(3, 1, 0);
    let layer = map.layer(&key, slamesh_core::cell::Axis::Z).unwrap();
    assert_eq!((layer.pred[1], layer.var[35]), (0.41, 0.05));
    assert!(map.layer(&key, slamesh_core::cell::Axis::X).is_some());
}

/// Scans of a place the map does not hold (another scene) find no convincing pose: each frame
/// is `NotLocalized`, named with its scores, and the next one searches again.
#[test]
fn a_place_the_map_does_not_hold_is_not_localized() {
    let dir = scratch("map-elsewhere");
    let mapping = options(&dir.join("mapping"), Config::default());
    let (_, map_file) = map_and_save(&mut Drive::town(40, 4), &dir, mapping);
    let mut street = Drive::long_street(5, 1.0, 9);
    let mut records = Vec::new();
    let opts = RunOptions {
        map: Some(map_file),
        localize_only: true,
        picture: false,
        ..options(&dir.join("elsewhere"), Config::default())
    };
    let s = run::<KittiCapacity>(&mut street, &opts, |r| records.push(r.clone())).unwrap();
    assert_eq!(s.used, 0, "no frame was placed in a map of another scene");
    for r in &records {
        assert_eq!(r.status, "NotLocalized", "frame {}", r.frame);
        let e = r.error.as_deref().unwrap_or_default();
        assert!(e.contains("not localized in the map"), "{e}");
        println!("{e}");
    }
}

/// A run under a sliding window saves every cell it had: those the window evicted went to the
/// map file as they left.
#[test]
fn a_windowed_run_saves_the_cells_it_evicted() {
    let dir = scratch("map-window");
    let windowed = RunOptions {
        window: slamesh::run::config_file::WindowSettings {
            max_age_frames: Some(3),
            ..Default::default()
        },
        ..options(&dir.join("out"), Config::default())
    };
    let (s, file) = map_and_save(&mut Drive::town(24, 3), &dir, windowed);
    assert!(s.evicted_cells > 0);
    let mut f = MapFile::open(&file).unwrap();
    let mut map = MeshMap::with_capacity(1 << 16, 1 << 17, Config::default().lattice());
    f.load_all(&mut map).unwrap();
    let loaded = map.cell_count();
    println!(
        "window: {} cells at the end, {} evicted, {loaded} distinct cells in the file",
        s.map_cells, s.evicted_cells
    );
    assert!(loaded > s.map_cells + s.evicted_cells / 2, "{loaded} cells");
    assert!(loaded <= s.map_cells + s.evicted_cells, "{loaded} cells");
}

/// A path as a command-line argument.
fn p(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// The saved-map flags as the README lists them: `run --save-map`, `localize` from a given
/// pose and with `--update --save-map`, and the refusals.
#[test]
fn save_map_localize_and_map_on_from_the_command_line() {
    let dir = scratch("saved-map");
    let (_, scans) = common::street_drive(6);
    let scans_dir = common::write_scan_folder(&dir, &scans);
    let (mapped, map) = (dir.join("mapped"), dir.join("site.slamesh"));
    common::slamesh_run_ok(&scans_dir, &mapped, &["--save-map", p(&map)]);
    let file = MapFile::open(&map).unwrap();
    assert_eq!((file.info.frames, file.poses.len()), (6, 6));
    let run_poses =
        slamesh::formats::trajectory::read_kitti(&mapped.join("poses_kitti.txt")).unwrap();

    // Localize from a given pose (the map's origin, tried first), the map left as it is.
    let here = dir.join("here");
    common::slamesh_ok(&[
        "localize",
        p(&scans_dir),
        "--map",
        p(&map),
        "--out",
        p(&here),
        "--initial-pose",
        "0 0 0 0",
        "-q",
    ]);
    let poses = slamesh::formats::trajectory::read_kitti(&here.join("poses_kitti.txt")).unwrap();
    for (a, b) in poses.iter().zip(&run_poses) {
        assert!((a.translation.vector - b.translation.vector).norm() < 0.02);
    }
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(here.join("report.json")).unwrap()).unwrap();
    assert_eq!(r["frames"][0]["status"], "Relocalized");
    assert!(r["frames"][0]["relocalization"]
        .as_str()
        .unwrap()
        .contains("found in the map"));

    // With --update, the map grows on and can be saved again, its frames counted on.
    let (updated, map2) = (dir.join("updated"), dir.join("site2.slamesh"));
    common::slamesh_ok(&[
        "localize",
        p(&scans_dir),
        "--map",
        p(&map),
        "--out",
        p(&updated),
        "--update",
        "--save-map",
        p(&map2),
        "-q",
    ]);
    let file2 = MapFile::open(&map2).unwrap();
    assert_eq!((file2.info.frames, file2.poses.len()), (12, 12));

    // Refusals: localize without a map, an initial pose of the wrong length.
    let out = common::slamesh(&["localize", p(&scans_dir), "--out", p(&dir.join("x"))]);
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("--map"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let out = common::slamesh(&[
        "localize",
        p(&scans_dir),
        "--map",
        p(&map),
        "--out",
        p(&dir.join("y")),
        "--initial-pose",
        "1 2",
    ]);
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("2 numbers"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}
