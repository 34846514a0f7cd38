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
    if let Some(crate::cli::input::SweepArg::Auto) = args.source.sweep {
        return Err(CliError::BadFlag {
            flag: "--sweep",
            reason: "auto is for run, mesh and localize: bench times the sweep it is given".into(),
        });
    }
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

/// `--scaling`: the same passes on each of [`thread_counts`]: each stage's median and the whole
/// frame's, the speed against one thread, and what Amdahl's law projects from the 1- and
/// 2-thread medians ([`Amdahl`]) beside what was measured.
fn scaling(
    source: &mut crate::run::Input,
    opts: &RunOptions,
    repeat: usize,
    json: bool,
) -> Result<(), CliError> {
    let mut rows: Vec<ScalingRow> = Vec::new();
    for threads in thread_counts() {
        let opts = RunOptions {
            threads,
            ..opts.clone()
        };
        let (timed, _, summary) = time_passes(source, &opts, repeat)?;
        let medians = spreads(&timed)
            .into_iter()
            // Reading is shown (its own column, not in `total`); bench runs no window.
            .filter(|(n, _)| n != "evict")
            .map(|(n, s)| (n, s.median))
            .collect();
        rows.push(ScalingRow {
            threads: summary.threads,
            medians,
        });
    }
    let whole = Amdahl::fit(&rows, "total");
    if json {
        say!("{}", scaling_json(&opts.input, &rows, whole.as_ref()));
    } else {
        say_scaling(&rows, whole.as_ref());
    }
    Ok(())
}

/// One thread count's medians (ms) by stage, `total` last.
struct ScalingRow {
    threads: usize,
    medians: Vec<(String, f64)>,
}

impl ScalingRow {
    fn median(&self, stage: &str) -> f64 {
        self.medians
            .iter()
            .find(|(n, _)| n == stage)
            .map_or(0.0, |(_, ms)| *ms)
    }
}

/// Amdahl's law fitted to a stage's 1- and 2-thread medians: the share `serial` of its
/// one-thread time that does not shrink with threads, so that `n` threads would take
/// `t1 * (serial + (1 - serial) / n)`.
struct Amdahl {
    t1: f64,
    serial: f64,
}

impl Amdahl {
    /// The fit of `stage` in `rows`; `None` without both a 1- and a 2-thread row, or when the
    /// stage takes no time.
    fn fit(rows: &[ScalingRow], stage: &str) -> Option<Self> {
        let at = |n: usize| {
            rows.iter()
                .find(|r| r.threads == n)
                .map(|r| r.median(stage))
        };
        let (t1, t2) = (at(1)?, at(2)?);
        (t1 > 0.0).then(|| Amdahl {
            t1,
            serial: (2.0 * t2 / t1 - 1.0).clamp(0.0, 1.0),
        })
    }

    /// The projected speed on `n` threads against one.
    fn speed(&self, n: usize) -> f64 {
        1.0 / (self.serial + (1.0 - self.serial) / n.max(1) as f64)
    }

    /// The milliseconds of the one-thread time that do not shrink.
    fn serial_ms(&self) -> f64 {
        self.t1 * self.serial
    }
}

/// The thread counts a projection is stated for: those measured and up to 16.
fn projected_counts(rows: &[ScalingRow]) -> Vec<usize> {
    let mut n: Vec<usize> = rows.iter().map(|r| r.threads).collect();
    n.extend([4, 8, 16]);
    n.sort_unstable();
    n.dedup();
    n
}

fn say_scaling(rows: &[ScalingRow], whole: Option<&Amdahl>) {
    let Some(first) = rows.first() else { return };
    let names: Vec<&str> = first.medians.iter().map(|(n, _)| n.as_str()).collect();
    let head: String = names.iter().map(|n| format!(" {n:>11}")).collect();
    say!("median ms a frame by stage:");
    say!("{:>8}{head} {:>8}", "threads", "speed");
    let one = first.median("total");
    for r in rows {
        let cells: String = r
            .medians
            .iter()
            .map(|(_, ms)| format!(" {ms:>11.2}"))
            .collect();
        let speed = one / r.median("total").max(1e-9);
        say!("{:>8}{cells} {:>7.2}x", r.threads, speed);
    }
    let fits: Vec<Option<Amdahl>> = names.iter().map(|n| Amdahl::fit(rows, n)).collect();
    let serial: String = fits
        .iter()
        .map(|f| {
            f.as_ref().map_or(format!(" {:>11}", "-"), |f| {
                format!(" {:>11.2}", f.serial_ms())
            })
        })
        .collect();
    say!("{:>8}{serial}", "serial");
    let Some(whole) = whole else { return };
    say!(
        "Amdahl from 1 and 2 threads: {:.0} % of a frame's one-thread time is serial ({:.2} ms, the row above by stage); projected speed:",
        whole.serial * 100.0,
        whole.serial_ms()
    );
    for n in projected_counts(rows) {
        let measured = rows
            .iter()
            .find(|r| r.threads == n)
            .map_or(String::new(), |r| {
                format!(" (measured {:.2}x)", one / r.median("total").max(1e-9))
            });
        say!("{:>8} {:>6.2}x{measured}", n, whole.speed(n));
    }
}

fn scaling_json(input: &str, rows: &[ScalingRow], whole: Option<&Amdahl>) -> serde_json::Value {
    let one = rows.first().map_or(0.0, |r| r.median("total"));
    let measured: Vec<_> = rows
        .iter()
        .map(|r| {
            let stages: serde_json::Map<String, serde_json::Value> = r
                .medians
                .iter()
                .map(|(n, ms)| (n.clone(), (*ms).into()))
                .collect();
            let total = r.median("total");
            serde_json::json!({"threads": r.threads, "median_ms": total,
                "speed_vs_one": one / total.max(1e-9), "stage_median_ms": stages})
        })
        .collect();
    let amdahl = whole.map(|w| {
        let serial_ms: serde_json::Map<String, serde_json::Value> = rows[0]
            .medians
            .iter()
            .filter_map(|(n, _)| Amdahl::fit(rows, n).map(|f| (n.clone(), f.serial_ms().into())))
            .collect();
        let projected: Vec<_> = projected_counts(rows)
            .into_iter()
            .map(|n| serde_json::json!({"threads": n, "speed_vs_one": w.speed(n)}))
            .collect();
        serde_json::json!({"serial_share": w.serial, "serial_ms": w.serial_ms(),
            "stage_serial_ms": serial_ms, "projected": projected})
    });
    serde_json::json!({"input": input, "scaling": measured, "amdahl_from_1_and_2": amdahl})
}
