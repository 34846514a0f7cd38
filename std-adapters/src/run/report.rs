//! What a run reports: a record per frame, the summary, the per-stage spreads, and the files
//! `report.json`, `poses_tum.txt` and `poses_kitti.txt`.
//!
//! Trajectories: the TUM file has one line per used frame with its timestamp; the KITTI file
//! has one line per frame (KITTI files have no timestamps), a skipped frame repeating the last
//! pose (the report lists the skipped frames). `report.json` is written at the end from the
//! frame records spooled during the run, so they cost no memory.

use crate::io::atomic::write_atomic;
use crate::io::error::FileError;
use crate::io::trajectory::{write_kitti_line, write_tum_line};
use crate::run::session::RunOptions;
use crate::run::source::FrameSource;
use crate::run::timing::StageMs;
use serde::Serialize;
use slamesh_core::Pose;
use std::io::Write;
use std::path::Path;

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

impl FrameRecord {
    /// The record of frame `frame` from `file` before anything is known of it: skipped, until
    /// the pipeline says otherwise.
    pub fn skipped(frame: usize, file: String) -> Self {
        FrameRecord {
            frame,
            file,
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
        }
    }
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

/// Writes `poses_tum.txt` (used frames, with their stamps) and `poses_kitti.txt` (every frame,
/// a skipped one holding the last pose) into `out`.
pub(crate) fn write_trajectories(
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

/// Writes `report.json` into `out`: the run, its configuration and summary, then the frame
/// records spooled in `frames` (one JSON object a line).
pub(crate) fn write_report(
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
        config: crate::io::config_file::documented_toml(&opts.config, &opts.preset),
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
