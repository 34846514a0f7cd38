//! The map's shown triangles by tile of [`TILE_CELLS`]³ cells, kept current from the layers
//! each frame changes: what a grid made while a run goes on reads near the sensor
//! ([`crate::navmap::background`]: the ROS 2 node's `map`, the live view's `/map`), and what
//! the node's mesh markers are made of (`ros2::mesh_tiles`).
//!
//! Memory: the shown triangles of every tile seen, three points and their mean variance each
//! (76 bytes a triangle).

use slamesh_core::cell::{Axis, CellKey};
use slamesh_core::lattice::{LatticeTable, VERTICES};
use slamesh_core::layer::{Layer, Shown};
use std::collections::BTreeMap;

/// Cells along a tile's edge.
pub const TILE_CELLS: i32 = 8;

/// A tile's key: its cells' keys divided by [`TILE_CELLS`].
pub type TileKey = (i32, i32, i32);

/// The tile holding cell `key`.
pub fn tile_of(key: &CellKey) -> TileKey {
    (
        key.x.div_euclid(TILE_CELLS),
        key.y.div_euclid(TILE_CELLS),
        key.z.div_euclid(TILE_CELLS),
    )
}

/// The map's shown triangles (the engine's world) by tile.
pub struct TiledMesh {
    lattice: LatticeTable,
    shown: Shown,
    tiles: BTreeMap<TileKey, Layers>,
}

/// A tile's layers (by cell and axis), each layer's triangles.
type Layers = BTreeMap<(CellKey, u8), LayerTriangles>;

/// A layer's shown triangles: three points each, and each triangle's corners' mean
/// Gaussian-process variance.
#[derive(Debug, Default)]
struct LayerTriangles {
    points: Vec<[f64; 3]>,
    variances: Vec<f32>,
}

impl LayerTriangles {
    /// Triangles held.
    fn count(&self) -> usize {
        self.variances.len()
    }
}

impl TiledMesh {
    /// For the map's `lattice`, showing triangles as `shown` says.
    pub fn new(lattice: LatticeTable, shown: Shown) -> Self {
        TiledMesh {
            lattice,
            shown,
            tiles: BTreeMap::new(),
        }
    }

    /// Takes the layers a frame changed, as they are after it: a layer that shows nothing
    /// leaves its tile.
    pub fn update<'a>(&mut self, layers: impl IntoIterator<Item = &'a (CellKey, Axis, Layer)>) {
        for (key, axis, layer) in layers {
            let vertices: Vec<[f64; 3]> = (0..VERTICES)
                .map(|j| {
                    let v = layer.vertex(&self.lattice, key, *axis, j);
                    [v.x, v.y, v.z]
                })
                .collect();
            let mut triangles = LayerTriangles::default();
            for t in layer.triangles(&self.lattice, self.shown) {
                triangles.points.extend(t.map(|j| vertices[j]));
                triangles.variances.push(layer.mean_variance(&t));
            }
            let entry = self.tiles.entry(tile_of(key)).or_default();
            let id = (*key, *axis as u8);
            if triangles.count() == 0 {
                entry.remove(&id);
            } else {
                entry.insert(id, triangles);
            }
        }
    }

    /// Forgets every tile's triangles (after a loop closure, whose update holds every layer)
    /// and says which tiles there were.
    pub fn clear(&mut self) -> Vec<TileKey> {
        let all = self.tiles.keys().copied().collect();
        self.tiles.clear();
        all
    }

    /// Tile `t`'s triangles' points, three a triangle, layer by layer.
    pub fn points_of(&self, t: TileKey) -> impl Iterator<Item = &[f64; 3]> {
        self.tiles
            .get(&t)
            .into_iter()
            .flat_map(|l| l.values().flat_map(|t| &t.points))
    }

    /// Calls `each` with the triangles of the tiles within `half` metres of `centre` along x
    /// and y (the engine's world), and their mean variances.
    pub fn each_triangle_near(
        &self,
        centre: [f64; 2],
        half: f64,
        each: &mut dyn FnMut([slamesh_core::Point; 3], f32),
    ) {
        let side = f64::from(TILE_CELLS) * self.lattice.cell_size;
        let near = |t: i32, c: f64| {
            let lo = f64::from(t) * side;
            lo <= c + half && lo + side >= c - half
        };
        let tiles =
            (self.tiles.iter()).filter(|(t, _)| near(t.0, centre[0]) && near(t.1, centre[1]));
        for (_, layers) in tiles {
            for layer in layers.values() {
                for (t, v) in layer.points.chunks_exact(3).zip(&layer.variances) {
                    each(std::array::from_fn(|k| t[k].map(|c| c as f32)), *v);
                }
            }
        }
    }

    /// Triangles held, over all tiles.
    pub fn triangles(&self) -> usize {
        self.tiles
            .values()
            .flat_map(|l| l.values())
            .map(LayerTriangles::count)
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::flat_layer;

    #[test]
    fn layers_fill_their_tiles_and_the_near_ones_are_handed_over() {
        let config = slamesh_core::Config::default();
        let mut m = TiledMesh::new(config.lattice().table(), Shown::new(&config.mesh));
        // Cells in tile (0, 0, 0), (1, 0, 0) and (0, 2, 0): 8 cells of 1.6 m to a tile.
        let layers: Vec<(CellKey, Axis, Layer)> = [(0, 0), (8, 0), (0, 16)]
            .iter()
            .map(|&(x, y)| (CellKey { x, y, z: 0 }, Axis::Z, flat_layer()))
            .collect();
        m.update(&layers);
        let per_layer = m.triangles() / 3;
        assert!(per_layer > 0);
        assert_eq!(m.points_of((1, 0, 0)).count(), 3 * per_layer);
        // Within 5 m of the origin: tile (0, 0, 0) and, its edge at 12.8 m, not the others.
        let mut near = 0;
        m.each_triangle_near([0.0, 0.0], 5.0, &mut |_, v| {
            assert!(v.is_finite());
            near += 1
        });
        assert_eq!(near, per_layer);
        // A layer that shows nothing leaves its tile; clearing says which tiles there were.
        m.update(&[(CellKey { x: 8, y: 0, z: 0 }, Axis::Z, Layer::UNKNOWN)]);
        assert_eq!(m.points_of((1, 0, 0)).count(), 0);
        assert_eq!(m.clear().len(), 3);
        assert_eq!(m.triangles(), 0);
        assert_eq!(tile_of(&CellKey { x: 7, y: -1, z: 8 }), (0, -1, 1));
    }
}
