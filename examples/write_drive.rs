//! Writes the demo's simulated town drive as a KITTI odometry sequence, so that other tools
//! can run on the same scans: `velodyne/NNNNNN.bin` (x, y, z and a zero intensity, f32), the
//! true poses in `poses.txt` (relative to the first), `times.txt` (10 Hz) and a `calib.txt`
//! whose `Tr` is the identity (the poses are the sensor's). Used for KISS-ICP side by side
//! (`tools/kiss_icp_compare.py DIR --sequence --no-kitti-correction`, docs/journal.md).
//!
//! `cargo run --release --example write_drive -- --out DIR [--frames N] [--seed S]`
//! (1 000 frames, seed 1 by default). A second drive through the same town, for localizing in
//! a map of the first: `--noise-seed K` (the scans' noise; the town stays seed S's), `--start
//! F` (begin at frame F of the loop) and `--lateral-m M` (drive M metres to the left). Its
//! `poses.txt` is then relative to the loop's first pose, the first drive's frame. `--round`:
//! the drive goes on round the loop past its start (the loop is about 1 200 frames), for loop
//! closure. `--path campus` (about 2 400 frames, several loops through the town's inner
//! streets) or `--path block` (one block round and on past the start, about 450 frames)
//! drive another path; `--path hand-held` and `--path drone` carry a rig through the town at
//! 2 Hz with fast turns, as the example `hard_motion` does (`times.txt` then 2 Hz); `--path
//! office` walks a 16-beam sensor through the office of the navigation map's tests (about 900
//! frames). `--azimuth-steps N`: firings per turn of each of the 64 beams (1 000 by
//! default, about 55 000 points in range; 2 000 gives a KITTI-sized scan of about 110 000).
//! `--path car`: the town's drive with a car's smooth attitude. `--rolling`: each firing from
//! the pose at its own time over the frame's sweep; the scans are then written as binary PCD
//! files (`velodyne/NNNNNN.pcd`) with each point's time after the stamp in a field `t`.
//! `--shaken`: a rough road's vibration over the drive (a rolling sweep too). `--imu HZ`: an
//! IMU on the scanner (its axes the LiDAR's), its readings in EuRoC's `imu0/data.csv`.
//! `--untimed`: a rolling sweep's scans written as `.bin` files all the same, without their
//! points' times, as a KITTI-style folder of a real drive has them (the simulated head turns
//! counter-clockwise from +x, stamped at the sweep's start: `slamesh run --sweep ccw:0:0`).
//! `--kitti-raw`: KITTI raw's drive layout instead, untimed: `velodyne_points/data/*.bin`
//! with `timestamps.txt` (mid-sweep), `timestamps_start.txt` and `timestamps_end.txt`, and
//! with `--imu HZ` the readings as OXTS packets in `oxts/` (`slamesh run --sweep ccw:0:0.5`);
//! `poses.txt` (the true poses at those mid-sweep stamps) and `calib.txt` stay at the top for
//! `slamesh eval`. `--movers`: cars in both lanes, people on the sidewalks and parked cars
//! that pull out, along the drive's path (`slamesh_sim::traffic`), each point's truth in
//! `labels/NNNNNN.label` (SemanticKITTI's: 252 a moving car, 254 a person, 0 static).

#[path = "common/flags.rs"]
mod flags;

use flags::Flags;
use slamesh::formats::trajectory::write_kitti_line;
use slamesh::formats::{imu_csv, oxts, pcd};
use slamesh_sim::{Drive, ImuModel, Traffic, TrafficCounts, Vibration};
use std::fs::{self, File};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

type Error = Box<dyn std::error::Error>;

fn main() -> Result<(), Error> {
    let flags = Flags::from_env();
    let out = PathBuf::from(flags.value("--out").ok_or("--out DIR is required")?);
    let frames: usize = flags.parse_or("--frames", 1000)?;
    let seed: u64 = flags.parse_or("--seed", 1)?;
    let start: usize = flags.parse_or("--start", 0)?;
    let lateral: f64 = flags.parse_or("--lateral-m", 0.0)?;
    let (mut drive, scene, period_s) = path_drive(&flags, start + frames, seed)?;
    drive.lidar.azimuth_steps = flags.parse_or("--azimuth-steps", drive.lidar.azimuth_steps)?;
    let first = drive.poses[0].inverse();
    drive.seed = flags.parse_or("--noise-seed", seed)?;
    let left = nalgebra::Translation3::new(0.0, lateral, 0.0);
    drive.poses = drive.poses[start.min(drive.poses.len())..]
        .iter()
        .map(|p| p * left)
        .collect();
    let drive = with_traffic(&flags, drive, seed);
    let drive = with_motion(&flags, drive, period_s, seed, &out)?;
    if flags.has("--kitti-raw") {
        return write_kitti_raw(&drive, period_s, &out);
    }
    let timed = drive.sweep_s.is_some() && !flags.has("--untimed");
    fs::create_dir_all(out.join("velodyne"))?;
    if drive.traffic.is_some() {
        fs::create_dir_all(out.join("labels"))?;
    }
    let mut poses = BufWriter::new(File::create(out.join("poses.txt"))?);
    let mut times = BufWriter::new(File::create(out.join("times.txt"))?);
    for i in 0..drive.poses.len() {
        let labels = drive.traffic.is_some().then(|| out.join("labels"));
        write_scan(&drive, i, timed, &out.join("velodyne"), labels.as_deref())?;
        write_kitti_line(&mut poses, &(first * drive.poses[i]))?;
        writeln!(times, "{:.6}", i as f64 * period_s)?;
    }
    poses.flush()?;
    times.flush()?;
    fs::write(out.join("calib.txt"), "Tr: 1 0 0 0 0 1 0 0 0 0 1 0\n")?;
    println!(
        "{} frames of the {scene} (seed {seed}) in {}",
        drive.poses.len(),
        out.display()
    );
    Ok(())
}

/// The drive `--path` names (`frames` frames), its scene's name and its period (s): the
/// carried rigs scan twice a second (docs/design.md §1.11), the car ten times.
fn path_drive(
    flags: &Flags,
    frames: usize,
    seed: u64,
) -> Result<(Drive, &'static str, f64), Error> {
    let town = |drive| (drive, "town", 0.1);
    let carried = |how| (Drive::carried(frames, how, seed), "town", 0.5);
    Ok(match flags.value("--path") {
        Some("campus") => town(Drive::town_along(
            slamesh_sim::town::campus_path(),
            frames,
            seed,
        )),
        Some("block") => town(Drive::town_along(
            slamesh_sim::town::block_path(),
            frames,
            seed,
        )),
        Some("hand-held") => carried(slamesh_sim::town::Carried::HANDHELD),
        Some("drone") => carried(slamesh_sim::town::Carried::DRONE),
        Some("office") => (Drive::office(frames, seed), "office", 0.1),
        Some("car") => town(Drive::car(frames, seed)),
        Some(other) => {
            return Err(
                format!("--path {other}: campus, block, hand-held, drone, office or car").into(),
            )
        }
        None if flags.has("--round") => town(Drive::town_round(frames, seed)),
        None => town(Drive::town(frames, seed)),
    })
}

/// Where the KITTI raw layout's clock starts: 2011-09-26 13:02:25, a day of KITTI's drives.
const RAW_EPOCH_S: f64 = 1_317_042_145.0;

/// `drive` in KITTI raw's layout (`--kitti-raw`), its IMU's readings, if any, as OXTS packets
/// (moved there from `imu0/data.csv`, which `with_motion` wrote).
fn write_kitti_raw(drive: &Drive, period_s: f64, out: &Path) -> Result<(), Error> {
    let velodyne = out.join("velodyne_points");
    fs::create_dir_all(velodyne.join("data"))?;
    let stamps = |shift: f64| -> String {
        (0..drive.poses.len())
            .map(|i| oxts::format_time(RAW_EPOCH_S + i as f64 * period_s + shift) + "\n")
            .collect()
    };
    fs::write(velodyne.join("timestamps_start.txt"), stamps(0.0))?;
    fs::write(velodyne.join("timestamps.txt"), stamps(period_s / 2.0))?;
    fs::write(velodyne.join("timestamps_end.txt"), stamps(period_s))?;
    // The true poses at the scans' stamps, mid-sweep, relative to the first.
    let mid = |i: usize| drive.pose_after(i, period_s / 2.0);
    let first = mid(0).inverse();
    let mut poses = BufWriter::new(File::create(out.join("poses.txt"))?);
    for i in 0..drive.poses.len() {
        write_scan(drive, i, false, &velodyne.join("data"), None)?;
        let name = velodyne.join("data").join(format!("{i:06}.bin"));
        fs::rename(&name, velodyne.join("data").join(format!("{i:010}.bin")))?;
        write_kitti_line(&mut poses, &(first * mid(i)))?;
    }
    fs::write(out.join("calib.txt"), "Tr: 1 0 0 0 0 1 0 0 0 0 1 0\n")?;
    poses.flush()?;
    if drive.imu.is_some() {
        let end = drive.poses.len() as f64 * period_s;
        let readings = drive.imu_between(-1.0, end);
        let data = out.join("oxts").join("data");
        fs::create_dir_all(&data)?;
        let mut times = String::new();
        for (k, r) in readings.iter().enumerate() {
            fs::write(
                data.join(format!("{k:010}.txt")),
                oxts::encode_packet(r.gyro, r.accel),
            )?;
            times += &(oxts::format_time(RAW_EPOCH_S + r.stamp) + "\n");
        }
        fs::write(out.join("oxts").join("timestamps.txt"), times)?;
        fs::remove_dir_all(out.join("imu0"))?;
    }
    println!(
        "{} frames in KITTI raw's layout in {}",
        drive.poses.len(),
        out.display()
    );
    Ok(())
}

/// `drive` with a rolling sweep (`--rolling`), a rough road's shake (`--shaken`, a rolling
/// sweep too) and an IMU (`--imu HZ`, whose readings it writes into `out/imu0/data.csv`).
fn with_motion(
    flags: &Flags,
    mut drive: Drive,
    period_s: f64,
    seed: u64,
    out: &Path,
) -> Result<Drive, Error> {
    let shaken = flags.has("--shaken");
    if shaken || flags.has("--rolling") {
        drive.sweep_s = Some(period_s);
    }
    if shaken {
        drive = drive.shaken(Vibration::rough_road());
    }
    if let Some(hz) = flags.value("--imu") {
        let hz: f64 = hz
            .parse()
            .map_err(|_| format!("--imu {hz}: not a rate in Hz"))?;
        drive = drive.with_imu(ImuModel::mems(hz, seed));
        let end = drive.poses.len() as f64 * period_s;
        fs::create_dir_all(out.join("imu0"))?;
        let csv = imu_csv::encode(&drive.imu_between(-1.0, end));
        fs::write(out.join("imu0").join("data.csv"), csv)?;
    }
    Ok(drive)
}

/// Frame `i` of `drive` into `dir`: a binary PCD with each point's time (`timed`: a rolling
/// sweep's, unless `--untimed`), else a KITTI `.bin`; each point's truth into `labels` as
/// SemanticKITTI's `.label` (a little-endian `u32` a point).
fn write_scan(
    drive: &Drive,
    i: usize,
    timed: bool,
    dir: &Path,
    labels_dir: Option<&Path>,
) -> Result<(), Error> {
    let (points, times, labels) = drive.scan_labelled(i);
    if timed {
        let file = pcd::encode_pcd_timed(&points, &times);
        fs::write(dir.join(format!("{i:06}.pcd")), file)?;
    } else {
        let mut bin = Vec::new();
        for p in points {
            for v in [p[0], p[1], p[2], 0.0] {
                bin.extend_from_slice(&v.to_le_bytes());
            }
        }
        fs::write(dir.join(format!("{i:06}.bin")), bin)?;
    }
    if let Some(labels_dir) = labels_dir {
        let bytes: Vec<u8> = labels
            .iter()
            .flat_map(|l| l.semantic_kitti().to_le_bytes())
            .collect();
        fs::write(labels_dir.join(format!("{i:06}.label")), bytes)?;
    }
    Ok(())
}

/// `drive` with `--movers`: [`TrafficCounts::TOWN`]'s cars, people and parked cars that
/// leave, along the drive's own path.
fn with_traffic(flags: &Flags, drive: Drive, seed: u64) -> Drive {
    if !flags.has("--movers") {
        return drive;
    }
    let traffic = Traffic::along_poses(&drive.poses, TrafficCounts::TOWN, seed);
    drive.with_traffic(traffic)
}
