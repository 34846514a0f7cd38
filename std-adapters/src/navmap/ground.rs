//! The ground of a navigation grid: the floor the robot can reach from its path, and the height
//! every cell is judged against (docs/design.md §1.18).
//!
//! Ground grows from the floor cells under the path (or, with no path, the largest stretch of
//! floor) to floor cells within [`BRIDGE_CELLS`] (a gap between scan rings is bridged) whose
//! floor differs by no more than a step and a cell's rise at the slope limit; a kerb higher
//! than a step, a car's roof or a table are floor, not ground. Where the run's scans saw the
//! floor ([`crate::navmap::hits`]) their floor must climb so too: the mesh rounds a kerb into
//! a slope, the points see it sharp; the ground cells a kerb was found from (its foot, where
//! the mesh starts rounding it up) are no cell's reference. A cell with no ground of its own
//! is judged against the nearest ground within about [`REFERENCE_M`].

use crate::navmap::grid::{cell_at, disc, tile_of, Cell, CellIndex, Grid, Tile, TILE_CELLS};
use crate::navmap::hits::Floors;
use nalgebra::Vector3;
use slamesh_core::cell::BuildCellHasher;
use std::collections::{HashMap, HashSet};

/// How far (m) a cell with no ground of its own looks for ground to be judged against.
pub const REFERENCE_M: f64 = 2.0;
/// The side (m) of the blocks the ground a cell is judged against is looked up in.
pub const BLOCK_M: f64 = 0.5;
/// How far (cells) the ground grows across a gap in the floor.
pub const BRIDGE_CELLS: i64 = 3;
/// How far (m) from a point of the path its ground is looked for.
pub const SEED_M: f64 = 1.0;
/// A set of cells (hashed as the grid's tiles are).
pub(super) type CellSet = HashSet<CellIndex, BuildCellHasher>;

/// A set of cells as bits by the grid's tiles: 512 bytes a tile touched, where a hashed set
/// took about 36 bytes a cell (the ground of the 1 000-frame town's map: 107 MB).
#[derive(Default)]
pub(super) struct CellBits(HashMap<(i64, i64), Box<[u64; TILE_CELLS / 64]>, BuildCellHasher>);

impl CellBits {
    /// Adds cell `i`; whether it was new.
    pub(super) fn insert(&mut self, (ix, iy): CellIndex) -> bool {
        let (key, k) = tile_of(ix, iy);
        let words = self
            .0
            .entry(key)
            .or_insert_with(|| Box::new([0; TILE_CELLS / 64]));
        let (w, bit) = (k / 64, 1u64 << (k % 64));
        let new = words[w] & bit == 0;
        words[w] |= bit;
        new
    }

    /// Whether cell `i` is in the set.
    pub(super) fn contains(&self, (ix, iy): CellIndex) -> bool {
        let (key, k) = tile_of(ix, iy);
        self.0
            .get(&key)
            .is_some_and(|words| words[k / 64] & (1u64 << (k % 64)) != 0)
    }

    /// The cells in the set, tile by tile.
    pub(super) fn cells(&self) -> impl Iterator<Item = CellIndex> + '_ {
        self.0.iter().flat_map(|(&key, words)| {
            (0..TILE_CELLS)
                .filter(|&k| words[k / 64] & (1u64 << (k % 64)) != 0)
                .map(move |k| cell_at(key, k))
        })
    }
}

/// A hop of the ground's growth: its offset, and the offsets of the cells it passes over.
type Hop = (CellIndex, Vec<CellIndex>);

/// How far apart (cells) two cells' points' floors are compared for a kerb's face (two
/// cells whose points' floors differ by more than the robot climbs there, with the mesh
/// rising between them: the ground enters neither; docs/design.md §1.18).
pub const FACE_CELLS: i64 = 3;

impl Grid {
    /// Keeps in each cell's reference, until the references are set, the lowest floor the
    /// scans' points saw in it (`floors`; only floors two points fell in,
    /// [`ScanFloor::twice`](crate::navmap::hits::ScanFloor::twice):
    /// a kerb's face is judged on them), and counts the cells that have one.
    pub(super) fn take_scans_floor(&mut self, floors: &Floors) {
        floors(&mut |f| {
            if !f.twice {
                return;
            }
            let q = self.level * f.at;
            let (ix, iy) = self.index_of(q.x, q.y);
            let (key, k) = tile_of(ix, iy);
            if let Some(tile) = self.tiles.get_mut(&key) {
                let r = &mut tile[k].reference;
                self.scans_floor += usize::from(!r.is_finite());
                *r = r.min(q.z as f32);
            }
        });
    }

    /// The floor cells the ground grows from: for each point of `path` (map frame), the
    /// highest floor cell below it within [`SEED_M`], and the cells of `ground` with floor
    /// (known to be ground); with neither, the cells of the largest stretch of floor
    /// (`faces`: [`kerb_faces`](Self::kerb_faces), which the stretches stop at).
    pub(super) fn seeds(
        &self,
        path: &[Vector3<f64>],
        ground: &[CellIndex],
        faces: &CellSet,
    ) -> Vec<CellIndex> {
        let r = (SEED_M / self.resolution).ceil() as i64;
        let mut seeds: Vec<CellIndex> = path
            .iter()
            .filter_map(|p| {
                let q = self.level * p;
                let (cx, cy) = self.index_of(q.x, q.y);
                disc(r)
                    .into_iter()
                    .map(|(dx, dy)| (cx + dx, cy + dy))
                    .filter_map(|(ix, iy)| {
                        let f = self.cell(ix, iy)?.floor;
                        (f.is_finite() && (f as f64) < q.z).then_some((f, (ix, iy)))
                    })
                    .max_by(|a, b| a.0.total_cmp(&b.0))
                    .map(|(_, i)| i)
            })
            .collect();
        let has_floor = |i: &&CellIndex| self.cell(i.0, i.1).is_some_and(|c| c.floor.is_finite());
        seeds.extend(ground.iter().filter(has_floor));
        if seeds.is_empty() {
            seeds = self.largest_floor(faces);
        }
        seeds.sort_unstable();
        seeds.dedup();
        seeds
    }

    /// The cells of the largest stretch of floor (cells joined as [`grow_ground`](Self::grow_ground) joins them).
    pub(super) fn largest_floor(&self, faces: &CellSet) -> Vec<CellIndex> {
        let mut seen = CellBits::default();
        let mut best: Vec<CellIndex> = Vec::new();
        for (ix, iy) in self.floor_cells() {
            if seen.contains((ix, iy)) {
                continue;
            }
            let mut part = Vec::new();
            let visit = |i| seen.insert(i);
            self.stretch(vec![(ix, iy)], faces, visit, |_| {}, |i| part.push(i));
            if part.len() > best.len() {
                best = part;
            }
        }
        best
    }

    /// Every cell with floor, in a fixed order.
    pub(super) fn floor_cells(&self) -> Vec<CellIndex> {
        let mut keys: Vec<&(i64, i64)> = self.tiles.keys().collect();
        keys.sort_unstable();
        let mut out = Vec::new();
        for &(tx, ty) in keys {
            for (k, c) in self.tiles[&(tx, ty)].iter().enumerate() {
                if c.floor.is_finite() {
                    out.push(cell_at((tx, ty), k));
                }
            }
        }
        out
    }

    /// The cells a kerb's face stands in, as the scans' points saw it (`Cell::reference` before
    /// the references are set): two cells within [`FACE_CELLS`] of each other whose points'
    /// floors differ by more than the robot steps (or, further apart than that, than its
    /// slope limit climbs over the distance with half a step for the points' noise), where
    /// the mesh rises the same way by more than half a step too (it rounds a kerb into a slope,
    /// but does not rise where a swaying hand-held walk's points scatter over a flat floor),
    /// and the upper cell's two floors agree within a step (a top to stand on, not a wall's
    /// foot, whose points' floor is the wall's lowest return). Both cells are the face: the
    /// points see a kerb's face in a cell or two between the street's floor and the
    /// pavement's, or spread over a few cells where they hit it slanting at its end, and
    /// whichever way the ground comes it does not climb across. Judged pair by pair, not along
    /// the ground's way, so it does not hang on the order the ground grows in.
    pub(super) fn kerb_faces(&self) -> CellSet {
        // No points' floor (a saved map's grid): no face to find.
        if self.scans_floor == 0 {
            return CellSet::default();
        }
        let (step, tan) = (
            self.robot.max_step_m,
            self.robot.max_slope_deg.to_radians().tan(),
        );
        // Each pair once: the offsets of half the disc, with the rise allowed over each.
        let half: Vec<(i64, i64, f32)> = disc(FACE_CELLS)
            .into_iter()
            .filter(|&(dx, dy)| dy > 0 || (dy == 0 && dx > 0))
            .map(|(dx, dy)| {
                let d = ((dx * dx + dy * dy) as f64).sqrt() * self.resolution;
                (dx, dy, step.max(d * tan + step / 2.0) as f32)
            })
            .collect();
        let half_step = (step / 2.0) as f32;
        // The points' floor and the mesh's.
        let floors = |c: &Cell| {
            (c.reference.is_finite() && c.floor.is_finite()).then_some((c.reference, c.floor))
        };
        let mut faces = CellSet::default();
        // Tile by tile, the neighbours looked up in the tile and the eight around it.
        for (&key, tile) in &self.tiles {
            let around: Vec<Option<&Tile>> = (-1..=1)
                .flat_map(|oy| (-1..=1).map(move |ox| (key.0 + ox, key.1 + oy)))
                .map(|k| self.tiles.get(&k))
                .collect();
            for (k, c) in tile.iter().enumerate() {
                let Some(one) = floors(c) else { continue };
                let i = cell_at(key, k);
                for &(dx, dy, allowed) in &half {
                    let n = (i.0 + dx, i.1 + dy);
                    let (nkey, nk) = tile_of(n.0, n.1);
                    let at = (nkey.1 - key.1 + 1) * 3 + (nkey.0 - key.0 + 1);
                    let Some(other) = around[at as usize].and_then(|t| floors(&t[nk])) else {
                        continue;
                    };
                    // Lower and upper cell: (points' floor, mesh floor) each.
                    let (low, top) = if other.0 > one.0 {
                        (one, other)
                    } else {
                        (other, one)
                    };
                    let (rise, mesh_rise) = (top.0 - low.0, top.1 - low.1);
                    let stands = (top.0 - top.1).abs() <= 2.0 * half_step;
                    if rise > allowed && mesh_rise > half_step && stands {
                        faces.insert(i);
                        faces.insert(n);
                    }
                }
            }
        }
        faces
    }

    /// The floor cells joined to `from` through neighbours within [`BRIDGE_CELLS`] (a gap in
    /// the mesh between scan rings is bridged) whose floors differ by no more than a step and
    /// a cell's rise at the slope limit, the mesh's and, where the scans' points saw it, the
    /// points' (`Cell::reference` before the references are set), and that are no kerb's
    /// face (`faces`, [`kerb_faces`](Self::kerb_faces)); `visit` says whether a cell is new
    /// (and marks it), `at_a_kerb` hears of each cell a join was refused from by the points
    /// alone, and `reach` of each cell joined, in the order they are.
    pub(super) fn stretch(
        &self,
        from: Vec<CellIndex>,
        faces: &CellSet,
        mut visit: impl FnMut(CellIndex) -> bool,
        mut at_a_kerb: impl FnMut(CellIndex),
        mut reach: impl FnMut(CellIndex),
    ) {
        // One cell's rise at the slope limit over a step, whatever the gap: a gap is unseen,
        // and a kerb must not be bridged as a slope.
        let rise = (self.robot.max_step_m
            + self.resolution * self.robot.max_slope_deg.to_radians().tan())
            as f32;
        // Each hop with the cells it passes over (a bridge over a kerb's face would skip it).
        let near: Vec<Hop> = disc(BRIDGE_CELLS)
            .into_iter()
            .filter(|&d| d != (0, 0))
            .map(|(dx, dy)| {
                let m = dx.abs().max(dy.abs());
                let over = (1..m)
                    .map(|k| {
                        let at = |d: i64| (d as f64 * k as f64 / m as f64).round() as i64;
                        (at(dx), at(dy))
                    })
                    .collect();
                ((dx, dy), over)
            })
            .collect();
        let floor = |i: CellIndex| {
            self.cell(i.0, i.1)
                .map(|c| c.floor)
                .filter(|f| f.is_finite())
        };
        // Each cell reached carries the last floor the scans' points saw on the way to it
        // (its own where they saw one): a cell whose points' floor differs from it by more
        // than `rise` (a step and one cell at the slope limit, whatever the hop) is not
        // reached that way, and the cell it was tried from is a kerb's foot (`at_a_kerb`).
        // Neither a bridge nor the cells the points did not see earn more slope, so the
        // mesh's slope across a kerb's shadow (interpolated where no point fell) does not
        // carry the ground over it.
        // Before the references are set, a cell's reference is the floor its points saw.
        let own = |i: CellIndex| {
            let f = self.cell(i.0, i.1)?.reference;
            f.is_finite().then_some(f)
        };
        let mut queue: Vec<(CellIndex, Option<f32>)> = from
            .into_iter()
            .filter(|&i| visit(i))
            .map(|i| (i, own(i)))
            .collect();
        while let Some((i, carried)) = queue.pop() {
            let Some(f) = floor(i) else { continue };
            reach(i);
            for ((dx, dy), over) in &near {
                let n = (i.0 + dx, i.1 + dy);
                // One look-up for the neighbour's floors, the mesh's and the points'.
                let Some(c) = self.cell(n.0, n.1) else {
                    continue;
                };
                if !(c.floor.is_finite() && (c.floor - f).abs() <= rise) {
                    continue;
                }
                let seen = c.reference.is_finite().then_some(c.reference);
                let face = |(ox, oy): &(i64, i64)| faces.contains(&(i.0 + ox, i.1 + oy));
                let climbs = !faces.contains(&n)
                    && !over.iter().any(face)
                    && match (carried, seen) {
                        (Some(a), Some(b)) => (a - b).abs() <= rise,
                        _ => true,
                    };
                if !climbs {
                    at_a_kerb(i);
                } else if visit(n) {
                    queue.push((n, seen.or(carried)));
                }
            }
        }
    }

    /// Marks the floor reachable from `seeds` as ground, and gives the ground cells a kerb
    /// was found from (its foot: [`stretch`](Self::stretch)'s `at_a_kerb`); `faces` as
    /// [`kerb_faces`](Self::kerb_faces) gives them.
    pub(super) fn grow_ground(&mut self, seeds: Vec<CellIndex>, faces: &CellSet) -> CellSet {
        let mut seen = CellBits::default();
        let mut feet = CellSet::default();
        let at_a_kerb = |i| {
            feet.insert(i);
        };
        self.stretch(seeds, faces, |i| seen.insert(i), at_a_kerb, |_| {});
        // What it reached is what it saw with a floor (only a seed may have none).
        for (ix, iy) in seen.cells() {
            if self.cell(ix, iy).is_some_and(|c| c.floor.is_finite()) {
                self.cell_mut(ix, iy).ground = true;
            }
        }
        feet
    }

    /// Each cell's reference: its ground, or the ground nearest it within about
    /// [`REFERENCE_M`]: the lowest ground cell of the nearest block of [`BLOCK_M`] that holds
    /// any (nearest, not lowest over the whole reach: on a slope of a few degrees the lowest
    /// ground two metres away lies more than a step below a cell's own floor). The ground
    /// cells in `kerb_feet` are no other cell's reference. Returns the blocks it looked in.
    pub(super) fn set_references(&mut self, kerb_feet: &CellSet) -> GroundBlocks {
        let blocks = GroundBlocks::of(self, kerb_feet);
        let near = blocks.offsets(self.resolution, REFERENCE_M);
        for (&(tx, ty), tile) in self.tiles.iter_mut() {
            for (k, c) in tile.iter_mut().enumerate() {
                c.reference = if c.ground {
                    c.floor
                } else {
                    let cell = cell_at((tx, ty), k);
                    blocks.nearest(cell, &near).unwrap_or(f32::INFINITY)
                };
            }
        }
        blocks
    }
}

/// The lowest ground floor in each block of [`BLOCK_M`] square: a cell with no ground of its
/// own is judged against the nearest block's.
pub(super) struct GroundBlocks {
    /// Cells along a block's side.
    block: i64,
    lowest: HashMap<(i64, i64), f32, BuildCellHasher>,
}

impl GroundBlocks {
    /// The blocks of `grid`'s ground cells, but for `kerb_feet` (where the mesh rounds a
    /// kerb up: no cell's reference).
    pub(super) fn of(grid: &Grid, kerb_feet: &CellSet) -> GroundBlocks {
        let block = (BLOCK_M / grid.resolution).round().max(1.0) as i64;
        let mut lowest: HashMap<(i64, i64), f32, BuildCellHasher> = HashMap::default();
        for (&(tx, ty), tile) in &grid.tiles {
            for (k, c) in tile.iter().enumerate().filter(|(_, c)| c.ground) {
                let (ix, iy) = cell_at((tx, ty), k);
                if kerb_feet.contains(&(ix, iy)) {
                    continue;
                }
                let b = lowest
                    .entry((ix.div_euclid(block), iy.div_euclid(block)))
                    .or_insert(f32::INFINITY);
                *b = b.min(c.floor);
            }
        }
        GroundBlocks { block, lowest }
    }

    /// Block offsets within `reach_m` (cells of `resolution`), nearest first.
    pub(super) fn offsets(&self, resolution: f64, reach_m: f64) -> Vec<(i64, i64)> {
        let reach = (reach_m / (self.block as f64 * resolution)).ceil() as i64;
        let mut near: Vec<(i64, i64)> = (-reach..=reach)
            .flat_map(|dy| (-reach..=reach).map(move |dx| (dx, dy)))
            .filter(|(dx, dy)| dx * dx + dy * dy <= reach * reach)
            .collect();
        near.sort_by_key(|&(dx, dy)| (dx * dx + dy * dy, dy, dx));
        near
    }

    /// The ground of the first block with ground at `offsets` from cell `(ix, iy)`'s.
    pub(super) fn nearest(&self, (ix, iy): CellIndex, offsets: &[(i64, i64)]) -> Option<f32> {
        let (bx, by) = self.block_of((ix, iy));
        offsets
            .iter()
            .find_map(|(dx, dy)| self.lowest.get(&(bx + dx, by + dy)))
            .copied()
    }

    /// The block holding cell `(ix, iy)`.
    pub(super) fn block_of(&self, (ix, iy): CellIndex) -> (i64, i64) {
        (ix.div_euclid(self.block), iy.div_euclid(self.block))
    }
}
