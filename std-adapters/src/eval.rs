//! Odometry error metrics against reference poses (DESIGN §3).

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
}
