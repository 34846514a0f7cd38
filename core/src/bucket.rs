//! Bucketing a scan into world-fixed cells (docs/design.md §1.1 steps 2-3).
//!
//! Points are moved into the world by the current pose estimate, keyed by [`CellKey`], stored
//! cell-local (metres from the cell's minimum corner, so `f32` keeps sub-micrometre precision
//! anywhere in the world) and sorted by key: a cell's points are one contiguous run. Cells with
//! fewer than `min_points` points are skipped. When the cell list is full, further cells are
//! dropped in key order and counted. Owns no memory. The per-point step ([`Placement::point`])
//! runs through the [`Executor`], so a parallel loop can place the points.

use crate::bounded::BoundedVec;
use crate::cell::CellKey;
use crate::executor::Executor;
use crate::math::{to_point, to_vec3, Point, Pose};
use crate::sort::KeySorter;

/// A cell of the current scan: its key and its run of points in the bucketed buffer.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CellSpan {
    /// The cell.
    pub key: CellKey,
    /// Index of its first point.
    pub start: u32,
    /// Number of points.
    pub len: u32,
}

impl CellSpan {
    /// The cell's points in `bucketed`; empty if the span does not fit (it always does for
    /// spans made by [`bucket`] on that buffer).
    pub fn points<'a>(&self, bucketed: &'a [(CellKey, Point)]) -> &'a [(CellKey, Point)] {
        let start = self.start as usize;
        bucketed
            .get(start..start + self.len as usize)
            .unwrap_or(&[])
    }
}

/// What bucketing did with one scan.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BucketStats {
    /// Cells listed for reconstruction.
    pub cells: usize,
    /// Cells skipped for having fewer than `min_points` points.
    pub sparse_cells: usize,
    /// Cells dropped because the cell list was full.
    pub dropped_cells: usize,
}

/// Where one point goes: moved into the world by the pose, keyed by its cell, and stored
/// relative to the cell's minimum corner.
#[derive(Debug, Clone, Copy)]
pub struct Placement {
    t_world_sensor: Pose,
    cell_size: f64,
}

impl Placement {
    /// Placement at `t_world_sensor` in cells of edge `cell_size`.
    pub fn new(t_world_sensor: &Pose, cell_size: f64) -> Self {
        Self {
            t_world_sensor: *t_world_sensor,
            cell_size,
        }
    }

    /// The cell of sensor-frame point `p` and `p` relative to the cell's minimum corner;
    /// `None` when the point is beyond the key range (or not finite).
    #[inline]
    pub fn point(&self, p: &Point) -> Option<(CellKey, Point)> {
        let w = self.t_world_sensor * nalgebra::Point3::from(to_vec3(p));
        let key = CellKey::containing(&w.coords, self.cell_size)?;
        let local = w.coords - key.min_corner(self.cell_size);
        Some((key, to_point(&local)))
    }
}

/// Appends the placed points, in order, to `out`; points without a cell are left out, and so
/// are those beyond `out`'s capacity.
pub fn collect(
    placed: impl Iterator<Item = Option<(CellKey, Point)>>,
    out: &mut BoundedVec<(CellKey, Point)>,
) {
    for e in placed.flatten() {
        if out.push(e).is_err() {
            break;
        }
    }
}

/// Places every scan point in its cell ([`Placement::point`], the unit `exec` runs) and
/// appends the placed ones to `out` in input order.
pub fn place_all(
    points: &[Point],
    placement: &Placement,
    out: &mut BoundedVec<(CellKey, Point)>,
    exec: &impl Executor,
) {
    let fits = exec.filter_map_into(points, out, |p, _: &mut ()| placement.point(p), |()| {});
    if !fits {
        collect(points.iter().map(|p| placement.point(p)), out);
    }
}

/// Buckets `points_sensor` into cells as `placement` places them (`sorter` is scratch space;
/// `exec` runs the placement and the sort).
pub fn bucket(
    points_sensor: &[Point],
    placement: &Placement,
    min_points: usize,
    bucketed: &mut BoundedVec<(CellKey, Point)>,
    sorter: &mut KeySorter,
    cells: &mut BoundedVec<CellSpan>,
    exec: &impl Executor,
) -> BucketStats {
    bucketed.clear();
    cells.clear();
    // The points buffer and `bucketed` have the same capacity: nothing is left out for room.
    place_all(points_sensor, placement, bucketed, exec);
    exec.sort(sorter, bucketed);
    let mut stats = BucketStats::default();
    let mut start = 0usize;
    while let Some(&(key, _)) = bucketed.get(start) {
        let len = bucketed
            .get(start..)
            .map_or(0, |rest| rest.iter().take_while(|(k, _)| *k == key).count());
        if len < min_points {
            stats.sparse_cells += 1;
        } else if cells
            .push(CellSpan {
                key,
                start: start as u32,
                len: len as u32,
            })
            .is_err()
        {
            stats.dropped_cells += 1;
        }
        start += len.max(1);
    }
    stats.cells = cells.len();
    stats
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    #[test]
    fn points_are_grouped_by_cell_and_sparse_cells_skipped() {
        let mut pts = [[0.0f32; 3]; 8];
        for (i, p) in pts.iter_mut().enumerate().take(5) {
            *p = [0.1 + 0.1 * i as f32, 0.2, 0.3]; // cell (0, 0, 0)
        }
        pts[5] = [-0.5, 0.2, 0.3]; // cell (-1, 0, 0), alone
        pts[6] = [1.7, 0.2, 0.3];
        pts[7] = [1.8, 0.2, 0.3];
        let mut b = BoundedVec::with_capacity(8);
        let mut c = BoundedVec::with_capacity(4);
        let t = Pose::translation(0.0, 0.0, 0.0);
        let s = bucket(
            &pts,
            &Placement::new(&t, 1.6),
            2,
            &mut b,
            &mut KeySorter::with_capacity(8),
            &mut c,
            &crate::executor::Serial,
        );
        assert_eq!((s.cells, s.sparse_cells), (2, 1));
        assert_eq!(c[0].key, CellKey::new(0, 0, 0));
        assert_eq!(c[0].len, 5);
        let local = c[1].points(&b)[0].1;
        assert!(
            (local[0] - 0.1).abs() < 1e-5,
            "stored relative to the cell corner"
        );
    }

    #[test]
    fn pose_moves_points_before_keying() {
        let pts = [[0.5f32, 0.5, 0.5]; 3];
        let mut b = BoundedVec::with_capacity(3);
        let mut c = BoundedVec::with_capacity(1);
        let t = Pose::translation(-1.0, 0.0, 0.0);
        bucket(
            &pts,
            &Placement::new(&t, 1.6),
            1,
            &mut b,
            &mut KeySorter::with_capacity(3),
            &mut c,
            &crate::executor::Serial,
        );
        assert_eq!(c[0].key, CellKey::new(-1, 0, 0));
        let local = Vec3::new(1.1, 0.5, 0.5);
        assert!((to_vec3(&b[0].1) - local).norm() < 1e-6);
    }
}
