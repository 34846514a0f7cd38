//! A long simulated drive through the run machinery, reporting resident memory as it goes:
//! the memory figures of the README.
//!
//! `cargo run --release --example long_run -- --frames 5000 [--evict-after N] [--memory-cap MB]
//!  [--threads N] [--every K]`
//!
//! Drives [`Drive::long_street`] (1 m a frame, 64-beam scans with 2 cm noise) through
//! `slamesh::run::run` with the default preset, printing every K frames (default 500) the frame,
//! the map's cells and layers, the current and the peak resident memory, and at the end the
//! summary. Outputs go to a temporary folder, removed afterwards.

#[path = "common/flags.rs"]
mod flags;

use flags::Flags;
use slamesh::outputs::mesh_spool::MeshFormat;
use slamesh::run::config_file::WindowSettings;
use slamesh::run::{memory, FrameSource};
use slamesh::run::{run, RunOptions};
use slamesh_core::{Config, KittiCapacity};
use slamesh_sim::Drive;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let flags = Flags::from_env();
    let frames: usize = flags.parse_or("--frames", 1000)?;
    let every: usize = flags.parse_or("--every", 500)?;
    let threads: usize = flags.parse_or("--threads", 0)?;
    let window = WindowSettings {
        max_age_frames: flags.value("--evict-after").map(str::parse).transpose()?,
        memory_cap_mb: flags.value("--memory-cap").map(str::parse).transpose()?,
        ..WindowSettings::default()
    };
    let mut drive = Drive::long_street(frames, 1.0, 7);
    let out = std::env::temp_dir().join(format!("slamesh-long-run-{}", std::process::id()));
    let opts = RunOptions {
        out: out.clone(),
        config: Config::default(),
        preset: "default".into(),
        window,
        threads,
        mesh_formats: vec![MeshFormat::Ply],
        given_poses: None,
        input: format!("simulated long street, {frames} frames"),
        ..RunOptions::default()
    };
    println!(
        "{:>7} {:>9} {:>9} {:>8} {:>9}",
        "frame", "cells", "layers", "RSS MB", "peak MB"
    );
    let mut statuses = std::collections::BTreeMap::<String, usize>::new();
    let summary = run::<KittiCapacity>(&mut drive, &opts, |rec| {
        *statuses.entry(rec.status.to_string()).or_default() += 1;
        if (rec.frame + 1) % every == 0 {
            println!(
                "{:>7} {:>9} {:>9} {:>8.0} {:>9.0}",
                rec.frame + 1,
                rec.map_cells,
                rec.map_layers,
                rec.rss_mb.unwrap_or(f64::NAN),
                memory::peak_rss_bytes().map_or(f64::NAN, memory::mb)
            );
        }
    })?;
    let truth = &drive.poses;
    let end = summary.poses.last().map(|(i, p)| {
        let t = truth[0].inverse() * truth[*i];
        (p.translation.vector - t.translation.vector).norm()
    });
    println!(
        "{} frames, {} used, {:.1} Hz, median {:.1} ms; peak RSS {:.0} MB; evicted {} cells; \
         mesh {} triangles; end-point error {:.2} m over {:.0} m",
        drive.frames(),
        summary.used,
        summary.hz,
        summary
            .stage_ms
            .iter()
            .find(|(n, _)| n == "total")
            .map_or(0.0, |(_, s)| s.median),
        summary.peak_rss_mb.unwrap_or(f64::NAN),
        summary.evicted_cells,
        summary.mesh_triangles,
        end.unwrap_or(f64::NAN),
        (frames.saturating_sub(1)) as f64,
    );
    println!("frames by status: {statuses:?}");
    std::fs::remove_dir_all(&out)?;
    Ok(())
}
