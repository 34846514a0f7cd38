//! Rolling sweeps and deskewing: a car driven round the simulated town (10 Hz, up to 10 m/s,
//! with turns; `Drive::car`, whose attitude follows the hills, not the roughness) scanned
//! three ways, each run through the whole command path (`slamesh::run::run`):
//!
//! - `static`: every firing of a scan from the scan's pose (no motion during the sweep);
//! - `rolling`: each firing from the pose at its own time over the 0.1 s sweep, as a real
//!   spinning LiDAR does, not deskewed;
//! - `deskewed`: the same rolling scans, deskewed with the per-point times.
//!
//! Prints, per run, the mean and largest frame-to-frame translation error, the mean rotation
//! error and the 100 m segment error, against the true poses.
//!
//! `cargo run --release --example rolling_sweep -- [--frames N] [--preset NAME] [--seed S] [--town]`

#[path = "common/flags.rs"]
mod flags;

use flags::Flags;
use slamesh::eval::odometry::{consecutive_errors, segment_errors};
use slamesh::formats::trajectory;
use slamesh::run::config_file;
use slamesh::run::session::Deskew;
use slamesh::run::{run, RunOptions};
use slamesh_core::{KittiCapacity, Pose};
use slamesh_sim::Drive;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let flags = Flags::from_env();
    let frames: usize = flags.parse_or("--frames", 300)?;
    let seed: u64 = flags.parse_or("--seed", 1)?;
    let preset = flags.value("--preset").unwrap_or("default");
    let config = config_file::preset(preset).ok_or("unknown preset")?;
    // `--town`: the town drive's own attitude, which jitters with the road's roughness.
    let town = flags.has("--town");
    let what = if town { "town drive" } else { "car drive" };
    println!("{what}, {frames} frames, preset {preset}, seed {seed}");
    println!("run       mean step cm  worst cm  mean rot deg  100 m segment %");
    for (name, sweep, deskew) in [
        ("static", None, Deskew::Off),
        ("rolling", Some(0.1), Deskew::Off),
        ("deskewed", Some(0.1), Deskew::Auto),
    ] {
        let mut drive = match town {
            true => Drive::town(frames, seed),
            false => Drive::car(frames, seed),
        };
        drive.sweep_s = sweep;
        let out =
            std::env::temp_dir().join(format!("slamesh-rolling-{name}-{}", std::process::id()));
        let opts = RunOptions {
            out: out.clone(),
            config,
            preset: preset.into(),
            threads: 0,
            input: format!("simulated town, {name}"),
            deskew,
            ..RunOptions::default()
        };
        run::<KittiCapacity>(&mut drive, &opts, |_| {})?;
        let estimate = trajectory::read_kitti(&out.join("poses_kitti.txt"))?;
        std::fs::remove_dir_all(&out)?;
        let truth: Vec<Pose> = drive
            .poses
            .iter()
            .map(|p| drive.poses[0].inverse() * p)
            .collect();
        let e = consecutive_errors(&estimate, &truth);
        let seg = segment_errors(&estimate, &truth, &[100.0]);
        let seg = seg.first().map_or(f64::NAN, |s| s.translation_percent);
        println!(
            "{name:<9} {:>12.3} {:>9.2} {:>13.4} {:>16.3}",
            e.mean_translation_m * 100.0,
            e.max_translation_m * 100.0,
            e.mean_rotation_deg,
            seg
        );
    }
    Ok(())
}
