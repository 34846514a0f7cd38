//! The loop-closure thread's corrections (docs/design.md §1.14, "Correction"): the map rebuilt
//! at the corrected poses a slice of frames at a time between looks at the run's messages,
//! given up for a newer one once the run has sent its last frame and the graph has moved on,
//! and spread over the run's threads from then on. A correction that moves no frame enough
//! goes to the run at once, the trajectory's alone.

use super::{config_error, Worker};
use crate::io::error::FileError;
use crate::loop_closure::streaming::RebuiltOutputs;
use crate::loop_closure::Closure;
use crate::parallel::Workers;
use slamesh_core::math::rotation_angle;
use slamesh_core::motion::ConstantVelocity;
use slamesh_core::pipeline::{Known, Scan, Stepped};
use slamesh_core::{Capacity, NoProbe, Pipeline, Pose};

/// Frames a rebuild fuses between two looks at the run's messages and checks.
const REBUILD_SLICE: usize = 16;

impl<C: Capacity> Worker<C> {
    /// Starts a correction: a rebuild of the map when some frame moved more than
    /// `rebuild_m` or turned more than `rebuild_deg` from where the run's map has it, else
    /// the trajectory's alone, sent now.
    pub(super) fn start_correction(&mut self) -> Result<(), FileError> {
        self.dirty = false;
        let corrections = self.correction.clone();
        let moved = self
            .frames
            .iter()
            .zip(&corrections)
            .map(|(f, c)| {
                let apart = (f.in_map * f.raw).inverse() * (c * f.raw);
                (
                    apart.translation.vector.norm(),
                    rotation_angle(&apart).to_degrees(),
                )
            })
            .fold((0.0, 0.0), |a: (f64, f64), b| (a.0.max(b.0), a.1.max(b.1)));
        let closures = std::mem::take(&mut self.new_closures);
        if moved.0 <= self.s.rebuild_m && moved.1 <= self.s.rebuild_deg {
            self.send(None, corrections, closures);
            return Ok(());
        }
        let (mut pipeline, outputs) = match &self.streaming {
            Some(w) => {
                let Some(mut p) = self.submap.take() else {
                    // Its pipeline is still out (not while nothing is in flight): next time.
                    self.new_closures = closures;
                    self.dirty = true;
                    return Ok(());
                };
                p.map_mut().clear();
                p.set_map_updates(true);
                (p, Some(RebuiltOutputs::create(w, self.rebuilds)?))
            }
            None => match self.rebuild.take() {
                Some(p) => (p, None),
                None => (
                    Box::new(Pipeline::<C>::new(self.config).map_err(config_error)?),
                    None,
                ),
            },
        };
        self.rebuilds += 1;
        // From the saved map's cells, when the run started from one; its frame count is the
        // saved map's and the count of frames rebuilt.
        if let Some(saved) = &mut self.saved {
            saved.load_all(pipeline.map_mut())?;
        }
        pipeline.restore_progress(self.first_counter(), ConstantVelocity::new());
        self.rebuilding = Some(Rebuild {
            pipeline,
            outputs,
            corrections,
            closures,
            started: std::time::Instant::now(),
        });
        Ok(())
    }

    /// Gives up the rebuild under way when the graph has moved on since it started and the
    /// run has sent its last frame: the map it would bring is replaced as soon as it lands,
    /// so the next correction's rebuild starts now instead (the run waits for it at its end).
    /// Its closures go with the next correction. A windowed run's rebuild is kept: its
    /// outputs are files, and no check runs while it does, so the graph does not move then.
    pub(super) fn drop_stale_rebuild(&mut self) {
        if self.streaming.is_some() {
            return;
        }
        let Some(r) = self.rebuilding.take() else {
            return;
        };
        let mut p = r.pipeline;
        p.map_mut().clear();
        self.rebuild = Some(p);
        let mut closures = r.closures;
        closures.append(&mut self.new_closures);
        self.new_closures = closures;
        log::debug!(
            "loop closure: a rebuild given up after {:.1} s for the newer correction",
            r.started.elapsed().as_secs_f64()
        );
    }

    /// Fuses the next `REBUILD_SLICE` frames into the map being rebuilt (frames that came
    /// after the rebuild started at the graph's newest correction); the finished map is sent.
    pub(super) fn rebuild_slice(&mut self) -> Result<(), FileError> {
        let Some(mut r) = self.rebuilding.take() else {
            return Ok(());
        };
        let next = r.corrections.len().min(self.frames.len());
        let done = (r.pipeline.frames() - self.first_counter()) as usize;
        if done >= self.frames.len() {
            // Every rebuilt cell counts as seen now: the corrected map is the one to register
            // against and fuse into, none of it stale.
            let seen: Vec<_> = r.pipeline.map().layers().map(|l| (l.key, l.axis)).collect();
            for (key, axis) in seen {
                let _ = r.pipeline.map_mut().layer_mut(&key, axis, self.counter);
            }
            log::debug!(
                "loop closure: map rebuilt from {} frames in {:.1} s",
                done,
                r.started.elapsed().as_secs_f64()
            );
            for (f, c) in self.frames.iter_mut().zip(&r.corrections) {
                f.in_map = *c;
            }
            self.send(Some((r.pipeline, r.outputs)), r.corrections, r.closures);
            return Ok(());
        }
        if next < self.frames.len() {
            r.corrections.extend_from_slice(&self.correction[next..]);
        }
        self.take_the_run_s_threads();
        for i in done..(done + REBUILD_SLICE).min(self.frames.len()) {
            let pose = r.corrections[i] * self.frames[i].raw;
            let points = self.spool.read(i)?;
            // A frame that fails is counted all the same, so that frame `i` is the
            // pipeline's `i`-th.
            let fused = match &self.pool {
                // The same map as on one thread (the executor only spreads the work).
                Some(pool) => r
                    .pipeline
                    .step(Scan::Raw(&points), Known::Pose(pose), pool, &mut NoProbe)
                    .map(Stepped::into_outcome),
                None => r.pipeline.integrate_scan(&points, &pose),
            };
            let Ok(o) = fused else {
                continue;
            };
            if let (Some(w), Some(out)) = (&mut self.streaming, &mut r.outputs) {
                let map = r.pipeline.map_mut();
                (w.evict)(
                    map,
                    o.stats.frame,
                    &pose,
                    out.spool.as_mut(),
                    out.saved_map.as_mut(),
                )?;
            }
        }
        self.rebuilding = Some(r);
        Ok(())
    }

    /// Once the run has sent its last frame it waits for this thread, and its threads are
    /// idle: the rebuild spreads its work over as many (`threads`) from then on. Not in a
    /// windowed run: the pool's buffers are not in what its memory cap counts.
    fn take_the_run_s_threads(&mut self) {
        let windowed = self.streaming.is_some();
        if self.finishing && self.pool.is_none() && self.threads != 1 && !windowed {
            self.pool = Workers::new(self.threads).ok();
        }
    }
}

/// A map being rebuilt a slice at a time between checks.
pub(super) struct Rebuild<C: Capacity> {
    pipeline: Box<Pipeline<C>>,
    /// A windowed run's: what leaves the rebuilt map's window.
    outputs: Option<RebuiltOutputs>,
    /// Each frame's correction it is built with (frames that came later appended).
    corrections: Vec<Pose>,
    /// The closures in the graph it was started from, not yet sent.
    closures: Vec<Closure>,
    started: std::time::Instant,
}
