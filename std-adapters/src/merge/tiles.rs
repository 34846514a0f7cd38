//! B's map read by tile, and B fused into A one tile of the merged map at a time (docs/design.md
//! §1.20): what keeps a merge's memory bounded whatever the maps' sizes.
//!
//! Owns B's open map file ([`TiledB`]): a place's cloud is read from B's tiles within its
//! radius ([`TiledB::around`]). The fusion ([`fuse_by_tile`]) first reads each of B's tiles
//! once to learn which tiles of the merged map (A's frame) its confident vertices land in; then,
//! for each tile of the merged map in order, it loads A's blocks of that tile, fuses into it the
//! vertices of B that land there (as a scan from the nearest pose of B's path, moved into A),
//! writes the tile, and lets it go. Memory: the pipeline's map holds one tile and what one
//! tile's fusion adds; B's tiles are read one at a time. A tile's vertices are fused in the
//! cells they land in, so nothing crosses into a tile already written.

use super::{along, MAX_POINTS};
use crate::formats::map_file::{tile_distance, MapFile, MapWriter};
use crate::io::error::FileError;
use slamesh_core::cell::CellKey;
use slamesh_core::lattice::{Lattice, LatticeTable};
use slamesh_core::map::{LayerRef, MeshMap};
use slamesh_core::map_file::{tile_of, TILE_CELLS};
use slamesh_core::math::Vec3;
use slamesh_core::{Capacity, Pipeline, Point, Pose};
use std::collections::{BTreeMap, BTreeSet};

/// B's map, read by tile.
pub(super) struct TiledB {
    file: MapFile,
    /// Each tile's layers at most.
    bounds: BTreeMap<CellKey, usize>,
    lattice: Lattice,
    table: LatticeTable,
    tile_m: f64,
    /// Vertices with a variance below this are confident (the mesh's own threshold).
    max_var: f32,
}

impl TiledB {
    pub(super) fn new(file: MapFile, max_var: f32) -> Self {
        let lattice = file.info.lattice;
        Self {
            bounds: file.tile_bounds(),
            table: lattice.table(),
            tile_m: lattice.cell_size * f64::from(TILE_CELLS),
            lattice,
            file,
            max_var,
        }
    }

    /// Scans fused into B's map.
    pub(super) fn frames(&self) -> u32 {
        self.file.info.frames
    }

    /// A map of its own holding B's `tiles`.
    fn load(&mut self, tiles: &[CellKey]) -> Result<MeshMap, FileError> {
        let most: usize = tiles.iter().filter_map(|t| self.bounds.get(t)).sum();
        let mut map = MeshMap::with_capacity(most, most, self.lattice);
        for t in tiles {
            self.file.load_tile(*t, &mut map)?;
        }
        Ok(map)
    }

    /// The confident vertices of `layers`, in B's frame.
    fn vertices<'m>(&self, layers: impl Iterator<Item = LayerRef<'m>>, mut each: impl FnMut(Vec3)) {
        for l in layers {
            for (j, var) in l.layer.var.iter().enumerate() {
                if *var < self.max_var {
                    each(l.layer.vertex(&self.table, &l.key, l.axis, j));
                }
            }
        }
    }

    /// Reads B's tile `from` and calls `each` with every confident vertex moved into A's frame
    /// by `t_ab` and the tile of the merged map it lands in. Returns the tile's cells and
    /// layers.
    fn landing(
        &mut self,
        from: CellKey,
        t_ab: &Pose,
        mut each: impl FnMut(Vec3, CellKey),
    ) -> Result<(usize, usize), FileError> {
        let map = self.load(&[from])?;
        let cell = self.lattice.cell_size;
        self.vertices(map.layers(), |v| {
            let moved = (t_ab * nalgebra::Point3::from(v)).coords;
            if let Some(key) = CellKey::containing(&moved, cell) {
                each(moved, tile_of(&key));
            }
        });
        Ok((map.cell_count(), map.layer_count()))
    }

    /// A place's cloud: the confident vertices of B's cells within `radius_m` of `pose`, in
    /// its frame, evenly thinned to at most [`MAX_POINTS`]; read from the tiles within reach.
    pub(super) fn around(&mut self, pose: &Pose, radius_m: f64) -> Result<Vec<Point>, FileError> {
        let here = pose.translation.vector;
        let tiles: Vec<CellKey> = (self.bounds.keys())
            .filter(|t| tile_distance(t, self.tile_m, &here) <= radius_m)
            .copied()
            .collect();
        let map = self.load(&tiles)?;
        let near = (map.layers())
            .filter(|l| (l.key.centre(self.lattice.cell_size) - here).norm() <= radius_m);
        let to_sensor = pose.inverse();
        let mut points = Vec::new();
        self.vertices(near, |v| {
            let p = to_sensor * nalgebra::Point3::from(v);
            points.push([p.x as f32, p.y as f32, p.z as f32]);
        });
        let every = points.len().div_ceil(MAX_POINTS).max(1);
        Ok(points.into_iter().step_by(every).collect())
    }
}

/// What the fusion did: B's confident vertices fused, and the cells and layers of A and B as
/// read.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Fused {
    pub(super) vertices: usize,
    pub(super) a: (usize, usize),
    pub(super) b: (usize, usize),
}

/// Fuses B (at `t_ab`, its path `b_path`) into A (`a`) a tile at a time, writing each tile of
/// the merged map to `out` (see the module docs). B's vertices of a tile are fused as a scan
/// from the pose of B's path (one every `every_m`) nearest to the tile, moved into A.
pub(super) fn fuse_by_tile<C: Capacity>(
    pipeline: &mut Pipeline<C>,
    a: &mut MapFile,
    b: &mut TiledB,
    b_path: &[(f64, Pose)],
    t_ab: &Pose,
    every_m: f64,
    out: &mut MapWriter,
) -> Result<Fused, FileError> {
    pipeline.set_map_updates(true);
    let mut fused = Fused::default();
    let lands = landing_tiles(b, t_ab, &mut fused)?;
    let anchors: Vec<Pose> = (along(b_path, every_m, usize::MAX).into_iter())
        .map(|i| t_ab * b_path[i].1)
        .collect();
    let mut tiles: BTreeSet<CellKey> = a.index.iter().map(|e| e.tile).collect();
    tiles.extend(lands.keys().copied());
    for tile in tiles {
        let map = pipeline.map_mut();
        map.clear();
        a.load_tile(tile, map)?;
        fused.a.0 += map.cell_count();
        fused.a.1 += map.layer_count();
        if let Some(from) = lands.get(&tile) {
            let world = b_vertices_in(b, from, t_ab, tile)?;
            let centre = tile.centre(b.tile_m);
            let d = |p: &&Pose| (p.translation.vector - centre).norm_squared();
            if let Some(anchor) = anchors.iter().min_by(|x, y| d(x).total_cmp(&d(y))) {
                let to_sensor = anchor.inverse();
                let points: Vec<Point> = (world.iter())
                    .map(|v| to_sensor * nalgebra::Point3::from(*v))
                    .map(|p| [p.x as f32, p.y as f32, p.z as f32])
                    .collect();
                for chunk in points.chunks(MAX_POINTS) {
                    if pipeline.integrate_scan(chunk, anchor).is_ok() {
                        fused.vertices += chunk.len();
                    }
                }
            }
        }
        let layers = pipeline.map().layers().filter(|l| tile_of(&l.key) == tile);
        out.add_layers(layers)?;
    }
    Ok(fused)
}

/// For each tile of the merged map, the tiles of B with confident vertices that land in it at
/// `t_ab`; B's cells and layers counted into `fused.b` (each of B's tiles read once).
fn landing_tiles(
    b: &mut TiledB,
    t_ab: &Pose,
    fused: &mut Fused,
) -> Result<BTreeMap<CellKey, BTreeSet<CellKey>>, FileError> {
    let mut lands: BTreeMap<CellKey, BTreeSet<CellKey>> = BTreeMap::new();
    for from in b.bounds.keys().copied().collect::<Vec<_>>() {
        let (cells, layers) = b.landing(from, t_ab, |_, tile| {
            lands.entry(tile).or_default().insert(from);
        })?;
        fused.b.0 += cells;
        fused.b.1 += layers;
    }
    Ok(lands)
}

/// B's confident vertices (from its tiles `from`) that land in the merged map's `tile` at
/// `t_ab`, in A's frame.
fn b_vertices_in(
    b: &mut TiledB,
    from: &BTreeSet<CellKey>,
    t_ab: &Pose,
    tile: CellKey,
) -> Result<Vec<Vec3>, FileError> {
    let mut world = Vec::new();
    for t in from {
        b.landing(*t, t_ab, |moved, lands_in| {
            if lands_in == tile {
                world.push(moved);
            }
        })?;
    }
    Ok(world)
}
