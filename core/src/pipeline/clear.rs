//! Clearing what moves from the pipeline's map with its last scan ([`crate::clearing`]).

use super::Pipeline;
use crate::capacity::Capacity;
use crate::cell::{Axis, CellKey};
use crate::clearing::{self, ClearingConfig, ClearingStats, RangeImage};
use crate::math::Pose;
use crate::real::Real;

impl<C: Capacity, R: Real> Pipeline<C, R> {
    /// Clears from the map what the last scan's points, fused at `t_world_sensor` (its
    /// outcome's pose), see through ([`crate::clearing`]), filling `image` with them first.
    /// Nothing is cleared in a fixed map ([`set_map_updates`](Self::set_map_updates) off).
    /// `forgot` is told each layer that forgot a vertex.
    pub fn clear_seen_through(
        &mut self,
        t_world_sensor: &Pose,
        image: &mut RangeImage,
        cfg: &ClearingConfig,
        forgot: impl FnMut(CellKey, Axis),
    ) -> ClearingStats {
        if !self.map_updates {
            return ClearingStats::default();
        }
        image.fill(&self.points);
        let show = self.config.mesh.variance_show as f32;
        clearing::clear_seen_through(&mut self.map, image, t_world_sensor, show, cfg, forgot)
    }
}
