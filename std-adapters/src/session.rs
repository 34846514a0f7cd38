//! One run of the pipeline over a sequence of frames, with everything the command writes:
//! trajectories (KITTI and TUM), the mesh, and `report.json`.
//!
//! [`run`] reads each frame from a [`FrameSource`], estimates its pose (or takes a given one),
//! extracts the mesh of the cells it updated, applies the sliding window, and records timings,
//! counts and memory. A frame that cannot be read or used is reported (its file, index and
//! reason) and skipped; the run goes on. Outputs are written at the end, each to a temporary
//! name then renamed; evicted cells are spooled to disk as they leave, so memory stays flat.
//!
//! Trajectories: the TUM file has one line per used frame with its timestamp; the KITTI file
//! has one line per frame (KITTI files have no timestamps), a skipped frame repeating the last
//! pose (the report lists the skipped frames).
//!
//! Checkpoints: with `checkpoint_every`, the map and the run's totals are saved every so many
//! frames; with `resume`, a killed run continues from its last checkpoint and ends with the
//! same poses and mesh as an uninterrupted run (frames after the checkpoint are redone).

use crate::atomic::write_atomic;
use crate::checkpoint::{self, Progress};
use crate::config_file::WindowSettings;
use crate::file_error::FileError;
use crate::memory;
use crate::mesh_file::{MeshCounts, MeshFormat, MeshSpool};
use crate::parallel::Workers;
use crate::scans::{read_scan, ScanFolder};
use crate::timing::{StageMs, StageTimer};
use crate::trajectory::{write_kitti_line, write_tum_line};
use crate::window::Window;
use serde::Serialize;
use slamesh_core::layer::Shown;
use slamesh_core::{Capacity, Config, Pipeline, Point, Pose};
use std::fmt;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Frames to run over.
pub trait FrameSource {
    /// Number of frames.
    fn frames(&self) -> usize;
    /// What to call frame `i` in messages (its file).
    fn label(&self, i: usize) -> String;
    /// Timestamp of frame `i` (seconds).
    fn stamp(&self, i: usize) -> f64;
    /// The points of frame `i`, in the sensor frame.
    fn read(&mut self, i: usize) -> Result<Vec<Point>, FileError>;
}

impl FrameSource for ScanFolder {
    fn frames(&self) -> usize {
        self.paths.len()
    }
    fn label(&self, i: usize) -> String {
        self.paths[i].display().to_string()
    }
    fn stamp(&self, i: usize) -> f64 {
        self.stamps[i]
    }
    fn read(&mut self, i: usize) -> Result<Vec<Point>, FileError> {
        read_scan(&self.paths[i])
    }
}

/// How to run. The default is the default configuration, one thread per core, no mesh file,
/// no window, no checkpoints.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Output folder (created if missing).
    pub out: PathBuf,
    /// Pipeline configuration.
    pub config: Config,
    /// Name of the preset it came from (for the report).
    pub preset: String,
    /// Sliding-window eviction.
    pub window: WindowSettings,
    /// Reconstruction threads (1: serial; 0: one per core).
    pub threads: usize,
    /// Mesh files to write (`mesh.ply`, `mesh.obj`; none: no mesh file).
    pub mesh_formats: Vec<MeshFormat>,
    /// Poses to mesh with instead of estimating them (meshing only), one per frame.
    pub given_poses: Option<Vec<Pose>>,
    /// What the input was (for the report).
    pub input: String,
    /// Write a checkpoint after every this many frames ([`crate::checkpoint`]).
    pub checkpoint_every: Option<usize>,
    /// Continue from the checkpoint in `out` instead of starting over.
    pub resume: bool,
}

/// What happened to one frame (a line of `report.json`).
#[derive(Debug, Clone, Serialize)]
pub struct FrameRecord {
    /// Frame index.
    pub frame: usize,
    /// Its file.
    pub file: String,
    /// The registration status (`FirstScan`, `Converged`, `Degenerate`, ...), or `Skipped`.
    pub status: String,
    /// Why it was skipped.
    pub error: Option<String>,
    /// Milliseconds per stage.
    pub ms: StageMs,
    /// Points read.
    pub points: usize,
    /// Points after filtering and down-sampling.
    pub points_kept: usize,
    /// Cells of the scan reconstructed.
    pub scan_cells: usize,
    /// Layers of the scan.
    pub scan_layers: usize,
    /// Cells in the map after the frame.
    pub map_cells: usize,
    /// Layers in the map after the frame.
    pub map_layers: usize,
    /// Triangles of the cells this frame updated.
    pub triangles_updated: usize,
    /// Cells evicted after this frame.
    pub evicted_cells: usize,
    /// Conditioning of the registration: the mean squared normal component along its
    /// weakest direction (0 to 1/3; small is weak).
    pub conditioning: f64,
    /// Directions registration left to the motion model (see the `Degenerate` status).
    pub degenerate_directions: usize,
    /// Resident memory after the frame (MB).
    pub rss_mb: Option<f64>,
}

/// Median and 95th percentile of one stage (ms).
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct Spread {
    /// Median.
    pub median: f64,
    /// 95th percentile.
    pub p95: f64,
}

/// The end of a run (the `summary` of `report.json`).
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// Frames in the input.
    pub frames: usize,
    /// Frames used.
    pub used: usize,
    /// Frames skipped, with their reasons.
    pub skipped: Vec<String>,
    /// Wall time of the frame loop (seconds).
    pub seconds: f64,
    /// Used frames per second of wall time.
    pub hz: f64,
    /// Reconstruction threads.
    pub threads: usize,
    /// Median and 95th percentile per stage over used frames (ms).
    pub stage_ms: Vec<(String, Spread)>,
    /// The mesh written.
    pub mesh_vertices: u64,
    /// The mesh written.
    pub mesh_triangles: u64,
    /// Map cells at the end.
    pub map_cells: usize,
    /// Map layers at the end.
    pub map_layers: usize,
    /// Cells evicted during the run.
    pub evicted_cells: usize,
    /// Layer budget under the memory cap, if one was set.
    pub max_layers: Option<usize>,
    /// Peak resident memory of the process (MB).
    pub peak_rss_mb: Option<f64>,
    /// The estimated (or given) pose of each used frame, frame index first.
    #[serde(skip)]
    pub poses: Vec<(usize, Pose)>,
}

/// Why a run could not start or finish.
#[derive(Debug)]
pub enum RunError {
    /// The configuration is invalid.
    Config(String),
    /// An output could not be written.
    File(FileError),
}

impl fmt::Display for RunError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RunError::Config(m) => write!(f, "configuration: {m}"),
            RunError::File(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for RunError {}

impl From<FileError> for RunError {
    fn from(e: FileError) -> Self {
        RunError::File(e)
    }
}

/// Headroom for the rest of the process under a memory cap: IO buffers of a scan, thread
/// stacks, the allocator's slack.
pub const PROCESS_HEADROOM_BYTES: usize = 24 << 20;

/// Runs over every frame of `source`; `on_frame` sees each record as it is made (for progress
/// and messages). Writes the outputs into `opts.out`.
pub fn run<C: Capacity>(
    source: &mut impl FrameSource,
    opts: &RunOptions,
    mut on_frame: impl FnMut(&FrameRecord),
) -> Result<Summary, RunError> {
    let out = &opts.out;
    std::fs::create_dir_all(out)
        .map_err(|e| FileError::at(out, format!("cannot create the output folder: {e}")))?;
    let workers =
        Workers::new(opts.threads).map_err(|e| RunError::Config(format!("threads: {e}")))?;
    let mut window = opts.window.rules();
    let mut max_layers = None;
    if let Some(cap) = opts.window.memory_cap_mb {
        let other = memory::rss_bytes().unwrap_or(0) as usize + PROCESS_HEADROOM_BYTES;
        let budget = Window::max_layers::<C>((cap * 1e6) as usize, other).map_err(|e| {
            RunError::Config(format!(
                "memory cap {cap} MB is below what this capacity needs with an empty map: {:.0} MB",
                e.needed_bytes as f64 / 1e6
            ))
        })?;
        window.max_layers = Some(budget);
        max_layers = Some(budget);
    }
    let mut pipeline = Pipeline::<C>::new(opts.config)
        .map_err(|e| RunError::Config(format!("{}: {}", e.field, e.reason)))?;
    let show = &opts.config.mesh;
    let mesh_path = out.join("mesh.ply");
    let frames_path = out.join(".report.frames.spool");
    let checkpoint_path = checkpoint::path(out);
    let fingerprint = fingerprint::<C>(source, opts);
    let (mut spool, frames_file, mut progress) = if opts.resume {
        if !checkpoint_path.exists() {
            return Err(FileError::at(
                &checkpoint_path,
                "cannot resume: no checkpoint here (was the run started with --checkpoint-every?)",
            )
            .into());
        }
        let progress = checkpoint::read(&checkpoint_path, pipeline.map_mut())?;
        if progress.fingerprint != fingerprint {
            return Err(FileError::at(
                &checkpoint_path,
                format!(
                    "cannot resume: the checkpoint is of another run\n  it has:   {}\n  this run: {fingerprint}",
                    progress.fingerprint
                ),
            )
            .into());
        }
        pipeline.restore_progress(progress.pipeline_frames, progress.motion_model());
        let spool = MeshSpool::resume(&mesh_path, opts.config.lattice(), show, progress.mesh)?;
        let frames = crate::atomic::open_cut(&frames_path, progress.report_bytes)?;
        (spool, frames, progress)
    } else {
        let spool = MeshSpool::new(&mesh_path, opts.config.lattice(), show)?;
        let frames = std::fs::File::create(&frames_path)
            .map_err(|e| FileError::at(&frames_path, format!("cannot create: {e}")))?;
        let progress = Progress {
            fingerprint,
            next_frame: 0,
            pipeline_frames: 0,
            motion: (None, None),
            poses: Vec::new(),
            skipped: Vec::new(),
            evicted_cells: 0,
            used_ms: Vec::new(),
            seconds: 0.0,
            report_bytes: 0,
            mesh: MeshCounts::default(),
        };
        (spool, frames, progress)
    };
    let mut frame_lines = BufWriter::new(frames_file);

    let mut timer = StageTimer::new();
    let mut spool_error = None;
    let start = Instant::now();
    // Loop seconds before this process (from the checkpoint when resuming).
    let seconds_before = progress.seconds;
    let first = progress.next_frame;
    for i in first..source.frames() {
        let mut rec = FrameRecord {
            frame: i,
            file: source.label(i),
            status: "Skipped".into(),
            error: None,
            ms: StageMs::default(),
            points: 0,
            points_kept: 0,
            scan_cells: 0,
            scan_layers: 0,
            map_cells: 0,
            map_layers: 0,
            triangles_updated: 0,
            evicted_cells: 0,
            conditioning: 0.0,
            degenerate_directions: 0,
            rss_mb: None,
        };
        let t_read = Instant::now();
        let scan = source.read(i);
        rec.ms.read = t_read.elapsed().as_secs_f64() * 1e3;
        let outcome = scan.map_err(|e| e.to_string()).and_then(|points| {
            rec.points = points.len();
            let given = match &opts.given_poses {
                Some(p) => Some(p.get(i).ok_or("no given pose for this frame")?),
                None => None,
            };
            let r = match given {
                Some(pose) => pipeline.integrate_scan_with(&points, pose, &workers, &mut timer),
                None => pipeline.process_scan_with(&points, &workers, &mut timer),
            };
            r.map_err(|e| format!("{}: frame {i}: {e}", source.label(i)))
        });
        rec.ms = StageMs {
            read: rec.ms.read,
            ..timer.take()
        };
        match outcome {
            Ok(o) => {
                rec.status = format!("{:?}", o.status);
                rec.points_kept = o.stats.filter.kept;
                rec.scan_cells = o.stats.bucket.cells;
                rec.scan_layers = o.stats.scan_layers;
                rec.conditioning = o.stats.conditioning;
                rec.degenerate_directions = o.stats.degenerate_directions;
                let t = Instant::now();
                rec.triangles_updated = updated_triangles(&pipeline, &workers);
                rec.ms.mesh = t.elapsed().as_secs_f64() * 1e3;
                let t = Instant::now();
                if !window.is_off() {
                    rec.evicted_cells =
                        window.evict(pipeline.map_mut(), o.stats.frame, &o.t_world_sensor, |l| {
                            if opts.window.save_evicted && spool_error.is_none() {
                                spool_error = spool.add_layer(l).err();
                            }
                        });
                    progress.evicted_cells += rec.evicted_cells;
                }
                rec.ms.evict = t.elapsed().as_secs_f64() * 1e3;
                rec.ms.total = rec.ms.pipeline() + rec.ms.evict;
                progress.poses.push((i, o.t_world_sensor));
                progress.used_ms.push(rec.ms);
            }
            Err(e) => {
                rec.error = Some(e.clone());
                progress.skipped.push(e);
            }
        }
        if let Some(e) = spool_error.take() {
            return Err(e.into());
        }
        rec.map_cells = pipeline.map().cell_count();
        rec.map_layers = pipeline.map().layer_count();
        rec.rss_mb = memory::rss_bytes().map(memory::mb);
        serde_json::to_writer(&mut frame_lines, &rec)
            .map_err(std::io::Error::from)
            .and_then(|()| frame_lines.write_all(b"\n"))
            .map_err(|e| FileError::at(&frames_path, format!("cannot write: {e}")))?;
        on_frame(&rec);
        if let Some(every) = opts.checkpoint_every.filter(|&n| n > 0) {
            if (i + 1) % every == 0 && i + 1 < source.frames() {
                frame_lines
                    .flush()
                    .map_err(|e| FileError::at(&frames_path, format!("cannot write: {e}")))?;
                spool.flush()?;
                progress.next_frame = i + 1;
                progress.pipeline_frames = pipeline.frames();
                progress.motion = pipeline.motion().history();
                progress.seconds = seconds_before + start.elapsed().as_secs_f64();
                progress.report_bytes = frames_path.metadata().map_or(0, |m| m.len());
                progress.mesh = spool.counts();
                checkpoint::write(&checkpoint_path, &progress, pipeline.map())?;
            }
        }
    }
    progress.seconds = seconds_before + start.elapsed().as_secs_f64();
    let Progress {
        poses,
        skipped,
        evicted_cells: evicted_total,
        used_ms,
        seconds,
        ..
    } = progress;
    frame_lines
        .flush()
        .map_err(|e| FileError::at(&frames_path, format!("cannot write: {e}")))?;
    drop(frame_lines);

    write_trajectories(out, source, &poses)?;
    spool.add_map(pipeline.map())?;
    let outputs: Vec<(PathBuf, MeshFormat)> = opts
        .mesh_formats
        .iter()
        .map(|&f| (mesh_file_path(out, f), f))
        .collect();
    let counts: MeshCounts = spool.finish(&outputs)?;
    let summary = Summary {
        frames: source.frames(),
        used: poses.len(),
        skipped,
        seconds,
        hz: poses.len() as f64 / seconds.max(1e-9),
        threads: workers.threads(),
        stage_ms: spreads(&used_ms),
        mesh_vertices: counts.vertices,
        mesh_triangles: counts.triangles,
        map_cells: pipeline.map().cell_count(),
        map_layers: pipeline.map().layer_count(),
        evicted_cells: evicted_total,
        max_layers,
        peak_rss_mb: memory::peak_rss_bytes().map(memory::mb),
        poses,
    };
    write_report(out, opts, &summary, &frames_path)?;
    let _ = std::fs::remove_file(&frames_path);
    // The run is complete: nothing is left to resume.
    let _ = std::fs::remove_file(&checkpoint_path);
    Ok(summary)
}

/// What identifies a run for resuming: its input, frames, capacity, configuration, window and
/// given poses (the thread count is left out: it does not change the results).
fn fingerprint<C: Capacity>(source: &impl FrameSource, opts: &RunOptions) -> String {
    format!(
        "input {:?}, {} frames, capacity {}, config {:?}, window {:?}, {} given poses",
        opts.input,
        source.frames(),
        std::any::type_name::<C>(),
        opts.config,
        opts.window,
        opts.given_poses.as_ref().map_or(0, Vec::len)
    )
}

/// `mesh.ply` or `mesh.obj` in `out`.
pub fn mesh_file_path(out: &Path, format: MeshFormat) -> PathBuf {
    out.join(match format {
        MeshFormat::Ply => "mesh.ply",
        MeshFormat::Obj => "mesh.obj",
    })
}

/// Triangles of the map layers the last scan updated (the mesh a viewer would refresh).
fn updated_triangles<C: Capacity>(pipeline: &Pipeline<C>, workers: &Workers) -> usize {
    let shown = Shown::new(&pipeline.config().mesh);
    let lattice = pipeline.map().lattice().table();
    let map = pipeline.map();
    workers.sum(pipeline.last_scan(), |s| {
        map.layer(&s.key, s.axis)
            .map_or(0, |l| l.triangles(&lattice, shown).count())
    })
}

/// Median and 95th percentile of each stage over `ms`, in [`StageMs::NAMES`] order.
pub fn spreads(ms: &[StageMs]) -> Vec<(String, Spread)> {
    (0..StageMs::NAMES.len())
        .map(|k| {
            let mut v: Vec<f64> = ms.iter().map(|m| m.values()[k]).collect();
            v.sort_by(f64::total_cmp);
            let at = |q: f64| {
                v.get(((v.len() as f64 - 1.0) * q).round() as usize)
                    .copied()
                    .unwrap_or(0.0)
            };
            (
                StageMs::NAMES[k].to_string(),
                Spread {
                    median: at(0.5),
                    p95: at(0.95),
                },
            )
        })
        .collect()
}

fn write_trajectories(
    out: &Path,
    source: &impl FrameSource,
    poses: &[(usize, Pose)],
) -> Result<(), FileError> {
    write_atomic(&out.join("poses_tum.txt"), |w| {
        writeln!(
            w,
            "# timestamp tx ty tz qx qy qz qw (LiDAR pose in the first LiDAR frame)"
        )?;
        poses
            .iter()
            .try_for_each(|(i, p)| write_tum_line(w, source.stamp(*i), p))
    })?;
    write_atomic(&out.join("poses_kitti.txt"), |w| {
        let mut held = Pose::identity();
        let mut next = poses.iter().peekable();
        for i in 0..source.frames() {
            if let Some((_, p)) = next.next_if(|(j, _)| *j == i) {
                held = *p;
            }
            write_kitti_line(w, &held)?;
        }
        Ok(())
    })
}

fn write_report(
    out: &Path,
    opts: &RunOptions,
    summary: &Summary,
    frames: &Path,
) -> Result<(), FileError> {
    #[derive(Serialize)]
    struct Head<'a> {
        input: &'a str,
        preset: &'a str,
        config: String,
        summary: &'a Summary,
    }
    let head = Head {
        input: &opts.input,
        preset: &opts.preset,
        config: crate::config_file::documented_toml(&opts.config, &opts.preset),
        summary,
    };
    write_atomic(&out.join("report.json"), |w| {
        let head = serde_json::to_string_pretty(&head).map_err(std::io::Error::from)?;
        // The head object without its closing brace, then the streamed frame records.
        let open = head
            .trim_end()
            .strip_suffix('}')
            .unwrap_or(&head)
            .trim_end();
        w.write_all(open.as_bytes())?;
        w.write_all(b",\n  \"frames\": [\n")?;
        let lines = std::io::BufReader::new(std::fs::File::open(frames)?);
        for (k, line) in std::io::BufRead::lines(lines).enumerate() {
            let line = line?;
            if k > 0 {
                w.write_all(b",\n")?;
            }
            w.write_all(b"    ")?;
            w.write_all(line.as_bytes())?;
        }
        w.write_all(b"\n  ]\n}\n")
    })
}
