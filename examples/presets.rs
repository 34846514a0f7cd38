//! Presets side by side on every simulated set: the office walk (16 beams, 1 to 15 m, 10 Hz),
//! the hand-held and drone drives (32 beams, 2 Hz, through streets and a hall) and the town's
//! car drive (64 beams, 10 Hz). Per set and preset: steps within 5 cm and 0.5 degree, the mean
//! consecutive-frame error, the ATE and the median ms a frame. `auto` is a preset fitted to
//! the first scan's scale (`slamesh::run::scale`), as the command's default preset is.
//!
//! `cargo run --release --example presets -- [--frames N] [--presets a,b,...] [--sets a,b,...]
//! [--seed S]` (sets: office, hand-held, drone, car; N scans each, 300 by default, 120 for the
//! 2 Hz ones; the scenes and the scans' noise from seed S, 1 by default).

#[path = "common/flags.rs"]
mod flags;

use flags::Flags;
use slamesh::eval::odometry::{ate_rmse, consecutive_errors};
use slamesh::parallel::Workers;
use slamesh::run::config_file;
use slamesh::run::scale;
use slamesh_core::pipeline::{Known, Scan, Stepped};
use slamesh_core::{Config, KittiCapacity, NoProbe, Pipeline, Pose};
use slamesh_sim::town::Carried;
use slamesh_sim::Drive;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let flags = Flags::from_env();
    let frames: usize = flags.parse_or("--frames", 300)?;
    let seed: u64 = flags.parse_or("--seed", 1)?;
    let list = |flag: &str, all: &str| -> Vec<String> {
        flags
            .value(flag)
            .unwrap_or(all)
            .split(',')
            .map(str::to_owned)
            .collect()
    };
    let presets = list("--presets", "fast,default,town");
    let sets = list("--sets", "office,hand-held,drone,car");
    let workers = Workers::new(0)?;
    for set in &sets {
        let drive = match set.as_str() {
            "office" => Drive::office(frames, seed),
            "hand-held" => Drive::carried(frames.min(120), Carried::HANDHELD, seed),
            "drone" => Drive::carried(frames.min(120), Carried::DRONE, seed),
            "car" => Drive::car(frames, seed),
            other => return Err(format!("unknown set {other}").into()),
        };
        let n = drive.poses.len();
        let truth: Vec<Pose> = drive
            .poses
            .iter()
            .map(|p| drive.poses[0].inverse() * p)
            .collect();
        for name in &presets {
            let base: Config = config_file::preset(name).ok_or("unknown preset")?;
            let config = if config_file::scales_itself(name) {
                scale::fit(&base, &drive.scan(0)).map_or(base, |f| f.config)
            } else {
                base
            };
            let mut pipeline = Pipeline::<KittiCapacity>::new(config)?;
            let mut estimate = Vec::with_capacity(n);
            let mut ms = Vec::with_capacity(n);
            for i in 0..n {
                let scan = drive.scan(i);
                let t = Instant::now();
                let pose = match pipeline
                    .step(Scan::Raw(&scan), Known::Nothing, &workers, &mut NoProbe)
                    .map(Stepped::into_outcome)
                {
                    Ok(o) => o.t_world_sensor,
                    Err(_) => *estimate.last().unwrap_or(&Pose::identity()),
                };
                ms.push(t.elapsed().as_secs_f64() * 1e3);
                estimate.push(pose);
            }
            ms.sort_by(f64::total_cmp);
            let tracked = (1..n)
                .filter(|&i| {
                    let step = |p: &[Pose]| p[i - 1].inverse() * p[i];
                    let e = step(&truth).inverse() * step(&estimate);
                    e.translation.vector.norm() <= 0.05 && e.rotation.angle().to_degrees() <= 0.5
                })
                .count();
            let c = consecutive_errors(&estimate, &truth);
            println!(
                "{set:9} {name:8} cell {:.2} m: {tracked} of {} steps tracked; mean step error \
                 {:.2} cm, {:.3} deg; ATE {:.3} m; median {:.1} ms a frame",
                config.grid.cell_size_m,
                n - 1,
                c.mean_translation_m * 100.0,
                c.mean_rotation_deg,
                ate_rmse(&estimate, &truth),
                ms[n / 2]
            );
        }
    }
    Ok(())
}
