//! Things that move through a scene: cars in both lanes, people on the sidewalks, and parked
//! cars that pull out, each a box that follows a path at its own speed. A drive with
//! [`Traffic`] casts its rays into the scene and the movers where they are at the frame's
//! time, and tells each point's truth: static, or on a mover ([`Label`]).
//!
//! The movers stand still within one sweep (a rolling sweep's firings all see them where they
//! are at its start): at 10 m/s and 10 Hz that is up to a metre of smear a real sensor would
//! show, which the removal must not rely on.

use crate::scene::{OrientedBox, Scene};
use crate::town::Polyline;
use slamesh_core::random::SplitMix64;
use slamesh_core::Pose;

/// What a mover is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MoverKind {
    /// A car driving along its lane.
    Car,
    /// A person walking along a sidewalk.
    Pedestrian,
    /// A car parked by the road that pulls out and drives off.
    Leaving,
}

/// A box that follows a path: at `start_s` it stands `at_m` metres along the path, then moves
/// along it at `speed_m_s` (negative: against the path's direction), `lateral_m` to the left
/// of it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mover {
    /// What it is.
    pub kind: MoverKind,
    /// Half extents along its heading, across it and up (metres).
    pub half: [f64; 3],
    /// Offset to the left of the path (metres).
    pub lateral_m: f64,
    /// Where along the path it stands until `start_s` (metres).
    pub at_m: f64,
    /// Speed along the path (m/s).
    pub speed_m_s: f64,
    /// When it starts to move (seconds into the drive).
    pub start_s: f64,
}

/// The truth of a point, as SemanticKITTI's labels number it (a `u32` a point, moving classes
/// from 252 up).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Label {
    /// Part of the static scene.
    Static,
    /// On a moving car (252, `moving-car`); a parked car that leaves counts as one throughout.
    MovingCar,
    /// On a walking person (254, `moving-person`).
    MovingPerson,
}

impl Label {
    /// SemanticKITTI's number for it (0, unlabelled, for the static scene).
    pub fn semantic_kitti(self) -> u32 {
        match self {
            Label::Static => 0,
            Label::MovingCar => 252,
            Label::MovingPerson => 254,
        }
    }
}

/// Movers along one path through a scene.
#[derive(Debug, Clone)]
pub struct Traffic {
    line: Polyline,
    /// The movers.
    pub movers: Vec<Mover>,
}

/// How many of each kind [`Traffic::street`] places (the default: none).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TrafficCounts {
    /// Cars in the drive's own direction.
    pub same_way: usize,
    /// Cars coming the other way.
    pub oncoming: usize,
    /// People on the sidewalks.
    pub pedestrians: usize,
    /// Parked cars that pull out.
    pub leaving: usize,
}

impl TrafficCounts {
    /// The town drive: 18 cars in both lanes, 4 pedestrians, 2 parked cars that leave.
    pub const TOWN: TrafficCounts = TrafficCounts {
        same_way: 8,
        oncoming: 10,
        pedestrians: 4,
        leaving: 2,
    };
}

/// The lane of the cars going the path's way, to the left of it (m): beside the drive's car,
/// which keeps to the path.
const SAME_WAY_LANE_M: f64 = -2.4;
/// The oncoming lane (m).
const ONCOMING_LANE_M: f64 = 2.6;
/// Where the parked cars stand (m): the kerb on the right.
const KERB_M: f64 = -3.6;
/// The sidewalks' walking line (m), either side.
const SIDEWALK_M: f64 = 7.4;
/// Added to a drive's seed for its traffic's draws (the scene's own stay as they were).
const TRAFFIC_SEED: u64 = 0x7_4a_ff_1c;
/// A car's half extents (m).
const CAR_HALF: [f64; 3] = [2.2, 0.9, 0.75];
/// A person's half extents (m).
const PERSON_HALF: [f64; 3] = [0.3, 0.3, 0.87];

impl Traffic {
    /// No movers along `path`.
    pub fn new(path: Vec<[f64; 2]>, closed: bool) -> Self {
        Traffic {
            line: Polyline::new(path, closed),
            movers: Vec::new(),
        }
    }

    /// Movers along a street drive's `path` (the drive starts at its beginning and covers
    /// about `reach_m` of it), deterministic from `seed`: cars going its way start within
    /// `reach_m` ahead at 6 to 12 m/s in the lane beside it; oncoming cars start up to twice as
    /// far ahead at 7 to 12 m/s; people walk either sidewalk at 1 to 1.6 m/s; parked cars
    /// stand at the kerb a quarter and two thirds of the way, and pull out at 6 m/s some
    /// seconds after the drive passed them (a revisit finds them gone).
    pub fn street(
        path: Vec<[f64; 2]>,
        closed: bool,
        reach_m: f64,
        counts: TrafficCounts,
        seed: u64,
    ) -> Self {
        let mut traffic = Traffic::new(path, closed);
        let mut rng = SplitMix64(seed.wrapping_add(TRAFFIC_SEED));
        let car = |lateral_m, at_m, speed_m_s, kind| Mover {
            kind,
            half: CAR_HALF,
            lateral_m,
            at_m,
            speed_m_s,
            start_s: 0.0,
        };
        for _ in 0..counts.same_way {
            let (at, speed) = (rng.range(15.0, reach_m), rng.range(6.0, 12.0));
            traffic
                .movers
                .push(car(SAME_WAY_LANE_M, at, speed, MoverKind::Car));
        }
        for _ in 0..counts.oncoming {
            let (at, speed) = (rng.range(30.0, 2.0 * reach_m), rng.range(7.0, 12.0));
            traffic
                .movers
                .push(car(ONCOMING_LANE_M, at, -speed, MoverKind::Car));
        }
        for k in 0..counts.pedestrians {
            let side = if k % 2 == 0 { 1.0 } else { -1.0 };
            let speed = rng.range(1.0, 1.6) * if rng.next_f64() < 0.5 { 1.0 } else { -1.0 };
            traffic.movers.push(Mover {
                kind: MoverKind::Pedestrian,
                half: PERSON_HALF,
                lateral_m: side * SIDEWALK_M,
                at_m: rng.range(10.0, reach_m),
                speed_m_s: speed,
                start_s: 0.0,
            });
        }
        for k in 0..counts.leaving {
            let at = reach_m * (0.25 + 0.42 * k as f64);
            traffic.movers.push(Mover {
                // Passed at about 8 m/s, gone some seconds later.
                start_s: at / 8.0 + rng.range(3.0, 6.0),
                ..car(KERB_M, at, 6.0, MoverKind::Leaving)
            });
        }
        traffic
    }

    /// [`Traffic::street`] along the path a drive's `poses` trace (their positions, an open
    /// path), reaching its whole length.
    pub fn along_poses(poses: &[Pose], counts: TrafficCounts, seed: u64) -> Self {
        let path: Vec<[f64; 2]> = poses
            .iter()
            .map(|p| [p.translation.x, p.translation.y])
            .collect();
        let length = path
            .windows(2)
            .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
            .sum();
        Self::street(path, false, length, counts, seed)
    }

    /// Where each mover is at `t` seconds, on the ground of `scene`: one box a mover (an open
    /// path's mover past either end is gone: `None`).
    pub fn boxes_at(&self, scene: &Scene, t: f64) -> Vec<Option<OrientedBox>> {
        self.movers
            .iter()
            .map(|m| {
                let s = m.at_m + m.speed_m_s * (t - m.start_s).max(0.0);
                if !self.line.closed() && !(0.0..=self.line.total()).contains(&s) {
                    return None;
                }
                let ([x, y], heading) = self.line.at(s);
                let (x, y) = (
                    x - heading.sin() * m.lateral_m,
                    y + heading.cos() * m.lateral_m,
                );
                Some(OrientedBox {
                    centre: [x, y, scene.ground_height(x, y) + m.half[2]],
                    half: m.half,
                    yaw: heading,
                })
            })
            .collect()
    }

    /// The label of a point on mover `k`.
    pub fn label_of(&self, k: usize) -> Label {
        match self.movers.get(k).map(|m| m.kind) {
            Some(MoverKind::Pedestrian) => Label::MovingPerson,
            Some(_) => Label::MovingCar,
            None => Label::Static,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn movers_follow_their_lanes_at_their_speeds_and_parked_cars_wait() {
        let path = vec![[0.0, 0.0], [500.0, 0.0]];
        let traffic = Traffic::street(path, false, 200.0, TrafficCounts::TOWN, 1);
        assert_eq!(traffic.movers.len(), 24);
        let scene = Scene::default();
        let (now, later) = (traffic.boxes_at(&scene, 0.0), traffic.boxes_at(&scene, 2.0));
        for (k, m) in traffic.movers.iter().enumerate() {
            let (Some(a), Some(b)) = (now[k], later[k]) else {
                // Only an oncoming car may have left the open path's start.
                assert!(m.speed_m_s < 0.0 && now[k].is_some(), "{m:?}");
                continue;
            };
            assert!((a.centre[1] - m.lateral_m).abs() < 1e-9, "{m:?}");
            assert!((a.centre[2] - m.half[2]).abs() < 1e-9, "on the ground");
            let moved = b.centre[0] - a.centre[0];
            let expected = match m.kind {
                MoverKind::Leaving => 0.0,
                _ => 2.0 * m.speed_m_s,
            };
            assert!((moved - expected).abs() < 1e-9, "{m:?}: {moved}");
        }
        // A parked car pulls out once its time has come.
        let leaving = traffic
            .movers
            .iter()
            .position(|m| m.kind == MoverKind::Leaving);
        let k = leaving.expect("a parked car");
        let m = traffic.movers[k];
        let gone = traffic.boxes_at(&scene, m.start_s + 1.0)[k].expect("on the path");
        assert!((gone.centre[0] - (m.at_m + 6.0)).abs() < 1e-9);
    }

    #[test]
    fn labels_are_semantic_kitti_s_moving_classes() {
        assert_eq!(Label::Static.semantic_kitti(), 0);
        assert_eq!(Label::MovingCar.semantic_kitti(), 252);
        assert_eq!(Label::MovingPerson.semantic_kitti(), 254);
    }
}
