//! How much of what moved a map kept: a mesh scored against scans whose points are labelled
//! static or moving (SemanticKITTI's `.label` files; `slamesh_sim`'s drives with movers write
//! them).
//!
//! The truth is every scan's points at the reference poses, thinned to one point per
//! [`TRUTH_VOXEL_M`] cube of each kind. The mesh is sampled by area ([`super::mesh`]) and each
//! sample takes the label of the nearest truth point within [`MATCH_M`] (none: unmatched).
//! From those, as the KTH DynamicMap benchmark scores a map's points:
//! - SA, static accuracy: the share of static truth points with a static sample within
//!   [`MATCH_M`] (what of the static scene the map kept);
//! - DA, dynamic accuracy: the share of moving truth points with no moving sample within
//!   [`MATCH_M`] (what of the movers the map does not hold);
//! - AA = sqrt(SA · DA);
//!
//! and the mesh's ghost area (the samples labelled moving, as square metres) and its static
//! F1 at 0.1 m (against the static truth alone).

use super::mesh::voxel_index::VoxelIndex;
use super::mesh::{accumulate, sample_triangles, score};
use slamesh_core::{Point, Pose};

/// Whether a SemanticKITTI label is of a moving class (its lower 16 bits 250 or more; the
/// upper 16 are an instance id).
pub fn is_moving_label(label: u32) -> bool {
    (label & 0xffff) >= 250
}

/// The truth's thinning (metres).
pub const TRUTH_VOXEL_M: f64 = 0.1;
/// How near a sample must lie to a truth point to take its label (metres).
pub const MATCH_M: f64 = 0.3;
/// The mesh's sampling: one sample per this squared (metres).
const SAMPLE_M: f64 = 0.05;

/// Scans' points in the world, static and moving apart.
#[derive(Debug, Clone, Default)]
pub struct LabelledCloud {
    /// Points of the static scene.
    pub static_points: Vec<Point>,
    /// Points on things that moved.
    pub moving: Vec<Point>,
}

impl LabelledCloud {
    /// The truth from scans (sensor frame), each point's `moving` flag, and their poses;
    /// ranges outside `[range_min_m, range_max_m]` left out. Each kind is thinned as
    /// [`accumulate`] thins a reference.
    pub fn accumulate(
        scans: impl IntoIterator<Item = (Vec<Point>, Vec<bool>, Pose)>,
        range_min_m: f64,
        range_max_m: f64,
    ) -> Self {
        let (mut still, mut moved) = (Vec::new(), Vec::new());
        for (points, moving, pose) in scans {
            let (m, s): (Vec<_>, Vec<_>) = points.iter().zip(&moving).partition(|(_, m)| **m);
            still.push((s.into_iter().map(|(p, _)| *p).collect(), pose));
            moved.push((m.into_iter().map(|(p, _)| *p).collect(), pose));
        }
        let thinned = |scans| accumulate(scans, TRUTH_VOXEL_M, range_min_m, range_max_m);
        LabelledCloud {
            static_points: thinned(still),
            moving: thinned(moved),
        }
    }
}

/// A mesh against a [`LabelledCloud`] (see the module).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct DynamicScore {
    /// Static accuracy (0 to 1).
    pub sa: f64,
    /// Dynamic accuracy (0 to 1).
    pub da: f64,
    /// sqrt(SA · DA).
    pub aa: f64,
    /// Mesh area nearest to what moved (m²).
    pub ghost_m2: f64,
    /// Mesh area nearest to the static scene (m²).
    pub static_m2: f64,
    /// Mesh area near no truth point (m²).
    pub unmatched_m2: f64,
    /// F1 at 0.1 m against the static truth.
    pub static_f1: f64,
}

/// Scores the mesh of `triangles` against `truth`.
pub fn score_dynamic(triangles: &[[Point; 3]], truth: &LabelledCloud) -> DynamicScore {
    let samples = sample_triangles(triangles.iter().copied(), SAMPLE_M, 1);
    let by_static = VoxelIndex::new(&truth.static_points, MATCH_M);
    let by_moving = VoxelIndex::new(&truth.moving, MATCH_M);
    let (mut static_samples, mut moving_samples, mut unmatched) = (Vec::new(), Vec::new(), 0);
    for p in &samples {
        let (s, m) = (by_static.nearest_distance(p), by_moving.nearest_distance(p));
        match (s.is_finite(), m.is_finite()) {
            (false, false) => unmatched += 1,
            _ if s <= m => static_samples.push(*p),
            _ => moving_samples.push(*p),
        }
    }
    let kept_static = VoxelIndex::new(&static_samples, MATCH_M);
    let kept_moving = VoxelIndex::new(&moving_samples, MATCH_M);
    let share = |points: &[Point], index: &VoxelIndex, near: bool| {
        let n = points
            .iter()
            .filter(|p| index.nearest_distance(p).is_finite() == near)
            .count();
        n as f64 / points.len().max(1) as f64
    };
    let sa = share(&truth.static_points, &kept_static, true);
    let da = if truth.moving.is_empty() {
        1.0
    } else {
        share(&truth.moving, &kept_moving, false)
    };
    let area = |n: usize| n as f64 * SAMPLE_M * SAMPLE_M;
    let f1 = score(&samples, &truth.static_points, &[0.1]);
    DynamicScore {
        sa,
        da,
        aa: (sa * da).sqrt(),
        ghost_m2: area(moving_samples.len()),
        static_m2: area(static_samples.len()),
        unmatched_m2: area(unmatched),
        static_f1: f1.first().map_or(0.0, |s| s.f1),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moving_classes_are_known_with_or_without_an_instance() {
        assert!(!is_moving_label(0) && !is_moving_label(10) && !is_moving_label((7 << 16) | 10));
        assert!(is_moving_label(252) && is_moving_label(254) && is_moving_label((7 << 16) | 252));
    }

    /// Two triangles over the square `[x0, x0 + 1] x [0, 1]` at height `z`.
    fn square(x0: f32, z: f32) -> [[Point; 3]; 2] {
        [
            [[x0, 0.0, z], [x0 + 1.0, 0.0, z], [x0 + 1.0, 1.0, z]],
            [[x0, 0.0, z], [x0 + 1.0, 1.0, z], [x0, 1.0, z]],
        ]
    }

    /// Points 5 cm apart over the same square.
    fn grid(x0: f32, z: f32) -> Vec<Point> {
        (0..400)
            .map(|k| [x0 + 0.05 * (k % 20) as f32, 0.05 * (k / 20) as f32, z])
            .collect()
    }

    #[test]
    fn a_mesh_over_a_mover_s_points_is_ghost_area_and_lowers_the_dynamic_accuracy() {
        let scan = |points: Vec<Point>, moving: bool| {
            let n = points.len();
            (points, vec![moving; n], Pose::identity())
        };
        let truth = LabelledCloud::accumulate(
            [scan(grid(0.0, 0.0), false), scan(grid(5.0, 0.0), true)],
            0.0,
            100.0,
        );
        // Thinned to one point a 10 cm cube.
        assert_eq!((truth.static_points.len(), truth.moving.len()), (100, 100));
        // The static square alone: everything kept, nothing moving held.
        let clean = score_dynamic(&square(0.0, 0.0), &truth);
        assert!(clean.sa > 0.99 && clean.da == 1.0, "{clean:?}");
        assert!(
            (clean.static_m2 - 1.0).abs() < 0.1 && clean.ghost_m2 == 0.0,
            "{clean:?}"
        );
        assert!(clean.static_f1 > 0.9, "{clean:?}");
        // With the mover's square too: a square metre of ghost, none of it removed.
        let both: Vec<[Point; 3]> = square(0.0, 0.0)
            .into_iter()
            .chain(square(5.0, 0.0))
            .collect();
        let ghosted = score_dynamic(&both, &truth);
        assert!((ghosted.ghost_m2 - 1.0).abs() < 0.1, "{ghosted:?}");
        assert!(ghosted.da < 0.01 && ghosted.sa > 0.99, "{ghosted:?}");
        // Floating far from both: unmatched.
        let away = score_dynamic(&square(20.0, 3.0), &truth);
        assert!(away.unmatched_m2 > 0.9 && away.sa == 0.0, "{away:?}");
    }
}
