//! Range filter, KITTI vertical-angle correction and voxel down-sampling (docs/design.md §1.1 step 1).
//!
//! Owns no memory: it fills the caller's buffers. Drop rules: non-finite points and points
//! outside `[range_min, range_max]` are dropped; when the work buffer is full, further input
//! points are dropped in input order. Everything dropped is counted in [`FilterStats`].

use crate::bounded::BoundedVec;
use crate::cell::CellKey;
use crate::config::{Config, FilterConfig};
use crate::executor::Executor;
use crate::math::{to_point, to_vec3, Point, Vec3};
use crate::sort::KeySorter;

/// What the filter kept and dropped from one scan.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FilterStats {
    /// Points given.
    pub input: usize,
    /// Dropped: a coordinate was NaN or infinite.
    pub non_finite: usize,
    /// Dropped: range outside `[range_min, range_max]` (or a voxel index beyond `i32`).
    pub out_of_range: usize,
    /// Of `out_of_range`, those closer than `range_min` (the rest are farther than
    /// `range_max`, or beyond the key range).
    pub too_near: usize,
    /// Dropped: the work buffer was full.
    pub over_capacity: usize,
    /// Points after down-sampling.
    pub kept: usize,
}

impl FilterStats {
    /// Counts one dropped point.
    pub fn count(&mut self, why: Dropped) {
        match why {
            Dropped::NonFinite => self.non_finite += 1,
            Dropped::TooNear => {
                self.out_of_range += 1;
                self.too_near += 1;
            }
            Dropped::OutOfRange => self.out_of_range += 1,
        }
    }
}

/// KITTI's vertical-angle correction (IMLS-SLAM, CT-ICP; docs/design.md §1.8): each point is rotated
/// up by a fixed angle about the horizontal axis perpendicular to its azimuth. The angle's
/// sine and cosine are computed once, not per point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VerticalCorrection {
    cos: f64,
    sin: f64,
}

impl VerticalCorrection {
    /// The correction by `angle_rad` (positive lifts points).
    pub fn new(angle_rad: f64) -> Self {
        Self {
            cos: libm::cos(angle_rad),
            sin: libm::sin(angle_rad),
        }
    }

    /// The corrected point.
    #[inline]
    pub fn apply(&self, p: &Vec3) -> Vec3 {
        // u = p × z / |p × z| is horizontal and perpendicular to the azimuth; Rodrigues with
        // u ⟂ p reduces to p cos α + (u × p) sin α.
        let axis = Vec3::new(p.y, -p.x, 0.0);
        let norm = axis.norm();
        if norm < 1e-9 {
            return *p;
        }
        p * self.cos + (axis / norm).cross(p) * self.sin
    }
}

/// What the filter does to one point: the range test, the vertical correction and the voxel
/// key. Built once per scan; [`Preparation::point`] is the unit a parallel loop runs.
#[derive(Debug, Clone, Copy)]
pub struct Preparation {
    r2_min: f64,
    r2_max: f64,
    correction: Option<VerticalCorrection>,
    leaf_m: f64,
}

/// Why the filter dropped a point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dropped {
    /// A coordinate was NaN or infinite.
    NonFinite,
    /// Its range was below `range_min`.
    TooNear,
    /// Its range was above `range_max` (or its voxel index beyond `i32`).
    OutOfRange,
}

impl Preparation {
    /// The preparation for `cfg` with voxels of edge `leaf_m`.
    pub fn new(cfg: &FilterConfig, leaf_m: f64) -> Self {
        Self {
            r2_min: cfg.range_min_m * cfg.range_min_m,
            r2_max: cfg.range_max_m * cfg.range_max_m,
            correction: (cfg.vertical_correction_deg != 0.0)
                .then(|| VerticalCorrection::new(cfg.vertical_correction_deg.to_radians())),
            leaf_m,
        }
    }

    /// The point, corrected, with its voxel key; or why it is dropped.
    #[inline]
    pub fn point(&self, p: &Point) -> Result<(CellKey, Point), Dropped> {
        if !(p[0].is_finite() && p[1].is_finite() && p[2].is_finite()) {
            return Err(Dropped::NonFinite);
        }
        let mut v = to_vec3(p);
        let r2 = v.norm_squared();
        if r2 < self.r2_min {
            return Err(Dropped::TooNear);
        }
        if r2 > self.r2_max {
            return Err(Dropped::OutOfRange);
        }
        if let Some(c) = &self.correction {
            v = c.apply(&v);
        }
        let key = CellKey::containing(&v, self.leaf_m).ok_or(Dropped::OutOfRange)?;
        Ok((key, to_point(&v)))
    }
}

/// Appends prepared points to `work` in order, counting what was dropped (and what did not
/// fit) into `stats`.
pub fn collect(
    prepared: impl Iterator<Item = Result<(CellKey, Point), Dropped>>,
    work: &mut BoundedVec<(CellKey, Point)>,
    stats: &mut FilterStats,
) {
    for p in prepared {
        match p {
            Ok(entry) => {
                if work.push(entry).is_err() {
                    stats.over_capacity += 1;
                }
            }
            Err(dropped) => stats.count(dropped),
        }
    }
}

/// Filters `raw` (sensor frame) and down-samples it to one centroid per voxel of edge `leaf_m`,
/// written to `out` in voxel-key order. `work` and `sorter` are scratch space; `exec` runs
/// the per-point preparation and the sort.
#[allow(clippy::too_many_arguments)]
pub fn filter_and_downsample(
    raw: &[Point],
    cfg: &FilterConfig,
    leaf_m: f64,
    work: &mut BoundedVec<(CellKey, Point)>,
    sorter: &mut KeySorter,
    out: &mut BoundedVec<Point>,
    exec: &impl Executor,
) -> FilterStats {
    let prep = Preparation::new(cfg, leaf_m);
    work.clear();
    let mut stats = FilterStats {
        input: raw.len(),
        ..FilterStats::default()
    };
    prepare_all(raw, &prep, work, &mut stats, exec);
    downsample(work, sorter, out, &mut stats, exec);
    stats
}

/// Prepares every raw point ([`Preparation::point`], the unit `exec` runs) and appends the kept
/// ones to `work` in input order, counting the dropped ones into `stats`.
pub fn prepare_all(
    raw: &[Point],
    prep: &Preparation,
    work: &mut BoundedVec<(CellKey, Point)>,
    stats: &mut FilterStats,
    exec: &impl Executor,
) {
    let fits = exec.filter_map_into(
        raw,
        work,
        |p, dropped: &mut FilterStats| match prep.point(p) {
            Ok(e) => Some(e),
            Err(why) => {
                dropped.count(why);
                None
            }
        },
        |s| {
            stats.non_finite += s.non_finite;
            stats.out_of_range += s.out_of_range;
            stats.too_near += s.too_near;
        },
    );
    if !fits {
        collect(raw.iter().map(|p| prep.point(p)), work, stats);
    }
}

/// Sorts the prepared points in `work` by voxel (`exec` runs the sort) and writes one
/// centroid per voxel to `out` (cleared first); sets `stats.kept`.
pub fn downsample(
    work: &mut BoundedVec<(CellKey, Point)>,
    sorter: &mut KeySorter,
    out: &mut BoundedVec<Point>,
    stats: &mut FilterStats,
    exec: &impl Executor,
) {
    out.clear();
    exec.sort(sorter, work);
    let mut i = 0;
    while let Some(&(key, _)) = work.get(i) {
        let mut sum = Vec3::zeros();
        let mut count = 0usize;
        while let Some((k, p)) = work.get(i) {
            if *k != key {
                break;
            }
            sum += to_vec3(p);
            count += 1;
            i += 1;
        }
        // `out` has the capacity of `work`, and there are no more voxels than points.
        let _ = out.push(to_point(&(sum / count as f64)));
    }
    stats.kept = out.len();
}

/// A scan filtered apart from a pipeline, for
/// [`Pipeline::step`](crate::Pipeline::step) as a
/// [`Scan::Filtered`](crate::pipeline::Scan::Filtered): its points
/// (sensor frame, one per voxel, in voxel-key order) and what the filter did.
#[derive(Debug, Clone, Copy)]
pub struct Filtered<'a> {
    /// The down-sampled points.
    pub points: &'a [Point],
    /// What the filter kept and dropped.
    pub stats: FilterStats,
}

/// The filter with buffers of its own, at the capacities of a pipeline's (`C`): filters the
/// next scan, on another thread, while a pipeline registers this one. Its result is the
/// pipeline's own filter's, to the bit (same function, same capacities).
#[derive(Debug)]
pub struct ScanFilter {
    work: BoundedVec<(CellKey, Point)>,
    sorter: KeySorter,
    points: BoundedVec<Point>,
}

impl ScanFilter {
    /// A filter with the buffers of capacity `C`
    /// ([`Capacity::filter_bytes`](crate::capacity::Capacity::filter_bytes)), allocated now.
    #[cfg(any(feature = "alloc", test))]
    pub fn new<C: crate::capacity::Capacity>() -> Self {
        Self {
            work: BoundedVec::with_capacity(C::POINTS),
            sorter: KeySorter::with_capacity(C::SORT_ENTRIES),
            points: BoundedVec::with_capacity(C::POINTS),
        }
    }

    /// Filters and down-samples `raw` (sensor frame) as a pipeline with `config` would.
    pub fn filter(&mut self, raw: &[Point], config: &Config, exec: &impl Executor) -> Filtered<'_> {
        let stats = filter_and_downsample(
            raw,
            &config.filter,
            config.voxel_leaf_m(),
            &mut self.work,
            &mut self.sorter,
            &mut self.points,
            exec,
        );
        Filtered {
            points: &self.points,
            stats,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cfg() -> FilterConfig {
        FilterConfig {
            range_min_m: 1.0,
            range_max_m: 50.0,
            vertical_correction_deg: 0.0,
        }
    }

    #[test]
    fn drops_bad_points_and_merges_voxels() {
        let raw = [
            [f32::NAN, 0.0, 0.0],
            [f32::INFINITY, 1.0, 1.0],
            [0.1, 0.1, 0.1],     // too close
            [100.0, 0.0, 0.0],   // too far
            [10.05, 0.05, 0.05], // voxel (50, 0, 0) at 0.2 m
            [10.15, 0.15, 0.15], // same voxel
            [20.1, 0.1, 0.1],    // another voxel
        ];
        let mut work = BoundedVec::with_capacity(16);
        let mut out = BoundedVec::with_capacity(16);
        let s = filter_and_downsample(
            &raw,
            &cfg(),
            0.2,
            &mut work,
            &mut KeySorter::with_capacity(16),
            &mut out,
            &crate::executor::Serial,
        );
        assert_eq!(
            (s.non_finite, s.out_of_range, s.over_capacity, s.kept),
            (2, 2, 0, 2)
        );
        assert!((out[0][0] - 10.1).abs() < 1e-5 && (out[0][1] - 0.1).abs() < 1e-5);
        assert!((out[1][0] - 20.1).abs() < 1e-5);
    }

    #[test]
    fn over_capacity_points_are_dropped_in_input_order() {
        let raw: [Point; 5] = core::array::from_fn(|i| [2.0 + i as f32, 0.0, 0.0]);
        let mut work = BoundedVec::with_capacity(3);
        let mut out = BoundedVec::with_capacity(3);
        let s = filter_and_downsample(
            &raw,
            &cfg(),
            0.2,
            &mut work,
            &mut KeySorter::with_capacity(3),
            &mut out,
            &crate::executor::Serial,
        );
        assert_eq!((s.over_capacity, s.kept), (2, 3));
        assert!((out[2][0] - 4.0).abs() < 1e-6);
    }

    #[test]
    fn vertical_correction_lifts_points_by_the_angle() {
        let p = Vec3::new(30.0, 40.0, 0.0);
        let q = VerticalCorrection::new(0.22f64.to_radians()).apply(&p);
        assert!((q.norm() - p.norm()).abs() < 1e-9);
        let elevation = libm::atan2(q.z, libm::hypot(q.x, q.y));
        assert!((elevation - 0.22f64.to_radians()).abs() < 1e-12);
        assert!((libm::atan2(q.y, q.x) - libm::atan2(p.y, p.x)).abs() < 1e-12);
    }
}
