//! The fixed `n x n` vertex lattice of a layer (docs/design.md §1.3).
//!
//! A layer along axis `d` has its vertices at fixed locations `(a_i, b_j)` in the cell's two
//! location axes; only the coordinate along `d` (the *prediction*) is estimated. Vertex
//! `j = i_a · N + i_b`. Two placements: cell-interval centres (`full_cover = false`) or evenly
//! spaced values including both faces (`full_cover = true`, so neighbouring cells share their
//! border vertices and the mesh has no gaps).

use crate::cell::{Axis, CellKey};
use crate::math::Vec3;

/// Vertices per lattice side.
pub const N: usize = 6;
/// Vertices per layer.
pub const VERTICES: usize = N * N;

/// Where lattice vertices sit inside a cell, and how big the cell is.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Lattice {
    /// Cell edge in metres.
    pub cell_size: f64,
    /// Vertices on both faces (`true`) or at interval centres (`false`).
    pub full_cover: bool,
}

impl Lattice {
    /// The local coordinate (metres from the cell's minimum face) of lattice index `i < N`.
    #[inline]
    pub fn coordinate(&self, i: usize) -> f64 {
        let i = i as f64;
        if self.full_cover {
            i * self.cell_size / (N as f64 - 1.0)
        } else {
            (i + 0.5) * self.cell_size / N as f64
        }
    }

    /// The cell-local location `(a, b)` of vertex `j`.
    #[inline]
    pub fn location(&self, j: usize) -> (f64, f64) {
        (self.coordinate(j / N), self.coordinate(j % N))
    }

    /// The world position of vertex `j` of the layer along `axis` in cell `key`, whose
    /// prediction is `d_local` (metres from the cell's minimum face along `axis`).
    #[inline]
    pub fn vertex_world(&self, key: &CellKey, axis: Axis, j: usize, d_local: f64) -> Vec3 {
        place(
            key.min_corner(self.cell_size),
            axis,
            self.location(j),
            d_local,
        )
    }

    /// The `N` coordinates, computed once (each is a division), for loops over many vertices.
    pub fn table(&self) -> LatticeTable {
        LatticeTable {
            cell_size: self.cell_size,
            coordinates: core::array::from_fn(|i| self.coordinate(i)),
        }
    }
}

/// A [`Lattice`] with its coordinates computed: the same numbers, without the divisions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LatticeTable {
    /// Cell edge in metres.
    pub cell_size: f64,
    /// [`Lattice::coordinate`] of each index.
    pub coordinates: [f64; N],
}

impl LatticeTable {
    /// [`Lattice::location`] of vertex `j < VERTICES` (`(0, 0)` beyond).
    #[inline]
    pub fn location(&self, j: usize) -> (f64, f64) {
        let c = |i: usize| self.coordinates.get(i).copied().unwrap_or(0.0);
        (c(j / N), c(j % N))
    }

    /// [`Lattice::vertex_world`].
    #[inline]
    pub fn vertex_world(&self, key: &CellKey, axis: Axis, j: usize, d_local: f64) -> Vec3 {
        place(
            key.min_corner(self.cell_size),
            axis,
            self.location(j),
            d_local,
        )
    }
}

/// The point at cell-local `(a, b)` and `d` along `axis` from the cell corner `corner`.
#[inline]
fn place(corner: Vec3, axis: Axis, (la, lb): (f64, f64), d_local: f64) -> Vec3 {
    let (a, b) = axis.locations();
    let mut v = corner;
    v[a] += la;
    v[b] += lb;
    v[axis.index()] += d_local;
    v
}

/// The 4-neighbours of vertex `j` in counter-clockwise order `(+a, +b, -a, -b)`, `None` past
/// the lattice border. Consecutive pairs give edge cross products along `+d`.
#[inline]
pub fn neighbours(j: usize) -> [Option<usize>; 4] {
    let (ia, ib) = (j / N, j % N);
    [
        (ia + 1 < N).then(|| j + N),
        (ib + 1 < N).then(|| j + 1),
        (ia > 0).then(|| j - N),
        (ib > 0).then(|| j - 1),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn placements() {
        let l = Lattice {
            cell_size: 1.2,
            full_cover: false,
        };
        assert!((l.coordinate(0) - 0.1).abs() < 1e-12);
        assert!((l.coordinate(5) - 1.1).abs() < 1e-12);
        let l = Lattice {
            cell_size: 1.2,
            full_cover: true,
        };
        assert_eq!(l.coordinate(0), 0.0);
        assert!((l.coordinate(5) - 1.2).abs() < 1e-12);
    }

    #[test]
    fn full_cover_border_vertices_coincide_across_cells() {
        let l = Lattice {
            cell_size: 1.6,
            full_cover: true,
        };
        // Vertex (i_a = 5) of cell y = 0 and vertex (i_a = 0) of cell y = 1 for a z layer... the
        // a axis of a z layer is x, so step the key along x.
        let left = l.vertex_world(&CellKey::new(0, 0, 0), Axis::Z, 5 * N + 2, 0.3);
        let right = l.vertex_world(&CellKey::new(1, 0, 0), Axis::Z, 2, 0.3);
        assert!((left - right).norm() < 1e-12);
    }

    #[test]
    fn the_table_gives_the_lattice_s_numbers() {
        for full_cover in [false, true] {
            let l = Lattice {
                cell_size: 1.6,
                full_cover,
            };
            let t = l.table();
            for j in 0..VERTICES {
                assert_eq!(t.location(j), l.location(j));
                let key = CellKey::new(-3, 7, 2);
                assert_eq!(
                    t.vertex_world(&key, Axis::Y, j, 0.4),
                    l.vertex_world(&key, Axis::Y, j, 0.4)
                );
            }
        }
    }

    #[test]
    fn neighbour_table_stays_inside() {
        assert_eq!(neighbours(0), [Some(N), Some(1), None, None]);
        assert_eq!(
            neighbours(VERTICES - 1),
            [None, None, Some(VERTICES - 1 - N), Some(VERTICES - 2)]
        );
    }
}
