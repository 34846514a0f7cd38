//! Constant-velocity pose prediction (docs/design.md §1.1 step 2).
//!
//! Predicts `T_k = T_{k-1} · (T_{k-2}⁻¹ · T_{k-1})`: the last motion, expressed in the sensor
//! frame, repeated (constant body velocity, right for a turning vehicle). With fewer than two
//! poses the increment is the identity.

use crate::math::{renormalized, Pose, Vec3};

/// The last two poses.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ConstantVelocity {
    last: Option<Pose>,
    before: Option<Pose>,
}

impl ConstantVelocity {
    /// No history.
    pub const fn new() -> Self {
        Self {
            last: None,
            before: None,
        }
    }

    /// Records the pose of the newest scan.
    pub fn push(&mut self, t_world_sensor: Pose) {
        self.before = self.last;
        self.last = Some(renormalized(t_world_sensor));
    }

    /// The history `(before, last)`: what a checkpoint saves.
    pub fn history(&self) -> (Option<Pose>, Option<Pose>) {
        (self.before, self.last)
    }

    /// A model with the history `(before, last)` (from [`history`](Self::history)); a
    /// `before` without a `last` is dropped.
    pub fn from_history(before: Option<Pose>, last: Option<Pose>) -> Self {
        let mut m = Self::new();
        for p in [before, last].into_iter().flatten() {
            m.push(p);
        }
        if last.is_none() {
            m = Self::new();
        }
        m
    }

    /// Whether two poses are known, so the velocity is.
    pub fn velocity_known(&self) -> bool {
        self.before.is_some()
    }

    /// The newest pose.
    pub fn last(&self) -> Option<Pose> {
        self.last
    }

    /// The last step's translation as the world saw it (zero while the velocity is unknown):
    /// a start for a rig whose heading changes independently of its path.
    pub fn world_step(&self) -> Vec3 {
        match (self.before, self.last) {
            (Some(b), Some(l)) => l.translation.vector - b.translation.vector,
            _ => Vec3::zeros(),
        }
    }

    /// The predicted pose of the next scan.
    pub fn predict(&self) -> Pose {
        match (self.before, self.last) {
            (Some(b), Some(l)) => renormalized(l * (b.inverse() * l)),
            (None, Some(l)) => l,
            _ => Pose::identity(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    #[test]
    fn repeats_the_last_body_frame_motion() {
        let step = Pose::from_parts(
            Translation3::new(1.0, 0.0, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, 0.1),
        );
        let mut cv = ConstantVelocity::new();
        assert_eq!(cv.predict(), Pose::identity());
        cv.push(Pose::identity());
        assert_eq!(cv.predict(), Pose::identity());
        cv.push(step);
        let want = step * step;
        let got = cv.predict();
        assert!((got.translation.vector - want.translation.vector).norm() < 1e-12);
        assert!(got.rotation.angle_to(&want.rotation) < 1e-12);
    }

    #[test]
    fn a_long_run_of_predictions_keeps_a_unit_rotation() {
        // Before renormalisation the quaternion's norm error grew ~2.4x a frame: 1.8 by frame 43.
        let step = Pose::from_parts(
            Translation3::new(1.0, 0.02, 0.0),
            UnitQuaternion::from_euler_angles(0.001, -0.002, 0.013),
        );
        let mut cv = ConstantVelocity::new();
        cv.push(Pose::identity());
        cv.push(step);
        for _ in 0..10_000 {
            let p = cv.predict();
            assert!((p.rotation.coords.norm() - 1.0).abs() < 1e-12);
            let increment = cv.last().unwrap().inverse() * p;
            assert!((increment.translation.vector - step.translation.vector).norm() < 1e-9);
            cv.push(p);
        }
    }
}
