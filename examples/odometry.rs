//! Runs the core pipeline over KITTI sequences and prints consecutive-frame errors.
//!
//! `cargo run --release --example odometry -- [--threads N] [--steps] [--scalar f32] ../shared/data/kitti-mini/00 [more]`
//!
//! Without `--threads` the core's serial loop runs; with it, the rayon loop on N threads.
//! `--steps` also prints, per step, the reference step length and the step's error.
//! `--scalar f32` runs the single-precision reconstruction (`Pipeline<_, f32>`, the
//! firmware's) instead of `f64`.

use slamesh::eval::odometry::consecutive_errors;
use slamesh::formats::kitti;
use slamesh::parallel::Rayon;
use slamesh::sources::scans::ScanFolder;
use slamesh_core::pipeline::{Known, Scan};
use slamesh_core::{Config, KittiCapacity, NoProbe, Pipeline, Pose, Real};
use std::path::Path;
use std::time::Instant;

/// The poses of a sequence and each scan's milliseconds, with the scalar `R`.
fn track<R: Real>(
    dir: &Path,
    rayon: Option<&Rayon>,
) -> Result<(Vec<Pose>, Vec<f64>), Box<dyn std::error::Error>> {
    let mut pipeline = Pipeline::<KittiCapacity, R>::new(Config::kitti())?;
    let mut poses = Vec::new();
    let mut ms = Vec::new();
    for path in ScanFolder::open(dir)?.paths {
        let scan = kitti::read_bin(&path)?;
        let start = Instant::now();
        let out = match rayon {
            Some(r) => pipeline
                .step(Scan::Raw(&scan), Known::Nothing, r, &mut NoProbe)?
                .into_outcome(),
            None => pipeline.process_scan(&scan)?,
        };
        ms.push(start.elapsed().as_secs_f64() * 1e3);
        if std::env::var_os("VERBOSE").is_some() {
            eprintln!(
                "{:?} {:?} cells {} layers {} residuals {} pairs {} lm {} cond {:.2e}",
                path.file_name().unwrap_or_default(),
                out.status,
                out.stats.bucket.cells,
                out.stats.scan_layers,
                out.stats.associate.residuals,
                out.stats.associate.pairs,
                out.stats.lm_iterations,
                out.stats.conditioning
            );
        }
        poses.push(out.t_world_sensor);
    }
    Ok((poses, ms))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut dirs: Vec<String> = std::env::args().skip(1).collect();
    let steps = dirs.iter().any(|a| a == "--steps");
    dirs.retain(|a| a != "--steps");
    let single = match dirs.iter().position(|a| a == "--scalar") {
        Some(i) if i + 1 < dirs.len() => {
            let single = match dirs[i + 1].as_str() {
                "f32" => true,
                "f64" => false,
                other => return Err(format!("--scalar {other}: f32 or f64").into()),
            };
            dirs.drain(i..i + 2);
            single
        }
        _ => false,
    };
    let threads = match dirs.iter().position(|a| a == "--threads") {
        Some(i) if i + 1 < dirs.len() => {
            let n: usize = dirs[i + 1].parse()?;
            dirs.drain(i..i + 2);
            Some(n)
        }
        _ => None,
    };
    if dirs.is_empty() {
        eprintln!(
            "usage: odometry [--threads N] [--steps] [--scalar f32|f64] <KITTI sequence folder>..."
        );
        std::process::exit(2);
    }
    let rayon = threads.map(Rayon::new).transpose()?;
    let (mut t_all, mut r_all) = (0.0, 0.0);
    println!(
        "{:<28} {:>8} {:>8} {:>9} {:>10}",
        "sequence", "t [cm]", "max [cm]", "r [deg]", "ms/scan"
    );
    for dir in &dirs {
        let dir = Path::new(dir);
        let reference = kitti::reference_lidar_poses(dir)?;
        let (poses, mut ms) = if single {
            track::<f32>(dir, rayon.as_ref())?
        } else {
            track::<f64>(dir, rayon.as_ref())?
        };
        let e = consecutive_errors(&poses, &reference);
        if steps {
            for i in 1..poses.len().min(reference.len()) {
                let length = (reference[i - 1].inverse() * reference[i])
                    .translation
                    .vector
                    .norm();
                let step = consecutive_errors(&poses[i - 1..=i], &reference[i - 1..=i]);
                println!(
                    "  step {i}: reference {length:.3} m, error {:.2} cm",
                    step.mean_translation_m * 100.0
                );
            }
        }
        ms.sort_by(f64::total_cmp);
        println!(
            "{:<28} {:>8.2} {:>8.2} {:>9.4} {:>10.1}",
            dir.display(),
            e.mean_translation_m * 100.0,
            e.max_translation_m * 100.0,
            e.mean_rotation_deg,
            ms[ms.len() / 2]
        );
        t_all += e.mean_translation_m;
        r_all += e.mean_rotation_deg;
    }
    let n = dirs.len() as f64;
    println!(
        "{:<28} {:>8.2} {:>8} {:>9.4}",
        "mean",
        t_all / n * 100.0,
        "",
        r_all / n
    );
    Ok(())
}
