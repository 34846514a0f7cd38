//! The IMU as a motion prior (docs/design.md §1.19), measured on the simulator through the
//! whole command path (`slamesh::run::run`):
//!
//! - the car round the town with a rolling 0.1 s sweep, calm (`Drive::car`), and shaken by a
//!   rough road (`Vibration::rough_road`: roll, pitch and yaw swings of 0.5 to 2.5 degrees at
//!   2 to 8 Hz), without and with an IMU (a MEMS unit at 200 Hz, 0.3 m from the LiDAR and
//!   turned 90 degrees about z, as configured);
//! - the hand-held rig and the drone (2 scans a second, turns of up to 45 degrees between
//!   scans), without and with the IMU (400 Hz).
//!
//! Prints per run: frames, frames not converged and recovered, the mean frame-to-frame
//! translation error, the 100 m and 200 m segment errors, the ATE and the run's seconds.
//!
//! `cargo run --release --example imu_prior -- [--frames N] [--carried-frames N] [--seed S] [--only car|carried]`
//! (`IMU_AXES=1`: where each run's error lies, by axis along the path; `IMU_DEBUG=1`: each
//! step's error)

#[path = "common/flags.rs"]
mod flags;

use flags::Flags;
use nalgebra::{Translation3, UnitQuaternion};
use slamesh::eval::odometry::{ate_rmse, consecutive_errors, segment_errors};
use slamesh::formats::trajectory;
use slamesh::inertial::ImuOptions;
use slamesh::run::{config_file, run, RunOptions};
use slamesh_core::{Capacity, KittiCapacity, Lidar32Capacity, Pose};
use slamesh_sim::town::Carried;
use slamesh_sim::{Drive, ImuModel, Vibration};
use std::time::Instant;

/// The IMU's place on the LiDAR in every run with one: 0.3 m off, turned 90 degrees.
fn mount() -> Pose {
    Pose::from_parts(
        Translation3::new(0.3, 0.0, -0.1),
        UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::FRAC_PI_2),
    )
}

/// Runs `drive` through the command's run loop and prints its line.
fn measure<C: Capacity>(
    name: &str,
    mut drive: Drive,
    imu: bool,
) -> Result<(), Box<dyn std::error::Error>> {
    let out = std::env::temp_dir().join(format!("slamesh-imu-{name}-{}", std::process::id()));
    let mut options = ImuOptions {
        enabled: imu,
        ..ImuOptions::default()
    };
    options.calibration.lidar_from_imu = mount();
    let opts = RunOptions {
        out: out.clone(),
        config: config_file::preset("default").ok_or("no default preset")?,
        preset: "default".into(),
        threads: 0,
        input: format!("simulated, {name}"),
        imu: options,
        ..RunOptions::default()
    };
    let (mut not_converged, mut recovered) = (0, 0);
    let t = Instant::now();
    run::<C>(&mut drive, &opts, |r| {
        not_converged += usize::from(r.status == "NotConverged");
        recovered += usize::from(r.status == "Recovered");
    })?;
    let seconds = t.elapsed().as_secs_f64();
    let estimate = trajectory::read_kitti(&out.join("poses_kitti.txt"))?;
    std::fs::remove_dir_all(&out)?;
    let truth: Vec<Pose> = drive
        .poses
        .iter()
        .map(|p| drive.poses[0].inverse() * p)
        .collect();
    let e = consecutive_errors(&estimate, &truth);
    if std::env::var_os("IMU_AXES").is_some() {
        print_axes(name, &estimate, &truth);
    }
    if std::env::var_os("IMU_DEBUG").is_some() {
        for i in 1..estimate.len() {
            let d = (truth[i - 1].inverse() * truth[i]).inverse()
                * (estimate[i - 1].inverse() * estimate[i]);
            println!(
                "  {i} {:.2} cm {:.3} deg",
                d.translation.vector.norm() * 100.0,
                d.rotation.angle().to_degrees()
            );
        }
    }
    let seg = |m: f64| {
        segment_errors(&estimate, &truth, &[m])
            .first()
            .map_or(f64::NAN, |s| s.translation_percent)
    };
    println!(
        "{name:<22} {:>6} {:>6} {:>6} {:>9.3} {:>8.3} {:>8.3} {:>8.3} {:>7.1}",
        estimate.len(),
        not_converged,
        recovered,
        e.mean_translation_m * 100.0,
        seg(100.0),
        seg(200.0),
        ate_rmse(&estimate, &truth),
        seconds
    );
    Ok(())
}

/// Where a run's error lies (`IMU_AXES`): the position error along x, y and z at frames
/// along the path (unaligned, in the first pose's frame), each axis's RMS, and the largest
/// error of the estimated up.
fn print_axes(name: &str, estimate: &[Pose], truth: &[Pose]) {
    let n = estimate.len().min(truth.len());
    let along = slamesh::eval::odometry::distances_along(truth);
    let mut sq = [0.0f64; 3];
    let mut tilt = 0.0f64;
    for i in 0..n {
        let d = estimate[i].translation.vector - truth[i].translation.vector;
        for k in 0..3 {
            sq[k] += d[k] * d[k];
        }
        let up = |p: &Pose| p.rotation * nalgebra::Vector3::z();
        tilt = tilt.max(up(&estimate[i]).angle(&up(&truth[i])).to_degrees());
        if i % 20 == 0 || i + 1 == n {
            println!(
                "  {name} frame {i}: {:.1} m along, error x {:.3} y {:.3} z {:.3} m",
                along[i], d.x, d.y, d.z
            );
        }
    }
    let rms = sq.map(|s| (s / n.max(1) as f64).sqrt());
    println!(
        "  {name}: RMS x {:.3} y {:.3} z {:.3} m, up at most {tilt:.3} deg off",
        rms[0], rms[1], rms[2]
    );
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let flags = Flags::from_env();
    let frames: usize = flags.parse_or("--frames", 300)?;
    let carried: usize = flags.parse_or("--carried-frames", 120)?;
    let seed: u64 = flags.parse_or("--seed", 1)?;
    let only = flags.value("--only");
    let imu = |hz: f64| {
        let mut m = ImuModel::mems(hz, seed);
        m.lidar_from_imu = mount();
        m
    };
    println!(
        "run                    frames notcnv recovd  step cm  100 m %  200 m %    ATE m       s"
    );
    if only != Some("carried") {
        let car = || {
            let mut d = Drive::car(frames, seed);
            d.sweep_s = Some(0.1);
            d
        };
        measure::<KittiCapacity>("car, calm", car(), false)?;
        measure::<KittiCapacity>("car, calm, IMU", car().with_imu(imu(200.0)), true)?;
        let shaken = || car().shaken(Vibration::rough_road());
        measure::<KittiCapacity>("car, shaken", shaken(), false)?;
        measure::<KittiCapacity>("car, shaken, IMU", shaken().with_imu(imu(200.0)), true)?;
    }
    if only != Some("car") {
        for (name, how) in [("hand-held", Carried::HANDHELD), ("drone", Carried::DRONE)] {
            let rig = || Drive::carried(carried, how, seed);
            measure::<Lidar32Capacity>(name, rig(), false)?;
            let with = format!("{name}, IMU");
            measure::<Lidar32Capacity>(&with, rig().with_imu(imu(400.0)), true)?;
        }
    }
    Ok(())
}
