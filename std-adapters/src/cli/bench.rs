//! `slamesh bench`: the pipeline timed stage by stage over a folder of scans.

use crate::cli::error::CliError;
use crate::cli::input::InputArgs;
use crate::cli::settings::Profile;
use crate::say;
use clap::Args;
use slamesh::io::config_file::WindowSettings;
use slamesh::run::report::spreads;
use slamesh::run::timing::StageMs;
use slamesh::run::{run, RunOptions};
use slamesh_core::KittiCapacity;

/// `slamesh bench`'s arguments.
#[derive(Args, Debug)]
pub struct BenchArgs {
    /// The input and how to read it, as for `run`.
    #[command(flatten)]
    pub source: InputArgs,
    /// The preset or configuration file (its [window] section is not used: bench times the
    /// pipeline without eviction).
    #[command(flatten)]
    pub profile: Profile,
    /// Reconstruction threads (1: serial; 0: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Timed passes over the scans.
    #[arg(long, default_value_t = 3)]
    pub repeat: usize,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// A warm-up pass, then `repeat` timed passes: per-stage median and 95th percentile.
pub fn bench(args: &BenchArgs) -> Result<(), CliError> {
    let (input, threads, repeat, json) = (&args.source.input, args.threads, args.repeat, args.json);
    let mut s = args.profile.resolve("default")?;
    let mut source = args.source.open()?;
    crate::cli::settings::fit_to_scene(&mut s, &mut source);
    let (config, preset) = (s.config, s.preset);
    let out = std::env::temp_dir().join(format!("slamesh-bench-{}", std::process::id()));
    let opts = RunOptions {
        out: out.clone(),
        config,
        preset: preset.to_string(),
        window: WindowSettings::default(),
        threads,
        mesh_formats: Vec::new(),
        given_poses: None,
        input: input.display().to_string(),
        ..RunOptions::default()
    };
    let mut timed: Vec<StageMs> = Vec::new();
    let mut last = None;
    for pass in 0..=repeat.max(1) {
        let summary = run::<KittiCapacity>(&mut source, &opts, |rec| {
            if pass > 0 && rec.error.is_none() {
                timed.push(rec.ms);
            }
        })?;
        last = Some(summary);
    }
    let _ = std::fs::remove_dir_all(&out);
    let summary = last.ok_or(CliError::NoFrameUsed)?;
    let stages = spreads(&timed);
    let total = stages
        .iter()
        .find(|(n, _)| n == "total")
        .map_or(0.0, |(_, s)| s.median);
    let peak = summary.peak_rss_mb;
    if json {
        let stage_json: serde_json::Map<String, serde_json::Value> = stages
            .iter()
            .map(|(n, s)| {
                (
                    n.clone(),
                    serde_json::json!({"median_ms": s.median, "p95_ms": s.p95}),
                )
            })
            .collect();
        say!(
            "{}",
            serde_json::json!({
                "input": input.display().to_string(),
                "preset": preset,
                "threads": summary.threads,
                "scans_timed": timed.len(),
                "stages": stage_json,
                "hz": 1000.0 / total.max(1e-9),
                "peak_rss_mb": peak,
            })
        );
    } else {
        say!(
            "{} scans timed ({} passes after a warm-up), preset {}, {} thread(s)",
            timed.len(),
            repeat.max(1),
            preset,
            summary.threads
        );
        say!("{:<12} {:>10} {:>10}", "stage", "median ms", "p95 ms");
        for (name, s) in &stages {
            say!("{:<12} {:>10.2} {:>10.2}", name, s.median, s.p95);
        }
        say!(
            "{:.1} scans/s at the median total; peak memory {}",
            1000.0 / total.max(1e-9),
            peak.map_or("unknown".into(), |m| format!("{m:.0} MB"))
        );
    }
    Ok(())
}
