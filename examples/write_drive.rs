//! Writes the demo's simulated town drive as a KITTI odometry sequence, so that other tools
//! can run on the same scans: `velodyne/NNNNNN.bin` (x, y, z and a zero intensity, f32), the
//! true poses in `poses.txt` (relative to the first), `times.txt` (10 Hz) and a `calib.txt`
//! whose `Tr` is the identity (the poses are the sensor's). Used for KISS-ICP side by side
//! (`tools/kiss_icp_compare.py DIR --sequence --no-kitti-correction`, docs/benchmarks.md).
//!
//! `cargo run --release --example write_drive -- --out DIR [--frames N] [--seed S]`
//! (1 000 frames, seed 1 by default).

#[path = "common/flags.rs"]
mod flags;

use flags::Flags;
use slamesh::io::trajectory::write_kitti_line;
use slamesh_sim::Drive;
use std::fs::{self, File};
use std::io::{BufWriter, Write};
use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let flags = Flags::from_env();
    let out = PathBuf::from(flags.value("--out").ok_or("--out DIR is required")?);
    let frames: usize = flags.parse_or("--frames", 1000)?;
    let seed: u64 = flags.parse_or("--seed", 1)?;
    let drive = Drive::town(frames, seed);
    fs::create_dir_all(out.join("velodyne"))?;
    let mut poses = BufWriter::new(File::create(out.join("poses.txt"))?);
    let mut times = BufWriter::new(File::create(out.join("times.txt"))?);
    let first = drive.poses[0].inverse();
    for i in 0..drive.poses.len() {
        let mut bin = Vec::new();
        for p in drive.scan(i) {
            for v in [p[0], p[1], p[2], 0.0] {
                bin.extend_from_slice(&v.to_le_bytes());
            }
        }
        fs::write(out.join("velodyne").join(format!("{i:06}.bin")), bin)?;
        write_kitti_line(&mut poses, &(first * drive.poses[i]))?;
        writeln!(times, "{:.6}", i as f64 * 0.1)?;
    }
    poses.flush()?;
    times.flush()?;
    fs::write(out.join("calib.txt"), "Tr: 1 0 0 0 0 1 0 0 0 0 1 0\n")?;
    println!(
        "{} frames of the town (seed {seed}) in {}",
        drive.poses.len(),
        out.display()
    );
    Ok(())
}
