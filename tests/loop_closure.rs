//! Loop closure (docs/design.md §1.14): a drive that comes back to where it began closes its
//! loop, and the place it came back to is one surface in the map; a look-alike street it has
//! never driven closes nothing; a run with no loop gives the same bytes with it on as off;
//! the closure thread never holds a frame up.

use crate::common;

use common::{kitti_mini, scratch};
use slamesh::eval::duplicates::duplicated_near;
use slamesh::eval::odometry::ate_rmse;
use slamesh::formats::map_file::MapFile;
use slamesh::loop_closure::settings::LoopSettings;
use slamesh::outputs::mesh_spool::MeshFormat;
use slamesh::run::{run, FrameSource, Input, RunOptions, Summary};
use slamesh_core::map::MeshMap;
use slamesh_core::{Config, KittiCapacity, Pose};
use slamesh_sim::town::Carried;
use slamesh_sim::{Drive, Lidar};
use std::path::Path;

/// The look-alike streets: 120 m long, 40 m apart.
const LENGTH_M: f64 = 120.0;
const GAP_M: f64 = 40.0;

fn options(out: &Path, loop_closure: bool) -> RunOptions {
    let mut config = Config::default();
    let settings = LoopSettings::default();
    if loop_closure {
        settings.configure(&mut config);
    }
    RunOptions {
        out: out.to_path_buf(),
        config,
        preset: "default".into(),
        threads: 2,
        input: "test".into(),
        mesh_formats: vec![MeshFormat::Ply],
        save_map: Some(out.join("map.slamesh")),
        loop_closure: loop_closure.then_some(settings),
        ..RunOptions::default()
    }
}

fn run_ok(source: &mut impl FrameSource, opts: &RunOptions) -> Summary {
    match run::<KittiCapacity>(source, opts, |_| {}) {
        Ok(s) => s,
        Err(e) => panic!("{e}"),
    }
}

/// The drive through the look-alike streets with a lighter scanner (half the firings, 60 m):
/// down the first street, back up its twin, and 60 m into the first again.
fn twin_drive() -> Drive {
    let mut d = Drive::twin_streets(10_000, LENGTH_M, GAP_M, 3);
    d.lidar = Lidar::hdl64(500);
    d.lidar.max_range_m = 60.0;
    d
}

fn loaded(path: &Path) -> MeshMap {
    MapFile::open(path).unwrap().load_new().unwrap()
}

/// The look-alike drive, with loop closure off and on: on, it closes the loop where the
/// drive comes back into the first street, with every closure where the truth has it (none
/// in the twin street, 40 m off); the map has no more surfaces mapped twice where it came
/// back than off, and the longest frame stays far below a map rebuild's time.
#[test]
fn the_true_return_closes_and_the_look_alike_street_does_not() {
    let dir = scratch("loop-twin");
    let mut drive = twin_drive();
    let n = drive.frames();
    let to_first = drive.poses[0].inverse();
    let truth: Vec<Pose> = drive.poses.iter().map(|p| to_first * p).collect();
    let off = run_ok(&mut drive, &options(&dir.join("off"), false));
    let on = run_ok(&mut drive, &options(&dir.join("on"), true));
    assert_eq!((off.used, on.used), (n, n));
    let report = on.loop_closure.as_ref().expect("loop closure ran");
    // The frames where the drive is back in the first street, and in the twin one.
    let back_from = truth
        .iter()
        .position(|p| p.translation.vector.y.abs() < 1.0 && p.translation.vector.x < -10.0)
        .expect("the drive comes back");
    assert!(!report.closures.is_empty(), "no loop closed: {report:?}");
    for c in &report.closures {
        let t = truth[c.frame].translation.vector;
        let found = nalgebra::Vector3::from(c.position);
        println!(
            "closure: frame {} with {}, {:.0} % on the map ({:.0} % walls, elsewhere {:.0} %), \
             correction {:.3} m {:.3} deg, {:.3} m from the truth",
            c.frame,
            c.with_frame,
            100.0 * c.hit_share,
            100.0 * c.wall_share,
            100.0 * c.runner_up_share,
            c.correction_m,
            c.correction_deg,
            (found - t).norm()
        );
        assert!(
            c.frame >= back_from,
            "closed at frame {} before the return",
            c.frame
        );
        assert!((found - t).norm() < 0.5, "a false closure: {c:?}");
        assert!(c.applied_at_frame.is_some());
    }
    let est = |s: &Summary| s.poses.iter().map(|(_, p)| *p).collect::<Vec<_>>();
    let (ate_off, ate_on) = (ate_rmse(&est(&off), &truth), ate_rmse(&est(&on), &truth));
    let twice = |s: &Path| duplicated_near(&loaded(s), 0.3, 0.3, &truth[back_from], 60.0);
    let (dup_off, dup_on) = (
        twice(&dir.join("off/map.slamesh")),
        twice(&dir.join("on/map.slamesh")),
    );
    let longest = |run: &str| {
        let text = std::fs::read_to_string(dir.join(run).join("report.json")).unwrap();
        let r: serde_json::Value = serde_json::from_str(&text).unwrap();
        r["frames"]
            .as_array()
            .unwrap()
            .iter()
            .filter_map(|f| f["ms"]["total"].as_f64())
            .fold(0.0, f64::max)
    };
    let (slowest_off, slowest_on) = (longest("off"), longest("on"));
    println!("longest frame: off {slowest_off:.0} ms, on {slowest_on:.0} ms");
    // A rebuild of the map takes seconds; no frame waited for one.
    assert!(slowest_on < 1000.0, "a frame took {slowest_on} ms");
    println!(
        "ATE off {ate_off:.3} m, on {ate_on:.3} m; surfaces mapped twice near the return: off \
         {dup_off}, on {dup_on}; {} corrections, {} rebuilds",
        report.corrections, report.rebuilds
    );
    assert!(
        ate_on <= ate_off * 1.05,
        "ATE {ate_on} m with, {ate_off} m without"
    );
    assert!(
        dup_on <= dup_off,
        "duplicates: {dup_on} with, {dup_off} without"
    );
}

/// Before the drive comes back, nothing is closed, and the outputs with loop closure on are
/// those with it off, byte for byte.
#[test]
fn a_run_without_a_loop_gives_the_same_bytes_with_loop_closure_on() {
    let dir = scratch("loop-none");
    let mut drive = twin_drive();
    // Down the first street and into the second, never back.
    drive.poses.truncate(200);
    let off = run_ok(&mut drive, &options(&dir.join("off"), false));
    let on = run_ok(&mut drive, &options(&dir.join("on"), true));
    assert!(on.loop_closure.as_ref().unwrap().closures.is_empty());
    assert_eq!(off.poses, on.poses);
    for f in ["poses_kitti.txt", "mesh.ply"] {
        let (a, b) = (
            std::fs::read(dir.join("off").join(f)).unwrap(),
            std::fs::read(dir.join("on").join(f)).unwrap(),
        );
        assert!(a == b, "{f} differs");
    }
    assert!(
        !dir.join("on/.loop-closure.scans").exists(),
        "the scan spool is removed"
    );
    // A hand-held rig and a drone (2 Hz, fast turns), which never come back.
    for (name, how) in [("hand-held", Carried::HANDHELD), ("drone", Carried::DRONE)] {
        let mut drive = Drive::carried(60, how, 1);
        let off = run_ok(
            &mut drive,
            &options(&dir.join(format!("{name}-off")), false),
        );
        let on = run_ok(&mut drive, &options(&dir.join(format!("{name}-on")), true));
        assert_eq!(off.poses, on.poses, "{name}");
    }
    // KITTI's scans too, when the data is here.
    let Some(kitti) = kitti_mini() else { return };
    for seq in ["00", "01"] {
        let mut source = Input::open(&kitti.join(seq), None, Default::default()).unwrap();
        let off = run_ok(
            &mut source,
            &options(&dir.join(format!("k{seq}-off")), false),
        );
        let on = run_ok(&mut source, &options(&dir.join(format!("k{seq}-on")), true));
        assert_eq!(off.poses, on.poses, "kitti {seq}");
    }
}
