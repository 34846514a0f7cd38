//! Finding a revisit and checking it (docs/design.md §1.14): which earlier frames a keyframe
//! may be near given how far the odometry may have drifted since, the local map they made,
//! and the search of [`Pipeline::step`] (the pose known to be somewhere near the keyframe's) of the keyframe's scan in it.

use crate::loop_closure::settings::LoopSettings;
use slamesh_core::math::rotation_angle;
use slamesh_core::pipeline::{Known, Relocalized, Scan, Stepped};
use slamesh_core::relocalize::{along_path, AllResident, Search};
use slamesh_core::{Capacity, NoProbe, Pipeline, Point, Pose, RegistrationStatus, Serial};

/// An earlier frame as the detector sees it: where it is now thought to be and how far along
/// the path it was taken.
#[derive(Debug, Clone, Copy)]
pub struct Past {
    /// Its index among the spooled frames.
    pub index: usize,
    /// Its pose, as corrected so far.
    pub pose: Pose,
    /// Metres travelled from the start to it.
    pub travelled_m: f64,
}

/// The frames of a possible revisit: those within reach of the current pose (the search's
/// path), and the wider neighbourhood whose scans make the local map.
#[derive(Debug, Clone, Default)]
pub struct Revisit {
    /// The frames within the drift's reach of the current pose, in path order.
    pub near: Vec<Past>,
    /// Frames to build the local map from (at most [`LoopSettings::submap_frames`]).
    pub submap: Vec<Past>,
}

/// How far the odometry may have drifted over `travelled_m` metres.
pub fn reach_m(s: &LoopSettings, travelled_m: f64) -> f64 {
    s.reach_m + s.reach_per_m * travelled_m
}

/// The earlier frames a keyframe at `pose`, `travelled_m` along the path, may be revisiting:
/// frames at least `min_travel_m` of path behind it whose positions lie within the drift's
/// reach ([`reach_m`]) of its own. `None` when there is none.
pub fn revisit(
    s: &LoopSettings,
    pose: &Pose,
    travelled_m: f64,
    past: impl Iterator<Item = Past>,
) -> Option<Revisit> {
    let here = pose.translation.vector;
    let mut r = Revisit::default();
    let mut wide = Vec::new();
    for p in past {
        let behind = travelled_m - p.travelled_m;
        if behind < s.min_travel_m {
            continue;
        }
        let d = (p.pose.translation.vector - here).norm();
        let reach = reach_m(s, behind);
        if d <= reach {
            r.near.push(p);
        }
        if d <= reach + s.submap_margin_m {
            wide.push(p);
        }
    }
    if r.near.is_empty() {
        return None;
    }
    let every = wide.len().div_ceil(s.submap_frames.max(1)).max(1);
    r.submap = wide.into_iter().step_by(every).collect();
    Some(r)
}

/// A checked revisit: the keyframe's pose in the local map of the earlier frames, and how
/// it was judged.
#[derive(Debug, Clone, Copy)]
pub struct Verified {
    /// The keyframe's pose in the earlier frames' (corrected) world.
    pub pose: Pose,
    /// The search's judgement.
    pub found: Relocalized,
}

/// Builds the local map of `revisit.submap` (each frame's scan from `scan`) in `pipeline`
/// and searches it for `points` along `revisit.near`. `Some` only when the search accepted a
/// pose ([`RegistrationStatus::Relocalized`]: settled, enough of the scan on the map and its
/// walls, nothing elsewhere nearly as good) and that pose is within the drift's reach of
/// `pose`: the odometry cannot be further off than it can drift.
pub fn verify<C: Capacity, E>(
    s: &LoopSettings,
    pipeline: &mut Pipeline<C>,
    points: &[Point],
    pose: &Pose,
    travelled_m: f64,
    revisit: &Revisit,
    mut scan: impl FnMut(usize) -> Result<Vec<Point>, E>,
) -> Result<Option<Verified>, E> {
    pipeline.map_mut().clear();
    pipeline.set_map_updates(true);
    for p in &revisit.submap {
        // A frame that will not integrate (empty after filtering) leaves a gap only.
        let _ = pipeline.integrate_scan(&scan(p.index)?, &p.pose);
    }
    Ok(search(s, pipeline, points, pose, travelled_m, revisit))
}

/// Searches the local map `pipeline` holds (made by [`verify`] from the earlier frames' scans,
/// or loaded from a saved map) for `points` along `revisit.near`, judged as [`verify`] says.
pub fn search<C: Capacity>(
    s: &LoopSettings,
    pipeline: &mut Pipeline<C>,
    points: &[Point],
    pose: &Pose,
    travelled_m: f64,
    revisit: &Revisit,
) -> Option<Verified> {
    pipeline.set_map_updates(false);
    let spacing = pipeline.config().grid.cell_size_m;
    let mut candidates = vec![*pose];
    along_path(revisit.near.iter().map(|p| &p.pose), spacing, |c| {
        candidates.push(c)
    });
    let known = Known::Somewhere {
        candidates: &candidates,
        search: &Search::default(),
        paging: &mut AllResident,
    };
    let Ok(Stepped::Searched(found)) =
        pipeline.step(Scan::Raw(points), known, &Serial, &mut NoProbe)
    else {
        return None;
    };
    let unverified = crate::mutants::on("closure-unverified");
    if found.outcome.status != RegistrationStatus::Relocalized && !unverified {
        return None;
    }
    let at = found.outcome.t_world_sensor;
    let oldest = revisit
        .near
        .iter()
        .map(|p| travelled_m - p.travelled_m)
        .fold(0.0, f64::max);
    let moved = (at.translation.vector - pose.translation.vector).norm();
    let turned = rotation_angle(&(pose.inverse() * at)).to_degrees();
    let within = moved <= reach_m(s, oldest) && turned <= s.turn_deg + s.turn_per_m * oldest;
    (within || unverified).then_some(Verified { pose: at, found })
}
