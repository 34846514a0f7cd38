//! Loop closure (docs/design.md §1.14): a drive that comes back to where it began closes its
//! loop, and the place it came back to is one surface in the map; a look-alike street it has
//! never driven closes nothing; a run with no loop gives the same bytes with it on as off;
//! the closure thread never holds a frame up; the command closes loops by default wherever a
//! run can, and says why where it cannot.

use crate::common;

use common::{kitti_mini, scratch, slamesh, write_bin, write_scan_folder};
use slamesh::eval::duplicates::duplicated_near;
use slamesh::eval::odometry::ate_rmse;
use slamesh::formats::map_file::MapFile;
use slamesh::formats::trajectory::{Format, Trajectory};
use slamesh::loop_closure::settings::LoopSettings;
use slamesh::loop_closure::{stage, LoopReport};
use slamesh::outputs::mesh_spool::MeshFormat;
use slamesh::run::window::Window;
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

/// The first frame where the look-alike drive is back in the first street.
fn back_in_the_first_street(truth: &[Pose]) -> usize {
    truth
        .iter()
        .position(|p| p.translation.vector.y.abs() < 1.0 && p.translation.vector.x < -10.0)
        .expect("the drive comes back")
}

/// Loop closure on is no worse than off: its ATE (within 5 %) and its surfaces mapped twice
/// near the return (`(on, off)` each).
fn assert_no_worse((ate_on, ate_off): (f64, f64), (dup_on, dup_off): (usize, usize)) {
    println!(
        "ATE {ate_on:.3} m with, {ate_off:.3} m without; twice {dup_on} with, {dup_off} without"
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
    let report = loops(&on).expect("loop closure ran");
    // Where the drive is back in the first street.
    let back_from = back_in_the_first_street(&truth);
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
    assert_no_worse((ate_on, ate_off), (dup_on, dup_off));
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
    assert!(loops(&on).unwrap().closures.is_empty());
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

/// What loop closure did in a run (its part of the summary), when it was on.
fn loops(summary: &Summary) -> Option<LoopReport> {
    summary.stage(stage::NAME)
}

/// `summary.loop_closure` of a run's report.json (null when loop closure was off).
fn loop_report(out: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(out.join("report.json")).unwrap();
    let report: serde_json::Value = serde_json::from_str(&text).unwrap();
    report["summary"]["loop_closure"].clone()
}

/// `slamesh run` closes loops unless told not to: on by default, with the same bytes as off
/// on a drive with no loop, from a saved map too; under a memory cap or window only when
/// asked (it takes a share of the cap), saying so; off, saying why, where a run cannot close
/// loops (a fixed map, a saved map under a cap), and an error there when `--loop-closure on`
/// asks for it.
#[test]
fn the_command_closes_loops_by_default_where_it_can() {
    let dir = scratch("loop-command");
    let input = dir.join("scans");
    std::fs::create_dir_all(&input).unwrap();
    let mut drive = Drive::town(6, 3);
    for i in 0..6 {
        write_bin(&input.join(format!("{i:06}.bin")), &drive.read(i).unwrap());
    }
    let run = |name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let mut args = vec![
            "run",
            input.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(&["--no-picture", "--threads", "2"]);
        args.extend_from_slice(extra);
        (slamesh(&args), out)
    };
    let (o, on) = run(
        "default",
        &["--save-map", dir.join("map.slamesh").to_str().unwrap()],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report = loop_report(&on);
    assert!(report["spool_bytes"].as_u64().unwrap() > 0, "{report}");
    assert_eq!(report["closures"].as_array().map(Vec::len), Some(0));
    assert!(
        !on.join(".loop-closure.scans").exists(),
        "the spool is removed"
    );
    let (o, off) = run("off", &["--loop-closure", "off"]);
    assert!(o.status.success());
    assert!(loop_report(&off).is_null());
    for f in ["poses_kitti.txt", "mesh.ply"] {
        let same = std::fs::read(on.join(f)).unwrap() == std::fs::read(off.join(f)).unwrap();
        assert!(same, "{f} differs with loop closure on");
    }
    let map = dir.join("map.slamesh");
    let map = map.to_str().unwrap();
    for (name, flags) in [
        ("capped", vec!["--memory-cap", "200"]),
        ("windowed", vec!["--evict-after", "50"]),
    ] {
        // On by default there too: it takes a share of the cap.
        let (o, out) = run(name, &flags);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{name}: {stderr}");
        assert!(!loop_report(&out).is_null(), "{name}: {stderr}");
        let mut off = flags.clone();
        off.extend_from_slice(&["--loop-closure", "off"]);
        let (o, out) = run(&format!("{name}-off"), &off);
        assert!(o.status.success(), "{name}");
        assert!(loop_report(&out).is_null(), "{name}: --loop-closure off");
        let mut asked = flags.clone();
        asked.extend_from_slice(&["--loop-closure", "on"]);
        // From a saved map, a rebuild would load it whole: refused.
        asked.extend_from_slice(&["--map", map]);
        let (o, _) = run(&format!("{name}-from-map"), &asked);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(
            !o.status.success(),
            "{name}: --map and --loop-closure on ran"
        );
        assert!(
            stderr.contains("--loop-closure: ") && stderr.contains("not under a memory cap"),
            "{name}: {stderr}"
        );
    }
    from_a_saved_map(&dir, &input, map);
}

/// From a saved map `map` (of the scans in `input`) `run` closes loops, against the map's
/// path too; `localize` in it does not, and refuses to be asked, unless `--update`.
fn from_a_saved_map(dir: &Path, input: &Path, map: &str) {
    let (o, from_map) = {
        let out = dir.join("from-map");
        let args = [
            "run",
            input.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--map",
            map,
            "--no-picture",
        ];
        (slamesh(&args), out)
    };
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!loop_report(&from_map).is_null(), "from a saved map: on");
    let localize = |extra: &[&str]| {
        let out = dir.join("localized");
        let mut args = vec!["localize", input.to_str().unwrap(), "--map", map];
        args.extend_from_slice(&["--out", out.to_str().unwrap(), "--no-picture"]);
        args.extend_from_slice(extra);
        (slamesh(&args), out)
    };
    let (o, out) = localize(&[]);
    assert!(o.status.success() && loop_report(&out).is_null());
    let (o, _) = localize(&["--loop-closure", "on"]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && stderr.contains("the map is fixed"),
        "{stderr}"
    );
    let (o, out) = localize(&["--update"]);
    assert!(
        o.status.success() && !loop_report(&out).is_null(),
        "localize --update: on"
    );
}

/// Two sessions round one block: the first maps the start of it and saves its map; the
/// second starts inside that map (other noise, half a lane over), drives on round the block
/// and back into the first session's streets. With loop closure it closes its loop against
/// the saved map: its poses, in the first session's frame, come nearer the truth than
/// without, and where it came back the map holds no more surfaces twice than the two
/// sessions mapped at their true poses.
#[test]
fn a_second_session_closes_its_loop_against_the_saved_map() {
    let dir = scratch("loop-sessions");
    let block = Drive::town_along(slamesh_sim::town::block_path(), 530, 3);
    // Each session's scans simulated once (the simulator's scans cost more than the runs),
    // read by its runs: with and without loop closure, and at the true poses.
    let mut first = block.clone();
    first.poses.truncate(230);
    let first_folder = scanned(&first, &dir.join("first-scans"));
    // The town preset's fixed cells, as the command maps a town.
    let town = slamesh::run::config_file::preset("town").unwrap();
    let mapped = RunOptions {
        config: town,
        ..options(&dir.join("first"), false)
    };
    run_ok(&mut open(&first_folder), &mapped);
    let mut second = block.clone();
    second.seed = 1_000;
    let over = nalgebra::Translation3::new(0.0, 0.5, 0.0);
    second.poses = block.poses[180..].iter().map(|p| p * over).collect();
    let to_first = block.poses[0].inverse();
    let truth: Vec<Pose> = second.poses.iter().map(|p| to_first * p).collect();
    let folder = scanned(&second, &dir.join("second"));
    let session = |name: &str, on: bool| {
        let mut config = town;
        let s = LoopSettings::default();
        if on {
            s.configure(&mut config);
        }
        let opts = RunOptions {
            map: mapped.save_map.clone(),
            config,
            loop_closure: on.then_some(s),
            ..options(&dir.join(name), false)
        };
        let summary = run_ok(&mut open(&folder), &opts);
        let off_truth: Vec<f64> = (summary.poses.iter().zip(&truth))
            .map(|((_, p), t)| (p.translation.vector - t.translation.vector).norm())
            .collect();
        let rms = (off_truth.iter().map(|d| d * d).sum::<f64>() / off_truth.len() as f64).sqrt();
        (summary, rms)
    };
    let floor_map = mapped_at_truth(&dir, &block, [&first_folder, &folder], &truth, &town);
    let (off, ate_off) = session("off", false);
    let (on, ate_on) = session("on", true);
    let closures = &loops(&on).unwrap().closures;
    let with_saved = closures.iter().filter(|c| c.in_saved_map).count();
    // Where the second session came back into the first one's streets.
    let back = truth.len() - 60;
    let twice = |map: &Path| duplicated_near(&loaded(map), 0.3, 0.3, &truth[back], 60.0);
    let saved = |s: &str| dir.join(s).join("map.slamesh");
    let (dup_off, dup_on) = (twice(&saved("off")), twice(&saved("on")));
    let floor = twice(&floor_map);
    println!(
        "second session, in the first's frame: ATE {ate_off:.3} m without loop closure, \
         {ate_on:.3} m with ({} closures, {with_saved} against the saved map); surfaces mapped \
         twice near the return {dup_off} and {dup_on} (at the true poses {floor})",
        closures.len()
    );
    assert!(loops(&off).is_none());
    assert!(with_saved >= 2, "{closures:?}");
    // With loop closure at most 0.8 of without: 0.5 before layers kept their facing (0.022 m
    // against 0.044); since then the run without it ends nearer (0.039 m) and the one with it
    // 0.024 to 0.028 m over six runs (loop closure's timing varies), 0.62 to 0.71 of it.
    assert!(ate_on < 0.8 * ate_off, "{ate_on} against {ate_off}");
    // Issue 57's target: the second session's poses within 5 cm of the truth (RMS).
    assert!(ate_on <= 0.05, "ATE {ate_on} m with loop closure");
    // The revisited street is one surface: as many pairs as the metric finds in the map
    // made at the true poses (surfaces crossing a cell face), within a fifth (58 at the true
    // poses, 58 to 66 with loop closure, 62 without, over five runs; the runs with it differ
    // with the threads' timing).
    assert!(
        dup_on as f64 <= 1.2 * floor as f64,
        "{dup_on} against {floor} at the true poses"
    );
}

/// `d`'s scans, simulated once, written as a folder of `.bin` files in `dir`.
fn scanned(d: &Drive, dir: &Path) -> std::path::PathBuf {
    let mut d = d.clone();
    let scans: Vec<_> = (0..d.frames()).map(|i| d.read(i).unwrap()).collect();
    write_scan_folder(dir, &scans)
}

/// A folder of scans as a run reads it.
fn open(folder: &Path) -> Input {
    Input::open(folder, None, Default::default()).unwrap()
}

/// The two sessions of [`a_second_session_closes_its_loop_against_the_saved_map`] mapped at
/// their true poses (the scans in `folders`: the first session's, the start of `block`, then
/// the second's from that map): the saved map that is the duplicate metric's floor there.
fn mapped_at_truth(
    dir: &Path,
    block: &Drive,
    folders: [&Path; 2],
    second_truth: &[Pose],
    config: &Config,
) -> std::path::PathBuf {
    let given = |poses: Vec<Pose>| {
        Some(Trajectory {
            format: Format::Kitti,
            stamps: None,
            poses,
        })
    };
    let to_first = block.poses[0].inverse();
    let mut first = open(folders[0]);
    let first_truth = (block.poses[..first.frames()].iter())
        .map(|p| to_first * p)
        .collect();
    let opts = RunOptions {
        config: *config,
        given_poses: given(first_truth),
        ..options(&dir.join("truth-first"), false)
    };
    run_ok(&mut first, &opts);
    let opts = RunOptions {
        config: *config,
        map: opts.save_map,
        given_poses: given(second_truth.to_vec()),
        ..options(&dir.join("truth"), false)
    };
    run_ok(&mut open(folders[1]), &opts);
    dir.join("truth").join("map.slamesh")
}

/// Under a memory cap (asked for: `--loop-closure on`), the look-alike drive closes its loop
/// as without one: the rebuild keeps the run's window, and what left the window before the
/// correction is written again at the corrected poses (the mesh holds it), with the
/// rebuild's files gone at the end.
#[test]
fn under_a_memory_cap_the_loop_closes_and_what_left_the_window_moves_with_it() {
    let dir = scratch("loop-capped");
    let mut drive = twin_drive();
    let to_first = drive.poses[0].inverse();
    let truth: Vec<Pose> = drive.poses.iter().map(|p| to_first * p).collect();
    // A cap a few megabytes above the least with loop closure (what the process holds
    // now counts).
    let capped = |out: &str, on: bool| {
        let other = slamesh::run::memory::other_bytes();
        let least = Window::least_cap_bytes_closing::<KittiCapacity>(other);
        let mut opts = options(&dir.join(out), on);
        opts.window.memory_cap_mb = Some((least as f64 + 4e6) / 1e6);
        // And an age: the streets left behind leave the map.
        opts.window.max_age_frames = Some(100);
        opts.window.save_evicted = true;
        opts
    };
    let off = run_ok(&mut drive, &capped("off", false));
    let on = run_ok(&mut drive, &capped("on", true));
    let report = loops(&on).expect("loop closure ran");
    let est = |s: &Summary| s.poses.iter().map(|(_, p)| *p).collect::<Vec<_>>();
    let (ate_off, ate_on) = (ate_rmse(&est(&off), &truth), ate_rmse(&est(&on), &truth));
    let back_from = back_in_the_first_street(&truth);
    let twice = |s: &str| {
        let map = loaded(&dir.join(s).join("map.slamesh"));
        duplicated_near(&map, 0.3, 0.3, &truth[back_from], 60.0)
    };
    let (dup_off, dup_on) = (twice("off"), twice("on"));
    println!(
        "under a cap 4 MB above the least and an age of 100 frames: layer budgets {:?} and {:?}, \
         {} and {} cells evicted; ATE off {ate_off:.3} m, \
         on {ate_on:.3} m ({} closures, {} rebuilds); surfaces twice near the return \
         {dup_off} and {dup_on}",
        off.max_layers,
        on.max_layers,
        off.evicted_cells,
        on.evicted_cells,
        report.closures.len(),
        report.rebuilds
    );
    assert!(on.evicted_cells > 0, "the map was never a window");
    assert!(!report.closures.is_empty(), "no loop closed: {report:?}");
    for c in &report.closures {
        let t = truth[c.frame].translation.vector;
        let found = nalgebra::Vector3::from(c.position);
        assert!((found - t).norm() < 0.5, "a false closure: {c:?}");
    }
    // The revisited street is mapped twice less often than without loop closure (7 and 19
    // cells: every keyframe due is checked, however far behind the thread is, so the same
    // closures are found on every run).
    assert!(
        dup_on < dup_off,
        "surfaces twice near the return: {dup_on} with, {dup_off} without"
    );
    assert!(
        ate_on <= ate_off * 1.05,
        "ATE {ate_on} m with, {ate_off} m without"
    );
    let left: Vec<_> = std::fs::read_dir(dir.join("on"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
    // What left the window is in the mesh, as without loop closure.
    let triangles = |s: &str| {
        let path = dir.join(s).join("mesh.ply");
        slamesh::formats::ply::read_ply_mesh(&path)
            .unwrap()
            .triangles
            .len()
    };
    let (t_off, t_on) = (triangles("off"), triangles("on"));
    assert!(
        10 * t_on > 9 * t_off,
        "triangles: {t_on} with, {t_off} without"
    );
}

/// A library run that asks for loop closure where it cannot close loops (here at given poses)
/// is refused, naming why, with and without a memory cap: the cap decides only whether loop
/// closure fits, never whether it may run.
#[test]
fn a_library_run_asking_for_loop_closure_where_it_cannot_is_refused() {
    let dir = scratch("loop-refused");
    let mut drive = Drive::town(3, 3);
    // A cap loop closure fits under, whatever the test process already holds (other tests
    // run beside this one).
    let roomy = || {
        let least =
            Window::least_cap_bytes_closing::<KittiCapacity>(slamesh::run::memory::other_bytes());
        Some((least as f64 + 50e6) / 1e6)
    };
    for cap in [None, roomy()] {
        let mut opts = options(&dir.join("out"), true);
        opts.given_poses = Some(slamesh::formats::trajectory::Trajectory {
            format: slamesh::formats::trajectory::Format::Kitti,
            stamps: None,
            poses: drive.poses.clone(),
        });
        opts.window.memory_cap_mb = cap;
        let Err(e) = run::<KittiCapacity>(&mut drive, &opts, |_| {}) else {
            panic!("ran with loop closure at given poses (cap {cap:?})");
        };
        let e = e.to_string();
        assert!(
            e.contains("loop closure") && e.contains("the poses are given"),
            "{e}"
        );
    }
}
