//! Loop closure as one of a run's stages ([`crate::stage::RunStage`]): its thread starts with
//! the run, is handed each frame the run used, and between frames brings the corrections it
//! has ready (every pose moved, the motion model with them, a rebuilt map and, in a windowed
//! run, the outputs of what left its window); at the end it is waited for, and what it did is
//! its part of the run's summary (`loop_closure`). A frame after which loops were closed notes
//! them in its record (`loop_closures`), and its event carries the whole map and path again.
//!
//! Holds the thread's end ([`LoopClosure`]) from the run's start to its end, then its report.
//! A resumed run starts it anew: the frames before the checkpoint are not searched.

use crate::io::error::FileError;
use crate::loop_closure::settings::LoopSettings;
use crate::loop_closure::{LoopClosure, LoopReport};
use crate::stage::lent::Between;
use crate::stage::{Note, RunStage, Start, Used};
use slamesh_core::Capacity;

/// Its name: the key of its part of the run's summary ([`LoopReport`]), read back with
/// `summary.stage::<LoopReport>(NAME)`.
pub const NAME: &str = "loop_closure";

/// Where the thread spools the scans it may search later, in the output folder (removed at
/// the end).
pub const SPOOL_FILE: &str = ".loop-closure.scans";

/// Loop closure in a run, with its settings.
pub struct LoopClosureStage<C: Capacity> {
    settings: LoopSettings,
    /// Its thread, from the run's start to its end.
    closer: Option<LoopClosure<C>>,
    /// What it did, once the run ended.
    report: Option<LoopReport>,
}

impl<C: Capacity> LoopClosureStage<C> {
    /// Loop closure with `settings`, its thread not yet started.
    pub fn new(settings: LoopSettings) -> Self {
        Self {
            settings,
            closer: None,
            report: None,
        }
    }
}

impl<C: Capacity> RunStage<C> for LoopClosureStage<C> {
    fn name(&self) -> &'static str {
        NAME
    }

    fn start(&mut self, start: &Start<'_>) -> Result<(), FileError> {
        self.closer = Some(LoopClosure::start(
            *start.config,
            self.settings,
            &start.out.join(SPOOL_FILE),
            start.map.map(|(path, _)| path),
            start.windowed.map(|w| w()),
            start.threads,
        )?);
        Ok(())
    }

    fn between(&mut self, run: &mut Between<'_, C>) -> Option<Note> {
        let closer = self.closer.as_mut()?;
        let i = run.next_frame;
        let closed = closer.apply(run.pipeline, run.poses, i, &mut run.outputs);
        if closed.is_empty() {
            return None;
        }
        let moved: Vec<String> = closed.iter().map(|c| c.describe()).collect();
        for said in &moved {
            log::info!("frame {i}: {said}");
        }
        Some(Note {
            moved,
            ..Note::of("loop_closures", &closed)
        })
    }

    fn used(&mut self, frame: &Used<'_>) -> Option<Note> {
        if let Some(c) = &mut self.closer {
            let pose = (frame.fused_at, frame.information);
            c.observe(frame.frame, frame.counter, pose, frame.fused_points);
        }
        None
    }

    fn wind_up(&mut self, run: &mut Between<'_, C>) {
        if let Some(c) = self.closer.take() {
            let outputs = &mut run.outputs;
            self.report = Some(c.finish(run.pipeline, run.poses, run.next_frame, outputs));
        }
    }

    fn summary(&self) -> Option<serde_json::Value> {
        serde_json::to_value(self.report.as_ref()?).ok()
    }
}
