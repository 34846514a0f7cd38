//! Deskewing on the simulator's rolling sweep, through the command's run loop: a car driven
//! through the town at up to 10 m/s (`Drive::car`, 10 Hz, 0.1 s sweeps), each firing cast from
//! the pose at its own time. Deskewed, its frame-to-frame errors must come within 1.3 times
//! those of the same drive scanned with no motion during a sweep (the target of issue 20), and
//! below those of the rolling scans left bent.

use slamesh::eval::odometry::consecutive_errors;
use slamesh::formats::trajectory;
use slamesh::run::session::Deskew;
use slamesh::run::{run, RunOptions};
use slamesh_core::{Config, KittiCapacity, Pose};
use slamesh_sim::Drive;

/// Frames of the drive: from standstill up to 7 m/s, the first straight.
const FRAMES: usize = 60;

/// Mean frame-to-frame translation error (m) and the number of deskewed frames.
fn mean_step_error(sweep: Option<f64>, deskew: Deskew, name: &str) -> (f64, usize) {
    let mut drive = Drive::car(FRAMES, 1);
    drive.sweep_s = sweep;
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
    run::<KittiCapacity>(&mut drive, &opts, |r| {
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
