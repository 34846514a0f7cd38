//! Mesh accuracy against a reference point cloud: the mesh is sampled uniformly by area, then
//! precision (mesh samples within `d` of the reference), recall (reference points within `d`
//! of the mesh samples) and their F-score, at several distances (the SLAMesh paper used
//! 0.3 m). Also builds a reference from scans and their reference poses.

use nalgebra::Vector3;
use slamesh_core::random::SplitMix64;
use slamesh_core::{Point, Pose};
use voxel_index::VoxelIndex;

/// Precision, recall and F-score at one distance.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct MeshScore {
    /// The distance (metres).
    pub threshold_m: f64,
    /// Share of mesh samples within the distance of the reference.
    pub precision: f64,
    /// Share of reference points within the distance of the mesh.
    pub recall: f64,
    /// Harmonic mean of the two.
    pub f1: f64,
}

/// The distances of the evaluation protocol (metres).
pub const THRESHOLDS: [f64; 3] = [0.1, 0.2, 0.3];

/// Points spread uniformly over `triangles`, about one per `spacing_m²`, deterministic from
/// `seed`.
pub fn sample_triangles(
    triangles: impl IntoIterator<Item = [Point; 3]>,
    spacing_m: f64,
    seed: u64,
) -> Vec<Point> {
    let mut rng = SplitMix64(seed);
    let mut out = Vec::new();
    for t in triangles {
        let [a, b, c] = t.map(|p| Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64));
        let area = 0.5 * (b - a).cross(&(c - a)).norm();
        if !area.is_finite() {
            continue;
        }
        let expected = area / (spacing_m * spacing_m);
        let mut count = expected.floor() as usize;
        if rng.next_f64() < expected - expected.floor() {
            count += 1;
        }
        for _ in 0..count {
            let (mut u, mut v) = (rng.next_f64(), rng.next_f64());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            let p = a + (b - a) * u + (c - a) * v;
            out.push([p.x as f32, p.y as f32, p.z as f32]);
        }
    }
    out
}

/// Scores of `mesh_samples` against `reference` at each of `thresholds`.
pub fn score(mesh_samples: &[Point], reference: &[Point], thresholds: &[f64]) -> Vec<MeshScore> {
    let largest = thresholds.iter().copied().fold(0.0, f64::max).max(1e-3);
    let ref_index = VoxelIndex::new(reference, largest);
    let d_mesh: Vec<f64> = mesh_samples
        .iter()
        .map(|p| ref_index.nearest_distance(p))
        .collect();
    score_with_precision_distances(&d_mesh, mesh_samples, reference, thresholds)
}

/// Scores where the mesh samples' distances to the truth are known (`d_mesh`, e.g. exact
/// distances to the true surfaces of a simulation); recall is measured from `reference`.
pub fn score_with_precision_distances(
    d_mesh: &[f64],
    mesh_samples: &[Point],
    reference: &[Point],
    thresholds: &[f64],
) -> Vec<MeshScore> {
    let largest = thresholds.iter().copied().fold(0.0, f64::max).max(1e-3);
    let mesh_index = VoxelIndex::new(mesh_samples, largest);
    let d_ref: Vec<f64> = reference
        .iter()
        .map(|p| mesh_index.nearest_distance(p))
        .collect();
    thresholds
        .iter()
        .map(|&t| {
            let share = |d: &[f64]| {
                if d.is_empty() {
                    0.0
                } else {
                    d.iter().filter(|&&x| x <= t).count() as f64 / d.len() as f64
                }
            };
            let (precision, recall) = (share(d_mesh), share(&d_ref));
            let f1 = if precision + recall > 0.0 {
                2.0 * precision * recall / (precision + recall)
            } else {
                0.0
            };
            MeshScore {
                threshold_m: t,
                precision,
                recall,
                f1,
            }
        })
        .collect()
}

/// A reference cloud from scans (sensor frame) and their poses: the points in the world,
/// thinned to one per `voxel_m` cube (the first point of each), keeping ranges in
/// `[range_min_m, range_max_m]`.
pub fn accumulate(
    scans: impl IntoIterator<Item = (Vec<Point>, Pose)>,
    voxel_m: f64,
    range_min_m: f64,
    range_max_m: f64,
) -> Vec<Point> {
    let mut seen = std::collections::HashSet::new();
    let mut out = Vec::new();
    for (points, pose) in scans {
        for p in points {
            let v = Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            let r = v.norm();
            if !(r >= range_min_m && r <= range_max_m) {
                continue;
            }
            let w = pose * nalgebra::Point3::from(v);
            let key = [w.x, w.y, w.z].map(|c| (c / voxel_m).floor() as i64);
            if seen.insert(key) {
                out.push([w.x as f32, w.y as f32, w.z as f32]);
            }
        }
    }
    out
}

/// A voxel hash of points for radius queries.
pub(crate) mod voxel_index {
    use slamesh_core::Point;
    use std::collections::HashMap;

    /// Points bucketed in cubes of the query radius.
    pub struct VoxelIndex<'a> {
        points: &'a [Point],
        size: f64,
        cells: HashMap<[i64; 3], Vec<u32>>,
    }

    impl<'a> VoxelIndex<'a> {
        /// Indexes `points` for queries up to `radius`.
        pub fn new(points: &'a [Point], radius: f64) -> Self {
            let mut cells: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
            for (i, p) in points.iter().enumerate() {
                cells.entry(key(p, radius)).or_default().push(i as u32);
            }
            VoxelIndex {
                points,
                size: radius,
                cells,
            }
        }

        /// Distance to the nearest point if it is within the radius, else infinity.
        pub fn nearest_distance(&self, p: &Point) -> f64 {
            let k = key(p, self.size);
            let mut best = f64::INFINITY;
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let Some(ids) = self.cells.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) else {
                            continue;
                        };
                        for &i in ids {
                            let q = &self.points[i as usize];
                            let d2: f64 = (0..3).map(|c| ((p[c] - q[c]) as f64).powi(2)).sum();
                            best = best.min(d2);
                        }
                    }
                }
            }
            let d = best.sqrt();
            if d <= self.size {
                d
            } else {
                f64::INFINITY
            }
        }
    }

    fn key(p: &Point, size: f64) -> [i64; 3] {
        p.map(|c| (c as f64 / size).floor() as i64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles tiling the unit square at height `z`.
    fn square(z: f32) -> [[Point; 3]; 2] {
        [
            [[0.0, 0.0, z], [1.0, 0.0, z], [1.0, 1.0, z]],
            [[0.0, 0.0, z], [1.0, 1.0, z], [0.0, 1.0, z]],
        ]
    }

    #[test]
    fn sampling_is_uniform_by_area_and_deterministic() {
        let s = sample_triangles(square(0.0), 0.02, 1);
        assert!((s.len() as f64 - 2500.0).abs() < 3.0, "{}", s.len());
        assert!(s
            .iter()
            .all(|p| (0.0..=1.0).contains(&p[0]) && (0.0..=1.0).contains(&p[1])));
        assert_eq!(s, sample_triangles(square(0.0), 0.02, 1));
        let left = s.iter().filter(|p| p[0] < 0.5).count() as f64 / s.len() as f64;
        assert!((left - 0.5).abs() < 0.03, "{left}");
    }

    #[test]
    fn a_mesh_sampled_from_the_reference_scores_one_and_a_shifted_one_scores_by_distance() {
        let reference = sample_triangles(square(0.0), 0.02, 7);
        for s in score(&reference, &reference, &THRESHOLDS) {
            assert_eq!((s.precision, s.recall, s.f1), (1.0, 1.0, 1.0), "{s:?}");
        }
        let mesh = sample_triangles(square(0.0), 0.02, 8);
        assert!(score(&mesh, &reference, &THRESHOLDS)
            .iter()
            .all(|s| s.f1 > 0.999));
        // 15 cm above: nothing within 0.1 m, everything within 0.2 m.
        let lifted = sample_triangles(square(0.15), 0.05, 8);
        let s = score(&lifted, &reference, &THRESHOLDS);
        assert_eq!((s[0].precision, s[0].recall, s[0].f1), (0.0, 0.0, 0.0));
        assert_eq!((s[1].precision, s[1].recall), (1.0, 1.0));
        // Half the reference missing from the mesh: recall 0.5, precision 1.
        let half: Vec<Point> = reference.iter().copied().filter(|p| p[0] < 0.5).collect();
        let s = score(&sample_triangles(square(0.0), 0.02, 9), &half, &[0.1]);
        assert_eq!(s[0].recall, 1.0);
        // Mesh samples up to 0.1 m past the reference's edge still count: 0.6 of the square.
        assert!((s[0].precision - 0.6).abs() < 0.03, "{:?}", s[0]);
    }

    #[test]
    fn accumulation_moves_thins_and_filters_by_range() {
        let scan = vec![
            [1.0, 0.0, 0.0],
            [1.001, 0.0, 0.0],
            [50.0, 0.0, 0.0],
            [0.1, 0.0, 0.0],
        ];
        let pose = Pose::translation(10.0, 0.0, 0.0);
        let r = accumulate([(scan, pose)], 0.05, 0.5, 40.0);
        assert_eq!(r, vec![[11.0, 0.0, 0.0]]);
    }
}
