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
use crate::math::{to_point, to_vec3, Point, Pose, Vec3};
use crate::real::Real;
use crate::sort::KeySorter;
use core::marker::PhantomData;

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
/// relative to the cell's minimum corner, in the arithmetic of the scalar `R` ([`Real`]).
///
/// With `f64`, each point is moved by the pose and keyed in world coordinates. With `f32`,
/// whose 24-bit mantissa would lose millimetres a few kilometres from the origin, the world
/// coordinates are never formed: the pose's translation is split, in `f64` and once, into the
/// corner of the cell the sensor is in and what is left of it (less than a cell), and each
/// point is moved by the rotation and that remainder only. Its coordinates are then within
/// the sensor's range, where `f32` resolves a few micrometres, wherever the sensor is.
#[derive(Debug, Clone, Copy)]
pub struct Placement<R = f64> {
    t_world_sensor: Pose,
    cell_size: f64,
    single: SinglePlacement,
    _scalar: PhantomData<fn() -> R>,
}

/// The `f32` form of a placement: the sensor's cell, the rotation and the rest of the
/// translation from that cell's corner.
#[derive(Debug, Clone, Copy)]
struct SinglePlacement {
    origin: Option<CellKey>,
    rotation: [[f32; 3]; 3],
    rest: [f32; 3],
    cell_size: f32,
    inv_cell_size: f32,
}

impl<R: Real> Placement<R> {
    /// Placement at `t_world_sensor` in cells of edge `cell_size`.
    pub fn new(t_world_sensor: &Pose, cell_size: f64) -> Self {
        let t = t_world_sensor.translation.vector;
        let origin = CellKey::containing(&t, cell_size);
        let rest = origin.map_or(Vec3::zeros(), |o| t - o.min_corner(cell_size));
        let m = t_world_sensor.rotation.to_rotation_matrix();
        Self {
            t_world_sensor: *t_world_sensor,
            cell_size,
            single: SinglePlacement {
                origin,
                rotation: core::array::from_fn(|i| core::array::from_fn(|j| m[(i, j)] as f32)),
                rest: to_point(&rest),
                cell_size: cell_size as f32,
                inv_cell_size: (1.0 / cell_size) as f32,
            },
            _scalar: PhantomData,
        }
    }

    /// The cell of sensor-frame point `p` and `p` relative to the cell's minimum corner;
    /// `None` when the point is beyond the key range (or not finite).
    #[inline]
    pub fn point(&self, p: &Point) -> Option<(CellKey, Point)> {
        if R::SINGLE {
            self.single.point(p)
        } else {
            let w = self.t_world_sensor * nalgebra::Point3::from(to_vec3(p));
            let key = CellKey::containing(&w.coords, self.cell_size)?;
            let local = w.coords - key.min_corner(self.cell_size);
            Some((key, to_point(&local)))
        }
    }
}

impl SinglePlacement {
    /// [`Placement::point`] in `f32`, relative to the sensor's cell.
    #[inline]
    fn point(&self, p: &Point) -> Option<(CellKey, Point)> {
        let (r, c) = (&self.rotation, self.cell_size);
        let mut w = [0.0f32; 3];
        let mut step = [0i32; 3];
        for k in 0..3 {
            w[k] = r[k][0] * p[0] + r[k][1] * p[1] + r[k][2] * p[2] + self.rest[k];
            let q = w[k] * self.inv_cell_size;
            // Within the range test, floor is truncation, one less below zero (as in
            // `CellKey::containing`); the test refuses NaN too.
            if !(q.abs() < 1e6) {
                return None;
            }
            let t = q as i32;
            step[k] = t - i32::from((t as f32) > q);
            w[k] -= step[k] as f32 * c;
        }
        let o = self.origin?;
        let key = CellKey::new(
            o.x.checked_add(step[0])?,
            o.y.checked_add(step[1])?,
            o.z.checked_add(step[2])?,
        );
        Some((key, w))
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
pub fn place_all<R: Real>(
    points: &[Point],
    placement: &Placement<R>,
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
pub fn bucket<R: Real>(
    points_sensor: &[Point],
    placement: &Placement<R>,
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
            &Placement::<f64>::new(&t, 1.6),
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
            &Placement::<f64>::new(&t, 1.6),
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

    /// The `f32` placement keys a point as the `f64` one does and stores it within what `f32`
    /// resolves at the point's range, near the origin and 5 km from it, where world
    /// coordinates in `f32` would be off by up to 0.5 mm (points within 0.1 mm of a cell face
    /// may go either way and are skipped). Measured 2026-12-03, points up to 80 m away: 20 µm
    /// at most (one `f32` step at 80 m is 7.6 µm).
    #[test]
    fn single_precision_places_points_where_double_precision_does() {
        let mut rng = crate::random::SplitMix64(3);
        for (x, y) in [(0.3, -2.0), (4_871.2, -3_305.9)] {
            let pose = Pose::from_parts(
                nalgebra::Translation3::new(x, y, 41.7),
                nalgebra::UnitQuaternion::from_euler_angles(0.02, -0.03, 2.4),
            );
            let (p64, p32) = (
                Placement::<f64>::new(&pose, 1.6),
                Placement::<f32>::new(&pose, 1.6),
            );
            let (mut compared, mut worst) = (0, 0.0f32);
            for _ in 0..5_000 {
                let p = [0.0; 3].map(|_: f32| (160.0 * rng.next_f64() - 80.0) as f32);
                let (Some((k64, l64)), Some((k32, l32))) = (p64.point(&p), p32.point(&p)) else {
                    panic!("a point near the sensor has a cell");
                };
                if l64.iter().any(|&v| !(1e-4..1.6 - 1e-4).contains(&v)) {
                    continue;
                }
                assert_eq!(k64, k32, "point {p:?} at ({x}, {y})");
                for k in 0..3 {
                    worst = worst.max((l64[k] - l32[k]).abs());
                }
                compared += 1;
            }
            assert!(compared > 4_900);
            assert!(
                worst < 5e-5,
                "cell-local coordinates differ by {worst} m at ({x}, {y})"
            );
        }
        let far = Pose::translation(1e12, 0.0, 0.0);
        assert_eq!(Placement::<f32>::new(&far, 1.6).point(&[0.0; 3]), None);
        let nan = [f32::NAN, 0.0, 0.0];
        assert_eq!(
            Placement::<f32>::new(&Pose::identity(), 1.6).point(&nan),
            None
        );
    }
}
