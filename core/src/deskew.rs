//! Deskewing: moving each point of a sweep to where the sensor would have seen it at the
//! scan's reference time (docs/design.md §1.9).
//!
//! A spinning LiDAR takes 0.05 to 0.2 s for a sweep, and the sensor moves meanwhile: each
//! point is measured from the pose the sensor had at its own time. With a constant body
//! velocity, the sensor's pose at `t` seconds after the reference time, in the reference
//! sensor frame, is `exp(t/Δ · log(M))`, where `M` is the last motion between two scans
//! (taken `Δ` seconds apart), the constant-velocity model the registration also predicts with.
//! A point `p` taken at `t` is therefore `exp(t/Δ · log(M)) · p` in the reference frame.
//! KISS-ICP deskews the same way (with the prediction, once, before registration).
//!
//! The reference time is the middle of the scan's time span, not its stamp. An error `δ` in
//! the motion then bends the scan symmetrically, points before the middle one way and points
//! after it the other, and registration's pose keeps no bias from it. Deskewed to one end
//! of the sweep, every point would move the same way, the estimate would take half of `δ`
//! into the next motion, and the loop between the two oscillates (docs/design.md §1.9). A
//! caller that wants the pose at the stamp moves it there with [`pose_at`].
//!
//! The exponential is evaluated at [`STEPS`] + 1 instants spread over the scan's times, and
//! each point is interpolated linearly between the two transforms around its time: for a
//! sweep that turns 0.3 rad, the interpolation is off by at most (0.3/64)²/8 · 50 m = 0.14 mm at 50 m. No allocation:
//! the table is on the stack (about 3 KB).

use crate::math::{renormalized, se3_exp, se3_log, Point, Pose};
use nalgebra::{Matrix3, Vector3};

/// Intervals of the transform table over a sweep's time span.
pub const STEPS: usize = 64;

/// Why a scan could not be deskewed; its points are left as they were.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DeskewError {
    /// The times and the points differ in number.
    LengthMismatch {
        /// Points.
        points: usize,
        /// Times.
        times: usize,
    },
    /// The motion's duration is not a positive finite number of seconds.
    BadInterval,
    /// The motion is not finite.
    BadMotion,
    /// The IMU's readings do not cover the sweep.
    Imu(crate::imu::ImuGap),
}

/// A transform in `f32`, applied to points.
#[derive(Clone, Copy)]
struct Affine {
    r: Matrix3<f32>,
    t: Vector3<f32>,
}

impl Affine {
    fn of(p: &Pose) -> Self {
        Self {
            r: p.rotation.to_rotation_matrix().matrix().map(|v| v as f32),
            t: p.translation.vector.map(|v| v as f32),
        }
    }

    #[inline]
    fn apply(&self, p: &Vector3<f32>) -> Vector3<f32> {
        self.r * p + self.t
    }
}

/// What [`deskew`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Deskewed {
    /// Points moved (those with a finite time).
    pub moved: usize,
    /// The reference time the points were moved to (seconds, on the scale of the times): the
    /// middle of their span.
    pub reference_s: f64,
}

/// Moves each point `points[i]`, measured at `times_s[i]` (seconds, from any origin such as
/// the scan's stamp), into the sensor frame at the middle of the times' span, for a sensor
/// that moved by `motion` (the body-frame motion `T_before⁻¹ · T_last` between two scans) in
/// `interval_s` seconds. Points with a non-finite time are left as they are.
pub fn deskew(
    points: &mut [Point],
    times_s: &[f32],
    motion: &Pose,
    interval_s: f64,
) -> Result<Deskewed, DeskewError> {
    if !(interval_s.is_finite() && interval_s > 0.0) {
        return Err(DeskewError::BadInterval);
    }
    let xi = se3_log(motion) / interval_s;
    if !xi.iter().all(|v| v.is_finite()) {
        return Err(DeskewError::BadMotion);
    }
    deskew_by(points, times_s, |t, mid| Ok(se3_exp(&(xi * (t - mid)))))
}

/// [`deskew`] with the sensor's motion over the sweep given by `pose_at(t, reference)`: its
/// pose at time `t` in its frame at the `reference` time (an IMU's rotation, say:
/// [`crate::imu`]). `pose_at` is asked at [`STEPS`] + 1 instants; its first error is returned
/// with every point left as it was.
pub fn deskew_by(
    points: &mut [Point],
    times_s: &[f32],
    mut pose_at: impl FnMut(f64, f64) -> Result<Pose, DeskewError>,
) -> Result<Deskewed, DeskewError> {
    if points.len() != times_s.len() {
        return Err(DeskewError::LengthMismatch {
            points: points.len(),
            times: times_s.len(),
        });
    }
    let Some((lo, hi)) = time_span(times_s) else {
        return Ok(Deskewed {
            moved: 0,
            reference_s: 0.0,
        });
    };
    let span = (hi - lo).max(f32::MIN_POSITIVE);
    let mid = (lo as f64 + hi as f64) / 2.0;
    let mut table = [Affine::of(&Pose::identity()); STEPS + 1];
    for (k, entry) in table.iter_mut().enumerate() {
        let t = lo as f64 + span as f64 * k as f64 / STEPS as f64;
        *entry = Affine::of(&pose_at(t, mid)?);
    }
    let mut moved = 0;
    for (p, &t) in points.iter_mut().zip(times_s) {
        if !t.is_finite() {
            continue;
        }
        let x = (t - lo) / span * STEPS as f32;
        let k = (x as usize).min(STEPS - 1);
        let a = x - k as f32;
        let v = Vector3::new(p[0], p[1], p[2]);
        let q = table[k].apply(&v) * (1.0 - a) + table[k + 1].apply(&v) * a;
        *p = [q.x, q.y, q.z];
        moved += 1;
    }
    Ok(Deskewed {
        moved,
        reference_s: mid,
    })
}

/// The earliest and the latest finite time, if any: the sweep's span.
pub fn time_span(times_s: &[f32]) -> Option<(f32, f32)> {
    let (lo, hi) = times_s
        .iter()
        .filter(|t| t.is_finite())
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), &t| {
            (l.min(t), h.max(t))
        });
    (lo <= hi).then_some((lo, hi))
}

/// The pose `dt_s` seconds after `pose`, moving with the constant body velocity of `motion`
/// over `interval_s` seconds: `pose · exp(dt/Δ · log(M))`. With `dt_s` the stamp's time minus
/// [`Deskewed::reference_s`], it turns the pose registration found for a deskewed scan into
/// the pose at the scan's stamp.
pub fn pose_at(pose: &Pose, motion: &Pose, interval_s: f64, dt_s: f64) -> Pose {
    renormalized(pose * se3_exp(&(se3_log(motion) * (dt_s / interval_s))))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{to_point, to_vec3, Twist};

    /// A sensor turning at 3 rad/s and moving at 10 m/s sees fixed world points at their
    /// own times; deskewing brings them back to the reference frame.
    #[test]
    fn deskewed_points_are_where_the_reference_pose_sees_them() {
        let velocity = Twist::new(0.1, -0.2, 3.0, 10.0, 0.5, 0.0);
        let interval = 0.1;
        let motion = se3_exp(&(velocity * interval));
        let world: [[f64; 3]; 5] = [
            [50.0, 0.0, 1.0],
            [0.0, -30.0, -2.0],
            [-5.0, 5.0, 0.0],
            [10.0, 40.0, 3.0],
            [-45.0, -10.0, 0.5],
        ];
        let times = [-0.05f32, -0.01, 0.0, 0.03, 0.05];
        let mut seen: [Point; 5] = core::array::from_fn(|i| {
            let sensor = se3_exp(&(velocity * times[i] as f64));
            to_point(
                &(sensor.inverse() * nalgebra::Point3::from(crate::math::Vec3::from(world[i])))
                    .coords,
            )
        });
        let d = deskew(&mut seen, &times, &motion, interval).unwrap();
        assert_eq!(d.moved, 5);
        assert!(d.reference_s.abs() < 1e-9, "the middle of -0.05..0.05");
        for (p, w) in seen.iter().zip(world) {
            let err = (to_vec3(p) - crate::math::Vec3::from(w)).norm();
            assert!(err < 2e-4 * 50.0, "{p:?} vs {w:?}: {err}");
        }
        // Times from 0 to 0.1 s: the points land in the frame at 0.05 s, and `pose_at` takes
        // that frame's pose back to the stamp.
        let later = [0.0f32, 0.04, 0.05, 0.08, 0.1];
        let mut seen: [Point; 5] = core::array::from_fn(|i| {
            let sensor = se3_exp(&(velocity * later[i] as f64));
            to_point(
                &(sensor.inverse() * nalgebra::Point3::from(crate::math::Vec3::from(world[i])))
                    .coords,
            )
        });
        let d = deskew(&mut seen, &later, &motion, interval).unwrap();
        assert!((d.reference_s - 0.05).abs() < 1e-7);
        let mid = se3_exp(&(velocity * 0.05));
        for (p, w) in seen.iter().zip(world) {
            let back = mid * nalgebra::Point3::from(to_vec3(p));
            let err = (back.coords - crate::math::Vec3::from(w)).norm();
            assert!(err < 2e-4 * 50.0, "{p:?} vs {w:?}: {err}");
        }
        let stamp = pose_at(&mid, &motion, interval, -d.reference_s);
        assert!((stamp.translation.vector.norm()) < 1e-6, "{stamp}");
    }

    #[test]
    fn bad_input_leaves_the_points_alone() {
        let mut pts = [[1.0f32, 2.0, 3.0]; 2];
        let m = Pose::identity();
        assert_eq!(
            deskew(&mut pts, &[0.0], &m, 0.1),
            Err(DeskewError::LengthMismatch {
                points: 2,
                times: 1
            })
        );
        assert_eq!(
            deskew(&mut pts, &[0.0; 2], &m, 0.0),
            Err(DeskewError::BadInterval)
        );
        assert_eq!(deskew(&mut pts, &[f32::NAN; 2], &m, 0.1).unwrap().moved, 0);
        assert_eq!(pts, [[1.0, 2.0, 3.0]; 2]);
    }
}
