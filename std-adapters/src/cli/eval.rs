//! `slamesh eval`: how far a trajectory or a mesh is from a reference, and building a reference
//! cloud from a KITTI sequence. Each mode has its own flags; several can run in one call.

use crate::cli::error::CliError;
use crate::cli::run::read_given_poses;
use crate::eval::dynamic::{is_moving_label, score_dynamic, LabelledCloud};
use crate::eval::mesh as mesh_eval;
use crate::eval::odometry::{self as eval, consecutive_errors, ConsecutiveErrors, SegmentError};
use crate::eval::topology::Topology;
use crate::formats::kitti;
use crate::formats::ply;
use crate::formats::trajectory::{self, Trajectory};
use crate::say;
use crate::sources::scans::{read_scan, ScanFolder};
use clap::Args;
use std::path::{Path, PathBuf};

/// `slamesh eval`'s arguments.
#[derive(Args, Debug)]
pub struct EvalArgs {
    /// The estimated trajectory (KITTI or TUM format, e.g. <run dir>/poses_kitti.txt).
    #[arg(long, requires = "reference")]
    pub estimate: Option<PathBuf>,
    /// Reference poses: a trajectory file, or a KITTI sequence folder (poses.txt and
    /// calib.txt, turned into LiDAR poses).
    #[arg(long, requires = "estimate")]
    pub reference: Option<PathBuf>,
    /// A mesh (PLY): alone, its boundary edges and connected pieces; with --cloud, its
    /// precision, recall and F1 at 0.1, 0.2, 0.3 m.
    #[arg(long)]
    pub mesh: Option<PathBuf>,
    /// The reference point cloud for --mesh (PLY, PCD or KITTI .bin, world frame).
    #[arg(long, requires = "mesh")]
    pub cloud: Option<PathBuf>,
    /// Score --mesh against a KITTI sequence's labelled scans (SemanticKITTI's
    /// labels/NNNNNN.label beside velodyne/, moving classes from 252; `write_drive --movers`
    /// writes them): the mesh's ghost area, SA, DA and AA (the KTH DynamicMap benchmark's
    /// measures on the mesh's samples) and its static F1 at 0.1 m.
    #[arg(long, value_name = "KITTI_SEQUENCE", requires = "mesh")]
    pub dynamic: Option<PathBuf>,
    /// Build a reference cloud from a KITTI sequence (its scans at its reference poses,
    /// one point per 5 cm, ranges 1.2-100 m) and write it to FILE.ply.
    #[arg(long, value_names = ["KITTI_SEQUENCE", "FILE"], num_args = 2)]
    pub build_reference: Option<Vec<PathBuf>>,
    /// KITTI calib.txt for a reference file of camera poses.
    #[arg(long)]
    pub calib: Option<PathBuf>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// With --estimate: where its plots go, PREFIX_trajectory.png (the estimate, aligned, over
    /// the reference) and PREFIX_error.png (each pose's error over the distance travelled)
    /// (default: the estimate's path without its extension, and `_eval`).
    #[arg(long, value_name = "PREFIX", conflicts_with = "no_plot")]
    pub plot: Option<PathBuf>,
    /// With --estimate: no plots.
    #[arg(long)]
    pub no_plot: bool,
}

/// One thing `eval` does.
enum Mode<'a> {
    BuildReference {
        sequence: &'a Path,
        out: &'a Path,
    },
    Trajectory {
        estimate: &'a Path,
        reference: &'a Path,
    },
    Mesh {
        mesh: &'a Path,
        cloud: Option<&'a Path>,
    },
    Dynamic {
        mesh: &'a Path,
        sequence: &'a Path,
    },
}

impl EvalArgs {
    /// The modes the flags ask for, in the order they run (clap has paired the flags).
    fn modes(&self) -> Vec<Mode<'_>> {
        let mut modes = Vec::new();
        if let Some([sequence, out]) = self.build_reference.as_deref() {
            modes.push(Mode::BuildReference { sequence, out });
        }
        if let (Some(estimate), Some(reference)) = (&self.estimate, &self.reference) {
            modes.push(Mode::Trajectory {
                estimate,
                reference,
            });
        }
        match (&self.mesh, &self.dynamic) {
            (Some(mesh), Some(sequence)) => modes.push(Mode::Dynamic { mesh, sequence }),
            (Some(mesh), None) => {
                let cloud = self.cloud.as_deref();
                modes.push(Mode::Mesh { mesh, cloud });
            }
            _ => {}
        }
        modes
    }
}

/// Runs every mode the flags ask for; none is an error.
pub fn eval(args: &EvalArgs) -> Result<(), CliError> {
    let modes = args.modes();
    if modes.is_empty() {
        return Err(CliError::NoEvalMode);
    }
    for mode in modes {
        match mode {
            Mode::BuildReference { sequence, out } => build_reference(sequence, out)?,
            Mode::Trajectory {
                estimate,
                reference,
            } => {
                let plot = (!args.no_plot).then(|| {
                    args.plot.clone().unwrap_or_else(|| {
                        let stem = estimate.file_stem().unwrap_or_default().to_string_lossy();
                        estimate.with_file_name(format!("{stem}_eval"))
                    })
                });
                trajectory_errors(
                    estimate,
                    reference,
                    args.calib.as_deref(),
                    args.json,
                    plot.as_deref(),
                )?
            }
            Mode::Mesh {
                mesh,
                cloud: Some(cloud),
            } => mesh_scores(mesh, cloud, args.json)?,
            Mode::Mesh { mesh, cloud: None } => mesh_topology(mesh, args.json)?,
            Mode::Dynamic { mesh, sequence } => dynamic_scores(mesh, sequence, args.json)?,
        }
    }
    Ok(())
}

fn trajectory_errors(
    estimate: &Path,
    reference: &Path,
    calib: Option<&Path>,
    json: bool,
    plot: Option<&Path>,
) -> Result<(), CliError> {
    let est_t = trajectory::read(estimate)?;
    let ref_t = if reference.is_dir() {
        kitti_reference(reference)?
    } else {
        read_given_poses(reference, calib)?
    };
    // Matched by time when both carry times (TUM files, a KITTI folder's times.txt), so that
    // frames a run skipped do not shift the pairs; by line otherwise.
    let (pairs, missing) = est_t.pair_with(&ref_t);
    warn_unpaired(&est_t, &ref_t, &missing);
    let est: Vec<_> = pairs.iter().map(|&(i, _)| est_t.poses[i]).collect();
    let reference: Vec<_> = pairs.iter().map(|&(_, k)| ref_t.poses[k]).collect();
    let e = consecutive_errors(&est, &reference);
    let n = est.len().min(reference.len());
    let path_m = eval::path_length(&reference[..n]);
    let (end_m, drift_percent) = eval::end_drift(&est, &reference);
    let ate = eval::ate_rmse(&est, &reference);
    let segments = eval::segment_errors(&est, &reference, &eval::KITTI_SEGMENTS);
    if let Some(prefix) = plot {
        write_plots(prefix, &est, &reference, ate)?;
    }
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
        say_errors(&e, path_m, (end_m, drift_percent), ate, &segments);
    }
    Ok(())
}

/// Names the estimated poses that found no reference pose (the first five).
fn warn_unpaired(est_t: &Trajectory, ref_t: &Trajectory, missing: &[usize]) {
    if missing.is_empty() {
        return;
    }
    let named: Vec<String> = missing
        .iter()
        .take(5)
        .map(|&i| match &est_t.stamps {
            Some(s) => format!("line {} (time {:.6})", i + 1, s[i]),
            None => format!("line {}", i + 1),
        })
        .collect();
    let within = match (&est_t.stamps, &ref_t.stamps) {
        (Some(_), Some(_)) => format!(
            " within {:.3} s",
            est_t.tolerance_s().max(ref_t.tolerance_s())
        ),
        _ => String::new(),
    };
    log::warn!(
        "{} estimated poses have no reference pose{within}: {}{}",
        missing.len(),
        named.join(", "),
        if missing.len() > 5 { ", ..." } else { "" }
    );
}

/// The trajectory's errors as lines for a person.
fn say_errors(
    e: &ConsecutiveErrors,
    path_m: f64,
    (end_m, drift_percent): (f64, f64),
    ate: f64,
    segments: &[SegmentError],
) {
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
    for s in segments {
        say!(
            "{:>4.0} m segments:             {:.3} % translation, {:.4} deg/100 m ({} segments)",
            s.length_m,
            s.translation_percent,
            s.rotation_deg_per_100m,
            s.segments
        );
    }
}

fn mesh_scores(mesh: &Path, cloud: &Path, json: bool) -> Result<(), CliError> {
    let m = ply::read_ply_mesh(mesh)?;
    let reference = read_scan(cloud)?;
    let triangles = m.triangle_corners();
    let samples = mesh_eval::sample_triangles(triangles, 0.05, 1);
    let scores = mesh_eval::score(&samples, &reference, &mesh_eval::THRESHOLDS);
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

fn mesh_topology(mesh: &Path, json: bool) -> Result<(), CliError> {
    let m = ply::read_ply_mesh(mesh)?;
    let t = Topology::of(&m.triangles);
    if json {
        say!("{}", serde_json::to_string(&t).unwrap_or_default());
    } else {
        say!(
            "mesh: {} vertices, {} triangles, {} edges",
            m.vertices.len(),
            t.triangles,
            t.edges
        );
        say!(
            "boundary edges: {} ({:.1} % of the edges); non-manifold edges: {}",
            t.boundary_edges,
            100.0 * t.boundary_share(),
            t.non_manifold_edges
        );
        say!(
            "connected pieces: {} (the largest has {} triangles)",
            t.pieces,
            t.largest_piece
        );
    }
    Ok(())
}

/// A KITTI sequence's scan files, each with its reference LiDAR pose; fewer poses than scans
/// is an error.
fn scans_at_poses(sequence: &Path) -> Result<Vec<(PathBuf, slamesh_core::Pose)>, CliError> {
    let scans = ScanFolder::open(sequence)?;
    let poses = kitti::reference_lidar_poses(&kitti::sequence_folder(sequence))?;
    if poses.len() < scans.paths.len() {
        return Err(CliError::TooFewPoses {
            sequence: sequence.display().to_string(),
            poses: poses.len(),
            scans: scans.paths.len(),
        });
    }
    Ok(scans.paths.into_iter().zip(poses).collect())
}

fn build_reference(sequence: &Path, out: &Path) -> Result<(), CliError> {
    let mut frames = Vec::new();
    for (path, pose) in scans_at_poses(sequence)? {
        match read_scan(&path) {
            Ok(points) => frames.push((points, pose)),
            Err(e) => log::warn!("skipped: {e}"),
        }
    }
    let cloud = mesh_eval::accumulate(frames, 0.05, 1.2, 100.0);
    ply::write_points(out, &cloud)?;
    say!(
        "wrote {} reference points to {}",
        cloud.len(),
        out.display()
    );
    Ok(())
}

/// `--mesh` against the labelled scans of `sequence` ([`crate::eval::dynamic`]).
fn dynamic_scores(mesh: &Path, sequence: &Path, json: bool) -> Result<(), CliError> {
    let m = ply::read_ply_mesh(mesh)?;
    let mut frames = Vec::new();
    for (path, pose) in scans_at_poses(sequence)? {
        let points = read_scan(&path)?;
        let moving = read_labels(&path, points.len())?;
        frames.push((points, moving, pose));
    }
    let truth = LabelledCloud::accumulate(frames, 1.2, 100.0);
    let triangles: Vec<[slamesh_core::Point; 3]> = m.triangle_corners().collect();
    let s = score_dynamic(&triangles, &truth);
    if json {
        say!("{}", serde_json::to_string(&s).unwrap_or_default());
        return Ok(());
    }
    say!(
        "truth: {} static and {} moving points (one per 10 cm cube)",
        truth.static_points.len(),
        truth.moving.len()
    );
    say!(
        "SA {:.2} %, DA {:.2} %, AA {:.2} %; ghost area {:.1} m² of {:.1} m² (static {:.1} m², \
         near no truth {:.1} m²); static F1 at 0.1 m {:.3}",
        100.0 * s.sa,
        100.0 * s.da,
        100.0 * s.aa,
        s.ghost_m2,
        s.ghost_m2 + s.static_m2 + s.unmatched_m2,
        s.static_m2,
        s.unmatched_m2,
        s.static_f1
    );
    Ok(())
}

/// Whether each of a scan's `n` points moved: its SemanticKITTI labels, `labels/STEM.label`
/// beside the scan's folder (one little-endian `u32` a point).
fn read_labels(scan: &Path, n: usize) -> Result<Vec<bool>, crate::io::FileError> {
    let stem = scan.file_stem().unwrap_or_default().to_string_lossy();
    let folder = scan
        .parent()
        .and_then(Path::parent)
        .unwrap_or(Path::new("."));
    let path = folder.join("labels").join(format!("{stem}.label"));
    let bytes = std::fs::read(&path).map_err(|e| {
        let what = "the scan's labels (SemanticKITTI's .label: a u32 a point)";
        crate::io::FileError::at(&path, format!("{what}: {e}"))
    })?;
    if bytes.len() != 4 * n {
        return Err(crate::io::FileError::at(
            &path,
            format!(
                "{} bytes: not one u32 label for each of the scan's {n} points",
                bytes.len()
            ),
        ));
    }
    Ok(bytes
        .chunks_exact(4)
        .map(|b| is_moving_label(u32::from_le_bytes([b[0], b[1], b[2], b[3]])))
        .collect())
}

/// A KITTI sequence folder's LiDAR poses, with its `times.txt` as their times when it has
/// one time a pose.
fn kitti_reference(sequence: &Path) -> Result<trajectory::Trajectory, crate::io::FileError> {
    for (file, what) in [
        ("poses.txt", "the reference poses"),
        ("calib.txt", "Tr, the LiDAR to the camera"),
    ] {
        if !sequence.join(file).is_file() {
            return Err(crate::io::FileError::at(
                sequence,
                format!(
                    "not a KITTI sequence folder: it has no {file} ({what}); give --reference a \
                     trajectory file (KITTI or TUM) or a folder with poses.txt and calib.txt"
                ),
            ));
        }
    }
    let poses = kitti::reference_lidar_poses(sequence)?;
    let stamps = std::fs::read_to_string(sequence.join("times.txt"))
        .ok()
        .and_then(|t| {
            t.split_whitespace()
                .map(|w| w.parse::<f64>().ok())
                .collect::<Option<Vec<_>>>()
        })
        .filter(|s| s.len() == poses.len());
    Ok(trajectory::Trajectory {
        format: trajectory::Format::Kitti,
        stamps,
        poses,
    })
}

/// Writes `PREFIX_trajectory.png` and `PREFIX_error.png` ([`crate::outputs::topview::plots`]).
fn write_plots(
    prefix: &Path,
    estimate: &[slamesh_core::Pose],
    reference: &[slamesh_core::Pose],
    ate: f64,
) -> Result<(), CliError> {
    use crate::outputs::topview::plots;
    let align = eval::rigid_alignment(estimate, reference);
    let aligned: Vec<_> = estimate.iter().map(|p| align * p).collect();
    let errors = eval::ate_errors(estimate, reference);
    let distance = eval::distances_along(reference);
    let name = |suffix: &str| {
        let stem = prefix.file_name().unwrap_or_default().to_string_lossy();
        prefix.with_file_name(format!("{stem}_{suffix}.png"))
    };
    let (trajectory, error) = (name("trajectory"), name("error"));
    plots::trajectories(&aligned, reference, ate, 1200).write_png(&trajectory)?;
    plots::error_over_distance(&distance, &errors, 1200).write_png(&error)?;
    log::info!("plots: {}, {}", trajectory.display(), error.display());
    Ok(())
}
