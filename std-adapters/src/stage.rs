//! What works inside a run beside registration, plugged in: a [`RunStage`] (not the core's
//! `Stage`, which names the pipeline's own steps for timing) is told the run's
//! start, sees each frame's scan fused and each pose kept, may change the map, counts into
//! the frame's record and the run's summary, writes what goes beside a map saved during or at
//! the end of the run, and has the whole map, read-only, at the end.
//!
//! A run holds its stages as a list ([`Stages`]) and names none of them: each lives in its
//! own room (clearing what moves in [`crate::dynamic`], the navigation map in
//! [`crate::navmap::stage`]) and `run/wiring.rs` is the one list that wires them from the
//! options. A run's stages are called in the list's order, on the run's thread, between the
//! core's steps: what they do is the same on any thread count.

use crate::formats::mesh_records::VertexProperties;
use crate::io::error::FileError;
use crate::outputs::mesh_spool::MeshSpool;
use crate::parallel::Workers;
use nalgebra::Vector3;
use slamesh_core::{Capacity, Pipeline, Point, Pose};
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

/// A capability that works inside a run. Every hook has a default that does nothing.
pub trait RunStage<C: Capacity>: Send {
    /// Its name: the key of its part of the run's summary.
    fn name(&self) -> &'static str;

    /// The bytes it takes at most, counted with the rest of the process under a memory cap.
    fn bytes(&self) -> usize {
        0
    }

    /// The run starts (anew or resumed), before its first frame.
    fn start(&mut self, _start: &Start<'_>) {}

    /// Whether it needs each used frame's own points ([`Used::points`]; asked after
    /// [`start`](Self::start)).
    fn needs_points(&self) -> bool {
        false
    }

    /// The frame's scan was fused into `pipeline`'s map at `pose`: it may change the map.
    /// Returns a count for the frame's record, under its name (e.g. `cleared_vertices`).
    fn fused(&mut self, _pipeline: &mut Pipeline<C>, _pose: &Pose) -> Option<(&'static str, u64)> {
        None
    }

    /// A used frame's pose was kept.
    fn used(&mut self, _frame: &Used<'_>) {}

    /// A map file was saved at `map`, during the run or at its end, with `path` (the stamped
    /// poses it holds, the map it started from first); `poses` are this run's (frame, pose).
    /// Writes what goes with it beside it (or removes what went with the map saved there
    /// before); returns what to add to the message that says the map was saved.
    fn beside_map(
        &self,
        _map: &Path,
        _path: &[(f64, Pose)],
        _poses: &[(usize, Pose)],
    ) -> Result<Option<String>, FileError> {
        Ok(None)
    }

    /// The run's end, once the map is whole and before the mesh files are written: writes its
    /// files from the whole map, read through `mesh` (what the window evicted, then the cells
    /// still in memory).
    fn finish(&mut self, _mesh: &mut MeshSpool, _end: &End<'_>) -> Result<(), FileError> {
        Ok(())
    }

    /// Properties it gives each vertex of the mesh files (after [`finish`](Self::finish)).
    fn vertex_properties(&self) -> Option<Box<dyn VertexProperties + '_>> {
        None
    }

    /// Its part of the run's summary (`report.json`), under its name.
    fn summary(&self) -> Option<serde_json::Value> {
        None
    }

    /// The files it may write into the output folder. A new run removes those a run before
    /// left there, so that what the folder holds after the run is this run's; the summary
    /// lists those that are there at its end.
    fn outputs(&self) -> &'static [&'static str] {
        &[]
    }
}

/// What a stage knows when the run starts.
#[derive(Debug, Clone, Copy)]
pub struct Start<'a> {
    /// A window or a memory cap bounds the run's memory: what grows with the area driven is
    /// not kept.
    pub bounded: bool,
    /// The saved map the run starts from, with its path (stamped poses).
    pub map: Option<(&'a Path, &'a [(f64, Pose)])>,
}

/// A used frame, as its pose was kept.
#[derive(Clone, Copy)]
pub struct Used<'a> {
    /// Its index.
    pub frame: usize,
    /// Its pose at its stamp (the trajectory's).
    pub at_stamp: &'a Pose,
    /// The pose its scan was fused at (a deskewed scan's reference time).
    pub fused_at: &'a Pose,
    /// Its own points in the sensor frame, when a stage [needs them](RunStage::needs_points).
    pub points: &'a [Point],
    /// The run's pool.
    pub workers: &'a Workers,
}

/// The run's end, as the stages see it.
pub struct End<'a> {
    /// This run's used frames and their poses (at their stamps); empty when none was used.
    pub poses: &'a [(usize, Pose)],
    /// The output folder.
    pub out: &'a Path,
    /// The map file saved at the end (`--save-map`), and its path.
    pub saved_map: Option<(&'a Path, &'a [(f64, Pose)])>,
    /// Which way is up in the map frame, and what said so, when something did (the IMU).
    pub up: Option<(Vector3<f64>, String)>,
}

/// A run's stages, in the order they are called.
pub struct Stages<C: Capacity>(Vec<Box<dyn RunStage<C>>>);

impl<C: Capacity> Default for Stages<C> {
    fn default() -> Self {
        Self(Vec::new())
    }
}

impl<C: Capacity> Stages<C> {
    /// No stage.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds `stage` at the end of the list.
    pub fn push(&mut self, stage: Box<dyn RunStage<C>>) {
        self.0.push(stage);
    }

    /// Adds `more`'s stages at the end of the list.
    pub fn extend(&mut self, more: Stages<C>) {
        self.0.extend(more.0);
    }

    /// The bytes they take at most, together.
    pub fn bytes(&self) -> usize {
        self.0.iter().map(|s| s.bytes()).sum()
    }

    /// Tells each the run starts.
    pub fn start(&mut self, start: &Start<'_>) {
        self.0.iter_mut().for_each(|s| s.start(start));
    }

    /// Whether any needs each used frame's own points.
    pub fn need_points(&self) -> bool {
        self.0.iter().any(|s| s.needs_points())
    }

    /// Tells each the frame's scan was fused at `pose`; their counts go into `counts` and
    /// the milliseconds they took together are returned.
    pub fn fused(
        &mut self,
        pipeline: &mut Pipeline<C>,
        pose: &Pose,
        counts: &mut BTreeMap<String, u64>,
    ) -> f64 {
        let t = Instant::now();
        for s in &mut self.0 {
            if let Some((name, n)) = s.fused(pipeline, pose) {
                counts.insert(name.to_string(), n);
            }
        }
        t.elapsed().as_secs_f64() * 1e3
    }

    /// Tells each a used frame's pose was kept.
    pub fn used(&mut self, frame: &Used<'_>) {
        self.0.iter_mut().for_each(|s| s.used(frame));
    }

    /// What each writes beside the map saved at `map` ([`RunStage::beside_map`]), joined for the
    /// message that says the map was saved; a stage that could not write is said there and
    /// logged (the map is saved either way).
    pub fn beside_map(&self, map: &Path, path: &[(f64, Pose)], poses: &[(usize, Pose)]) -> String {
        let mut said = String::new();
        for s in &self.0 {
            match s.beside_map(map, path, poses) {
                Ok(Some(m)) => said.push_str(&format!("; {m}")),
                Ok(None) => {}
                Err(e) => {
                    log::warn!("{e}");
                    said.push_str(&format!("; {}: not beside it: {e}", s.name()));
                }
            }
        }
        said
    }

    /// Each stage's end ([`RunStage::finish`]), in order; the first that fails is the error.
    pub fn finish(&mut self, mesh: &mut MeshSpool, end: &End<'_>) -> Result<(), FileError> {
        self.0.iter_mut().try_for_each(|s| s.finish(mesh, end))
    }

    /// The vertex properties the first stage that gives any gives the mesh files.
    pub fn vertex_properties(&self) -> Option<Box<dyn VertexProperties + '_>> {
        self.0.iter().find_map(|s| s.vertex_properties())
    }

    /// Their parts of the run's summary, by name.
    pub fn summaries(&self) -> BTreeMap<String, serde_json::Value> {
        (self.0.iter())
            .filter_map(|s| Some((s.name().to_string(), s.summary()?)))
            .collect()
    }

    /// The files they may write into the output folder.
    pub fn outputs(&self) -> Vec<&'static str> {
        self.0
            .iter()
            .flat_map(|s| s.outputs().iter().copied())
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slamesh_core::SmallCapacity as Small;

    /// Counts what it is told, and writes a file at the end.
    #[derive(Default)]
    struct Counting {
        started: bool,
        fused: u64,
        used: Vec<usize>,
    }

    impl RunStage<Small> for Counting {
        fn name(&self) -> &'static str {
            "counting"
        }
        fn bytes(&self) -> usize {
            100
        }
        fn start(&mut self, start: &Start<'_>) {
            self.started = !start.bounded;
        }
        fn fused(&mut self, _: &mut Pipeline<Small>, _: &Pose) -> Option<(&'static str, u64)> {
            self.fused += 1;
            Some(("fused_so_far", self.fused))
        }
        fn used(&mut self, frame: &Used<'_>) {
            self.used.push(frame.frame);
        }
        fn summary(&self) -> Option<serde_json::Value> {
            Some(serde_json::json!({ "used": self.used }))
        }
        fn outputs(&self) -> &'static [&'static str] {
            &["counted.txt"]
        }
    }

    #[test]
    fn a_stage_is_told_each_step_and_reports_under_its_name() {
        let mut stages = Stages::<Small>::new();
        stages.push(Box::new(Counting::default()));
        stages.push(Box::new(Counting::default()));
        assert_eq!(stages.bytes(), 200);
        stages.start(&Start {
            bounded: false,
            map: None,
        });
        let mut pipeline = Pipeline::<Small>::new(Default::default()).unwrap();
        let mut counts = BTreeMap::new();
        for _ in 0..3 {
            stages.fused(&mut pipeline, &Pose::identity(), &mut counts);
        }
        assert_eq!(counts.get("fused_so_far"), Some(&3));
        let workers = Workers::new(1).unwrap();
        for frame in [4, 7] {
            stages.used(&Used {
                frame,
                at_stamp: &Pose::identity(),
                fused_at: &Pose::identity(),
                points: &[],
                workers: &workers,
            });
        }
        let summaries = stages.summaries();
        assert_eq!(summaries.len(), 1, "one key for the two stages of one name");
        assert_eq!(summaries["counting"], serde_json::json!({ "used": [4, 7] }));
        assert_eq!(stages.outputs(), ["counted.txt", "counted.txt"]);
        assert!(!stages.need_points());
        assert!(stages.vertex_properties().is_none());
    }
}
