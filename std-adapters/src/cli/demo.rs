//! `slamesh demo`: a simulated drive through a procedural town, SLAM on it, and its accuracy
//! against the truth.

use crate::cli::error::CliError;
use crate::cli::notices::FrameNotices;
use crate::cli::progress;
use crate::cli::run::CapacityFlag;
use crate::cli::settings::{Profile, WindowFlags};
use crate::cli::terminal::{frame_messages, print_summary};
use crate::demo::run_demo;
use crate::outputs::mesh_spool::MeshFormat;
use crate::run::capacity;
use crate::run::RunOptions;
use crate::say;
use clap::Args;
use slamesh_sim::Drive;
use std::path::PathBuf;

/// `slamesh demo`'s arguments.
#[derive(Args, Debug)]
pub struct DemoArgs {
    /// Output folder.
    #[arg(long, default_value = "demo-out")]
    pub out: PathBuf,
    /// Frames to drive (10 a second; the loop is about 1 200 frames, 1.1 km).
    #[arg(long, default_value_t = 300)]
    pub frames: usize,
    /// The preset (town, the default here: meshing with 1.4 m cells, the better mesh and
    /// odometry in the town) or a configuration file.
    #[command(flatten)]
    pub profile: Profile,
    /// Reconstruction threads (1: serial; 0: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Seed of the town and the sensor noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The sliding window, as for `run`.
    #[command(flatten)]
    pub window: WindowFlags,
    /// The capacity class, as for `run` (auto: the smallest for the first scan).
    #[arg(long, value_enum, default_value_t = CapacityFlag::Auto)]
    pub capacity: CapacityFlag,
}

/// Drives, runs SLAM, writes the outputs and prints the accuracy.
pub fn demo(args: &DemoArgs, quiet: bool) -> Result<(), CliError> {
    let (out, frames, seed) = (&args.out, args.frames, args.seed);
    let mut s = args.profile.resolve("town")?;
    args.window.apply(&mut s.window)?;
    let opts = RunOptions {
        out: out.clone(),
        config: s.config,
        preset: s.preset.to_string(),
        window: s.window,
        threads: args.threads,
        mesh_formats: vec![MeshFormat::Ply],
        given_poses: None,
        input: format!("simulated town, seed {seed}, {frames} frames"),
        ..RunOptions::default()
    };
    log::info!(
        "demo: simulating {frames} frames through a procedural town (seed {seed}), output in {}",
        out.display()
    );
    let bar = progress(frames, quiet);
    let mut notices = FrameNotices::default();
    let on_frame = |rec: &_| {
        frame_messages(rec, &bar, &mut notices);
        bar.set_message(format!("{} ms", rec.ms.total.round()));
        bar.inc(1);
    };
    let class = args
        .capacity
        .class()
        .unwrap_or_else(|| capacity::choose(&mut Drive::town(frames.min(10), seed), &opts).id);
    let r = crate::with_capacity!(class, C => run_demo::<C>(frames, seed, &opts, on_frame))?;
    bar.finish_and_clear();
    notices.finish();
    print_summary(&r.summary, out);
    say!(
        "demo: {} frames, {:.0} m; consecutive error {:.2} cm (worst {:.2} cm), {:.4} deg",
        r.frames,
        r.path_m,
        r.consecutive.mean_translation_m * 100.0,
        r.consecutive.max_translation_m * 100.0,
        r.consecutive.mean_rotation_deg
    );
    say!(
        "demo: end-point error {:.2} m ({:.2} % of the path), ATE {:.2} m",
        r.end_drift.0,
        r.end_drift.1,
        r.ate_m
    );
    for s in &r.segments {
        say!(
            "demo: {:.0} m segments: {:.2} % translation, {:.3} deg/100 m ({} segments)",
            s.length_m,
            s.translation_percent,
            s.rotation_deg_per_100m,
            s.segments
        );
    }
    for m in &r.mesh {
        say!(
            "demo: mesh at {:.1} m: precision {:.3}, recall {:.3}, F1 {:.3}",
            m.threshold_m,
            m.precision,
            m.recall,
            m.f1
        );
    }
    say!(
        "demo: wrote {0}/topview.png and {0}/poses_true_kitti.txt",
        out.display()
    );
    Ok(())
}
