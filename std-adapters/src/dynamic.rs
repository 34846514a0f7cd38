//! What moves, taken out of the map as the run goes, a stage of the run in a room of its own
//! ([`crate::stage::RunStage`]; docs/design.md §1.21): after every second fused frame, that frame's kept points fill a
//! [`RangeImage`] and the map's vertices they see through lose their confidence, until what
//! moved away (a car that drove on, a person who walked past, a parked car that left) is
//! hidden and forgotten ([`slamesh_core::clearing`]). The mesh, the map file and the
//! navigation map made from the map at the end hold what stayed.
//!
//! It owns the range image (a fixed 92 KB, taken when the run starts, and counted under a
//! memory cap with the rest of the process) and the run's totals.
//! It guarantees that a run without it writes the same bytes as before it existed, and that
//! with it the map is the same on any thread count (serial, in the map's order).

use crate::stage::{Note, RunStage};
use slamesh_core::cell::{Axis, CellKey};
use slamesh_core::clearing::{ClearingConfig, ClearingStats, RangeImage};
use slamesh_core::{Capacity, Pipeline, Pose};

/// The clearing of a run: its range image, settings and totals.
#[derive(Debug)]
pub struct Clearing {
    image: RangeImage,
    config: ClearingConfig,
    totals: ClearingStats,
    /// The layers the last clearing made forget a vertex.
    changed: Vec<(CellKey, Axis)>,
}

/// A run clears on every this many frames (the frame counter's multiples): half the cost of
/// every frame, for 6 % more ghost area left on the simulated town with movers
/// (docs/journal.md).
pub const CLEAR_EVERY_FRAMES: u32 = 2;

/// What clearing did over a run, for `report.json`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct DynamicSummary {
    /// Sightings through map vertices (each raised a vertex's variance).
    pub seen_through: u32,
    /// Vertices forgotten.
    pub forgotten: u32,
}

/// The bytes a run's clearing holds: its range image.
pub const CLEARING_BYTES: usize = RangeImage::BINS * std::mem::size_of::<f32>();

impl Clearing {
    /// A clearing with `config`, its range image allocated now.
    pub fn new(config: ClearingConfig) -> Self {
        Self {
            image: RangeImage::new(),
            config,
            totals: ClearingStats::default(),
            changed: Vec::new(),
        }
    }

    /// On every [`CLEAR_EVERY_FRAMES`]th frame, clears from `pipeline`'s map what its last
    /// scan, fused at `t_world_sensor`, sees through, keeping which layers forgot a vertex
    /// ([`RunStage::changed`]).
    pub fn after_fusion<C: Capacity>(
        &mut self,
        pipeline: &mut Pipeline<C>,
        t_world_sensor: &Pose,
    ) -> ClearingStats {
        self.changed.clear();
        if !pipeline.frames().is_multiple_of(CLEAR_EVERY_FRAMES) {
            return ClearingStats::default();
        }
        let changed = &mut self.changed;
        let s =
            pipeline.clear_seen_through(t_world_sensor, &mut self.image, &self.config, |k, a| {
                changed.push((k, a))
            });
        self.totals.seen_through = self.totals.seen_through.saturating_add(s.seen_through);
        self.totals.forgotten = self.totals.forgotten.saturating_add(s.forgotten);
        s
    }

    /// What it did over the run so far.
    pub fn totals(&self) -> DynamicSummary {
        DynamicSummary {
            seen_through: self.totals.seen_through,
            forgotten: self.totals.forgotten,
        }
    }
}

/// In a run: after each fused frame ([`Clearing::after_fusion`]), the vertices it forgot in
/// the frame's record (`cleared_vertices`), its totals in the summary (`dynamic`).
impl<C: Capacity> RunStage<C> for Clearing {
    fn name(&self) -> &'static str {
        "dynamic"
    }

    fn bytes(&self) -> usize {
        CLEARING_BYTES
    }

    fn fused(&mut self, pipeline: &mut Pipeline<C>, pose: &Pose) -> Option<Note> {
        let forgotten = self.after_fusion(pipeline, pose).forgotten;
        Some(Note::of("cleared_vertices", forgotten))
    }

    /// The layers whose shown mesh the last clearing changed, wherever they are: a sink that
    /// keeps the map (the live view, the ROS 2 node's mesh) sends them again.
    fn changed(&self) -> &[(CellKey, Axis)] {
        &self.changed
    }

    fn summary(&self) -> Option<serde_json::Value> {
        serde_json::to_value(self.totals()).ok()
    }
}
