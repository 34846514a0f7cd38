//! Odometry error metrics against reference poses (docs/design.md §3): consecutive-frame errors,
//! end-point drift, ATE after rigid alignment, and KITTI's segment errors.

use nalgebra::{Matrix3, Vector3};
use slamesh_core::Pose;

/// Consecutive-frame errors of an estimated trajectory.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConsecutiveErrors {
    /// Mean translation error of the frame-to-frame motion (metres).
    pub mean_translation_m: f64,
    /// Mean rotation error of the frame-to-frame motion (degrees).
    pub mean_rotation_deg: f64,
    /// Largest translation error (metres).
    pub max_translation_m: f64,
    /// Number of frame pairs compared.
    pub pairs: usize,
}

/// Compares the motion between consecutive frames: for each `i`, the error transform
/// `inv(ref_{i-1}⁻¹ ref_i) · (est_{i-1}⁻¹ est_i)`. Uses the common prefix of both trajectories.
pub fn consecutive_errors(estimate: &[Pose], reference: &[Pose]) -> ConsecutiveErrors {
    let n = estimate.len().min(reference.len());
    let (mut t_sum, mut r_sum, mut t_max) = (0.0, 0.0, 0.0f64);
    for i in 1..n {
        let de = estimate[i - 1].inverse() * estimate[i];
        let dr = reference[i - 1].inverse() * reference[i];
        let e = dr.inverse() * de;
        let t = e.translation.vector.norm();
        t_sum += t;
        t_max = t_max.max(t);
        r_sum += e.rotation.angle().to_degrees();
    }
    let pairs = n.saturating_sub(1);
    let d = pairs.max(1) as f64;
    ConsecutiveErrors {
        mean_translation_m: t_sum / d,
        mean_rotation_deg: r_sum / d,
        max_translation_m: t_max,
        pairs,
    }
}

/// Path length of a trajectory (metres): the sum of its steps.
pub fn path_length(poses: &[Pose]) -> f64 {
    distances_along(poses).last().copied().unwrap_or(0.0)
}

/// The distance travelled to each pose from the first (metres): 0 first, then the running sum
/// of the steps.
pub fn distances_along(poses: &[Pose]) -> Vec<f64> {
    let mut along = 0.0;
    let mut out = Vec::with_capacity(poses.len());
    for (k, p) in poses.iter().enumerate() {
        if let Some(before) = k.checked_sub(1).map(|j| &poses[j]) {
            along += (p.translation.vector - before.translation.vector).norm();
        }
        out.push(along);
    }
    out
}

/// End-point drift: the distance between the last estimated and last reference positions
/// (metres) and as a percentage of the reference path. Uses the common prefix.
pub fn end_drift(estimate: &[Pose], reference: &[Pose]) -> (f64, f64) {
    let n = estimate.len().min(reference.len());
    if n < 2 {
        return (0.0, 0.0);
    }
    let end = (estimate[n - 1].translation.vector - reference[n - 1].translation.vector).norm();
    let path = path_length(&reference[..n]);
    (end, if path > 0.0 { 100.0 * end / path } else { 0.0 })
}

/// The rigid transform that best maps the estimated positions onto the reference ones
/// (Kabsch/Umeyama without scale), over the common prefix; the identity for no poses.
pub fn rigid_alignment(estimate: &[Pose], reference: &[Pose]) -> Pose {
    let n = estimate.len().min(reference.len());
    if n == 0 {
        return Pose::identity();
    }
    let p: Vec<Vector3<f64>> = estimate[..n].iter().map(|t| t.translation.vector).collect();
    let q: Vec<Vector3<f64>> = reference[..n]
        .iter()
        .map(|t| t.translation.vector)
        .collect();
    let mp = p.iter().sum::<Vector3<f64>>() / n as f64;
    let mq = q.iter().sum::<Vector3<f64>>() / n as f64;
    let mut h = Matrix3::zeros();
    for (a, b) in p.iter().zip(&q) {
        h += (a - mp) * (b - mq).transpose();
    }
    let rotation =
        nalgebra::UnitQuaternion::from_rotation_matrix(&slamesh_core::math::best_rotation(&h));
    let translation = mq - rotation * mp;
    Pose::from_parts(translation.into(), rotation)
}

/// Each estimated position's distance from its reference after the [`rigid_alignment`], over
/// the common prefix.
pub fn ate_errors(estimate: &[Pose], reference: &[Pose]) -> Vec<f64> {
    let align = rigid_alignment(estimate, reference);
    estimate
        .iter()
        .zip(reference)
        .map(|(e, r)| ((align * e).translation.vector - r.translation.vector).norm())
        .collect()
}

/// Absolute trajectory error: RMSE of the position differences after the
/// [`rigid_alignment`]. Uses the common prefix.
pub fn ate_rmse(estimate: &[Pose], reference: &[Pose]) -> f64 {
    let e = ate_errors(estimate, reference);
    if e.is_empty() {
        return 0.0;
    }
    (e.iter().map(|v| v * v).sum::<f64>() / e.len() as f64).sqrt()
}

/// KITTI's relative error over one segment length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SegmentError {
    /// Segment length (metres).
    pub length_m: f64,
    /// Mean translation error, percent of the length.
    pub translation_percent: f64,
    /// Mean rotation error, degrees per 100 m.
    pub rotation_deg_per_100m: f64,
    /// Segments averaged.
    pub segments: usize,
}

/// The KITTI odometry benchmark's segment lengths (metres).
pub const KITTI_SEGMENTS: [f64; 8] = [100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0];

/// KITTI's relative errors (the devkit's protocol): from every 10th frame, the segment to
/// the first frame at least `length` metres further along the reference path; the error is
/// the difference of the relative motions over it. Lengths the run is too short for are left
/// out.
pub fn segment_errors(estimate: &[Pose], reference: &[Pose], lengths: &[f64]) -> Vec<SegmentError> {
    let n = estimate.len().min(reference.len());
    let dist = distances_along(&reference[..n]);
    lengths
        .iter()
        .filter_map(|&length| {
            let (mut t, mut r, mut count) = (0.0, 0.0, 0);
            for first in (0..n).step_by(10) {
                let Some(last) = (first..n).find(|&j| dist[j] >= dist[first] + length) else {
                    break;
                };
                let dr = reference[first].inverse() * reference[last];
                let de = estimate[first].inverse() * estimate[last];
                let e = dr.inverse() * de;
                t += e.translation.vector.norm() / length;
                r += e.rotation.angle().to_degrees() / length;
                count += 1;
            }
            (count > 0).then(|| SegmentError {
                length_m: length,
                translation_percent: 100.0 * t / count as f64,
                rotation_deg_per_100m: 100.0 * r / count as f64,
                segments: count,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    #[test]
    fn identical_trajectories_give_zero_and_a_known_offset_its_size() {
        let traj: Vec<Pose> = (0..5)
            .map(|i| {
                Pose::from_parts(
                    Translation3::new(i as f64, 0.0, 0.0),
                    UnitQuaternion::from_euler_angles(0.0, 0.0, 0.05 * i as f64),
                )
            })
            .collect();
        let e = consecutive_errors(&traj, &traj);
        assert!(e.mean_translation_m < 1e-12 && e.mean_rotation_deg < 1e-9 && e.pairs == 4);
        // Every estimated step 2 cm longer along the body x axis.
        let mut est = vec![traj[0]];
        for i in 1..5 {
            let step = traj[i - 1].inverse() * traj[i];
            est.push(est[i - 1] * Translation3::new(0.02, 0.0, 0.0) * step);
        }
        let e = consecutive_errors(&est, &traj);
        assert!(
            (e.mean_translation_m - 0.02).abs() < 1e-9,
            "{}",
            e.mean_translation_m
        );
    }

    /// A drive of `n` 1 m steps turning by `yaw` radians a step.
    fn drive(n: usize, yaw: f64) -> Vec<Pose> {
        let mut poses = vec![Pose::identity()];
        let step = Pose::from_parts(
            Translation3::new(1.0, 0.0, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
        );
        for i in 1..n {
            poses.push(poses[i - 1] * step);
        }
        poses
    }

    #[test]
    fn the_distance_along_a_path_sums_its_steps() {
        let p = |x: f64, y: f64| Pose::translation(x, y, 0.0);
        let path = [p(0.0, 0.0), p(3.0, 4.0), p(3.0, 4.0), p(3.0, 5.0)];
        assert_eq!(distances_along(&path), vec![0.0, 5.0, 5.0, 6.0]);
        assert_eq!(path_length(&path), 6.0);
        assert!(distances_along(&[]).is_empty());
        assert_eq!(path_length(&[]), 0.0);
    }

    #[test]
    fn drift_ate_and_segments_have_their_known_values() {
        let truth = drive(400, 0.01);
        assert_eq!(end_drift(&truth, &truth), (0.0, 0.0));
        assert!(ate_rmse(&truth, &truth) < 1e-9);
        assert!(segment_errors(&truth, &truth, &KITTI_SEGMENTS)
            .iter()
            .all(|s| s.translation_percent < 1e-9));
        // Straight, every step 1 % too long: 1 % error on every segment, 1 % end drift.
        let truth = drive(400, 0.0);
        let mut est = vec![truth[0]];
        for i in 1..truth.len() {
            let step = truth[i - 1].inverse() * truth[i];
            let longer = Pose::from_parts(
                Translation3::from(step.translation.vector * 1.01),
                step.rotation,
            );
            est.push(est[i - 1] * longer);
        }
        let segs = segment_errors(&est, &truth, &KITTI_SEGMENTS);
        assert_eq!(
            segs.len(),
            3,
            "a 399 m path has 100, 200 and 300 m segments"
        );
        for s in &segs {
            assert!((s.translation_percent - 1.0).abs() < 0.02, "{s:?}");
            assert!(s.rotation_deg_per_100m < 1e-6);
        }
        let (_, percent) = end_drift(&est, &truth);
        assert!((percent - 1.0).abs() < 0.05, "{percent}");
        // A rigidly moved copy has no ATE.
        let truth = drive(400, 0.01);
        let moved: Vec<Pose> = truth
            .iter()
            .map(|p| {
                Pose::from_parts(
                    Translation3::new(5.0, -2.0, 1.0),
                    UnitQuaternion::from_euler_angles(0.0, 0.0, 0.3),
                ) * p
            })
            .collect();
        assert!(ate_rmse(&moved, &truth) < 1e-9);
        let (a, b) = (
            vec![Pose::identity(); 2],
            vec![Pose::identity(), Pose::translation(0.0, 0.0, 2.0)],
        );
        assert!(
            (ate_rmse(&a, &b) - 1.0).abs() < 1e-12,
            "aligned at the centroid: 1 m each"
        );
    }
}
