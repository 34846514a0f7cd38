//! Deskewing on the simulator's rolling sweep, through the command's run loop: a car driven
//! through the town at up to 10 m/s (`Drive::car`, 10 Hz, 0.1 s sweeps), each firing cast from
//! the pose at its own time. Deskewed, its frame-to-frame errors must come within 1.3 times
//! those of the same drive scanned with no motion during a sweep (the target of issue 20), and
//! below those of the rolling scans left bent. Written as `.bin` files, without the points'
//! times, and timed from the sweep (`--sweep`), it must track as the timed scans do.

use slamesh::eval::odometry::consecutive_errors;
use slamesh::formats::kitti::BinFields;
use slamesh::formats::trajectory;
use slamesh::run::session::Deskew;
use slamesh::run::{run, Input, RunOptions};
use slamesh::sources::sweep_times::SweepSpec;
use slamesh::sources::FrameSource;
use slamesh_core::{Config, KittiCapacity, Point, Pose};
use slamesh_sim::Drive;

/// Frames of the drive: from standstill up to 7 m/s, the first straight.
const FRAMES: usize = 60;

/// The car's drive, with a rolling sweep of `sweep` seconds.
fn car(sweep: Option<f64>) -> Drive {
    let mut drive = Drive::car(FRAMES, 1);
    drive.sweep_s = sweep;
    drive
}

/// Mean frame-to-frame translation error (m) against `drive`'s poses, and the number of
/// deskewed frames, of a run over `source`.
fn step_error(
    source: &mut impl FrameSource,
    drive: &Drive,
    deskew: Deskew,
    name: &str,
) -> (f64, usize) {
    let out = crate::common::scratch(&format!("deskew-{name}"));
    let opts = RunOptions {
        out: out.to_path_buf(),
        config: Config::default(),
        preset: "default".into(),
        threads: 2,
        input: format!("simulated car, {name}"),
        deskew,
        ..RunOptions::default()
    };
    let mut deskewed = 0;
    run::<KittiCapacity>(source, &opts, |r| {
        deskewed += usize::from(r.deskewed_points > 0)
    })
    .unwrap();
    let estimate = trajectory::read_kitti(&out.join("poses_kitti.txt")).unwrap();
    drop(out);
    let truth: Vec<Pose> = drive
        .poses
        .iter()
        .map(|p| drive.poses[0].inverse() * p)
        .collect();
    (
        consecutive_errors(&estimate, &truth).mean_translation_m,
        deskewed,
    )
}

/// [`step_error`] of the car's drive run as the simulator gives it.
fn mean_step_error(sweep: Option<f64>, deskew: Deskew, name: &str) -> (f64, usize) {
    let drive = car(sweep);
    step_error(&mut drive.clone(), &drive, deskew, name)
}

/// [`step_error`] of the car's rolling drive written as `.bin` files (no times) and read
/// back as a folder, its points timed from the sweep when `sweep` names one.
fn folder_step_error(sweep: Option<&str>, name: &str) -> (f64, usize) {
    let drive = car(Some(0.1));
    let scans: Vec<Vec<Point>> = (0..FRAMES).map(|i| drive.scan(i)).collect();
    let dir = crate::common::scratch(&format!("deskew-files-{name}"));
    let folder = crate::common::write_scan_folder(&dir, &scans);
    let mut input = Input::open(&folder, None, BinFields::default()).unwrap();
    if let Some(sweep) = sweep {
        let spec = SweepSpec::parse(sweep).unwrap().unwrap();
        input.time_from_sweep(&folder, &spec).unwrap();
    }
    step_error(&mut input, &drive, Deskew::Auto, name)
}

#[test]
fn deskewed_rolling_sweeps_track_as_well_as_scans_without_motion() {
    let (still, _) = mean_step_error(None, Deskew::Auto, "still");
    let (bent, none) = mean_step_error(Some(0.1), Deskew::Off, "bent");
    let (deskewed, frames) = mean_step_error(Some(0.1), Deskew::Auto, "deskewed");
    println!(
        "mean frame-to-frame error: no motion in a sweep {:.3} cm, rolling {:.3} cm, \
         deskewed {:.3} cm",
        still * 100.0,
        bent * 100.0,
        deskewed * 100.0
    );
    assert_eq!(none, 0, "--deskew off deskews nothing");
    // Every frame after the first two (the motion is unknown before).
    assert_eq!(frames, FRAMES - 2);
    assert!(
        deskewed <= 1.3 * still,
        "deskewed {deskewed} against {still}"
    );
    assert!(deskewed < bent, "deskewed {deskewed} against bent {bent}");
}

#[test]
fn untimed_scan_files_timed_from_their_sweep_track_as_the_timed_scans() {
    let (timed, _) = mean_step_error(Some(0.1), Deskew::Auto, "timed");
    let (untimed, none) = folder_step_error(None, "untimed");
    // The simulator's head turns counter-clockwise from +x, stamped at the sweep's start.
    let (swept, frames) = folder_step_error(Some("ccw:0:0"), "swept");
    let (wrong_way, _) = folder_step_error(Some("cw:0:0"), "wrong-way");
    println!(
        "mean frame-to-frame error: timed points {:.3} cm, untimed files {:.3} cm, timed \
         from the sweep {:.3} cm, from a sweep turning the wrong way {:.3} cm",
        timed * 100.0,
        untimed * 100.0,
        swept * 100.0,
        wrong_way * 100.0
    );
    assert_eq!(
        none, 0,
        "files without times are not deskewed unless --sweep says how"
    );
    assert_eq!(frames, FRAMES - 2);
    // Measured: 0.305 cm both (the azimuths give the simulator's own firing times back);
    // the bound is 1.3x, this one leaves 5 % for a platform's rounding.
    assert!(
        swept <= 1.05 * timed,
        "timed from the sweep {swept} against {timed}"
    );
    assert!(untimed > 2.0 * timed, "untimed {untimed} against {timed}");
    assert!(
        wrong_way > swept,
        "the wrong way {wrong_way} against {swept}"
    );
}

/// `report.json`'s `summary.input` of a run of `slamesh run FOLDER --sweep auto`.
fn auto_sweep(folder: &std::path::Path, name: &str) -> serde_json::Value {
    let out = crate::common::scratch(&format!("deskew-auto-{name}"));
    crate::common::slamesh_run_ok(folder, &out, &["--sweep", "auto", "--threads", "2"]);
    let report = std::fs::read_to_string(out.join("report.json")).unwrap();
    let report: serde_json::Value = serde_json::from_str(&report).unwrap();
    assert!(
        !out.join(".sweep-trial").exists(),
        "the trial's runs leave nothing behind"
    );
    report["summary"]["input"].clone()
}

#[test]
fn sweep_auto_finds_the_simulated_turn_and_leaves_kitti_odometry_untimed() {
    let drive = car(Some(0.1));
    let scans: Vec<Vec<Point>> = (0..30).map(|i| drive.scan(i)).collect();
    let dir = crate::common::scratch("deskew-auto-files");
    let folder = crate::common::write_scan_folder(&dir, &scans);
    let input = auto_sweep(&folder, "car");
    println!("{}", input["sweep_trial"]);
    assert_eq!(input["sweep_times"]["sweep"], "ccw:0:0", "{input}");
    assert_eq!(input["sweep_times"]["timed"], 30);
    // KITTI odometry's scans were deskewed by the dataset's makers: any sweep bends them.
    let Some(kitti) = crate::common::kitti_mini() else {
        return;
    };
    let input = auto_sweep(&kitti.join("01"), "kitti-01");
    println!("{}", input["sweep_trial"]);
    assert!(input["sweep_times"].is_null(), "{input}");
    let trial = input["sweep_trial"].as_str().unwrap();
    assert!(trial.starts_with("--sweep auto chose off"), "{trial}");
}
