//! What the scans hit: for each cell of a navigation grid, the heights the run's registered
//! points fell at, so that the grid sees a kerb's sharp face where the mesh, fusing a lattice
//! of 9 cm or more, rounded it into a slope a robot could climb (docs/design.md §1.18, "The
//! scans' floor").
//!
//! A column per cell (the grid's cells, in the level frame of the `up` the run started with)
//! keeps the 32 height bins of [`BIN_M`] over its lowest point that a point fell in, and the
//! lowest bin two points fell in: the floor as the points saw it ([`Hits::each_floor`]; a lone
//! stray return below the floor is not taken). A column no two points fell in alike hands
//! over its lowest point, marked as alone ([`ScanFloor::twice`]): a car's roof seen by one
//! ring a pass, which a neighbour's floor may bear out ([`crate::navmap::raised`]). Bins are
//! aligned to the level frame's zero (heights within 655 m of it), so a column's lowest bin
//! moving down shifts its mask.
//!
//! The hits are kept in **chunks** of the path, a new one every [`CHUNK_M`] travelled, each
//! with the pose of the frame it began at as the run kept it. When loop closure later corrects
//! the path, a chunk is moved as its first frame moved, so the hits follow the corrected map
//! as the rebuilt mesh does.
//!
//! A scan is counted in two steps: where each point falls (its cell and bin: the most of the
//! work, 120 000 points a 64-beam scan) point by point through the run's
//! [`Executor`], so on its pool, then the columns counted in the points' order, which
//! a column's bins depend on.
//!
//! Owns: the columns and chunks, and the room for one scan's binned points. Guarantees:
//! memory grows with the area seen within [`RANGE_M`] of the path (8 bytes a cell, in tiles
//! of 16 x 16, per chunk) and with the largest scan counted (24 bytes a point); the same
//! points in the same order give the same hits, on any executor.

use crate::navmap::grid::{cell_in_tiles_of, floor_index, level_of, tile_in_tiles_of};
use nalgebra::{Point3, Rotation3, Vector3};
use slamesh_core::bounded::BoundedVec;
use slamesh_core::cell::BuildCellHasher;
use slamesh_core::executor::Executor;
use slamesh_core::{Point, Pose};
use std::collections::HashMap;

/// A cell's floor as the scans' points saw it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanFloor {
    /// The cell's centre at the floor's height (map frame).
    pub at: Vector3<f64>,
    /// Two points fell in its bin; else it is the cell's lowest point, alone in its bin.
    pub twice: bool,
}

/// What hands the scans' floors to the grid: it calls its argument with each, as
/// [`Hits::each_floor`] does.
pub type Floors<'a> = dyn Fn(&mut dyn FnMut(ScanFloor)) + 'a;

/// `floors` handed over as [`Floors`] hands them (a window's copy of them, a test's).
pub fn hand(floors: &[ScanFloor]) -> impl Fn(&mut dyn FnMut(ScanFloor)) + '_ {
    move |each| floors.iter().for_each(|f| each(*f))
}

/// The height of a bin (m).
pub const BIN_M: f64 = 0.02;

/// How far from the sensor (m) a point counts: beyond it the rings fall further apart than a
/// kerb's face is tall, and the area kept grows as its square.
pub const RANGE_M: f64 = 20.0;

/// How far (m) the path travels before a new chunk begins.
pub const CHUNK_M: f64 = 30.0;

/// One cell's heights: bit `b` of `once` for bin `base + b` (the 32 bins over the lowest
/// point), and the lowest bin two points fell in.
#[derive(Debug, Clone, Copy)]
struct Column {
    once: u32,
    /// The lowest bin's index (level-frame z over [`BIN_M`], floored); `i16::MAX` for none.
    base: i16,
    /// The lowest bin two points fell in; `i16::MAX` for none.
    floor: i16,
}

impl Default for Column {
    fn default() -> Self {
        Column {
            once: 0,
            base: i16::MAX,
            floor: i16::MAX,
        }
    }
}

impl Column {
    /// Counts a point in bin `b`. A point more than 32 bins over the lowest one is passed
    /// over: it is no floor (but for a lone stray return below the floor, whose column then
    /// says nothing).
    fn add(&mut self, b: i16) {
        if b < self.base {
            let shift = i32::from(self.base) - i32::from(b);
            self.once = if shift >= 32 { 0 } else { self.once << shift };
            self.base = b;
        }
        let off = i32::from(b) - i32::from(self.base);
        if off < 32 {
            let bit = 1u32 << off;
            if self.once & bit != 0 {
                self.floor = self.floor.min(b);
            }
            self.once |= bit;
        }
    }

    /// The lowest bin two points fell in, if any.
    fn floor(&self) -> Option<i16> {
        (self.floor != i16::MAX).then_some(self.floor)
    }
}

/// Cells along a tile's side: smaller than the grid's, since a chunk's columns lie along a
/// street or a corridor, not over a block.
const TILE: i64 = 16;
const TILE_CELLS: usize = (TILE * TILE) as usize;

type Tile = Box<[Column; TILE_CELLS]>;

/// The tile holding cell `(ix, iy)` and the cell's place in it.
fn tile_of(ix: i64, iy: i64) -> ((i64, i64), usize) {
    tile_in_tiles_of(TILE, ix, iy)
}

/// The cell at place `k` of tile `(tx, ty)`: [`tile_of`] turned back.
fn cell_at(tile: (i64, i64), k: usize) -> (i64, i64) {
    cell_in_tiles_of(TILE, tile, k)
}

/// Where one point falls: its tile, its place in the tile and its bin.
#[derive(Debug, Clone, Copy, Default)]
struct Binned {
    tile: (i64, i64),
    k: u16,
    bin: i16,
}

/// `v` rounded down ([`floor_index`]), when it lies within `limit` of zero; a NaN does not.
#[inline]
fn floor_within(v: f64, limit: f64) -> Option<i64> {
    (v.abs() < limit).then(|| floor_index(v))
}

/// The hits of one stretch of the path.
struct Chunk {
    /// The frame it began at, and that frame's pose as the run kept it then.
    frame: usize,
    pose: Pose,
    tiles: HashMap<(i64, i64), Tile, BuildCellHasher>,
}

/// The heights a run's points fell at, cell by cell, in chunks of the path.
pub struct Hits {
    resolution: f64,
    /// Map frame to the level frame the columns are in.
    level: Rotation3<f64>,
    chunks: Vec<Chunk>,
    /// Room for one scan's binned points, kept for the next scan.
    binned: BoundedVec<Binned>,
}

impl Hits {
    /// No hits yet, for cells of `resolution` metres in the level frame of `up` (map frame).
    pub fn new(resolution: f64, up: &Vector3<f64>) -> Hits {
        Hits {
            resolution,
            level: level_of(up),
            chunks: Vec::new(),
            binned: BoundedVec::with_capacity(0),
        }
    }

    /// Counts frame `frame`'s `points` (sensor frame) at `pose` (sensor to map): those within
    /// [`RANGE_M`]; a point that is not finite is passed over. `kept` is the frame's pose as
    /// the run keeps it (what [`each_floor`](Self::each_floor)'s path is compared with).
    /// Where each point falls is worked out through `exec`.
    pub fn add(
        &mut self,
        frame: usize,
        kept: &Pose,
        pose: &Pose,
        points: &[Point],
        exec: &impl Executor,
    ) {
        let moved = |c: &Chunk| (kept.translation.vector - c.pose.translation.vector).norm();
        if self.chunks.last().is_none_or(|c| moved(c) >= CHUNK_M) {
            self.chunks.push(Chunk {
                frame,
                pose: *kept,
                tiles: HashMap::default(),
            });
        }
        let to_level = self.level * pose.rotation.to_rotation_matrix();
        let origin = self.level * pose.translation.vector;
        let (per_cell, per_bin) = (1.0 / self.resolution, 1.0 / BIN_M);
        let bin = |p: &Point, _: &mut ()| {
            let q = Vector3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            let w = to_level * q;
            // A floor lies below the sensor: what the points hit above it is passed over
            // (half a street's points, its walls), as is a point that is not finite or lies
            // beyond the range.
            if !(w.z < 0.0 && q.norm_squared() < RANGE_M * RANGE_M) {
                return None;
            }
            let w = w + origin;
            let ix = floor_within(w.x * per_cell, 1e15)?;
            let iy = floor_within(w.y * per_cell, 1e15)?;
            let b = floor_within(w.z * per_bin, f64::from(i16::MAX))?;
            let (tile, k) = tile_of(ix, iy);
            Some(Binned {
                tile,
                // Within a tile of 256 cells and within i16: the bounds above.
                k: k as u16,
                bin: b as i16,
            })
        };
        if self.binned.capacity() < points.len() {
            self.binned = BoundedVec::with_capacity(points.len());
        }
        self.binned.clear();
        // Room for every point: the executor cannot refuse.
        exec.filter_map_into(points, &mut self.binned, bin, |()| {});
        let Some(chunk) = self.chunks.last_mut() else {
            return;
        };
        let mut current: Option<((i64, i64), &mut Tile)> = None;
        for h in self.binned.iter() {
            if current.as_ref().map(|c| c.0) != Some(h.tile) {
                let tile = (chunk.tiles.entry(h.tile))
                    .or_insert_with(|| Box::new([Column::default(); TILE_CELLS]));
                current = Some((h.tile, tile));
            }
            if let Some((_, tile)) = current.as_mut() {
                tile[usize::from(h.k)].add(h.bin);
            }
        }
    }

    /// Calls `each` with every column's floor ([`Hits`]; where no two points fell in a bin,
    /// its lowest point, not [`twice`](ScanFloor::twice)) as a point in the map frame: the
    /// cell's centre at the bin's middle, moved as its chunk's first frame moved from the pose
    /// it had then to `now(frame)` (the path as it ends; `None`: not moved). A cell seen in
    /// several chunks comes once from each.
    pub fn each_floor(&self, now: &dyn Fn(usize) -> Option<Pose>, each: &mut dyn FnMut(ScanFloor)) {
        let back = self.level.inverse();
        for chunk in &self.chunks {
            let moved = now(chunk.frame).map(|p| p * chunk.pose.inverse());
            let mut keys: Vec<&(i64, i64)> = chunk.tiles.keys().collect();
            keys.sort_unstable();
            for key in keys {
                for (k, c) in chunk.tiles[key].iter().enumerate() {
                    let (b, twice) = match c.floor() {
                        Some(b) => (b, true),
                        None if c.base != i16::MAX => (c.base, false),
                        None => continue,
                    };
                    let (ix, iy) = cell_at(*key, k);
                    let level = Vector3::new(
                        (ix as f64 + 0.5) * self.resolution,
                        (iy as f64 + 0.5) * self.resolution,
                        (f64::from(b) + 0.5) * BIN_M,
                    );
                    let map = Point3::from(back * level);
                    let at = moved.map_or(map, |m| m * map).coords;
                    each(ScanFloor { at, twice });
                }
            }
        }
    }

    /// The frames the chunks began at, oldest first.
    pub fn chunk_frames(&self) -> impl Iterator<Item = usize> + '_ {
        self.chunks.iter().map(|c| c.frame)
    }

    /// Forgets all but the last `chunks` chunks (the live grid's bound: its window lies
    /// within the last stretches of the path; `0` forgets every hit).
    pub fn keep_last(&mut self, chunks: usize) {
        let old = self.chunks.len().saturating_sub(chunks);
        self.chunks.drain(..old);
    }

    /// The bytes the columns take.
    pub fn bytes(&self) -> usize {
        let tiles: usize = self.chunks.iter().map(|c| c.tiles.len()).sum();
        tiles * TILE_CELLS * std::mem::size_of::<Column>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slamesh_core::executor::Serial;

    #[test]
    fn rounding_down_is_floor_within_its_bounds() {
        for v in [
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.999,
            -2.999,
            1e14 + 0.5,
            -1e14 - 0.5,
        ] {
            assert_eq!(floor_within(v, 1e15), Some(v.floor() as i64), "{v}");
        }
        for v in [1e15, -1e15, f64::INFINITY, f64::NAN] {
            assert_eq!(floor_within(v, 1e15), None, "{v}");
        }
    }

    /// Counted on a pool, where each point falls is worked out in parallel: the same floors,
    /// in the same order, as counted serially (a column depends on its points' order).
    #[test]
    fn a_pool_counts_the_floor_the_serial_loop_counts() {
        let mut rng = slamesh_core::random::SplitMix64(5);
        let mut r = |a: f64, b: f64| (a + (b - a) * rng.next_f64()) as f32;
        // Points over a 30 m square, most below the sensor, some not finite.
        let points: Vec<Point> = (0..50_000)
            .map(|i| match i % 997 {
                0 => [f32::NAN, 0.0, -1.0],
                _ => [r(-15.0, 15.0), r(-15.0, 15.0), r(-2.0, 0.3)],
            })
            .collect();
        let pose = Pose::from_parts(
            nalgebra::Translation3::new(3.2, -1.7, 0.4),
            nalgebra::UnitQuaternion::from_euler_angles(0.03, -0.02, 0.7),
        );
        let floors = |hits: &Hits| {
            let mut all = Vec::new();
            hits.each_floor(&|_| None, &mut |f| all.push((f.at, f.twice)));
            all
        };
        let mut serial = Hits::new(0.1, &Vector3::z());
        serial.add(0, &pose, &pose, &points, &Serial);
        let want = floors(&serial);
        assert!(want.len() > 10_000, "{}", want.len());
        for threads in [2, 3, 16] {
            let pool = crate::parallel::Rayon::new(threads).unwrap();
            let mut spread = Hits::new(0.1, &Vector3::z());
            spread.add(0, &pose, &pose, &points, &pool);
            assert_eq!(floors(&spread), want, "{threads} threads");
        }
    }

    #[test]
    fn a_column_keeps_its_bins_when_a_lower_point_comes() {
        let mut c = Column::default();
        c.add(10);
        c.add(10);
        c.add(12);
        c.add(8);
        assert_eq!(c.base, 8);
        assert_eq!(c.once, 0b10101);
        assert_eq!(c.floor(), Some(10));
        c.add(8);
        assert_eq!(c.floor(), Some(8));
        // Far lower: what stood more than 32 bins over it is gone, the floor found kept.
        c.add(-100);
        assert_eq!((c.base, c.once, c.floor()), (-100, 1, Some(8)));
        // A point 32 bins or more over the lowest is passed over.
        c.add(-60);
        c.add(-60);
        assert_eq!((c.once, c.floor()), (1, Some(8)));
    }

    #[test]
    fn a_floor_is_two_points_low_and_a_chunk_moves_with_its_first_frame() {
        let mut hits = Hits::new(0.1, &Vector3::z());
        let pose = Pose::identity();
        // Two points in one bin at (1.05, 2.05, -0.51); one alone lower; one alone elsewhere
        // (handed over as alone); two above the sensor.
        let points = [
            [1.05, 2.05, -0.51],
            [1.06, 2.04, -0.51],
            [1.04, 2.02, -0.7],
            [5.0, 0.0, -1.0],
            [3.0, 3.0, 0.5],
            [3.0, 3.0, 0.5],
        ];
        hits.add(0, &pose, &pose, &points, &Serial);
        let mut got = Vec::new();
        let mut alone = Vec::new();
        hits.each_floor(&|_| None, &mut |f| {
            if f.twice {
                got.push(f.at)
            } else {
                alone.push(f.at)
            }
        });
        assert_eq!(got.len(), 1);
        assert_eq!(alone.len(), 1);
        assert!((alone[0] - Vector3::new(5.05, 0.05, -0.99)).norm() < 1e-9);
        assert!(
            (got[0] - Vector3::new(1.05, 2.05, -0.51)).norm() < 1e-9,
            "{:?}",
            got[0]
        );
        // The run's path corrected: its first frame 1 m further along x.
        let shifted = Pose::from_parts(
            nalgebra::Translation3::new(1.0, 0.0, 0.0),
            nalgebra::UnitQuaternion::identity(),
        );
        got.clear();
        hits.each_floor(&|_| Some(shifted), &mut |f| {
            got.extend(f.twice.then_some(f.at))
        });
        assert!(
            (got[0] - Vector3::new(2.05, 2.05, -0.51)).norm() < 1e-9,
            "{:?}",
            got[0]
        );
        // Points beyond the range or not finite count for nothing.
        let far = [[40.0, 0.0, -1.0], [40.0, 0.0, -1.0], [f32::NAN, 0.0, -1.0]];
        hits.add(1, &pose, &pose, &far, &Serial);
        let mut n = 0;
        hits.each_floor(&|_| None, &mut |f| n += usize::from(f.twice));
        assert_eq!(n, 1);
        // A chunk 30 m on; the first forgotten, then every one.
        let on = Pose::from_parts(
            nalgebra::Translation3::new(CHUNK_M, 0.0, 0.0),
            nalgebra::UnitQuaternion::identity(),
        );
        hits.add(2, &on, &on, &points, &Serial);
        let count = |hits: &Hits| {
            let mut n = 0;
            hits.each_floor(&|_| None, &mut |f| n += usize::from(f.twice));
            n
        };
        assert_eq!((hits.chunks.len(), count(&hits)), (2, 2));
        assert_eq!(hits.chunk_frames().collect::<Vec<_>>(), [0, 2]);
        hits.keep_last(1);
        assert_eq!(
            (hits.chunk_frames().collect::<Vec<_>>(), count(&hits)),
            (vec![2], 1)
        );
        hits.keep_last(0);
        assert_eq!((count(&hits), hits.bytes()), (0, 0));
    }
}
