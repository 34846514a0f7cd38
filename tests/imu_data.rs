//! The IMU on the data people have (issue 86): readings too slow or too still to be an IMU
//! ignored, registrations bent by an untimed shaken sweep not talking the IMU out, an IMU that
//! starts with the first scan levelling the map with the readings after it, and a KITTI raw
//! drive read with its OXTS packets and timed from its sweep.

use crate::common::{scratch, slamesh_run_ok, write_folder_with_imu};
use crate::imu::{car_frames, count, hand_held, options, run_drive, shaken_car, Altered};
use slamesh::eval::odometry::consecutive_errors;
use slamesh::formats::trajectory;
use slamesh::inertial::ImuSummary;
use slamesh::run::{run, Sample};
use slamesh_core::{KittiCapacity, Lidar32Capacity};
use slamesh_sim::{ImuModel, Vibration};

/// An IMU at `hz` in its mount ([`crate::imu::imu`]).
fn imu(hz: f64) -> ImuModel {
    crate::imu::imu(hz)
}

/// One reading a frame, the gyro still: a 10 Hz `/imu` topic that is no IMU.
fn decoy(s: &mut Vec<Sample>) {
    s.retain(|s| (s.stamp() * 10.0 - (s.stamp() * 10.0).round()).abs() < 1e-6);
    still(s);
}

/// The gyro still, at its rate.
fn still(s: &mut [Sample]) {
    for r in s.iter_mut().filter_map(Sample::imu_mut) {
        r.gyro = [0.0; 3];
    }
}

#[test]
fn readings_too_slow_or_too_still_to_be_an_imu_are_ignored_and_named() {
    let d = car_frames(20).with_imu(imu(200.0));
    let truth = d.poses.clone();
    let out = scratch("imu-decoy");
    let s = run::<KittiCapacity>(
        &mut Altered::new(d.clone(), decoy),
        &options(&out, true),
        |_| {},
    )
    .unwrap();
    let imu = s.stage::<ImuSummary>("imu").expect("readings came");
    let why = imu.ignored.expect("ignored");
    assert!(why.contains("10.0 Hz"), "{why}");
    assert_eq!((imu.prior_frames, imu.deskewed_frames), (0, 0));
    // The run is the run without it, to the bit.
    let off = scratch("imu-decoy-off");
    run::<KittiCapacity>(&mut d.clone(), &options(&off, false), |_| {}).unwrap();
    for f in ["poses_kitti.txt", "poses_tum.txt"] {
        let (a, b) = (out.join(f), off.join(f));
        assert_eq!(std::fs::read(a).unwrap(), std::fs::read(b).unwrap(), "{f}");
    }
    // A gyro at 400 Hz that never turns while the rig does: ignored once the rig turned.
    let h = hand_held(30);
    let (s, _, _) =
        run_drive::<Lidar32Capacity>(&mut Altered::new(h, |s| still(s)), &truth, true, "still");
    let why = s
        .stage::<ImuSummary>("imu")
        .and_then(|i| i.ignored)
        .expect("ignored");
    assert!(why.contains("while the registrations turned"), "{why}");
}

#[test]
fn registrations_bent_by_an_untimed_shaken_sweep_do_not_talk_the_imu_out() {
    let d = shaken_car(60);
    let truth = d.poses.clone();
    let (s, statuses, step) =
        run_drive::<KittiCapacity>(&mut Altered::untimed(d), &truth, true, "untimed-shaken");
    let imu = s.stage::<ImuSummary>("imu").expect("readings came");
    println!(
        "untimed shaken sweeps with the IMU: {:.2} cm a step, {} converged, {} runs of \
         misses put down to the registrations",
        step * 100.0,
        count(&statuses, "Converged"),
        imu.registrations_doubted
    );
    assert!(imu.set_aside.is_none(), "{:?}", imu.set_aside);
    assert!(imu.registrations_doubted > 0);
    assert_eq!(imu.prior_frames, 59);
}

#[test]
fn an_imu_that_starts_with_the_first_scan_levels_the_map_with_the_readings_after_it() {
    // The car stands still through the first frames; its IMU sits at the LiDAR, in its axes.
    let mut d = car_frames(8);
    d.poses = vec![d.poses[0]; 8];
    let d = d.with_imu(ImuModel::mems(200.0, 7));
    let dir = scratch("imu-starts-with-the-scan");
    let scans = write_folder_with_imu(&d, &dir);
    // Every reading before the first scan's stamp (0 s) dropped: the CSV starts with it.
    let csv = dir.join("imu0").join("data.csv");
    let text = std::fs::read_to_string(&csv).unwrap();
    let kept: Vec<&str> = text
        .lines()
        .filter(|l| {
            let t = l
                .split(',')
                .next()
                .and_then(|t| t.trim().parse::<f64>().ok());
            t.is_none_or(|t| t >= 0.0)
        })
        .collect();
    assert!(
        kept.len() < text.lines().count(),
        "readings before the scan were dropped"
    );
    std::fs::write(&csv, kept.join("\n") + "\n").unwrap();
    let out = dir.join("out");
    slamesh_run_ok(&scans, &out, &["--threads", "2"]);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let gravity = &report["summary"]["imu"]["gravity"];
    assert_eq!(gravity["levelled"], true, "{gravity}");
    // Up from the readings through the first 0.4 s, after the stamp.
    assert!(gravity["seconds"].as_f64().unwrap() >= 0.35, "{gravity}");
}

#[test]
fn a_kitti_raw_drive_is_read_with_its_oxts_packets_and_timed_from_its_sweep() {
    // The shaken car, its IMU at the LiDAR in its axes at 200 Hz (an extracted set's rate is
    // 100), as KITTI raw ships a drive.
    let d = car_frames(40)
        .shaken(Vibration::rough_road())
        .with_imu(ImuModel::mems(200.0, 7));
    let dir = scratch("imu-kitti-raw");
    let truth = crate::common::write_kitti_raw(&d, &dir);
    let out = dir.join("out");
    // The simulated head turns counter-clockwise from +x; the stamps are mid-sweep.
    slamesh_run_ok(&dir, &out, &["--threads", "2", "--sweep", "ccw:0:0.5"]);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let s = &report["summary"];
    assert_eq!(s["input"]["sweep_times"]["timed"], 40, "{}", s["input"]);
    let imu = &s["imu"];
    assert_eq!(imu["deskewed_frames"], 40, "{imu}");
    assert_eq!(imu["prior_frames"], 39, "{imu}");
    assert_eq!(imu["gravity"]["levelled"], true, "{imu}");
    let estimate = trajectory::read_kitti(&out.join("poses_kitti.txt")).unwrap();
    let step = consecutive_errors(&estimate, &truth).mean_translation_m;
    println!(
        "KITTI raw layout, shaken, OXTS at 200 Hz: {:.3} cm a step",
        step * 100.0
    );
    // Measured 0.557 cm (0.73 over 150 frames with write_drive --kitti-raw; without the IMU
    // 26 cm): the bound leaves 40 %.
    assert!(step < 0.008, "{step}");
    // Its default sweep is KITTI's (clockwise from behind): named in the report.
    let out = dir.join("out-default");
    slamesh_run_ok(&dir, &out, &["--threads", "2"]);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let input = &report["summary"]["input"];
    assert_eq!(input["sweep_times"]["sweep"], "kitti", "{input}");
}
