//! The robot's static transforms as the node reads them on `/tf_static` (a
//! `robot_state_publisher`'s): the LiDAR's place on the robot when no `lidar_in_base`
//! parameter gives it, and the IMU's on the LiDAR when the configuration's `[imu]` does not
//! ([`imu_on_lidar`]).
//!
//! What it guarantees: at most [`KEPT`] transforms are kept (the last one heard for each parent
//! and child; a transform that is not finite, or past the limit, is passed over), so that a
//! robot's whole tree costs a few kilobytes and a flood of them nothing more.

use crate::ros2::messages::TfMessage;
use slamesh_core::Pose;
use std::sync::{Arc, Mutex};

/// Transforms kept, at most.
pub const KEPT: usize = 256;

/// The static transforms heard so far, shared between the listening thread and the run.
#[derive(Debug, Clone, Default)]
pub struct StaticTransforms(Arc<Mutex<Vec<(String, String, Pose)>>>);

impl StaticTransforms {
    /// Keeps `message`'s transforms (parent frame, child frame, the child in the parent).
    pub fn keep(&self, message: &TfMessage) {
        let Ok(mut kept) = self.0.lock() else { return };
        for t in &message.transforms {
            let Some(pose) = t.transform.to_pose() else {
                continue;
            };
            let (parent, child) = (bare(&t.header.frame_id), bare(&t.child_frame_id));
            let at = kept.iter().position(|(p, c, _)| p == parent && c == child);
            match at {
                Some(k) => kept[k].2 = pose,
                None if kept.len() < KEPT => {
                    kept.push((parent.to_string(), child.to_string(), pose))
                }
                None => {}
            }
        }
    }

    /// `child` in `parent`, if heard as one transform (frame names compared without a leading
    /// `/`, as tf2 does).
    pub fn lookup(&self, parent: &str, child: &str) -> Option<Pose> {
        let (parent, child) = (bare(parent), bare(child));
        let kept = self.0.lock().ok()?;
        kept.iter()
            .find(|(p, c, _)| p == parent && c == child)
            .map(|k| k.2)
    }
}

/// The IMU on the LiDAR, for readings in frame `imu` and scans in `scans` (when known), the
/// robot's frame `base` and the LiDAR at `lidar_in_base` on it: `base -> imu` as `transforms`
/// heard it, seen from the LiDAR. Readings in the scans' own frame are the LiDAR's axes, and in
/// `base` the robot's; `None` when `/tf_static` said nothing of `base -> imu`.
pub fn imu_on_lidar(
    (imu, scans, base): (&str, Option<&str>, &str),
    lidar_in_base: &Pose,
    transforms: &StaticTransforms,
) -> Option<Pose> {
    let imu_in_base = match scans {
        Some(s) if bare(s) == bare(imu) => *lidar_in_base,
        _ if bare(imu) == bare(base) => Pose::identity(),
        _ => transforms.lookup(base, imu)?,
    };
    Some(lidar_in_base.inverse() * imu_in_base)
}

/// A frame's name without its leading `/`.
fn bare(frame: &str) -> &str {
    frame.trim_start_matches('/')
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ros2::messages::{Header, PoseMsg, TransformStamped};

    fn transform(parent: &str, child: &str, x: f64) -> TransformStamped {
        let pose = Pose::translation(x, 0.0, 1.0);
        TransformStamped {
            header: Header {
                frame_id: parent.into(),
                ..Header::default()
            },
            child_frame_id: child.into(),
            transform: PoseMsg::from(&pose),
        }
    }

    #[test]
    fn the_last_transform_of_each_pair_is_kept_within_the_limit() {
        let s = StaticTransforms::default();
        s.keep(&TfMessage {
            transforms: vec![
                transform("base_link", "velodyne", 0.5),
                transform("base_link", "imu", 0.1),
            ],
        });
        s.keep(&TfMessage {
            transforms: vec![transform("/base_link", "velodyne", 0.7)],
        });
        let lidar = s.lookup("base_link", "/velodyne").unwrap();
        assert_eq!(lidar.translation.vector.x, 0.7, "the last one heard");
        assert_eq!(
            s.lookup("/base_link", "velodyne")
                .unwrap()
                .translation
                .vector
                .x,
            0.7
        );
        assert_eq!(
            s.lookup("base_link", "imu").unwrap().translation.vector.x,
            0.1
        );
        assert_eq!(s.lookup("velodyne", "base_link"), None);
        let mut bad = transform("base_link", "nan", 0.0);
        bad.transform.position.x = f64::NAN;
        let many: Vec<_> = (0..2 * KEPT)
            .map(|k| transform("a", &k.to_string(), 0.0))
            .collect();
        s.keep(&TfMessage {
            transforms: vec![bad],
        });
        s.keep(&TfMessage { transforms: many });
        assert_eq!(s.lookup("base_link", "nan"), None);
        assert_eq!(s.0.lock().unwrap().len(), KEPT);
    }

    #[test]
    fn the_imu_on_the_lidar_comes_from_the_robots_transforms() {
        use nalgebra::{UnitQuaternion, Vector3};
        let s = StaticTransforms::default();
        // The IMU 0.2 m ahead of the robot's origin, turned a quarter about z; the LiDAR 1 m up.
        let turned =
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), std::f64::consts::FRAC_PI_2);
        let imu_in_base = Pose::from_parts(nalgebra::Translation3::new(0.2, 0.0, 0.0), turned);
        let mut t = transform("base_link", "imu_link", 0.0);
        t.transform = PoseMsg::from(&imu_in_base);
        s.keep(&TfMessage {
            transforms: vec![t],
        });
        let lidar = Pose::translation(0.0, 0.0, 1.0);
        let frames = ("imu_link", Some("velodyne"), "base_link");
        let placed = imu_on_lidar(frames, &lidar, &s).unwrap();
        assert!((placed.translation.vector - Vector3::new(0.2, 0.0, -1.0)).norm() < 1e-12);
        // A reading of a turn about the IMU's x is one about the LiDAR's y.
        let about = placed.rotation * Vector3::x();
        assert!((about - Vector3::y()).norm() < 1e-12, "{about}");
        // In the scans' own frame: the LiDAR's axes; in the robot's: seen from the LiDAR.
        let own = imu_on_lidar(("/velodyne", Some("velodyne"), "base_link"), &lidar, &s);
        assert_eq!(own, Some(Pose::identity()));
        let robot = imu_on_lidar(("base_link", Some("velodyne"), "base_link"), &lidar, &s);
        assert_eq!(robot, Some(lidar.inverse()));
        // Nothing heard of it: the configuration's place stands.
        assert_eq!(
            imu_on_lidar(("imu", Some("velodyne"), "base_link"), &lidar, &s),
            None
        );
    }
}
