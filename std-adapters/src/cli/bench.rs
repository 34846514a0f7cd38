//! `slamesh bench`: the pipeline timed stage by stage over a folder of scans, the cost of each
//! registration outcome (a hard motion's price), and with `--scaling` how the time scales
//! with the threads, from one to every core.

use crate::cli::error::CliError;
use crate::cli::input::InputArgs;
use crate::cli::settings::Profile;
use crate::run::config_file::WindowSettings;
use crate::run::report::{cost_by_outcome, spreads, FrameRecord, OutcomeCost, Summary};
use crate::run::timing::StageMs;
use crate::run::{run, RunOptions};
use crate::say;
use clap::Args;
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
    /// Time the scans on 1, 2, 4, ... threads up to every core, and say how the time scales
    /// (instead of one --threads).
    #[arg(long, conflicts_with = "threads")]
    pub scaling: bool,
}

/// A warm-up pass, then `repeat` timed passes: each used frame's stage times and its record,
/// and the last pass's summary.
type Timed = (Vec<StageMs>, Vec<FrameRecord>, Summary);

fn time_passes(
    source: &mut crate::run::Input,
    opts: &RunOptions,
    repeat: usize,
) -> Result<Timed, CliError> {
    let (mut timed, mut outcomes) = (Vec::new(), Vec::new());
    let mut last = None;
    for pass in 0..=repeat.max(1) {
        let summary = run::<KittiCapacity>(source, opts, |rec| {
            if pass > 0 && rec.error.is_none() {
                timed.push(rec.ms);
                outcomes.push(rec.clone());
            }
        })?;
        last = Some(summary);
    }
    let _ = std::fs::remove_dir_all(&opts.out);
    Ok((timed, outcomes, last.ok_or(CliError::NoFrameUsed)?))
}

/// The thread counts `--scaling` times: 1, 2, 4, ... and every core.
fn thread_counts() -> Vec<usize> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut n: Vec<usize> = std::iter::successors(Some(1usize), |k| Some(k * 2))
        .take_while(|k| *k < cores)
        .collect();
    n.push(cores);
    n
}

/// A warm-up pass, then `repeat` timed passes: per-stage median and 95th percentile.
pub fn bench(args: &BenchArgs) -> Result<(), CliError> {
    let (input, threads, repeat, json) = (&args.source.input, args.threads, args.repeat, args.json);
    let mut s = args.profile.resolve("default")?;
    let mut source = args.source.open()?;
    crate::run::scale::fit_to_scene(&mut s, &mut source);
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
    if args.scaling {
        return scaling(&mut source, &opts, repeat, json);
    }
    let (timed, outcomes, summary) = time_passes(&mut source, &opts, repeat)?;
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
                "outcomes": cost_by_outcome(&outcomes),
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
        say_outcomes(&cost_by_outcome(&outcomes));
    }
    Ok(())
}

/// Each registration outcome's cost a frame, as a table.
fn say_outcomes(costs: &[OutcomeCost]) {
    say!(
        "{:<14} {:>7} {:>10} {:>10} {:>7} {:>7}",
        "outcome",
        "frames",
        "median ms",
        "p95 ms",
        "rounds",
        "guesses"
    );
    for o in costs {
        say!(
            "{:<14} {:>7} {:>10.2} {:>10.2} {:>7.1} {:>7.1}",
            o.status,
            o.frames,
            o.median_ms,
            o.p95_ms,
            o.rounds,
            o.recovery_attempts
        );
    }
}

/// `--scaling`: the same passes on each of [`thread_counts`], the median whole frame's time
/// and the speed against one thread.
fn scaling(
    source: &mut crate::run::Input,
    opts: &RunOptions,
    repeat: usize,
    json: bool,
) -> Result<(), CliError> {
    let mut rows = Vec::new();
    for threads in thread_counts() {
        let opts = RunOptions {
            threads,
            ..opts.clone()
        };
        let (timed, _, summary) = time_passes(source, &opts, repeat)?;
        let total = spreads(&timed)
            .into_iter()
            .find(|(n, _)| n == "total")
            .map_or(0.0, |(_, s)| s.median);
        rows.push((summary.threads, total));
    }
    let one = rows.first().map_or(0.0, |r| r.1);
    if json {
        let rows: Vec<_> = rows
            .iter()
            .map(|(t, ms)| serde_json::json!({"threads": t, "median_ms": ms, "speed_vs_one": one / ms.max(1e-9)}))
            .collect();
        say!(
            "{}",
            serde_json::json!({"input": opts.input, "scaling": rows})
        );
    } else {
        say!("{:>8} {:>10} {:>12}", "threads", "median ms", "speed vs 1");
        for (t, ms) in &rows {
            say!("{:>8} {:>10.2} {:>12.2}", t, ms, one / ms.max(1e-9));
        }
    }
    Ok(())
}
