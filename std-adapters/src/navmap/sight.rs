//! What the path saw of a navigation grid: lines of sight cast over it from the path, so that
//! ground the surface reconstruction carried behind a wall is never free (docs/design.md §1.18).

use crate::navmap::grid::{cell_at, disc, tile_of, Cell, Grid};
use crate::navmap::ground::SEED_M;
use nalgebra::Vector3;

/// Metres of path between two points the lines of sight are cast from.
pub const CARVE_EVERY_M: f64 = 2.0;
/// How far (m) a line of sight reaches.
pub const CARVE_RANGE_M: f64 = 40.0;

impl Grid {
    /// Casts lines of sight over the grid from points of `path` (map frame) every
    /// [`CARVE_EVERY_M`], each out to [`CARVE_RANGE_M`] in directions a cell apart at that
    /// range, and marks the cells they cross as seen. A line stops at a cell with a surface
    /// at the sensor's height above the ground, or up to 0.2 m higher (a wall, not a car nor
    /// a ceiling): ground the reconstruction carried behind a wall is not seen, so never free.
    /// Lower obstacles cast a shadow: ground below the line from the sensor over an
    /// obstacle's top is not seen from there (the ground the reconstruction carried under a
    /// car's roof, or right behind a fence).
    pub(super) fn carve(&mut self, path: &[Vector3<f64>]) {
        let r = (SEED_M / self.resolution).ceil() as i64;
        let mut last: Option<Vector3<f64>> = None;
        let mut heights = Vec::new();
        for p in path {
            let q = self.level * p;
            if last.is_some_and(|l| (l - q).xy().norm() < CARVE_EVERY_M) {
                continue;
            }
            let (cx, cy) = self.index_of(q.x, q.y);
            let under = disc(r)
                .into_iter()
                .filter_map(|(dx, dy)| self.cell(cx + dx, cy + dy).filter(|c| c.ground))
                .map(|c| c.floor)
                .filter(|&f| (f as f64) < q.z)
                .fold(f32::NEG_INFINITY, f32::max);
            if !under.is_finite() {
                continue;
            }
            if last.is_none() {
                self.set_shadows();
            }
            last = Some(q);
            self.carve_from(q, q.z as f32 - under);
            heights.push(q.z as f32 - under);
        }
        if !heights.is_empty() {
            let mid = heights.len() / 2;
            let sensor = *heights.select_nth_unstable_by(mid, f32::total_cmp).1;
            self.carved = true;
            let tenths = |m: f64| ((m * 10.0).ceil() as u32).min(64);
            let (lo, hi) = (tenths(self.robot.height_m), tenths(sensor as f64));
            self.from_above = (lo..hi).fold(0u64, |m, b| m | 1 << b);
        }
    }

    /// [`carve`](Self::carve)'s lines from level-frame `q`, the sensor `height` above ground.
    pub(super) fn carve_from(&mut self, q: Vector3<f64>, height: f32) {
        // The tenths of a metre from the sensor's height to 0.2 m above it.
        let from = (height * 10.0).clamp(0.0, 61.0) as u32;
        let blocking: u64 = 0b111 << from;
        let rays = (std::f64::consts::TAU * CARVE_RANGE_M / self.resolution).ceil() as usize;
        let steps = (CARVE_RANGE_M / self.resolution) as usize;
        for k in 0..rays {
            let a = std::f64::consts::TAU * k as f64 / rays as f64;
            let (dx, dy) = (a.cos() * self.resolution, a.sin() * self.resolution);
            let mut at = None;
            // The steepest rise (height over distance, from the sensor) to an obstacle's top
            // so far along the line: ground seen under it is in its shadow.
            let mut horizon = f32::NEG_INFINITY;
            for s in 0..=steps {
                let cell = self.index_of(q.x + dx * s as f64, q.y + dy * s as f64);
                if at == Some(cell) {
                    continue;
                }
                at = Some(cell);
                let (key, k) = tile_of(cell.0, cell.1);
                let Some(tile) = self.tiles.get_mut(&key) else {
                    continue;
                };
                let c = &mut tile[k];
                let d = (s.max(1) as f64 * self.resolution) as f32;
                let rise = |z: f32| (z - q.z as f32) / d;
                c.visible |= !c.ground || rise(c.floor) > horizon;
                if c.heights & blocking != 0 {
                    break;
                }
                if c.shadow != i16::MIN {
                    horizon = horizon.max(rise(f32::from(c.shadow) / 10.0));
                }
            }
        }
    }
}

impl Grid {
    /// Sets every cell's [`shadow`](Cell::shadow): the highest obstacle top in it or a
    /// neighbour, so that a line of sight through a seam of the mesh (a cell or two between
    /// its voxel cells, in a car's side) is still shadowed by the car.
    fn set_shadows(&mut self) {
        let step = self.robot.max_step_m as f32;
        let mut tops: Vec<((i64, i64), i16)> = Vec::new();
        for (&(tx, ty), tile) in &self.tiles {
            for (k, c) in tile.iter().enumerate() {
                if let Some(top) = obstacle_top(c, step) {
                    let (ix, iy) = cell_at((tx, ty), k);
                    // Decimetres, rounded up: `as` saturates an infinite top (a wall).
                    let z = ((c.reference + top) * 10.0)
                        .ceil()
                        .max(f32::from(i16::MIN + 1));
                    tops.push(((ix, iy), z as i16));
                }
            }
        }
        for ((ix, iy), z) in tops {
            for (dx, dy) in disc(1) {
                let (key, k) = tile_of(ix + dx, iy + dy);
                if let Some(tile) = self.tiles.get_mut(&key) {
                    tile[k].shadow = tile[k].shadow.max(z);
                }
            }
        }
    }
}

/// The top (m above the cell's reference) of the obstacle standing in cell `c`: the end of the
/// run of sampled heights from its lowest above a `step`; `None` where none stands, infinite
/// where the run reaches 6.4 m.
fn obstacle_top(c: &Cell, step: f32) -> Option<f32> {
    if !c.obstacle || !c.reference.is_finite() {
        return None;
    }
    let from = ((step * 10.0).ceil() as u32).min(63);
    let above = c.heights >> from;
    if above == 0 {
        return None;
    }
    let start = above.trailing_zeros();
    let run = (!(above >> start)).trailing_zeros();
    let end = from + start + run;
    Some(if end >= 64 {
        f32::INFINITY
    } else {
        end as f32 / 10.0
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_obstacle_s_top_is_the_end_of_its_run_of_heights() {
        let cell = |heights: u64| Cell {
            heights,
            obstacle: true,
            reference: 0.0,
            ..Cell::default()
        };
        // Samples from 0.1 to 1.5 m (a car's side), and a balcony at 3 m above it.
        let car = (0..15).fold(0u64, |h, b| h | 1 << b) | 1 << 30;
        assert_eq!(obstacle_top(&cell(car), 0.08), Some(1.5));
        assert_eq!(obstacle_top(&cell(u64::MAX), 0.08), Some(f32::INFINITY));
        assert_eq!(obstacle_top(&cell(1 << 0), 0.08), None, "ground alone");
        let not_obstacle = Cell {
            obstacle: false,
            ..cell(car)
        };
        assert_eq!(obstacle_top(&not_obstacle, 0.08), None);
    }
}
