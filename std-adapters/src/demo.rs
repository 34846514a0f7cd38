//! The demo: a simulated drive through the procedural town, SLAM on it, and its accuracy
//! against the truth, with every output of `run` plus the true trajectory and a picture.

use crate::eval::mesh::{self as mesh_eval, MeshScore};
use crate::eval::odometry::{
    ate_rmse, consecutive_errors, end_drift, path_length, segment_errors, ConsecutiveErrors,
    SegmentError, KITTI_SEGMENTS,
};
use crate::formats::ply;
use crate::formats::trajectory::write_kitti_line;
use crate::io::atomic::write_atomic;
use crate::io::FileError;
use crate::outputs::mesh_spool::MeshFormat;
use crate::outputs::topview::map::{self, MapPicture};
use crate::run::report::{PICTURE_MARGIN_M, PICTURE_PIXELS};
use crate::run::{FrameRecord, Run, RunError, RunOptions, Summary};
use slamesh_core::{Capacity, Point, Pose};
use slamesh_sim::{Drive, SurfaceDistance};

/// What the demo measured.
#[derive(Debug, Clone)]
pub struct DemoReport {
    /// The run.
    pub summary: Summary,
    /// Frames driven.
    pub frames: usize,
    /// Path length of the true trajectory (metres).
    pub path_m: f64,
    /// Consecutive-frame errors.
    pub consecutive: ConsecutiveErrors,
    /// End-point error (metres) and as percent of the path.
    pub end_drift: (f64, f64),
    /// ATE after rigid alignment (metres).
    pub ate_m: f64,
    /// KITTI segment errors for the lengths the drive covers.
    pub segments: Vec<SegmentError>,
    /// Mesh accuracy: precision by exact distance to the true surfaces, recall of the true
    /// surfaces where the sensor saw them.
    pub mesh: Vec<MeshScore>,
}

/// Runs the demo: `frames` frames of [`Drive::town`] with seed `seed`, outputs into
/// `opts.out` (`opts.given_poses` is ignored; `mesh.ply` is always written, and scored as
/// written). Adds `poses_true_kitti.txt`, `reference.ply` (the true surfaces where the sensor
/// saw them, one point per 5 cm) and `topview.png`.
pub fn run_demo<C: Capacity>(
    frames: usize,
    seed: u64,
    opts: &RunOptions,
    on_frame: impl FnMut(&FrameRecord),
) -> Result<DemoReport, RunError> {
    let mut drive = Drive::town(frames, seed);
    let mut mesh_formats = opts.mesh_formats.clone();
    if !mesh_formats.contains(&MeshFormat::Ply) {
        mesh_formats.push(MeshFormat::Ply);
    }
    let opts = RunOptions {
        given_poses: None,
        mesh_formats,
        ..opts.clone()
    };
    let mut on_frame = on_frame;
    let mut run = Run::<C>::start(&drive, &opts)?;
    for i in 0..drive.poses.len() {
        on_frame(&run.step(&mut drive, i)?);
    }
    let summary = run.finish(&drive)?;
    // The mesh as written (welded), read back.
    let triangles: Vec<[Point; 3]> = ply::read_ply_mesh(&opts.out.join("mesh.ply"))?
        .triangle_corners()
        .collect();
    let truth: Vec<Pose> = drive
        .poses
        .iter()
        .map(|p| drive.poses[0].inverse() * p)
        .collect();
    let mut estimate = vec![Pose::identity(); truth.len()];
    for (i, p) in &summary.poses {
        estimate[*i] = *p;
    }
    write_atomic(&opts.out.join("poses_true_kitti.txt"), |w| {
        truth.iter().try_for_each(|p| write_kitti_line(w, p))
    })?;

    // The mesh against the true surfaces, both in the first sensor frame.
    let (scores, reference) = true_surface_scores(&drive, &triangles, seed, &mesh_eval::THRESHOLDS);
    ply::write_points(&opts.out.join("reference.ply"), &reference)?;

    // The picture, as a run's (its legend, colour scale, start and end), with the true path in
    // white under the estimate.
    let how = MapPicture {
        pixels: PICTURE_PIXELS,
        margin_m: PICTURE_MARGIN_M,
        z_lo: -3.0,
        z_top: triangles
            .iter()
            .flatten()
            .map(|v| v[2])
            .fold(2.0f32, f32::max)
            .min(20.0),
    };
    let all = |f: &mut dyn FnMut([Point; 3])| -> Result<(), FileError> {
        triangles.iter().for_each(|t| f(*t));
        Ok(())
    };
    let (mut view, _) = map::draw(all, &estimate, Some(&truth), how)?;
    view.write_png(&opts.out.join("topview.png"))?;

    Ok(DemoReport {
        frames: truth.len(),
        path_m: path_length(&truth),
        consecutive: consecutive_errors(&estimate, &truth),
        end_drift: end_drift(&estimate, &truth),
        ate_m: ate_rmse(&estimate, &truth),
        segments: segment_errors(&estimate, &truth, &KITTI_SEGMENTS),
        mesh: scores,
        summary,
    })
}

/// Scores of a mesh (`triangles`, in the drive's first sensor frame, sampled every 5 cm from
/// `seed`) against the drive's true surfaces at each of `thresholds`: precision by the exact
/// distance of each sample to the scene, recall from the true hits of every fifth frame (one
/// point per 5 cm), which are returned too.
pub fn true_surface_scores(
    drive: &Drive,
    triangles: &[[Point; 3]],
    seed: u64,
    thresholds: &[f64],
) -> (Vec<MeshScore>, Vec<Point>) {
    let to_first = drive.poses[0].inverse();
    let reference = mesh_eval::accumulate(
        (0..drive.poses.len())
            .step_by(5)
            .map(|i| (drive.true_points(i), to_first)),
        0.05,
        0.0,
        f64::INFINITY,
    );
    let samples = mesh_eval::sample_triangles(triangles.iter().copied(), 0.05, seed);
    let truth_distance = SurfaceDistance::new(&drive.scene);
    let d_mesh: Vec<f64> = samples
        .iter()
        .map(|p| {
            let w = drive.poses[0] * nalgebra::Point3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            truth_distance.distance(&w.coords)
        })
        .collect();
    let scores =
        mesh_eval::score_with_precision_distances(&d_mesh, &samples, &reference, thresholds);
    (scores, reference)
}
