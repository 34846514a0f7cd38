//! Whether to deskew again with the estimated motion: a car through the simulated town on
//! rolling sweeps (`Drive::car`, 10 Hz, up to 10 m/s), run three ways with the core alone:
//!
//! - `once`: deskewed with the predicted motion (the last step), registered and fused: what
//!   `slamesh run` does;
//! - `again-fuse`: registered as `once`, then deskewed again with the motion from the previous
//!   estimate to this one, and fused at the same pose;
//! - `again-register`: deskewed again likewise, and registered again before fusing (two
//!   registrations a frame).
//!
//! Prints the mean frame-to-frame error against the true poses at the middle of each sweep
//! (the time the deskewed points refer to).
//!
//! `cargo run --release --example deskew_again -- [FRAMES]`

use slamesh_core::deskew::deskew;
use slamesh_core::math::{se3_exp, se3_log};
use slamesh_core::{KittiCapacity, Pipeline, Pose};
use slamesh_sim::Drive;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let frames: usize = std::env::args().nth(1).map_or(Ok(200), |a| a.parse())?;
    let mut drive = Drive::car(frames + 1, 1);
    drive.sweep_s = Some(0.1);
    let config = slamesh::run::config_file::preset("default").ok_or("no default preset")?;
    // The true pose at the middle of each sweep.
    let truth: Vec<Pose> = (0..frames)
        .map(|i| {
            let step = drive.poses[i].inverse() * drive.poses[i + 1];
            drive.poses[i] * se3_exp(&(se3_log(&step) * 0.5))
        })
        .collect();
    for mode in ["once", "again-fuse", "again-register"] {
        let mut pipeline = Pipeline::<KittiCapacity>::new(config)?;
        let mut estimate: Vec<Pose> = Vec::new();
        for i in 0..frames {
            let (raw, times) = drive.scan_timed(i);
            let (Some(before), Some(last)) = pipeline.motion().history() else {
                estimate.push(pipeline.process_scan(&raw)?.t_world_sensor);
                continue;
            };
            let mut points = raw.clone();
            deskew(&mut points, &times, &(before.inverse() * last), 0.1)
                .map_err(|e| format!("{e:?}"))?;
            if mode == "once" {
                estimate.push(pipeline.process_scan(&points)?.t_world_sensor);
                continue;
            }
            // Register on a copy, then deskew again with the motion the estimate implies.
            let pose = pipeline.clone().process_scan(&points)?.t_world_sensor;
            let mut again = raw;
            deskew(&mut again, &times, &(last.inverse() * pose), 0.1)
                .map_err(|e| format!("{e:?}"))?;
            let fused = if mode == "again-fuse" {
                pipeline.integrate_scan(&again, &pose)?
            } else {
                pipeline.process_scan(&again)?
            };
            estimate.push(fused.t_world_sensor);
        }
        let error: f64 = (1..frames)
            .map(|i| {
                let e = (estimate[i - 1].inverse() * estimate[i]).inverse()
                    * (truth[i - 1].inverse() * truth[i]);
                e.translation.vector.norm()
            })
            .sum::<f64>()
            / (frames - 1) as f64;
        println!("{mode:<15} mean step error {:.3} cm", error * 100.0);
    }
    Ok(())
}
