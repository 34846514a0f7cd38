//! How well the scans' azimuth profiles find the turn between two scans (docs/design.md §1.11,
//! `core/src/azimuth.rs`), against a trajectory taken as the truth, next to the constant-
//! velocity prediction's turn from the same trajectory.
//!
//! Reads a KITTI-style folder (`DIR/velodyne/*.bin`, float32 x, y, z, intensity, in name
//! order) and a trajectory of sensor poses in KITTI's row format (a run's `poses_kitti.txt`,
//! or a written drive's `poses.txt`), and prints the median, 90th percentile and largest
//! error of each turn about the sensor's vertical, and the frames the profiles got wrong by
//! more than 5 degrees:
//!
//! `cargo run --release --example azimuth_turns -- DIR POSES`

use slamesh_core::azimuth::AzimuthProfile;
use slamesh_core::math::{pose_from_row, wrapped_angle};
use slamesh_core::{Point, Pose};
use std::path::{Path, PathBuf};

/// The turn about the sensor's vertical of a relative pose: where it takes the `x` axis.
fn yaw(p: &Pose) -> f64 {
    let x = p.rotation * nalgebra::Vector3::x();
    x.y.atan2(x.x)
}

fn read_bin(path: &Path) -> std::io::Result<Vec<Point>> {
    let bytes = std::fs::read(path)?;
    Ok(bytes
        .chunks_exact(16)
        .map(|c| {
            let f =
                |k: usize| f32::from_le_bytes([c[4 * k], c[4 * k + 1], c[4 * k + 2], c[4 * k + 3]]);
            [f(0), f(1), f(2)]
        })
        .collect())
}

fn quantiles(mut v: Vec<f64>) -> String {
    v.sort_by(f64::total_cmp);
    let q = |f: f64| v[((v.len() - 1) as f64 * f).round() as usize];
    format!(
        "median {:.2}, 90th percentile {:.2}, largest {:.2} degrees",
        q(0.5),
        q(0.9),
        q(1.0)
    )
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let [_, dir, poses] = &args[..] else {
        return Err("usage: azimuth_turns DIR POSES".into());
    };
    let poses: Vec<Pose> = std::fs::read_to_string(poses)?
        .lines()
        .map(|l| {
            let row: Vec<f64> = l
                .split_whitespace()
                .filter_map(|x| x.parse().ok())
                .collect();
            pose_from_row(&row).ok_or(format!("{poses}: a line is not a pose: {l}"))
        })
        .collect::<Result<_, _>>()?;
    let mut files: Vec<PathBuf> = std::fs::read_dir(Path::new(dir).join("velodyne"))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "bin"))
        .collect();
    files.sort();
    let (mut by_profile, mut by_prediction) = (Vec::new(), Vec::new());
    let mut earlier: Option<AzimuthProfile> = None;
    for (i, file) in files.iter().enumerate().take(poses.len()) {
        // The pipeline's range filter, roughly: the profile reads the filtered scan.
        let points: Vec<Point> = read_bin(file)?
            .into_iter()
            .filter(|p| (1.0..100.0).contains(&(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt()))
            .collect();
        let now = AzimuthProfile::of(&points);
        if let Some(e) = earlier {
            let truth = yaw(&(poses[i - 1].inverse() * poses[i]));
            let predicted = if i >= 2 {
                yaw(&(poses[i - 2].inverse() * poses[i - 1]))
            } else {
                0.0
            };
            match now.turn_from(&e, std::f64::consts::PI) {
                Some(t) => {
                    let err = wrapped_angle(t.yaw - truth).to_degrees();
                    if err.abs() > 5.0 {
                        println!(
                            "frame {i}: turn {:.1}, profiles {:.1}, prediction {:.1} degrees",
                            truth.to_degrees(),
                            t.yaw.to_degrees(),
                            predicted.to_degrees()
                        );
                    }
                    by_profile.push(err.abs());
                    by_prediction.push(wrapped_angle(predicted - truth).to_degrees().abs());
                }
                None => println!("frame {i}: the profiles share too few sectors"),
            }
        }
        earlier = Some(now);
    }
    if by_profile.is_empty() {
        return Err("fewer than two scans with profiles".into());
    }
    println!(
        "{} turns; the profiles' error: {}",
        by_profile.len(),
        quantiles(by_profile)
    );
    println!(
        "the constant-velocity prediction's error: {}",
        quantiles(by_prediction)
    );
    Ok(())
}
