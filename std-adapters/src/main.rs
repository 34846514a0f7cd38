//! `slamesh`: LiDAR odometry and meshing from the command line.
//!
//! - `slamesh run <INPUT> --out <DIR>`: estimate poses and build the mesh;
//! - `slamesh mesh <INPUT> --poses <FILE> --out <DIR>`: build the mesh at given poses;
//! - `slamesh eval --estimate <FILE> --reference <FILE|KITTI folder>`: odometry errors;
//! - `slamesh config [--preset NAME]`: print a documented configuration file.

use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use slamesh::config_file::{self, Settings, WindowSettings, PRESETS};
use slamesh::eval::consecutive_errors;
use slamesh::mesh_file::MeshFormat;
use slamesh::scans::ScanFolder;
use slamesh::session::{run, spreads, FrameSource, RunOptions, Summary};
use slamesh::timing::StageMs;
use slamesh::{kitti, trajectory, FileError};
use slamesh_core::{KittiCapacity, Pose};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "slamesh",
    version,
    about = "Real-time LiDAR localization and meshing"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Estimate the sensor's poses and build the mesh map. Writes poses_kitti.txt,
    /// poses_tum.txt, mesh.ply and report.json into --out.
    Run {
        #[command(flatten)]
        common: Common,
    },
    /// Build the mesh at given poses (meshing only; default preset: meshing).
    Mesh {
        #[command(flatten)]
        common: Common,
        /// LiDAR poses, one per frame (KITTI or TUM format).
        #[arg(long)]
        poses: PathBuf,
        /// KITTI calib.txt: the poses are camera poses (KITTI poses.txt); turn them into
        /// LiDAR poses with its Tr.
        #[arg(long)]
        calib: Option<PathBuf>,
    },
    /// Compare a trajectory with reference poses: consecutive-frame errors and end-point drift.
    Eval {
        /// The estimated trajectory (KITTI or TUM format, e.g. <run dir>/poses_kitti.txt).
        #[arg(long)]
        estimate: PathBuf,
        /// Reference poses: a trajectory file, or a KITTI sequence folder (poses.txt and
        /// calib.txt, turned into LiDAR poses).
        #[arg(long)]
        reference: PathBuf,
        /// KITTI calib.txt for a reference file of camera poses.
        #[arg(long)]
        calib: Option<PathBuf>,
        /// Print JSON instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Time the pipeline stage by stage: a warm-up pass over the scans, then --repeat timed
    /// passes (median and 95th percentile per stage, scans per second, peak memory).
    Bench {
        /// Scans, as for `run`.
        input: PathBuf,
        /// Parameter preset.
        #[arg(long, default_value = "default", value_parser = PRESETS)]
        preset: String,
        /// Reconstruction threads (1: serial; 0: one per core).
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// Timed passes over the scans.
        #[arg(long, default_value_t = 3)]
        repeat: usize,
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// Print a configuration file with every parameter and its documentation.
    Config {
        /// The preset to print.
        #[arg(long, default_value = "default", value_parser = PRESETS)]
        preset: String,
    },
}

#[derive(Args)]
struct Common {
    /// A folder of scans (.bin, .pcd or .ply, read in natural order), a KITTI sequence folder,
    /// or one scan file.
    input: PathBuf,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
    /// Parameter preset.
    #[arg(long, value_parser = PRESETS, conflicts_with = "config")]
    preset: Option<String>,
    /// A TOML configuration file (print one with `slamesh config`).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Reconstruction threads (1: serial; 0: one per core).
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// Also write mesh.obj.
    #[arg(long)]
    obj: bool,
    /// Evict map cells not seen for more than N frames.
    #[arg(long, value_name = "N")]
    evict_after: Option<u32>,
    /// Evict map cells farther than R metres from the sensor.
    #[arg(long, value_name = "R")]
    evict_radius: Option<f64>,
    /// Keep the process under this many MB by evicting the oldest cells.
    #[arg(long, value_name = "MB")]
    memory_cap: Option<f64>,
    /// Append evicted cells to the output mesh, so nothing is lost.
    #[arg(long)]
    save_evicted: bool,
    /// No progress bar.
    #[arg(long, short)]
    quiet: bool,
}

/// Prints a line to stdout; a closed pipe (`slamesh ... | head`) is not an error.
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout().lock(), $($arg)*);
    }};
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Run { common } => run_command(common, "default", None),
        Command::Mesh {
            common,
            poses,
            calib,
        } => read_given_poses(&poses, calib.as_deref())
            .map_err(|e| e.to_string())
            .and_then(|p| run_command(common, "meshing", Some(p))),
        Command::Eval {
            estimate,
            reference,
            calib,
            json,
        } => eval_command(&estimate, &reference, calib.as_deref(), json),
        Command::Bench {
            input,
            preset,
            threads,
            repeat,
            json,
        } => bench_command(&input, &preset, threads, repeat, json),
        Command::Config { preset } => {
            let c = config_file::preset(&preset).unwrap_or_default();
            say!("{}", config_file::documented_toml(&c, &preset).trim_end());
            Ok(())
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("slamesh: error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn settings(common: &Common, default_preset: &str) -> Result<Settings, String> {
    let mut s = match &common.config {
        Some(path) => config_file::read(path).map_err(|e| e.to_string())?,
        None => {
            let name = common.preset.as_deref().unwrap_or(default_preset);
            let preset = PRESETS
                .into_iter()
                .find(|p| *p == name)
                .unwrap_or("default");
            Settings {
                config: config_file::preset(preset).unwrap_or_default(),
                preset,
                window: WindowSettings::default(),
            }
        }
    };
    let w = &mut s.window;
    if let Some(n) = common.evict_after {
        w.max_age_frames = Some(n);
    }
    for (flag, value, slot) in [
        ("--evict-radius", common.evict_radius, &mut w.radius_m),
        ("--memory-cap", common.memory_cap, &mut w.memory_cap_mb),
    ] {
        if let Some(v) = value {
            if !(v > 0.0 && v.is_finite()) {
                return Err(format!("{flag}: must be a positive number, found {v}"));
            }
            *slot = Some(v);
        }
    }
    w.save_evicted |= common.save_evicted;
    Ok(s)
}

fn run_command(
    common: Common,
    default_preset: &str,
    given: Option<Vec<Pose>>,
) -> Result<(), String> {
    let s = settings(&common, default_preset)?;
    let mut source = ScanFolder::open(&common.input).map_err(|e| e.to_string())?;
    if let Some(p) = &given {
        if p.len() < source.frames() {
            eprintln!(
                "slamesh: warning: {} poses for {} frames; frames without a pose are skipped",
                p.len(),
                source.frames()
            );
        }
    }
    let mut mesh_formats = vec![MeshFormat::Ply];
    if common.obj {
        mesh_formats.push(MeshFormat::Obj);
    }
    let opts = RunOptions {
        out: common.out.clone(),
        config: s.config,
        preset: s.preset.to_string(),
        window: s.window,
        threads: common.threads,
        mesh_formats,
        given_poses: given,
        input: common.input.display().to_string(),
    };
    let bar = if common.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(source.frames() as u64)
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} frames  {per_sec}  eta {eta}  {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    eprintln!(
        "slamesh: {} frames from {} (preset {}), output in {}",
        source.frames(),
        common.input.display(),
        s.preset,
        common.out.display()
    );
    let summary = run::<KittiCapacity>(&mut source, &opts, |rec| {
        if let Some(e) = &rec.error {
            bar.suspend(|| eprintln!("slamesh: skipped: {e}"));
        }
        bar.set_message(format!(
            "{} ms, {} MB",
            rec.ms.total.round(),
            rec.rss_mb.unwrap_or(0.0).round()
        ));
        bar.inc(1);
    })
    .map_err(|e| e.to_string())?;
    bar.finish_and_clear();
    print_summary(&summary, &common.out);
    if summary.used == 0 {
        return Err("no frame could be used".into());
    }
    Ok(())
}

fn print_summary(s: &Summary, out: &Path) {
    let median = |name: &str| {
        s.stage_ms
            .iter()
            .find(|(n, _)| n == name)
            .map_or(0.0, |(_, m)| m.median)
    };
    say!(
        "slamesh: {} frames ({} used, {} skipped) in {:.1} s, {:.1} Hz, median {:.1} ms a frame on {} thread(s)",
        s.frames,
        s.used,
        s.skipped.len(),
        s.seconds,
        s.hz,
        median("total"),
        s.threads
    );
    say!(
        "slamesh: mesh {} triangles, {} vertices; map {} cells, {} evicted; peak memory {}",
        s.mesh_triangles,
        s.mesh_vertices,
        s.map_cells,
        s.evicted_cells,
        s.peak_rss_mb
            .map_or("unknown".into(), |m| format!("{m:.0} MB"))
    );
    say!(
        "slamesh: wrote {0}/poses_kitti.txt, {0}/poses_tum.txt, {0}/mesh.ply, {0}/report.json",
        out.display()
    );
}

fn read_given_poses(path: &Path, calib: Option<&Path>) -> Result<Vec<Pose>, FileError> {
    let poses = trajectory::read(path)?.poses;
    Ok(match calib {
        Some(c) => kitti::lidar_poses(&poses, &kitti::read_calib_tr(c)?),
        None => poses,
    })
}

fn eval_command(
    estimate: &Path,
    reference: &Path,
    calib: Option<&Path>,
    json: bool,
) -> Result<(), String> {
    let est = trajectory::read(estimate).map_err(|e| e.to_string())?.poses;
    let reference = if reference.is_dir() {
        kitti::reference_lidar_poses(reference)
    } else {
        read_given_poses(reference, calib)
    }
    .map_err(|e| e.to_string())?;
    if est.len() != reference.len() {
        eprintln!(
            "slamesh: warning: {} estimated poses, {} reference poses; comparing the first {}",
            est.len(),
            reference.len(),
            est.len().min(reference.len())
        );
    }
    let e = consecutive_errors(&est, &reference);
    let n = est.len().min(reference.len());
    let path_m: f64 = reference[..n]
        .windows(2)
        .map(|w| (w[1].translation.vector - w[0].translation.vector).norm())
        .sum();
    let end_m = if n > 0 {
        (est[n - 1].translation.vector - reference[n - 1].translation.vector).norm()
    } else {
        0.0
    };
    let drift_percent = if path_m > 0.0 {
        100.0 * end_m / path_m
    } else {
        0.0
    };
    if json {
        say!(
            "{}",
            serde_json::json!({
                "pairs": e.pairs,
                "mean_translation_m": e.mean_translation_m,
                "max_translation_m": e.max_translation_m,
                "mean_rotation_deg": e.mean_rotation_deg,
                "path_m": path_m,
                "end_error_m": end_m,
                "end_drift_percent": drift_percent,
            })
        );
    } else {
        say!("frame pairs:                 {}", e.pairs);
        say!(
            "consecutive translation:     mean {:.2} cm, max {:.2} cm",
            e.mean_translation_m * 100.0,
            e.max_translation_m * 100.0
        );
        say!(
            "consecutive rotation:        mean {:.4} deg",
            e.mean_rotation_deg
        );
        say!(
            "end-point error:             {:.3} m over {:.1} m ({:.3} %)",
            end_m,
            path_m,
            drift_percent
        );
    }
    Ok(())
}

fn bench_command(
    input: &Path,
    preset: &str,
    threads: usize,
    repeat: usize,
    json: bool,
) -> Result<(), String> {
    let mut source = ScanFolder::open(input).map_err(|e| e.to_string())?;
    let out = std::env::temp_dir().join(format!("slamesh-bench-{}", std::process::id()));
    let opts = RunOptions {
        out: out.clone(),
        config: config_file::preset(preset).unwrap_or_default(),
        preset: preset.to_string(),
        window: WindowSettings::default(),
        threads,
        mesh_formats: Vec::new(),
        given_poses: None,
        input: input.display().to_string(),
    };
    let mut timed: Vec<StageMs> = Vec::new();
    let mut last = None;
    for pass in 0..=repeat.max(1) {
        let summary = run::<KittiCapacity>(&mut source, &opts, |rec| {
            if pass > 0 && rec.error.is_none() {
                timed.push(rec.ms);
            }
        })
        .map_err(|e| e.to_string())?;
        last = Some(summary);
    }
    let _ = std::fs::remove_dir_all(&out);
    let summary = last.ok_or("no pass ran")?;
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
