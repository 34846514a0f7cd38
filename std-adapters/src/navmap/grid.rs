//! The 2.5D grid a navigation map is made of, from the mesh's triangles.
//!
//! The triangles are turned level first (the `up` direction made the grid's z) and sampled
//! densely (points at most half a cell apart, on every triangle whatever its slope), in two
//! passes over them:
//! 1. **floor**: each cell keeps its lowest sample of a triangle no steeper than the robot's
//!    slope limit (give or take [`FLOOR_NOISE_M`] across the triangle: small triangles of a
//!    noisy floor). **Ground** is the floor the robot can reach from its path
//!    ([`crate::navmap::ground`]): a car's roof or a pavement behind a kerb higher than a step
//!    is floor, not ground. Where a run's scans saw the floor ([`crate::navmap::hits`],
//!    [`Grid::build_with_floors`]) their floor must climb too: the mesh rounds a kerb.
//! 2. **classify**: a cell is judged against its own ground, or where it has none against the
//!    nearest ground within about two metres: a sample standing above that by more than a
//!    step and no more than the robot's height makes the cell an obstacle (but a floor
//!    sample within [`DOUBLE_FLOOR_M`] of a ground cell's floor is that floor seen twice); a
//!    ground sample gives the cell's height and spread for the elevation grid. An obstacle
//!    lower than [`LOW_RISE_M`] beside a taller one (its foot) or with no raised floor near
//!    (a ridge of a noisy floor) is settled as unknown instead (`Grid::settle_low_rises`).
//!    Where the mesh saw no ground, the scans' floor raised over the reference is something
//!    standing that the mesh dropped ([`crate::navmap::raised`]: a car's roof).
//!
//! Then lines of sight from the path mark what it saw ([`crate::navmap::sight`]). A cell is
//! occupied (an obstacle stands in it, or a surface between the robot's height and the
//! sensor's, seen from above, stands over it with no ground seen beneath: a car's roof), free
//! (ground in sight, nothing standing on it) or unknown (everything else: nothing seen, only
//! what the robot passes under, a surface with no ground near enough to judge it, ground out
//! of sight behind a wall or in an obstacle's shadow). The mesh holds only
//! triangles whose corners' mean Gaussian-process variance is below `mesh.variance_show`, so
//! a surface the map is unsure of is no surface here: unknown, never free. The grid is
//! stricter with what stands ([`crate::navmap::unsure`]): a triangle it is unsure of
//! leaves the cell it would stand in unknown.
//!
//! Memory: cells are kept in tiles of 64 x 64, made where a triangle falls (32 bytes a cell),
//! none for the space between streets.

use crate::io::error::FileError;
use crate::navmap::hits::Floors;
use crate::navmap::robot::Robot;
use crate::navmap::unsure::{is_sure, mean_variance};
use nalgebra::{Rotation3, Vector3};
use slamesh_core::cell::BuildCellHasher;
use slamesh_core::Point;
use std::collections::HashMap;

mod occupancy;

/// Cells along a tile's side.
pub(super) const TILE: i64 = 64;
pub(super) const TILE_CELLS: usize = (TILE * TILE) as usize;

/// What a navigation map says of a cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Occupancy {
    /// Nothing seen there (or only what the robot passes under).
    Unknown,
    /// Ground seen, nothing standing on it.
    Free,
    /// Something stands there between a step and the robot's height above the ground.
    Occupied,
}

/// The rotation from the map frame to the level frame whose z is `up`
/// ([`slamesh_core::math::level_rotation`]).
pub fn level_of(up: &Vector3<f64>) -> Rotation3<f64> {
    slamesh_core::math::level_rotation(up).to_rotation_matrix()
}

/// Anything that hands over a mesh's triangles (map frame), as many times as asked.
pub trait Triangles {
    /// Calls `each` with every triangle's three corners and their mean Gaussian-process
    /// variance ([`mean_variance`]; NaN where the mesh carries none).
    fn each_triangle(&mut self, each: &mut dyn FnMut([Point; 3], f32)) -> Result<(), FileError>;
}

impl Triangles for crate::outputs::mesh_spool::MeshSpool {
    fn each_triangle(&mut self, each: &mut dyn FnMut([Point; 3], f32)) -> Result<(), FileError> {
        self.for_each_triangle(|t, v| each(t, mean_variance(v)))
    }
}

impl Triangles for crate::formats::ply::PlyMesh {
    fn each_triangle(&mut self, each: &mut dyn FnMut([Point; 3], f32)) -> Result<(), FileError> {
        for t in &self.triangles {
            let corners = t.map(|i| self.vertices[i as usize]);
            let v = t.map(|i| self.variances.get(i as usize).copied().unwrap_or(f32::NAN));
            each(corners, mean_variance(v));
        }
        Ok(())
    }
}

#[derive(Debug, Clone, Copy)]
pub(super) struct Cell {
    /// The lowest floor sample (level frame z), infinite for none.
    pub(super) floor: f32,
    /// Whether that floor is ground: reachable from the path.
    pub(super) ground: bool,
    /// The height the cell is judged against: its ground, or the nearest ground
    /// (infinite for none). Until the references are set (`Grid::set_references`), the
    /// floor the scans' points saw in the cell (infinite for none), which the ground's growth
    /// reads.
    pub(super) reference: f32,
    /// Ground samples within a step of `reference`, the sum of their heights above it and of
    /// its squares.
    pub(super) n: u16,
    pub(super) sum: f32,
    pub(super) sum_sq: f32,
    /// The heights above `reference` samples stand at: bit `b` for `b` to `b + 1` tenths of a
    /// metre (0 to 6.4 m).
    pub(super) heights: u64,
    pub(super) obstacle: bool,
    /// Only a low rise was seen, the foot of something taller or a bump of the surface
    /// ([`Grid::settle_low_rises`]), or a standing surface the map is unsure of
    /// ([`is_sure`]): unknown, unless an obstacle was seen too.
    pub(super) doubtful: bool,
    /// Seen from the path: a line of sight reaches it ([`Grid::carve`]).
    pub(super) visible: bool,
    /// The highest obstacle top (level frame z, decimetres, rounded up) in the cell or a
    /// neighbour, the height a line of sight over it must clear; `i16::MIN` for none
    /// ([`Grid::carve`]). Small, so that a cell keeps to 32 bytes.
    pub(super) shadow: i16,
}

impl Default for Cell {
    fn default() -> Self {
        Cell {
            floor: f32::INFINITY,
            ground: false,
            reference: f32::INFINITY,
            n: 0,
            sum: 0.0,
            sum_sq: 0.0,
            heights: 0,
            obstacle: false,
            doubtful: false,
            visible: false,
            shadow: i16::MIN,
        }
    }
}

/// The height (m) a floor's mesh may rise across a triangle through its noise alone, over the
/// robot's slope limit ([`Grid::build`]'s floor).
pub const FLOOR_NOISE_M: f64 = 0.02;

/// How much higher (m) than a ground cell's floor a floor sample in it may lie and still be
/// that floor seen twice ([`Grid::build`]'s obstacles: a step up is told by its steep face).
pub const DOUBLE_FLOOR_M: f64 = 0.2;

impl Cell {
    /// Counts something standing `above` the cell's reference among its heights
    /// ([`Cell::heights`], 0 to 6.4 m).
    pub(super) fn mark_height(&mut self, above: f32) {
        if (0.0..6.4).contains(&above) {
            self.heights |= 1 << (above * 10.0) as u32;
        }
    }

    /// Pass 2 for one sample of height `z` in the cell, of a floor triangle or not, for a
    /// robot that climbs `step` and is `height` tall; `sure`: whether the map is sure of the
    /// triangle ([`is_sure`]). A sample of an unsure steep triangle, or of an unsure level
    /// one where it would stand, is no height and no obstacle: where it would make one, the
    /// cell is doubtful instead.
    fn classify(&mut self, z: f64, is_floor: bool, sure: bool, step: f32, height: f32) {
        let above = z as f32 - self.reference;
        if !above.is_finite() {
            return;
        }
        // A ground cell's floor seen again a little higher (two passes of a drifting map,
        // fused as two layers) is the same floor, not a step: a step's face is steep.
        let same_floor = self.ground && is_floor && above <= DOUBLE_FLOOR_M as f32;
        let stands = above > step && above <= height && !same_floor;
        if !sure && (stands || !is_floor) {
            // A surface the map is unsure of is no height and no obstacle: where it would
            // stand, the cell is doubtful.
            self.doubtful |= stands;
            return;
        }
        self.mark_height(above);
        if stands {
            self.obstacle = true;
        } else if is_floor && self.ground && above <= step {
            if self.n == u16::MAX {
                return;
            }
            self.n += 1;
            self.sum += above;
            self.sum_sq += above * above;
        }
    }
}

/// The height (m) under which a rise is only a foot or a bump when taller obstacles stand
/// beside it or no raised floor does (`Grid::settle_low_rises`). Measured on the simulated
/// town and office (docs/journal.md, "Low rises and unsure standing surfaces"): the fringe
/// along walls' feet and the ridges of the office's floor stand lower.
pub const LOW_RISE_M: f64 = 0.3;

/// How far (m) from an obstacle's cell ground is taken as the obstacle's edge: the surface
/// reconstruction carries ground up to about two tenths under a car's or a wall's foot.
pub const EDGE_M: f64 = 0.2;

pub(super) type Tile = Box<[Cell; TILE_CELLS]>;

/// A navigation grid: cells of `resolution` metres in the level frame.
pub struct Grid {
    pub(super) resolution: f64,
    pub(super) robot: Robot,
    /// Map frame to level frame.
    pub(super) level: Rotation3<f64>,
    pub(super) tiles: HashMap<(i64, i64), Tile, BuildCellHasher>,
    /// Whether lines of sight were cast (a path was given): free cells must then be seen.
    pub(super) carved: bool,
    /// The heights above a cell's reference (bits of [`Cell::heights`]) between the robot's
    /// and the sensor's median height where lines of sight were cast from: a surface there was
    /// seen from above. None where nothing was cast.
    pub(super) from_above: u64,
    /// Cells whose floor the scans' points saw ([`build_with_floors`](Self::build_with_floors)).
    pub(super) scans_floor: usize,
}

/// A cell's index: column and row (level frame x and y over the resolution, floored).
pub type CellIndex = (i64, i64);

impl Grid {
    /// The grid of the triangles `mesh` hands over, for `robot`, with cells of `resolution`
    /// metres, `up` (map frame) taken as up; `path` (sensor positions, map frame) is where the
    /// robot's ground is grown from (empty: from the largest stretch of floor).
    pub fn build(
        mesh: &mut dyn Triangles,
        robot: Robot,
        resolution: f64,
        up: Vector3<f64>,
        path: &[Vector3<f64>],
    ) -> Result<Grid, FileError> {
        Grid::build_with_floors(mesh, &|_| {}, robot, resolution, up, path, &[])
    }

    /// [`build`](Self::build), with the floor the scans' points saw (`floors` calls its
    /// argument with each, map frame: [`crate::navmap::hits::Hits::each_floor`]): the ground
    /// does not grow between two cells whose points' floors differ by more than the robot
    /// climbs ([`crate::navmap::ground`]), where the mesh rounded a kerb into a slope. The
    /// ground grows from `ground` too (cells known to be ground: a live grid's free cells
    /// around the window it makes, [`crate::navmap::live`]).
    pub fn build_with_floors(
        mesh: &mut dyn Triangles,
        floors: &Floors,
        robot: Robot,
        resolution: f64,
        up: Vector3<f64>,
        path: &[Vector3<f64>],
        ground: &[CellIndex],
    ) -> Result<Grid, FileError> {
        let level = level_of(&up);
        let mut grid = Grid {
            resolution,
            robot,
            level,
            tiles: HashMap::default(),
            from_above: 0,
            carved: false,
            scans_floor: 0,
        };
        let max_slope_tan = robot.max_slope_deg.to_radians().tan();
        mesh.each_triangle(&mut |t, _| {
            let (corners, is_floor) = grid.levelled(t, max_slope_tan);
            grid.samples(&corners, |c, z| {
                if is_floor {
                    c.floor = c.floor.min(z as f32);
                }
            });
        })?;
        grid.take_scans_floor(floors);
        let faces = grid.kerb_faces();
        let seeds = grid.seeds(path, ground, &faces);
        let kerb_feet = grid.grow_ground(seeds, &faces);
        let blocks = grid.set_references(&kerb_feet);
        let (step, height) = (robot.max_step_m as f32, robot.height_m as f32);
        mesh.each_triangle(&mut |t, variance| {
            let (corners, is_floor) = grid.levelled(t, max_slope_tan);
            let sure = is_sure(variance, is_floor);
            grid.samples(&corners, |c, z| c.classify(z, is_floor, sure, step, height));
        })?;
        grid.raise_from_scans(floors, &blocks);
        grid.settle_low_rises();
        grid.carve(path);
        Ok(grid)
    }

    /// Obstacle cells whose samples up to the robot's height all stand lower than
    /// [`LOW_RISE_M`] above their reference are no obstacle of their own ([`Cell::doubtful`])
    /// when a taller obstacle cell lies within [`EDGE_M`] (the rounding of a wall's or a car's
    /// foot, which the reconstruction carries out over the ground) or no floor raised more
    /// than a step above the cell's own reference does (a ridge where two layers of a noisy
    /// floor meet). A kerb keeps its face:
    /// the pavement behind it is raised floor (judged against the low cell's reference, since
    /// the pavement may be ground of its own). Decided for every cell before any changes, so
    /// the order of the cells does not matter.
    fn settle_low_rises(&mut self) {
        let low_bits = (LOW_RISE_M * 10.0).round() as u32;
        // A cell's top among the heights that make obstacles: what stands over the robot's
        // height (a wall's top the mesh leans out over its foot) is passed under.
        let reach = (self.robot.height_m * 10.0).ceil() as u32;
        let mask = if reach >= 64 {
            u64::MAX
        } else {
            (1u64 << reach) - 1
        };
        let top = |c: &Cell| 64 - (c.heights & mask).leading_zeros();
        let step = self.robot.max_step_m as f32;
        let near = disc((EDGE_M / self.resolution).round().max(1.0) as i64);
        let mut settled = Vec::new();
        for (&t, tile) in &self.tiles {
            for (k, c) in tile.iter().enumerate() {
                if !c.obstacle || top(c) > low_bits {
                    continue;
                }
                let (ix, iy) = cell_at(t, k);
                let any_near = |f: &dyn Fn(&Cell) -> bool| {
                    near.iter()
                        .any(|&(dx, dy)| self.cell(ix + dx, iy + dy).is_some_and(f))
                };
                let taller = any_near(&|n| n.obstacle && top(n) > low_bits);
                let raised = any_near(&|n| n.floor.is_finite() && n.floor - c.reference > step);
                if taller || !raised {
                    settled.push((ix, iy));
                }
            }
        }
        for (ix, iy) in settled {
            let c = self.cell_mut(ix, iy);
            c.obstacle = false;
            c.doubtful = true;
        }
    }

    /// The cell size (m).
    pub fn resolution(&self) -> f64 {
        self.resolution
    }

    /// How many cells' floor the scans' points saw (none: the grid is the mesh's alone).
    pub fn scans_floor_cells(&self) -> usize {
        self.scans_floor
    }

    /// The rotation from the map frame to the grid's level frame.
    pub fn level(&self) -> Rotation3<f64> {
        self.level
    }

    /// The cell holding level-frame `(x, y)`.
    pub fn index_of(&self, x: f64, y: f64) -> CellIndex {
        index_in(self.resolution, x, y)
    }

    /// Cell `(ix, iy)`'s ground height (level frame) and the variance of the ground samples
    /// in it; `None` where no ground was seen (or the ground was not in sight of the path),
    /// or where something low or unsure may stand on it (`Cell::doubtful`: unknown, so the
    /// elevation grid keeps to the ground the occupancy grid calls free or an obstacle's edge).
    pub fn elevation(&self, ix: i64, iy: i64) -> Option<(f64, f64)> {
        let c = self
            .cell(ix, iy)
            .filter(|c| c.ground && c.n > 0 && (c.visible || !self.carved) && !c.doubtful)?;
        let n = c.n as f64;
        let mean = c.sum as f64 / n;
        let var = (c.sum_sq as f64 / n - mean * mean).max(0.0);
        Some((c.reference as f64 + mean, var))
    }

    /// Every cell with an elevation ([`elevation`](Self::elevation)) whose column and row
    /// are multiples of `stride`, row by row from the lowest (only those are gathered: the
    /// 1 000-frame town's ground cells alone took 67 MB).
    pub fn ground_cells(&self, stride: i64) -> Vec<CellIndex> {
        let mut out = Vec::new();
        for (&(tx, ty), tile) in &self.tiles {
            for k in 0..TILE_CELLS {
                let (ix, iy) = cell_at((tx, ty), k);
                let on = ix.rem_euclid(stride) == 0 && iy.rem_euclid(stride) == 0;
                if on && tile[k].n > 0 && self.elevation(ix, iy).is_some() {
                    out.push((ix, iy));
                }
            }
        }
        out.sort_unstable_by_key(|&(x, y)| (y, x));
        out
    }

    /// The smallest box of cells holding every cell seen (free or occupied): its lowest and
    /// highest corners, inclusive; `None` when none was.
    pub fn bounds(&self) -> Option<(CellIndex, CellIndex)> {
        let mut b: Option<(CellIndex, CellIndex)> = None;
        for (&(tx, ty), tile) in &self.tiles {
            for (k, c) in tile.iter().enumerate() {
                if !(c.obstacle || (c.ground && c.n > 0)) {
                    continue;
                }
                let (ix, iy) = cell_at((tx, ty), k);
                b = Some(match b {
                    None => ((ix, iy), (ix, iy)),
                    Some((lo, hi)) => ((lo.0.min(ix), lo.1.min(iy)), (hi.0.max(ix), hi.1.max(iy))),
                });
            }
        }
        b
    }

    /// The triangle `t` in the level frame, and whether it is floor: its slope within the
    /// robot's limit, or within what [`FLOOR_NOISE_M`] of height across it gives (a small
    /// triangle of a noisy floor: with 0.5 m cells the mesh's vertices are 9 cm apart, and a
    /// centimetre or two of noise tilts a triangle by more than a robot's limit). A wall's
    /// triangle, nearly vertical, is never floor.
    fn levelled(&self, t: [Point; 3], max_slope_tan: f64) -> ([Vector3<f64>; 3], bool) {
        let p = t.map(|c| self.level * Vector3::new(c[0] as f64, c[1] as f64, c[2] as f64));
        let n = (p[1] - p[0]).cross(&(p[2] - p[0]));
        // |n.z| is twice the area seen from above, so |n.z| / longest is the triangle's
        // least width seen from above: the slope a rise of FLOOR_NOISE_M across it gives.
        let longest = [(p[1] - p[0]), (p[2] - p[1]), (p[0] - p[2])]
            .iter()
            .map(|e| e.xy().norm())
            .fold(0.0f64, f64::max);
        let (level, steep) = (n.z.abs(), n.xy().norm());
        let is_floor = level > 0.0 && steep <= max_slope_tan * level + FLOOR_NOISE_M * longest;
        (p, is_floor)
    }

    /// Calls `each` with the cell and the height of every sample of the triangle (the cell
    /// made if new): a barycentric lattice with points at most half a cell apart.
    fn samples(&mut self, p: &[Vector3<f64>; 3], mut each: impl FnMut(&mut Cell, f64)) {
        let longest = [(p[1] - p[0]), (p[2] - p[1]), (p[0] - p[2])]
            .iter()
            .map(|e| e.norm())
            .fold(0.0f64, f64::max);
        if !longest.is_finite() {
            return;
        }
        // At most 4 096 steps along an edge: a triangle longer than that is cut coarser.
        let steps = ((longest / (0.5 * self.resolution)).ceil() as usize).clamp(1, 4096);
        let (u, v) = ((p[1] - p[0]) / steps as f64, (p[2] - p[0]) / steps as f64);
        // The last sample's tile: a triangle's samples mostly share one, looked up once.
        let mut current: Option<((i64, i64), &mut Tile)> = None;
        for i in 0..=steps {
            for j in 0..=steps - i {
                let q = p[0] + u * i as f64 + v * j as f64;
                let (ix, iy) = index_in(self.resolution, q.x, q.y);
                let (key, k) = tile_of(ix, iy);
                if current.as_ref().map(|c| c.0) != Some(key) {
                    let tile = self
                        .tiles
                        .entry(key)
                        .or_insert_with(|| Box::new([Cell::default(); TILE_CELLS]));
                    current = Some((key, tile));
                }
                if let Some((_, tile)) = current.as_mut() {
                    each(&mut tile[k], q.z);
                }
            }
        }
    }

    pub(super) fn cell(&self, ix: i64, iy: i64) -> Option<&Cell> {
        let (key, k) = tile_of(ix, iy);
        self.tiles.get(&key).map(|t| &t[k])
    }

    pub(super) fn cell_mut(&mut self, ix: i64, iy: i64) -> &mut Cell {
        let (key, k) = tile_of(ix, iy);
        &mut self
            .tiles
            .entry(key)
            .or_insert_with(|| Box::new([Cell::default(); TILE_CELLS]))[k]
    }
}

/// The cell of `resolution` metres holding level-frame `(x, y)`.
pub(crate) fn index_in(resolution: f64, x: f64, y: f64) -> CellIndex {
    (floor_index(x / resolution), floor_index(y / resolution))
}

/// `v.floor() as i64` for every `v` (a NaN gives 0, beyond `i64` it saturates), by
/// truncation, one less below zero: `f64::floor` is a call to the C library on CPUs without
/// SSE4.1 (x86-64's baseline), three of which were most of counting a scan's floor
/// ([`crate::navmap::hits`]).
#[inline]
pub(crate) fn floor_index(v: f64) -> i64 {
    let t = v as i64;
    t.saturating_sub(i64::from((t as f64) > v))
}

/// The level-frame x and y of the lower-left corner of cell `(ix, iy)` of `resolution`
/// metres, to the micrometre: a whole number of cells, which `-287 x 0.1` would give as
/// -28.700000000000003 (for the files and messages that place a grid).
pub(crate) fn corner_in(resolution: f64, (ix, iy): CellIndex) -> [f64; 2] {
    [ix, iy].map(|i| (i as f64 * resolution * 1e6).round() / 1e6)
}

/// The offsets of the cells within `r` cells of a cell (a disc), nearest rows first.
pub(super) fn disc(r: i64) -> Vec<(i64, i64)> {
    (-r..=r)
        .flat_map(|dy| (-r..=r).map(move |dx| (dx, dy)))
        .filter(|(dx, dy)| dx * dx + dy * dy <= r * r)
        .collect()
}

/// The cell at place `k` of tile `(tx, ty)`: [`tile_of`] turned back.
pub(super) fn cell_at(tile: (i64, i64), k: usize) -> CellIndex {
    cell_in_tiles_of(TILE, tile, k)
}

/// The tile holding cell `(ix, iy)` and the cell's place in it.
pub(super) fn tile_of(ix: i64, iy: i64) -> ((i64, i64), usize) {
    tile_in_tiles_of(TILE, ix, iy)
}

/// [`cell_at`] for tiles of `side` x `side` cells.
pub(super) fn cell_in_tiles_of(side: i64, (tx, ty): (i64, i64), k: usize) -> CellIndex {
    (tx * side + k as i64 % side, ty * side + k as i64 / side)
}

/// [`tile_of`] for tiles of `side` x `side` cells.
pub(super) fn tile_in_tiles_of(side: i64, ix: i64, iy: i64) -> ((i64, i64), usize) {
    let key = (ix.div_euclid(side), iy.div_euclid(side));
    let k = (iy.rem_euclid(side) * side + ix.rem_euclid(side)) as usize;
    (key, k)
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::navmap::hits::{hand, ScanFloor};

    /// What `g` says of the cell holding level-frame `(x, y)`.
    pub(in crate::navmap) fn occupancy_at(g: &Grid, x: f64, y: f64) -> Occupancy {
        let (ix, iy) = g.index_of(x, y);
        g.occupancy(ix, iy)
    }

    /// Floors at `points`, each two points in a bin.
    fn twice(points: &[Vector3<f64>]) -> Vec<ScanFloor> {
        (points.iter())
            .map(|&at| ScanFloor { at, twice: true })
            .collect()
    }

    /// A floor of two triangles over `[x0, x1] x [y0, y1]` at height `z`.
    pub(in crate::navmap) fn floor(x0: f32, y0: f32, x1: f32, y1: f32, z: f32) -> Vec<[Point; 3]> {
        vec![
            [[x0, y0, z], [x1, y0, z], [x1, y1, z]],
            [[x0, y0, z], [x1, y1, z], [x0, y1, z]],
        ]
    }

    /// A wall from `(x, y0)` to `(x, y1)`, from `z0` to `z1`.
    fn wall(x: f32, y0: f32, y1: f32, z0: f32, z1: f32) -> Vec<[Point; 3]> {
        vec![
            [[x, y0, z0], [x, y1, z0], [x, y1, z1]],
            [[x, y0, z0], [x, y1, z1], [x, y0, z1]],
        ]
    }

    pub(in crate::navmap) struct Soup(pub(in crate::navmap) Vec<[Point; 3]>);

    impl Triangles for Soup {
        fn each_triangle(
            &mut self,
            each: &mut dyn FnMut([Point; 3], f32),
        ) -> Result<(), FileError> {
            self.0.iter().for_each(|t| each(*t, f32::NAN));
            Ok(())
        }
    }

    #[test]
    fn ground_walls_steps_ramps_and_overhangs() {
        let mut soup = Vec::new();
        // A street from x = 0 to 10, a kerb of 0.15 m up to a pavement from 10 to 12, a
        // wall at x = 12; a roof over the street at 4 m; a gentle ramp (10 degrees) and a
        // steep one (40) from y = 10 on.
        soup.extend(floor(0.0, 0.0, 10.0, 10.0, 0.0));
        soup.extend(floor(10.0, 0.0, 12.0, 10.0, 0.15));
        soup.extend(wall(10.0, 0.0, 10.0, 0.0, 0.15));
        soup.extend(wall(12.0, 0.0, 10.0, 0.15, 3.0));
        soup.extend(floor(0.0, 0.0, 3.0, 3.0, 4.0));
        let (t10, t40) = (10f32.to_radians().tan(), 40f32.to_radians().tan());
        soup.push([[0.0, 10.0, 0.0], [4.0, 10.0, 0.0], [4.0, 14.0, 4.0 * t10]]);
        soup.push([
            [0.0, 10.0, 0.0],
            [4.0, 14.0, 4.0 * t10],
            [0.0, 14.0, 4.0 * t10],
        ]);
        soup.push([[6.0, 10.0, 0.0], [9.0, 10.0, 0.0], [9.0, 12.0, 2.0 * t40]]);
        soup.push([
            [6.0, 10.0, 0.0],
            [9.0, 12.0, 2.0 * t40],
            [6.0, 12.0, 2.0 * t40],
        ]);
        let path = [Vector3::new(5.0, 5.0, 1.7)];
        let g = Grid::build(&mut Soup(soup), Robot::WHEELED, 0.1, Vector3::z(), &path).unwrap();
        let at = |x: f64, y: f64| occupancy_at(&g, x, y);
        assert_eq!(at(5.05, 5.05), Occupancy::Free, "the street");
        assert_eq!(at(1.05, 1.05), Occupancy::Free, "under the roof");
        assert_eq!(at(12.05, 5.05), Occupancy::Occupied, "the wall");
        // The kerb is higher than a step: the pavement is not reached, and within reference
        // distance of the street it stands higher than a step above it.
        assert_eq!(at(10.15, 5.05), Occupancy::Occupied, "the pavement's edge");
        assert_eq!(at(11.55, 5.05), Occupancy::Occupied, "the pavement");
        assert_eq!(at(2.05, 12.05), Occupancy::Free, "the gentle ramp");
        assert_eq!(at(7.55, 10.45), Occupancy::Occupied, "the steep ramp");
        assert_eq!(
            at(7.55, 11.85),
            Occupancy::Occupied,
            "the steep ramp above the robot and below the sensor, no ground seen under it"
        );
        assert_eq!(at(20.0, 20.0), Occupancy::Unknown, "nothing seen");
        let (ix, iy) = g.index_of(5.05, 5.05);
        let (h, var) = g.elevation(ix, iy).unwrap();
        assert!(h.abs() < 1e-6 && var < 1e-9, "{h} {var}");
        let (lo, hi) = g.bounds().unwrap();
        assert_eq!((lo, hi), ((0, 0), (120, 140)));
        // The traversability layers: the street level and cheap, the gentle ramp at its 10
        // degrees and cheaper than lethal, the wall's foot lethal.
        let mesh = crate::navmap::layers::NavMesh::of(&g, &Robot::WHEELED);
        let at_vertex = |x: f32, y: f32| {
            mesh.vertices
                .iter()
                .position(|v| (v[0] - x).abs() < 0.06 && (v[1] - y).abs() < 0.06)
                .unwrap()
        };
        let street = at_vertex(5.05, 5.05);
        assert!(mesh.slope_deg[street] < 0.5 && mesh.cost[street] < 0.1);
        let ramp = at_vertex(2.05, 12.05);
        assert!(
            (mesh.slope_deg[ramp] - 10.0).abs() < 1.0,
            "{}",
            mesh.slope_deg[ramp]
        );
        assert!(mesh.cost[ramp] > 0.5 && mesh.cost[ramp] < 1.0);
        let foot = at_vertex(9.85, 5.05);
        assert_eq!(mesh.cost[foot], 1.0);
        assert!(mesh.triangles.len() > mesh.vertices.len());
    }

    #[test]
    fn a_cell_index_is_floor_for_every_value() {
        let values = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.999,
            -2.999,
            -287.0,
            1e14 + 0.5,
            -1e14 - 0.5,
            9.3e18,
            -9.3e18,
            1e20,
            -1e20,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ];
        for v in values {
            assert_eq!(floor_index(v), v.floor() as i64, "{v}");
        }
    }

    #[test]
    fn the_seams_between_voxel_cells_and_where_they_cross_are_free() {
        // A street meshed as the default lattice meshes it: each 1.6 m cell's layer spans
        // its vertices at the interval centres, 0.133 m in from the cell's faces, so a seam
        // 0.267 m wide runs between neighbouring cells and four cells' seams cross at their
        // corner.
        let (cell, inset) = (1.6f32, 1.6f32 / 12.0);
        let side = cell - 2.0 * inset;
        let mut soup = Vec::new();
        for i in 0..4 {
            for j in 0..4 {
                let (x, y) = (i as f32 * cell + inset, j as f32 * cell + inset);
                soup.extend(floor(x, y, x + side, y + side, 0.0));
            }
        }
        let path = [Vector3::new(3.2, 3.2, 1.7)];
        let g = Grid::build(&mut Soup(soup), Robot::WHEELED, 0.1, Vector3::z(), &path).unwrap();
        let at = |x: f64, y: f64| occupancy_at(&g, x, y);
        assert_eq!(at(2.4, 2.4), Occupancy::Free, "a cell's own floor");
        assert_eq!(at(3.2, 2.4), Occupancy::Free, "the seam between two cells");
        assert_eq!(at(2.4, 3.2), Occupancy::Free, "the seam between two cells");
        // Every cell where the seams cross, at the corners inside the street.
        for corner in [(1.6, 1.6), (3.2, 3.2), (4.8, 1.6), (1.6, 4.8)] {
            for (dx, dy) in [(-0.1, -0.1), (-0.1, 0.0), (0.0, -0.1), (0.0, 0.0)] {
                let (x, y) = (corner.0 + dx + 0.05, corner.1 + dy + 0.05);
                assert_eq!(
                    at(x, y),
                    Occupancy::Free,
                    "the seams' crossing at ({x}, {y})"
                );
            }
        }
        assert_eq!(at(7.0, 7.0), Occupancy::Unknown, "beyond the street");
    }

    #[test]
    fn a_wall_s_rounded_foot_and_a_ridge_in_the_floor_are_no_obstacles() {
        // A street, a wall at x = 5 whose mesh curls out 0.2 m over the street at its foot
        // (up to 0.25 m high) and leans out 0.15 m over it at its top (from 1.5 m up: what
        // the robot passes under, no taller foot), and a ridge 0.15 m high across the street
        // at x = 2.
        let mut soup = floor(0.0, 0.0, 5.0, 10.0, 0.0);
        soup.extend(wall(5.0, 0.0, 10.0, 0.25, 2.0));
        let slant = |x0: f32, z0: f32, x1: f32, z1: f32| {
            [
                [[x0, 0.0, z0], [x1, 0.0, z1], [x1, 10.0, z1]],
                [[x0, 0.0, z0], [x1, 10.0, z1], [x0, 10.0, z0]],
            ]
        };
        soup.extend(slant(4.8, 0.0, 5.0, 0.25));
        soup.extend(slant(4.85, 2.0, 5.0, 1.5));
        soup.extend(slant(1.9, 0.0, 2.0, 0.15));
        soup.extend(slant(2.0, 0.15, 2.1, 0.0));
        let path = [Vector3::new(3.5, 5.0, 1.7)];
        let g = Grid::build(&mut Soup(soup), Robot::WHEELED, 0.1, Vector3::z(), &path).unwrap();
        let at = |x: f64| occupancy_at(&g, x, 5.05);
        assert_eq!(at(5.05), Occupancy::Occupied, "the wall");
        assert_eq!(at(4.85), Occupancy::Unknown, "the wall's foot");
        assert_eq!(at(2.05), Occupancy::Unknown, "the ridge");
        assert_eq!(at(3.05), Occupancy::Free, "the street");
    }

    /// Triangles, each with its mean variance.
    struct Listed(Vec<([Point; 3], f32)>);

    impl Triangles for Listed {
        fn each_triangle(
            &mut self,
            each: &mut dyn FnMut([Point; 3], f32),
        ) -> Result<(), FileError> {
            self.0.iter().for_each(|(t, v)| each(*t, *v));
            Ok(())
        }
    }

    #[test]
    fn a_standing_surface_the_map_is_unsure_of_leaves_its_ground_unknown() {
        // A street (sure) with a wall across it at x = 5 whose triangles carry `variance`:
        // only triangles steeper than the slope limit are held to STANDING_VARIANCE.
        let path = [Vector3::new(2.0, 5.0, 1.7)];
        let at = |variance: f32, x: f64| {
            let mut rated: Vec<([Point; 3], f32)> = floor(0.0, 0.0, 10.0, 10.0, 0.0)
                .into_iter()
                .map(|t| (t, 0.01))
                .collect();
            rated.extend(
                wall(5.0, 0.0, 10.0, 0.0, 2.0)
                    .into_iter()
                    .map(|t| (t, variance)),
            );
            let g =
                Grid::build(&mut Listed(rated), Robot::WHEELED, 0.1, Vector3::z(), &path).unwrap();
            let (ix, iy) = g.index_of(x, 5.05);
            (g.occupancy(ix, iy), g.elevation(ix, iy).is_some())
        };
        assert_eq!(at(0.1, 5.05), (Occupancy::Occupied, false), "a sure wall");
        assert_eq!(
            at(f32::NAN, 5.05).0,
            Occupancy::Occupied,
            "no variance known"
        );
        assert_eq!(at(0.25, 5.05), (Occupancy::Unknown, false), "an unsure one");
        assert_eq!(
            at(0.25, 3.05),
            (Occupancy::Free, true),
            "the street before it"
        );
    }

    #[test]
    fn a_level_surface_the_map_is_unsure_of_stands_only_where_it_is_sure() {
        // A street whose triangles carry `street`, and a level patch 0.5 m over it (a table's
        // top, or the shelf a single ring makes off a wall) carrying `shelf`: only level
        // triangles that would stand are held to LEVEL_VARIANCE.
        let path = [Vector3::new(2.0, 5.0, 1.7)];
        let at = |street: f32, shelf: f32, x: f64| {
            let rate = |v: f32| move |t: [Point; 3]| (t, v);
            let mut rated: Vec<([Point; 3], f32)> = floor(0.0, 0.0, 10.0, 10.0, 0.0)
                .into_iter()
                .map(rate(street))
                .collect();
            rated.extend(floor(5.0, 4.0, 5.3, 6.0, 0.5).into_iter().map(rate(shelf)));
            let g =
                Grid::build(&mut Listed(rated), Robot::WHEELED, 0.1, Vector3::z(), &path).unwrap();
            occupancy_at(&g, x, 5.05)
        };
        assert_eq!(at(0.01, 0.05, 5.15), Occupancy::Occupied, "a sure top");
        assert_eq!(at(0.01, f32::NAN, 5.15), Occupancy::Occupied, "none known");
        assert_eq!(at(0.01, 0.15, 5.15), Occupancy::Unknown, "an unsure one");
        assert_eq!(at(0.15, 0.01, 3.05), Occupancy::Free, "an unsure street");
        assert_eq!(at(0.15, 0.01, 5.15), Occupancy::Occupied, "a top over it");
    }

    #[test]
    fn a_kerb_the_mesh_rounds_into_a_slope_is_found_by_the_points_floor() {
        // A street at 0, a pavement at 0.15 m from x = 5.6, and between them the mesh's
        // rounding of the kerb at x = 5: a slope of 14 degrees, climbable for the wheeled
        // robot (15). The scans' points saw the kerb sharp at x = 5, but not the 0.3 m behind
        // its face (its shadow from the path).
        let mut soup = floor(0.0, 0.0, 5.0, 10.0, 0.0);
        soup.push([[5.0, 0.0, 0.0], [5.6, 0.0, 0.15], [5.6, 10.0, 0.15]]);
        soup.push([[5.0, 0.0, 0.0], [5.6, 10.0, 0.15], [5.0, 10.0, 0.0]]);
        soup.extend(floor(5.6, 0.0, 10.0, 10.0, 0.15));
        let floors: Vec<Vector3<f64>> = (0..100)
            .flat_map(|ix| (0..100).map(move |iy| (ix, iy)))
            .filter(|&(ix, _)| !(50..53).contains(&ix))
            .map(|(ix, iy)| {
                let (x, y) = (ix as f64 * 0.1 + 0.05, iy as f64 * 0.1 + 0.05);
                Vector3::new(x, y, if x < 5.0 { 0.01 } else { 0.16 })
            })
            .collect();
        let path = [Vector3::new(2.5, 5.0, 1.7)];
        let grid = |floors: &[Vector3<f64>]| {
            let floors = twice(floors);
            let each = hand(&floors);
            let mut soup = Soup(soup.clone());
            let z = Vector3::z();
            Grid::build_with_floors(&mut soup, &each, Robot::WHEELED, 0.1, z, &path, &[]).unwrap()
        };
        let at = |g: &Grid, x: f64| occupancy_at(g, x, 5.05);
        let (mesh_only, with_points) = (grid(&[]), grid(&floors));
        assert_eq!(
            at(&mesh_only, 8.05),
            Occupancy::Free,
            "the mesh alone climbs it"
        );
        assert_eq!(at(&with_points, 2.05), Occupancy::Free, "the street");
        // The pavement stands a kerb above the street near it, and further on (more than
        // the reference's reach from the street) is no ground the robot reaches.
        assert_eq!(at(&with_points, 5.85), Occupancy::Occupied, "the pavement");
        assert_eq!(
            at(&with_points, 8.05),
            Occupancy::Unknown,
            "the pavement's far side"
        );
        // The points' floor rising gently with the mesh's is climbed as before.
        let gentle: Vec<Vector3<f64>> = floors
            .iter()
            .map(|f| Vector3::new(f.x, f.y, (f.x - 5.0).clamp(0.0, 0.6) * 0.25))
            .collect();
        assert_eq!(at(&grid(&gentle), 8.05), Occupancy::Free, "a gentle rise");
    }

    #[test]
    fn a_kerb_whose_face_the_points_saw_slanting_is_not_climbed_in_two_hops() {
        // A street at 0, a pavement at 0.15 m from x = 5.4, the mesh rounding the kerb from
        // x = 4.8 into a slope of 14 degrees, climbable for the wheeled robot (15). The points
        // saw the face slanting (as at a kerb's end, seen along it): halfway up in the two
        // cells before the pavement, so no hop between neighbours rises a step.
        let mut soup = floor(0.0, 0.0, 4.8, 10.0, 0.0);
        soup.push([[4.8, 0.0, 0.0], [5.4, 0.0, 0.15], [5.4, 10.0, 0.15]]);
        soup.push([[4.8, 0.0, 0.0], [5.4, 10.0, 0.15], [4.8, 10.0, 0.0]]);
        soup.extend(floor(5.4, 0.0, 10.0, 10.0, 0.15));
        let floors: Vec<Vector3<f64>> = (0..100)
            .flat_map(|ix| (0..100).map(move |iy| (ix, iy)))
            .map(|(ix, iy)| {
                let (x, y) = (ix as f64 * 0.1 + 0.05, iy as f64 * 0.1 + 0.05);
                let z = match x {
                    x if x < 5.0 => 0.01,
                    x if x < 5.2 => 0.08,
                    _ => 0.16,
                };
                Vector3::new(x, y, z)
            })
            .collect();
        let floors = twice(&floors);
        let each = hand(&floors);
        let path = [Vector3::new(2.5, 5.0, 1.7)];
        let (robot, z) = (Robot::WHEELED, Vector3::z());
        let g = Grid::build_with_floors(&mut Soup(soup), &each, robot, 0.1, z, &path, &[]);
        let g = g.unwrap();
        let at = |x: f64| occupancy_at(&g, x, 5.05);
        assert_eq!(at(2.05), Occupancy::Free, "the street");
        assert_eq!(at(5.85), Occupancy::Occupied, "the pavement");
        assert!(!g.cell(58, 50).unwrap().ground, "no ground on the pavement");
    }

    #[test]
    fn a_cell_keeps_to_32_bytes() {
        assert_eq!(std::mem::size_of::<Cell>(), 32);
    }

    #[test]
    fn a_tilted_map_is_levelled_by_its_up() {
        // The street tilted by 20 degrees about x: with z as up its far side would stand above
        // a step; with the tilt's up it is level ground.
        let tilt = Rotation3::from_axis_angle(&Vector3::x_axis(), 20f64.to_radians());
        let soup: Vec<[Point; 3]> = floor(0.0, 0.0, 10.0, 10.0, 0.0)
            .into_iter()
            .map(|t| {
                t.map(|c| {
                    let p = tilt * Vector3::new(c[0] as f64, c[1] as f64, c[2] as f64);
                    [p.x as f32, p.y as f32, p.z as f32]
                })
            })
            .collect();
        let up = tilt * Vector3::z();
        let path = [tilt * Vector3::new(5.0, 5.0, 1.7)];
        let g = Grid::build(&mut Soup(soup), Robot::WHEELED, 0.1, up, &path).unwrap();
        let (ix, iy) = g.index_of(5.05, 5.05);
        assert_eq!(g.occupancy(ix, iy), Occupancy::Free);
    }
}
