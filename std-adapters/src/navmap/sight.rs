//! What the path saw of a navigation grid: lines of sight cast over it from the path, so that
//! ground the surface reconstruction carried behind a wall is never free (docs/design.md §1.18).

use crate::navmap::grid::{disc, tile_of, Grid};
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
    pub(super) fn carve(&mut self, path: &[Vector3<f64>]) {
        let r = (SEED_M / self.resolution).ceil() as i64;
        let mut last: Option<Vector3<f64>> = None;
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
            last = Some(q);
            self.carve_from(q, q.z as f32 - under);
            self.carved = true;
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
                c.visible = true;
                if c.heights & blocking != 0 {
                    break;
                }
            }
        }
    }
}
