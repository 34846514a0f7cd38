//! The `path` message, bounded: the trajectory in `map` from the first pose to the last, at
//! most [`MAX_POSES`] poses. Past that, every other pose is dropped and from then on only
//! every second frame's is kept (the stride doubles each time), so the message spans the whole
//! run ever more thinly and the newest pose is always its last: at most 147 KB in CDR, sent
//! each frame, where keeping every pose grew the message and the node's memory with the run
//! (36 000 poses an hour at 10 Hz: 2.6 MB a message; both serialised by rclpy, frame `map`).
//!
//! Each kept pose remembers its frame, so a loop closure's corrected trajectory (every used
//! frame's pose) moves each kept pose to its own frame's correction.

use crate::ros2::messages::{Header, PathMsg, PoseStamped};

/// The most poses the message holds.
pub const MAX_POSES: usize = 2048;

/// The trajectory message and the frame of each of its poses.
pub struct BoundedPath {
    msg: PathMsg,
    /// The used frame (counted from 0) of each pose in `msg`.
    frames: Vec<usize>,
    /// Frames pushed.
    pushed: usize,
    /// Frames kept: those whose number is a multiple of this (and the newest).
    stride: usize,
}

impl BoundedPath {
    /// An empty path in `frame_id`.
    pub fn new(frame_id: String) -> Self {
        BoundedPath {
            msg: PathMsg {
                header: Header {
                    frame_id,
                    ..Header::default()
                },
                poses: Vec::new(),
            },
            frames: Vec::new(),
            pushed: 0,
            stride: 1,
        }
    }

    /// Adds the next used frame's pose (its stamp the message's).
    pub fn push(&mut self, pose: PoseStamped) {
        let frame = self.pushed;
        self.pushed += 1;
        self.msg.header.stamp = pose.header.stamp;
        // The newest pose off the stride stands in until the next one comes.
        if self.frames.last().is_some_and(|f| f % self.stride != 0) {
            self.frames.pop();
            self.msg.poses.pop();
        }
        if self.frames.len() == MAX_POSES {
            self.thin();
        }
        self.frames.push(frame);
        self.msg.poses.push(pose);
    }

    /// Keeps every other pose of the stride and doubles it.
    fn thin(&mut self) {
        self.stride *= 2;
        let keep: Vec<bool> = self.frames.iter().map(|f| f % self.stride == 0).collect();
        let mut k = keep.iter();
        self.frames.retain(|_| *k.next().unwrap_or(&true));
        let mut k = keep.iter();
        self.msg.poses.retain(|_| *k.next().unwrap_or(&true));
    }

    /// Moves each pose to `corrected`'s for its frame (`corrected`: every used frame's,
    /// in order, as `pose_of` turns it into the message's), when it holds every frame pushed.
    pub fn correct<T>(
        &mut self,
        corrected: &[T],
        pose_of: impl Fn(&T) -> crate::ros2::messages::PoseMsg,
    ) {
        if corrected.len() != self.pushed {
            return;
        }
        for (p, f) in self.msg.poses.iter_mut().zip(&self.frames) {
            p.pose = pose_of(&corrected[*f]);
        }
    }

    /// The message.
    pub fn msg(&self) -> &PathMsg {
        &self.msg
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ros2::messages::{PoseMsg, Time};

    fn at(frame: usize) -> PoseStamped {
        PoseStamped {
            header: Header {
                stamp: Time::from_seconds(frame as f64),
                frame_id: "map".into(),
            },
            pose: PoseMsg::from(&slamesh_core::Pose::translation(frame as f64, 0.0, 0.0)),
        }
    }

    #[test]
    fn a_long_run_s_path_stays_bounded_and_spans_it_from_first_to_newest() {
        let mut path = BoundedPath::new("map".into());
        for f in 0..10_000 {
            path.push(at(f));
            assert!(path.msg().poses.len() <= MAX_POSES);
        }
        let poses = &path.msg().poses;
        assert_eq!(poses[0].pose.position.x, 0.0);
        assert_eq!(poses.last().unwrap().pose.position.x, 9_999.0);
        assert_eq!(path.msg().header.stamp, Time::from_seconds(9_999.0));
        // Evenly thinned: a stride of 8 after three halvings (10 000 / 8 = 1 250, and the newest).
        let gaps: Vec<f64> = poses
            .windows(2)
            .map(|w| w[1].pose.position.x - w[0].pose.position.x)
            .collect();
        assert!(
            gaps[..gaps.len() - 1].iter().all(|g| *g == 8.0),
            "{:?}",
            &gaps[..5]
        );
        assert_eq!(poses.len(), 1251);
        // A correction moves each pose to its own frame's.
        let corrected: Vec<f64> = (0..10_000).map(|f| f as f64 + 0.5).collect();
        path.correct(&corrected, |x| {
            PoseMsg::from(&slamesh_core::Pose::translation(*x, 0.0, 0.0))
        });
        assert_eq!(path.msg().poses[1].pose.position.x, 8.5);
        assert_eq!(path.msg().poses.last().unwrap().pose.position.x, 9_999.5);
        // One of another length is not this run's: left alone.
        path.correct(&corrected[..10], |_| PoseMsg::default());
        assert_eq!(path.msg().poses[1].pose.position.x, 8.5);
    }

    #[test]
    fn a_short_path_keeps_every_pose() {
        let mut path = BoundedPath::new("map".into());
        for f in 0..100 {
            path.push(at(f));
        }
        assert_eq!(path.msg().poses.len(), 100);
    }
}
