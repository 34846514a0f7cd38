//! What counting the scans' floor costs a frame (`navmap/hits.rs`, `run --navmap`): reads a
//! KITTI folder's scans with their poses (`poses.txt`, the sensor's: `write_drive` writes
//! such a folder) and counts each scan's floor, on one thread and on a pool of `--threads`,
//! timing each count. Both countings must give the same floors. Prints the median
//! milliseconds a scan.
//!
//! `cargo run --release --example floor_cost -- --scans DIR [--frames 50] [--threads 2]`

#[path = "common/flags.rs"]
mod flags;

use flags::Flags;
use nalgebra::Vector3;
use slamesh::formats::kitti::read_bin;
use slamesh::formats::trajectory::read_kitti;
use slamesh::navmap::hits::Hits;
use slamesh::parallel::Workers;
use slamesh_core::executor::Serial;
use std::path::PathBuf;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let flags = Flags::from_env();
    let folder = PathBuf::from(flags.value("--scans").ok_or("--scans DIR is required")?);
    let frames: usize = flags.parse_or("--frames", 50)?;
    let threads: usize = flags.parse_or("--threads", 2)?;
    let poses = read_kitti(&folder.join("poses.txt"))?;
    let pool = Workers::new(threads)?;
    let (mut serial, mut spread) = (Hits::new(0.1, &Vector3::z()), Hits::new(0.1, &Vector3::z()));
    let (mut one, mut many) = (Vec::new(), Vec::new());
    let mut points_seen = 0;
    for (i, pose) in poses.iter().enumerate().take(frames) {
        let points = read_bin(&folder.join(format!("velodyne/{i:06}.bin")))?;
        points_seen += points.len();
        let t = Instant::now();
        serial.add(i, pose, pose, &points, &Serial);
        one.push(t.elapsed().as_secs_f64() * 1e3);
        let t = Instant::now();
        spread.add(i, pose, pose, &points, &pool);
        many.push(t.elapsed().as_secs_f64() * 1e3);
    }
    let floors = |hits: &Hits| {
        let mut all = Vec::new();
        hits.each_floor(&|_| None, &mut |f| all.push((f.at, f.twice)));
        all
    };
    if floors(&serial) != floors(&spread) {
        return Err("the pool counted other floors than one thread".into());
    }
    println!(
        "{} scans of {} ({} points a scan): counting the floor took a median {:.2} ms a scan \
         on one thread, {:.2} ms on {} threads",
        one.len(),
        folder.display(),
        points_seen / one.len().max(1),
        median(&mut one),
        median(&mut many),
        pool.threads()
    );
    Ok(())
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}
