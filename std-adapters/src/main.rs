//! `slamesh`: LiDAR odometry and meshing from the command line.
//!
//! - `slamesh run <INPUT> --out <DIR>`: estimate poses and build the mesh;
//! - `slamesh mesh <INPUT> --poses <FILE> --out <DIR>`: build the mesh at given poses;
//! - `slamesh eval --estimate <FILE> --reference <FILE|KITTI folder>`: odometry errors;
//! - `slamesh config [--preset NAME]`: print a documented configuration file.

use clap::{Args, Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use slamesh::config_file::{self, Settings, WindowSettings, PRESETS};
use slamesh::eval::{self, consecutive_errors};
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
        #[arg(long, requires = "reference")]
        estimate: Option<PathBuf>,
        /// Reference poses: a trajectory file, or a KITTI sequence folder (poses.txt and
        /// calib.txt, turned into LiDAR poses).
        #[arg(long)]
        reference: Option<PathBuf>,
        /// A mesh (PLY) to score against --cloud: precision, recall and F1 at 0.1, 0.2, 0.3 m.
        #[arg(long, requires = "cloud")]
        mesh: Option<PathBuf>,
        /// The reference point cloud for --mesh (PLY, PCD or KITTI .bin, world frame).
        #[arg(long)]
        cloud: Option<PathBuf>,
        /// Build a reference cloud from a KITTI sequence (its scans at its reference poses,
        /// one point per 5 cm, ranges 1.2-100 m) and write it to FILE.ply.
        #[arg(long, value_names = ["KITTI_SEQUENCE", "FILE"], num_args = 2)]
        build_reference: Option<Vec<PathBuf>>,
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
        #[arg(long, default_value = "default", value_parser = PRESETS, conflicts_with = "config")]
        preset: String,
        /// A TOML configuration file instead of the preset (its [window] section is not used:
        /// bench times the pipeline without eviction).
        #[arg(long)]
        config: Option<PathBuf>,
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
    /// Simulate a drive through a procedural town, run SLAM on it and print its accuracy
    /// against the truth. Writes the outputs of `run`, the true trajectory and topview.png.
    Demo {
        /// Output folder.
        #[arg(long, default_value = "demo-out")]
        out: PathBuf,
        /// Frames to drive (10 a second; the loop is about 1 200 frames, 1.1 km).
        #[arg(long, default_value_t = 300)]
        frames: usize,
        /// Parameter preset (town: meshing with 1.4 m cells, the better mesh and odometry here).
        #[arg(long, default_value = "town", value_parser = PRESETS)]
        preset: String,
        /// A TOML configuration file instead of the preset.
        #[arg(long)]
        config: Option<PathBuf>,
        /// Reconstruction threads (1: serial; 0: one per core).
        #[arg(long, default_value_t = 0)]
        threads: usize,
        /// Seed of the town and the sensor noise.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// No progress bar.
        #[arg(long, short)]
        quiet: bool,
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
    /// Save a checkpoint (the map and the run so far, `checkpoint.bin` in the output folder)
    /// after every N frames, so that a killed run can be resumed.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    checkpoint_every: Option<u32>,
    /// Continue a killed run from the checkpoint in its output folder (same input and
    /// settings); it loses at most the frames after the last checkpoint.
    #[arg(long)]
    resume: bool,
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
            mesh,
            cloud,
            build_reference,
            calib,
            json,
        } => {
            let mut done = false;
            let mut result = Ok(());
            if let Some(v) = build_reference {
                done = true;
                result = result.and_then(|()| build_reference_command(&v[0], &v[1]));
            }
            if let (Some(e), Some(r)) = (&estimate, &reference) {
                done = true;
                result = result.and_then(|()| eval_command(e, r, calib.as_deref(), json));
            }
            if let (Some(m), Some(c)) = (&mesh, &cloud) {
                done = true;
                result = result.and_then(|()| mesh_eval_command(m, c, json));
            }
            if !done {
                result = Err("eval: give --estimate and --reference, --mesh and --cloud, or --build-reference".into());
            }
            result
        }
        Command::Bench {
            input,
            preset,
            config,
            threads,
            repeat,
            json,
        } => bench_command(&input, &preset, config.as_deref(), threads, repeat, json),
        Command::Demo {
            out,
            frames,
            preset,
            config,
            threads,
            seed,
            quiet,
        } => demo_command(
            out,
            frames,
            &preset,
            config.as_deref(),
            threads,
            seed,
            quiet,
        ),
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
        checkpoint_every: common.checkpoint_every.map(|n| n as usize),
        resume: common.resume,
    };
    let bar = progress(source.frames(), common.quiet);
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
    let path_m = eval::path_length(&reference[..n]);
    let (end_m, drift_percent) = eval::end_drift(&est, &reference);
    let ate = eval::ate_rmse(&est, &reference);
    let segments = eval::segment_errors(&est, &reference, &eval::KITTI_SEGMENTS);
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
                "ate_rmse_m": ate,
                "segments": segments.iter().map(|s| serde_json::json!({
                    "length_m": s.length_m,
                    "translation_percent": s.translation_percent,
                    "rotation_deg_per_100m": s.rotation_deg_per_100m,
                    "segments": s.segments,
                })).collect::<Vec<_>>(),
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
        say!("ATE (rigidly aligned):       {:.3} m RMSE", ate);
        for s in &segments {
            say!(
                "{:>4.0} m segments:             {:.3} % translation, {:.4} deg/100 m ({} segments)",
                s.length_m,
                s.translation_percent,
                s.rotation_deg_per_100m,
                s.segments
            );
        }
    }
    Ok(())
}

fn mesh_eval_command(mesh: &Path, cloud: &Path, json: bool) -> Result<(), String> {
    let m = slamesh::ply::read_ply_mesh(mesh).map_err(|e| e.to_string())?;
    let reference = slamesh::scans::read_scan(cloud).map_err(|e| e.to_string())?;
    let triangles = m.triangle_corners();
    let samples = slamesh::mesh_eval::sample_triangles(triangles, 0.05, 1);
    let scores = slamesh::mesh_eval::score(&samples, &reference, &slamesh::mesh_eval::THRESHOLDS);
    if json {
        say!("{}", serde_json::to_string(&scores).unwrap_or_default());
    } else {
        say!(
            "mesh: {} triangles, {} samples (5 cm apart); reference: {} points",
            m.triangles.len(),
            samples.len(),
            reference.len()
        );
        for s in &scores {
            say!(
                "at {:.1} m: precision {:.3}, recall {:.3}, F1 {:.3}",
                s.threshold_m,
                s.precision,
                s.recall,
                s.f1
            );
        }
    }
    Ok(())
}

fn build_reference_command(sequence: &Path, out: &Path) -> Result<(), String> {
    let scans = ScanFolder::open(sequence).map_err(|e| e.to_string())?;
    let poses = kitti::reference_lidar_poses(&kitti::sequence_folder(sequence))
        .map_err(|e| e.to_string())?;
    if poses.len() < scans.paths.len() {
        return Err(format!(
            "{}: {} reference poses for {} scans",
            sequence.display(),
            poses.len(),
            scans.paths.len()
        ));
    }
    let mut frames = Vec::new();
    for (path, pose) in scans.paths.iter().zip(&poses) {
        match slamesh::scans::read_scan(path) {
            Ok(points) => frames.push((points, *pose)),
            Err(e) => eprintln!("slamesh: skipped: {e}"),
        }
    }
    let cloud = slamesh::mesh_eval::accumulate(frames, 0.05, 1.2, 100.0);
    slamesh::ply::write_points(out, &cloud).map_err(|e| e.to_string())?;
    say!(
        "wrote {} reference points to {}",
        cloud.len(),
        out.display()
    );
    Ok(())
}

fn bench_command(
    input: &Path,
    preset: &str,
    config: Option<&Path>,
    threads: usize,
    repeat: usize,
    json: bool,
) -> Result<(), String> {
    let (config, preset) = match config {
        Some(path) => {
            let s = config_file::read(path).map_err(|e| e.to_string())?;
            (s.config, s.preset)
        }
        None => (config_file::preset(preset).unwrap_or_default(), preset),
    };
    let mut source = ScanFolder::open(input).map_err(|e| e.to_string())?;
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

/// A progress bar for `frames` frames (hidden with `--quiet` or off a terminal).
fn progress(frames: usize, quiet: bool) -> ProgressBar {
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(frames as u64)
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} frames  {per_sec}  eta {eta}  {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar
}

fn demo_command(
    out: PathBuf,
    frames: usize,
    preset: &str,
    config: Option<&Path>,
    threads: usize,
    seed: u64,
    quiet: bool,
) -> Result<(), String> {
    let (config, preset) = match config {
        Some(path) => {
            let s = config_file::read(path).map_err(|e| e.to_string())?;
            (s.config, s.preset)
        }
        None => (config_file::preset(preset).unwrap_or_default(), preset),
    };
    let opts = RunOptions {
        out: out.clone(),
        config,
        preset: preset.to_string(),
        window: WindowSettings::default(),
        threads,
        mesh_formats: vec![MeshFormat::Ply],
        given_poses: None,
        input: format!("simulated town, seed {seed}, {frames} frames"),
        ..RunOptions::default()
    };
    eprintln!("slamesh demo: simulating {frames} frames through a procedural town (seed {seed}), output in {}", out.display());
    let bar = progress(frames, quiet);
    let r = slamesh::demo::run_demo::<KittiCapacity>(frames, seed, &opts, |rec| {
        bar.set_message(format!("{} ms", rec.ms.total.round()));
        bar.inc(1);
    })
    .map_err(|e| e.to_string())?;
    bar.finish_and_clear();
    print_summary(&r.summary, &out);
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
