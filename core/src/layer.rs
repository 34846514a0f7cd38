//! [`Layer`]: the estimated state of one surface patch, and its lattice geometry.
//!
//! A layer stores, per lattice vertex, the prediction (metres from the cell's minimum face
//! along the layer's axis) and its GP variance. The same type is a scan's reconstruction and
//! the map's fused estimate, with the way its surface faces. 292 bytes, no heap.

use crate::cell::{Axis, CellKey};
use crate::facing::Facing;
use crate::lattice::{neighbours, LatticeTable, N, VERTICES};
use crate::math::{Pose, Vec3};
use crate::real::Real;

/// Which triangles of a layer are shown, from [`MeshConfig`](crate::config::MeshConfig).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shown {
    /// Mean vertex variance below this.
    pub variance: f32,
    /// Cosine of the angle to the layer's axis at least this.
    pub min_axis_cosine: f32,
}

impl Shown {
    /// The rule of `cfg`.
    pub fn new(cfg: &crate::config::MeshConfig) -> Self {
        Self {
            variance: cfg.variance_show as f32,
            min_axis_cosine: libm::cos(cfg.max_slope_deg.to_radians()) as f32,
        }
    }
}

/// How far above `variance_show` a triangle's mean variance may be for it to close a notch in
/// a confident surface ([`Layer::shown_mask`]). Measured on the simulated town drive
/// (`examples/triangle_errors.rs`, 100 frames): of the triangles with two confident
/// neighbours, 5.6 % are more than 0.1 m off the true surface up to 4/3 of the limit, as
/// many as of the shown ones (2 to 6 %); from 4/3 to 5/3 of it, 16 %.
pub const NOTCH_VARIANCE_FACTOR: f32 = 4.0 / 3.0;

/// Triangles of a layer's lattice: 5 x 5 quads, two each.
pub const TRIANGLES: usize = 2 * (N - 1) * (N - 1);

/// Triangle `t < TRIANGLES` of the lattice: of quad `q = t / 2` with corners `v00` at
/// `(i_a, i_b)`, `v10` one step along `a`, `v01` along `b`: `[v00, v10, v11]` for even `t`,
/// `[v00, v11, v01]` for odd.
#[inline]
pub const fn lattice_triangle(t: usize) -> [usize; 3] {
    let q = t / 2;
    let v00 = (q / (N - 1)) * N + q % (N - 1);
    if t.is_multiple_of(2) {
        [v00, v00 + N, v00 + N + 1]
    } else {
        [v00, v00 + N + 1, v00 + 1]
    }
}

/// The triangles across the edges of triangle `t` (`None` past the lattice border).
#[inline]
pub const fn triangle_neighbours(t: usize) -> [Option<usize>; 3] {
    let q = t / 2;
    let (ia, ib) = (q / (N - 1), q % (N - 1));
    if t.is_multiple_of(2) {
        // [v00, v10, v11]: the diagonal, the -b side, the +a side.
        [
            Some(t + 1),
            if ib > 0 {
                Some(2 * (ia * (N - 1) + ib - 1) + 1)
            } else {
                None
            },
            if ia + 1 < N - 1 {
                Some(2 * ((ia + 1) * (N - 1) + ib) + 1)
            } else {
                None
            },
        ]
    } else {
        // [v00, v11, v01]: the diagonal, the +b side, the -a side.
        [
            Some(t - 1),
            if ib + 1 < N - 1 {
                Some(2 * (ia * (N - 1) + ib + 1))
            } else {
                None
            },
            if ia > 0 {
                Some(2 * ((ia - 1) * (N - 1) + ib))
            } else {
                None
            },
        ]
    }
}

/// Per triangle `t`, the bits of the triangles across its edges ([`triangle_neighbours`]).
const NEIGHBOUR_MASKS: [u64; TRIANGLES] = {
    let mut masks = [0u64; TRIANGLES];
    let mut t = 0;
    while t < TRIANGLES {
        let around = triangle_neighbours(t);
        let mut k = 0;
        while k < 3 {
            if let Some(n) = around[k] {
                masks[t] |= 1 << n;
            }
            k += 1;
        }
        t += 1;
    }
    masks
};

/// Every triangle of a lattice.
const ALL_TRIANGLES: u64 = (1 << TRIANGLES) - 1;

/// The triangles with a neighbour across each of their three edges (none on the border).
const INTERIOR: u64 = {
    let mut mask = 0u64;
    let mut t = 0;
    while t < TRIANGLES {
        if NEIGHBOUR_MASKS[t].count_ones() == 3 {
            mask |= 1 << t;
        }
        t += 1;
    }
    mask
};

/// Predictions and variances at the `6 x 6` lattice of one layer.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Layer {
    /// Prediction of vertex `j`, cell-local along the layer's axis (metres).
    pub pred: [f32; VERTICES],
    /// GP variance of vertex `j` (unit signal variance, so about 0 to 2).
    pub var: [f32; VERTICES],
    /// Which way its surface faces along the axis ([`Facing`]).
    pub facing: Facing,
}

impl Layer {
    /// A layer whose every vertex is unknown (variance `f32::INFINITY`).
    pub const UNKNOWN: Layer = Layer {
        pred: [0.0; VERTICES],
        var: [f32::INFINITY; VERTICES],
        facing: Facing::Unknown,
    };

    /// The world position of vertex `j` of this layer, placed in cell `key` along `axis`.
    #[inline]
    pub fn vertex(&self, lattice: &LatticeTable, key: &CellKey, axis: Axis, j: usize) -> Vec3 {
        let d = self.pred.get(j).copied().unwrap_or(0.0);
        lattice.vertex_world(key, axis, j, f64::from(d))
    }

    /// The surface normal at vertex `j`: the mean of the cross products of consecutive edges
    /// to its usable 4-neighbours (variance below `max_var`, edge shorter than a cell),
    /// normalised, oriented along `+axis` (docs/design.md §1.4). `None` when no pair of edges is usable.
    pub fn normal(
        &self,
        lattice: &LatticeTable,
        axis: Axis,
        j: usize,
        max_var: f32,
    ) -> Option<Vec3> {
        self.normal_in::<f64>(lattice, axis, j, max_var)
            .map(|n| Vec3::new(n[0], n[1], n[2]))
    }

    /// [`normal`](Self::normal) computed in the scalar `R` ([`Real`]), as `[x, y, z]`.
    pub fn normal_in<R: Real>(
        &self,
        lattice: &LatticeTable,
        axis: Axis,
        j: usize,
        max_var: f32,
    ) -> Option<[R; 3]> {
        // Edges are differences of vertices of one cell: cell-local differences suffice. They
        // are taken in the layer's own (a, b, d) coordinates, a cyclic permutation of
        // (x, y, z), so their cross products are the same numbers, permuted.
        let (ia, ib) = (j / N, j % N);
        let d_centre = R::from_f32(*self.pred.get(j)?);
        let size = R::from_f64(lattice.cell_size);
        let max_sq = size * size;
        let at = |i: usize| R::from_f64(lattice.coordinates.get(i).copied().unwrap_or(0.0));
        let edge = |n: usize| -> Option<[R; 3]> {
            if !(*self.var.get(n)? < max_var) {
                return None;
            }
            let e = [
                at(n / N) - at(ia),
                at(n % N) - at(ib),
                R::from_f32(*self.pred.get(n)?) - d_centre,
            ];
            (e[0] * e[0] + e[1] * e[1] + e[2] * e[2] < max_sq).then_some(e)
        };
        let [n0, n1, n2, n3] = neighbours(j);
        let edges = [
            n0.and_then(edge),
            n1.and_then(edge),
            n2.and_then(edge),
            n3.and_then(edge),
        ];
        let mut sum = [R::ZERO; 3];
        for k in 0..4 {
            if let (Some(u), Some(v)) = (edges[k], edges[(k + 1) % 4]) {
                sum[0] += u[1] * v[2] - u[2] * v[1];
                sum[1] += u[2] * v[0] - u[0] * v[2];
                sum[2] += u[0] * v[1] - u[1] * v[0];
            }
        }
        let (a, b) = axis.locations();
        let mut n = [R::ZERO; 3];
        n[a] = sum[0];
        n[b] = sum[1];
        n[axis.index()] = sum[2];
        // Summed from zero in order, as nalgebra's `norm` does.
        let norm = (R::ZERO + n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        (norm > R::from_f64(1e-12)).then(|| n.map(|v| v / norm))
    }

    /// The layer of cell `key` along `axis` after its surface is moved by the small rigid
    /// motion `motion` (world frame), to first order: each vertex `p` moves by
    /// `Δ = motion·p - p`, and the surface through it then crosses the vertex's fixed
    /// location at `d + Δ_d - s_a Δ_a - s_b Δ_b`, with `(s_a, s_b)` the surface's slope there
    /// (central differences of the predictions, one-sided on the border). Exact for a plane
    /// and a translation; the error grows with the curvature times the motion's sideways
    /// part. Where the surface is steeper than 75 degrees against the axis the vertex moves
    /// by `Δ_d` alone. Predictions are clamped into the cell; variances are kept.
    pub fn moved(&self, lattice: &LatticeTable, key: &CellKey, axis: Axis, motion: &Pose) -> Layer {
        /// `s_a² + s_b²` above this (`tan² 75°`) is too steep to move along the surface.
        const MAX_SLOPE_SQ: f64 = 13.9;
        let (ia_axis, ib_axis) = axis.locations();
        let d_axis = axis.index();
        // Δ = (R - I) p + t, the same linear map for every vertex; with the vertex at
        // corner + c_a e_a + c_b e_b + d e_d it is the sum of a part for each lattice row, one
        // for each column and the step's `d` column times the prediction, each computed once.
        let mut step = motion.rotation.to_rotation_matrix().into_inner();
        for k in 0..3 {
            step[(k, k)] -= 1.0;
        }
        let c = &lattice.coordinates;
        let base = step * key.min_corner(lattice.cell_size) + motion.translation.vector;
        let rows: [Vec3; N] = core::array::from_fn(|i| base + step.column(ia_axis) * c[i]);
        let columns: [Vec3; N] = core::array::from_fn(|i| step.column(ib_axis) * c[i]);
        let along_d: Vec3 = step.column(d_axis).into();
        // Central differences (one-sided on the border): neighbours and spacing by index.
        let lo = |i: usize| i.saturating_sub(1);
        let hi = |i: usize| (i + 1).min(N - 1);
        let inv_span: [f64; N] = core::array::from_fn(|i| 1.0 / (c[hi(i)] - c[lo(i)]));
        let pred: [f64; VERTICES] = self.pred.map(f64::from);
        let mut out = *self;
        for ia in 0..N {
            for ib in 0..N {
                let j = ia * N + ib;
                let d = pred[j];
                let delta = rows[ia] + columns[ib] + along_d * d;
                let s_a = (pred[hi(ia) * N + ib] - pred[lo(ia) * N + ib]) * inv_span[ia];
                let s_b = (pred[ia * N + hi(ib)] - pred[ia * N + lo(ib)]) * inv_span[ib];
                let shift = if s_a * s_a + s_b * s_b <= MAX_SLOPE_SQ {
                    delta[d_axis] - s_a * delta[ia_axis] - s_b * delta[ib_axis]
                } else {
                    delta[d_axis]
                };
                out.pred[j] = (d + shift).clamp(0.0, lattice.cell_size) as f32;
            }
        }
        out
    }

    /// The lattice's triangles as vertex-index triples, counter-clockwise seen from `+axis`:
    /// 5 x 5 quads, two triangles each, kept as [`shown_mask`](Self::shown_mask) says.
    pub fn triangles<'a>(
        &'a self,
        lattice: &'a LatticeTable,
        shown: Shown,
    ) -> impl Iterator<Item = [usize; 3]> + 'a {
        let mask = self.shown_mask(lattice, shown);
        (0..TRIANGLES)
            .filter(move |t| mask & (1 << t) != 0)
            .map(lattice_triangle)
    }

    /// Which of the lattice's [`TRIANGLES`] triangles are shown, bit `t` for
    /// [`lattice_triangle`]`(t)` (docs/design.md §1.6). First those of the
    /// [`slope_mask`](Self::slope_mask) whose corners' mean variance is below
    /// `shown.variance`; then, in one pass over that set:
    /// - a notch is closed: a triangle within the slope limit whose mean variance is below
    ///   [`NOTCH_VARIANCE_FACTOR`] times the limit is shown when two of its three lattice
    ///   neighbours are;
    /// - a speck is dropped: a shown triangle inside the lattice (no edge on its border)
    ///   whose three neighbours are all hidden.
    pub fn shown_mask(&self, lattice: &LatticeTable, shown: Shown) -> u64 {
        let notch_variance = shown.variance * NOTCH_VARIANCE_FACTOR;
        // Every triangle's tests, without branches (the slope's where the variance
        // already hides it too: the mask is the same).
        let slope = self.slope_mask(lattice, shown.min_axis_cosine);
        let (mut confident, mut notch) = (0u64, 0u64);
        for t in 0..TRIANGLES {
            let variance = self.mean_variance(&lattice_triangle(t));
            let below_notch = variance < notch_variance;
            confident |= u64::from(below_notch && variance < shown.variance) << t;
            notch |= u64::from(below_notch) << t;
        }
        confident &= slope;
        notch &= slope & !confident;
        let mut mask = confident;
        for (t, around) in NEIGHBOUR_MASKS.iter().enumerate() {
            let shown_around = (confident & around).count_ones();
            if notch & (1 << t) != 0 && shown_around >= 2 {
                mask |= 1 << t;
            } else if confident & (1 << t) != 0 && shown_around == 0 && INTERIOR & (1 << t) != 0 {
                mask &= !(1 << t);
            }
        }
        mask
    }

    /// The triangles no steeper than the slope limit (the cosine of their angle to the axis
    /// at least `min_axis_cosine`), bit `t` for [`lattice_triangle`]`(t)`.
    pub fn slope_mask(&self, lattice: &LatticeTable, min_axis_cosine: f32) -> u64 {
        if min_axis_cosine <= 0.0 {
            return ALL_TRIANGLES;
        }
        let cos_sq = min_axis_cosine * min_axis_cosine;
        let at: [f32; N] = core::array::from_fn(|i| lattice.coordinates[i] as f32);
        let steep_enough = |n: [f32; 3]| {
            let norm_sq = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
            n[2] * n[2] >= cos_sq * norm_sq
        };
        let mut mask = 0u64;
        // Quad by quad: with `ha`, `hb` its sides and `d..` its corners' predictions, the
        // cross product of the edges from `v00` has the terms below; the ones left out are
        // products with an exact zero (a side along one axis), so the bits are those of the
        // full product.
        for ia in 0..N - 1 {
            let ha = at[ia + 1] - at[ia];
            for ib in 0..N - 1 {
                let hb = at[ib + 1] - at[ib];
                let v00 = ia * N + ib;
                let d00 = self.pred[v00];
                let (d10, d11, d01) = (
                    self.pred[v00 + N],
                    self.pred[v00 + N + 1],
                    self.pred[v00 + 1],
                );
                // [v00, v10, v11]: edges (ha, 0, d10 - d00) and (ha, hb, d11 - d00).
                let (du, dv) = (d10 - d00, d11 - d00);
                let even = steep_enough([-(du * hb), du * ha - ha * dv, ha * hb]);
                // [v00, v11, v01]: edges (ha, hb, d11 - d00) and (0, hb, d01 - d00).
                let (du, dv) = (d11 - d00, d01 - d00);
                let odd = steep_enough([hb * dv - du * hb, -(ha * dv), ha * hb]);
                let t = 2 * (ia * (N - 1) + ib);
                mask |= (u64::from(even) | u64::from(odd) << 1) << t;
            }
        }
        mask
    }

    /// Mean variance of three vertices (`INFINITY` for an index out of range).
    #[inline]
    pub fn mean_variance(&self, t: &[usize; 3]) -> f32 {
        t.iter()
            .map(|&j| self.var.get(j).copied().unwrap_or(f32::INFINITY))
            .sum::<f32>()
            / 3.0
    }
}

/// A layer reconstructed from the current scan.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ScanLayer {
    /// Its cell.
    pub key: CellKey,
    /// Its axis.
    pub axis: Axis,
    /// Its predictions and variances.
    pub layer: Layer,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lattice::Lattice;

    fn plane(f: impl Fn(f64, f64) -> f64) -> (Layer, Lattice) {
        let lattice = Lattice {
            cell_size: 1.6,
            full_cover: false,
        };
        let mut l = Layer::UNKNOWN;
        for j in 0..VERTICES {
            let (a, b) = lattice.location(j);
            l.pred[j] = f(a, b) as f32;
            l.var[j] = 0.01;
        }
        (l, lattice)
    }

    #[test]
    fn normal_of_a_tilted_plane() {
        // d = 0.2 + 0.5 a: normal ∝ (-0.5, 0, 1) in (a, b, d).
        for axis in Axis::ALL {
            let (l, lat) = plane(|a, _| 0.2 + 0.5 * a);
            let n = l.normal(&lat.table(), axis, 14, 0.5).unwrap();
            let (ia, ib) = axis.locations();
            let want = Vec3::new(-0.5, 0.0, 1.0).normalize();
            assert!((n[ia] - want.x).abs() < 1e-6 && (n[ib] - want.y).abs() < 1e-6);
            assert!((n[axis.index()] - want.z).abs() < 1e-6);
        }
    }

    #[test]
    fn a_plane_moved_by_a_small_motion_is_the_moved_plane() {
        use crate::math::{se3_exp, Twist};
        // d = 0.5 + 0.3 a - 0.2 b in a cell 13 m from the origin, moved by 0.25 degree and
        // 2 cm: its vertices move by up to 6 cm. The formula is first order; what it leaves
        // out is about the displacement times the rotation, 6 cm x 0.0044 = 0.26 mm at most.
        let motion = se3_exp(&Twist::new(0.002, -0.003, 0.0025, 0.012, -0.015, 0.009));
        let key = CellKey::new(7, -3, 2);
        for axis in Axis::ALL {
            let (l, lat) = plane(|a, b| 0.5 + 0.3 * a - 0.2 * b);
            let mut unmoved_error = 0.0f64;
            let table = lat.table();
            let moved = l.moved(&table, &key, axis, &motion);
            // The plane through three of its vertices, moved exactly.
            let at = |j: usize| motion * nalgebra::Point3::from(l.vertex(&table, &key, axis, j));
            let (p0, p1, p2) = (at(0), at(5), at(30));
            let n = (p1 - p0).cross(&(p2 - p0));
            for j in 0..VERTICES {
                // Where the line through vertex j's location along `axis` meets it.
                let base = l.vertex(&table, &key, axis, j);
                let mut dir = Vec3::zeros();
                dir[axis.index()] = 1.0;
                let t = n.dot(&(p0.coords - base)) / n.dot(&dir);
                let want = f64::from(l.pred[j]) + t;
                let got = f64::from(moved.pred[j]);
                assert!(
                    (got - want).abs() < 3e-4,
                    "{axis:?} {j}: {got} against {want}"
                );
                assert_eq!(moved.var[j], l.var[j]);
                unmoved_error = unmoved_error.max((f64::from(l.pred[j]) - want).abs());
            }
            assert!(
                unmoved_error > 0.004,
                "{axis:?}: the motion moves the plane by {unmoved_error}"
            );
        }
    }

    /// The normals computed in `f32` are those computed in `f64`, at every vertex of a curved
    /// layer along each axis, and usable at the same vertices (a few unusable).
    #[test]
    fn single_precision_normals_are_double_precision_normals() {
        let (mut l, lat) = plane(|a, b| 0.5 + 0.4 * a * a - 0.2 * b + 0.1 * a * b);
        l.var[7] = 0.9;
        l.var[20] = 0.9;
        let table = lat.table();
        for axis in Axis::ALL {
            for j in 0..VERTICES {
                let n64 = l.normal_in::<f64>(&table, axis, j, 0.5);
                let n32 = l.normal_in::<f32>(&table, axis, j, 0.5);
                assert_eq!(n64.is_some(), n32.is_some(), "vertex {j}");
                if let (Some(a), Some(b)) = (n64, n32) {
                    for k in 0..3 {
                        assert!(
                            (a[k] - f64::from(b[k])).abs() < 1e-6,
                            "vertex {j}: {a:?} {b:?}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn a_layer_moved_by_the_identity_is_unchanged() {
        let (l, lat) = plane(|a, b| 0.5 + 0.4 * a * a - 0.2 * b);
        let moved = l.moved(
            &lat.table(),
            &CellKey::new(1, 2, 3),
            Axis::Y,
            &Pose::identity(),
        );
        assert_eq!(moved, l);
    }

    #[test]
    fn corner_vertex_normal_uses_the_one_edge_pair_and_uncertain_vertices_are_skipped() {
        let (mut l, lat) = plane(|_, _| 0.4);
        let n = l.normal(&lat.table(), Axis::Z, 0, 0.5).unwrap();
        assert!((n - Vec3::z()).norm() < 1e-9);
        l.var[1] = 0.9;
        assert!(l.normal(&lat.table(), Axis::Z, 0, 0.5).is_none());
    }

    #[test]
    fn triangles_follow_the_variance_threshold() {
        let (mut l, lat) = plane(|_, _| 0.4);
        let show = |variance| Shown {
            variance,
            min_axis_cosine: 0.5,
        };
        assert_eq!(l.triangles(&lat.table(), show(1.0)).count(), 50);
        l.var[0] = 3.0; // in 1 triangle of quad (0, 0)... and the other one too
        assert_eq!(l.triangles(&lat.table(), show(1.0)).count(), 48);
    }

    #[test]
    fn a_notch_in_a_confident_surface_closes_and_a_lone_speck_goes() {
        let lat = plane(|_, _| 0.4).1;
        let table = lat.table();
        let show = |variance| Shown {
            variance,
            min_axis_cosine: 0.5,
        };
        let inner = 24; // quad (2, 2): no edge on the lattice's border
        let with_corners = |t: usize, corner_var: f32, rest: f32| {
            let mut l = plane(|_, _| 0.4).0;
            l.var = [rest; VERTICES];
            for j in lattice_triangle(t) {
                l.var[j] = corner_var;
            }
            l
        };
        // Corners at 1.2 against a limit of 1.1: the triangle is at 1.2, its three
        // neighbours (two corners each) at 0.80, so it is a notch and closes.
        let notch = with_corners(inner, 1.2, 0.01);
        assert_eq!(notch.mean_variance(&lattice_triangle(inner)), 1.2);
        assert_eq!(notch.triangles(&table, show(1.1)).count(), 50);
        // At 1.5 it is above 4/3 of the limit and stays hidden (its neighbours, at 1.003,
        // are shown).
        let hole = with_corners(inner, 1.5, 0.01);
        assert_eq!(
            hole.shown_mask(&table, show(1.1)),
            !(1u64 << inner) & ((1 << 50) - 1)
        );
        // One confident triangle in an uncertain layer: inside the lattice it goes; on the
        // border (triangle 0) it stays, for a neighbour cell may continue it.
        let speck = with_corners(inner, 0.01, 3.0);
        assert_eq!(speck.triangles(&table, show(0.5)).count(), 0);
        let edge = with_corners(0, 0.01, 3.0);
        assert_eq!(edge.shown_mask(&table, show(0.5)), 1);
    }

    #[test]
    fn triangles_steeper_than_the_limit_are_hidden() {
        // A step of 1 m between two lattice columns 0.27 m apart: the quads across it slope
        // at 75 degrees; the rest is flat.
        let (l, lat) = plane(|a, _| if a < 0.8 { 0.2 } else { 1.2 });
        let table = lat.table();
        let count = |deg: f64| {
            let shown = Shown::new(&crate::config::MeshConfig {
                variance_show: 1.0,
                max_slope_deg: deg,
            });
            l.triangles(&table, shown).count()
        };
        assert_eq!(count(90.0), 50);
        assert_eq!(count(55.0), 40, "the 5 quads across the step are hidden");
        // The steepest a surface can be against its best axis, normal (1, 1, 1)/√3 at 54.7
        // degrees from every axis, is kept at the default 55.
        let (slope, lat) = plane(|a, b| 1.5 - a - b);
        let shown = Shown::new(&crate::config::Config::default().mesh);
        assert_eq!(slope.triangles(&lat.table(), shown).count(), 50);
    }

    #[test]
    fn triangle_neighbours_share_an_edge_both_ways() {
        for t in 0..TRIANGLES {
            let tri = lattice_triangle(t);
            let around = triangle_neighbours(t);
            for n in around.iter().flatten() {
                let other = lattice_triangle(*n);
                let shared = tri.iter().filter(|v| other.contains(v)).count();
                assert_eq!(shared, 2, "{t} and {n}");
                assert!(triangle_neighbours(*n).contains(&Some(t)));
            }
            // Every edge inside the lattice has a triangle across.
            let inner = (0..3)
                .filter(|&k| {
                    let (p, q) = (tri[k], tri[(k + 1) % 3]);
                    let (pa, pb, qa, qb) = (p / N, p % N, q / N, q % N);
                    !((pa == qa && (pa == 0 || pa == N - 1))
                        || (pb == qb && (pb == 0 || pb == N - 1)))
                })
                .count();
            assert_eq!(around.iter().flatten().count(), inner, "{t}");
        }
    }
}
