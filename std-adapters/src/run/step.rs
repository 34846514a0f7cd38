//! One frame of a run, as named stages ([`Run::step`]): the run moved as a whole if a stage
//! moves it (a loop closed), read, prepare (deskew,
//! capacity, the given pose), register (the core's one entry point, with the next frame read
//! beside it), update the map (mesh counts, the window), record (the frame's line, the
//! checkpoint). A frame that cannot be used is a [`FrameError`]: recorded as skipped, the run
//! goes on; only an output that cannot be written stops it ([`RunError`]).

use crate::run::frame_error::{FrameError, FrameFault};
use crate::run::memory;
use crate::run::options::{Deskew, RunError};
use crate::run::prepare::Frame;
use crate::run::report::{registration_reason, updated_triangles, FrameRecord};
use crate::run::session::Run;
use crate::run::timing::StageMs;
use crate::sources::FrameSource;
use crate::stage::lent::{Between, RunOutputs};
use crate::stage::{Read, Used};
use slamesh_core::deskew;
use slamesh_core::pipeline::{Known, Scan, Stepped};
use slamesh_core::relocalize::Search;
use slamesh_core::{Capacity, RegistrationStatus};
use std::time::Instant;

impl<C: Capacity> Run<'_, C> {
    /// Runs frame `i`: the stages below, in order. A frame that cannot be read or used is
    /// recorded as skipped with its file, index and reason; only an output that cannot be
    /// written is an error.
    pub fn step(
        &mut self,
        source: &mut impl FrameSource,
        i: usize,
    ) -> Result<FrameRecord, RunError> {
        let mut rec = FrameRecord::skipped(i, source.label(i));
        self.between(i, &mut rec);
        let read = self.ahead.take(source, i);
        self.event.samples = source.samples(i);
        rec.samples = self.event.samples.len();
        // After the read: a recording knows a frame's stamp once it has read the message.
        rec.stamp = source.stamp(i);
        rec.stamp_ns = source.stamp_ns(i);
        let file = &rec.file;
        (self.stages).read(&Read {
            frame: i,
            file,
            samples: &self.event.samples,
        });
        rec.points_dropped_by_reader = read.dropped_by_reader;
        let motion = self.last_motion(source);
        let (mut frame, readable) = Frame::of(read.scan, &mut rec);
        self.recent.note(&rec);
        let ready = readable.and_then(|()| self.prepare(&mut frame, motion, i, &mut rec));
        let stepped = self.register(source, i, &frame, ready);
        let not_waited = self.take_timings(read.ms, &frame, &mut rec);
        if let Some(e) = self.stages.failed() {
            return Err(e.into());
        }
        match stepped.and_then(found_or_not) {
            Ok(stepped) => {
                self.take_outcome(&stepped, &mut rec);
                let o = stepped.into_outcome();
                self.update_map(&o, &mut rec)?;
                rec.ms.total = rec.ms.pipeline() + rec.ms.evict - not_waited;
                self.keep_pose(source, i, &o, &frame, &mut rec);
                if let Some(own) = &mut self.event.own_points {
                    *own = std::mem::take(&mut frame.points);
                }
            }
            Err(fault) => self.skip(FrameError::new(&rec.file, i, fault), &mut rec),
        }
        self.record(source, i, &mut rec)?;
        Ok(rec)
    }

    /// Lets the stages move the run as a whole before frame `i` (a loop closed).
    fn between(&mut self, i: usize, rec: &mut FrameRecord) {
        let mut run = Between {
            pipeline: &mut self.pipeline,
            poses: &mut self.progress.poses,
            next_frame: i,
            outputs: RunOutputs {
                spool: &mut self.files.spool,
                saved_map: &mut self.files.saved_map,
            },
        };
        self.stages.between(&mut run, &mut rec.notes);
    }

    /// The core's step on a worker of the pool, with what is known of the pose (the given
    /// one, nothing, or a stage's search: [`crate::stage::RunStage::search`]), while this thread reads the next frame
    /// (and starts filtering it unless it is to be deskewed or outgrows the capacity). A
    /// frame that is not ready still has the next one read.
    fn register(
        &mut self,
        source: &mut impl FrameSource,
        i: usize,
        frame: &Frame,
        ready: Result<(), FrameFault>,
    ) -> Result<Stepped, FrameFault> {
        let Run {
            pipeline,
            workers,
            clock,
            ahead,
            opts,
            stages,
            ..
        } = self;
        let (deskew, config, workers) = (opts.deskew, &opts.config, &*workers);
        let mut read_next = Some(|| {
            ahead.read_ahead(source, i + 1, workers, config, |points, times| {
                (times.is_none() || deskew == Deskew::Off) && points.len() <= C::POINTS
            })
        });
        let everywhere = Search::default();
        let searching = stages.search();
        let stepped = ready.and_then(|()| {
            let scan = match &frame.ahead {
                Some(a) => Scan::Filtered(a.filtered()),
                None => Scan::Raw(&frame.points),
            };
            let known = match (frame.given, searching) {
                (Some(pose), _) => Known::Pose(pose),
                (None, None) => frame.prior.map_or(Known::Nothing, Known::Near),
                (None, Some(s)) => Known::Somewhere {
                    candidates: s.candidates,
                    search: &everywhere,
                    paging: s.paging,
                },
            };
            // On a worker of the pool: its serial stages leave the other thread to the filter.
            workers
                .install_beside(
                    || pipeline.step(scan, known, workers, &mut clock.stages),
                    || read_next.take().map_or((), |mut next| next()),
                )
                .map_err(FrameFault::Refused)
        });
        if let Some(mut next) = read_next.take() {
            next();
        }
        stepped
    }

    /// The stages' times into `rec`; returns the filter's time run ahead that this step did
    /// not wait for (not part of the frame's total).
    fn take_timings(&mut self, read_ms: f64, frame: &Frame, rec: &mut FrameRecord) -> f64 {
        rec.ms = StageMs {
            read: read_ms,
            deskew: rec.ms.deskew,
            ..self.clock.stages.take()
        };
        let Some(a) = &frame.ahead else {
            return 0.0;
        };
        rec.ms.filter = a.filter_ms;
        a.filter_ms - a.wait_ms
    }

    /// The outcome's status, reason and counts into `rec`; a search's result to the stages.
    fn take_outcome(&mut self, stepped: &Stepped, rec: &mut FrameRecord) {
        let o = stepped.outcome();
        rec.status = o.status.into();
        rec.reason = registration_reason(o.status, &o.stats, &self.opts.config);
        if let Stepped::Searched(r) = stepped {
            (self.stages).searched(rec.frame, r, &mut rec.notes);
        }
        rec.take_stats(&o.stats);
        self.event.information = Some(o.stats.information);
    }

    /// Tells the stages the frame was fused (their time counts in the update's), counts the
    /// triangles the frame updated and applies the window (cells it evicts go to
    /// the mesh spool and the map being saved).
    fn update_map(
        &mut self,
        o: &slamesh_core::ScanOutcome,
        rec: &mut FrameRecord,
    ) -> Result<(), RunError> {
        let (pose, notes) = (&o.t_world_sensor, &mut rec.notes);
        rec.ms.update += self.stages.fused(&mut self.pipeline, pose, notes);
        let t = Instant::now();
        rec.triangles_updated = updated_triangles(&self.pipeline, &self.workers);
        rec.ms.mesh = t.elapsed().as_secs_f64() * 1e3;
        let t = Instant::now();
        if !self.window.is_off() {
            let spool = self
                .opts
                .window
                .save_evicted
                .then_some(&mut self.files.spool);
            rec.evicted_cells = self.window.evict_to(
                self.pipeline.map_mut(),
                o.stats.frame,
                &o.t_world_sensor,
                spool,
                self.files.saved_map.as_mut(),
            )?;
            self.progress.evicted_cells += rec.evicted_cells;
        }
        rec.ms.evict = t.elapsed().as_secs_f64() * 1e3;
        Ok(())
    }

    /// Keeps the frame's pose at its stamp (and shows the frame to the stages and loop
    /// closure).
    fn keep_pose(
        &mut self,
        source: &impl FrameSource,
        i: usize,
        o: &slamesh_core::ScanOutcome,
        frame: &Frame,
        rec: &mut FrameRecord,
    ) {
        // The pose of a deskewed scan is its reference time's (the middle of the sweep); the
        // stamp lies between it and the previous frame's, so the motion between the two
        // estimates interpolates it (the predicted motion would extrapolate).
        let history = self.pipeline.motion().history();
        let fused_at = &o.t_world_sensor;
        let by_stage = (self.stages).at_stamp(fused_at, frame.reference, rec.stamp, history);
        let at_stamp = match (by_stage, frame.to_stamp, history) {
            (Some(p), _, _) => p,
            (None, Some((_, dt, reference)), (Some(before), Some(last))) => deskew::pose_at(
                &o.t_world_sensor,
                &(before.inverse() * last),
                dt,
                -reference,
            ),
            _ => o.t_world_sensor,
        };
        self.progress.poses.push((i, at_stamp));
        let used = Used {
            frame: i,
            status: o.status,
            reference: frame.reference,
            history,
            at_stamp: &at_stamp,
            fused_at,
            information: &o.stats.information,
            counter: self.pipeline.frames(),
            fused_points: self.pipeline.last_points(),
            points: &frame.points,
            workers: &self.workers,
        };
        self.stages.used(&used, &mut rec.notes);
        rec.latency_ms = source.arrival(i).map(|a| a.elapsed().as_secs_f64() * 1e3);
        self.progress.used_ms.push(rec.ms);
    }

    /// A frame not used: its status and error into `rec`, its error among the skipped.
    fn skip(&mut self, e: FrameError, rec: &mut FrameRecord) {
        if let FrameFault::NotLocalized(_) = e.fault {
            // The search ran and found no convincing pose.
            rec.status = RegistrationStatus::NotLocalized.into();
        }
        let e = e.to_string();
        rec.error = Some(e.clone());
        self.progress.skipped.push(e);
    }

    /// The map's size and the process's memory into `rec`; its line into the report's spool;
    /// a checkpoint when one is due.
    fn record(
        &mut self,
        source: &impl FrameSource,
        i: usize,
        rec: &mut FrameRecord,
    ) -> Result<(), RunError> {
        rec.map_cells = self.pipeline.map().cell_count();
        rec.map_layers = self.pipeline.map().layer_count();
        rec.rss_mb = memory::rss_bytes().map(memory::mb);
        self.files.report.add(rec)?;
        if let Some(every) = self.opts.checkpoint_every.filter(|&n| n > 0) {
            if (i + 1).is_multiple_of(every) && i + 1 < source.frames() {
                self.checkpoint(i + 1)?;
            }
        }
        Ok(())
    }
}

/// A search that found no convincing pose is a frame not used.
fn found_or_not(stepped: Stepped) -> Result<Stepped, FrameFault> {
    match stepped {
        Stepped::Searched(r) if r.outcome.status == RegistrationStatus::NotLocalized => {
            Err(FrameFault::NotLocalized(Box::new(r)))
        }
        s => Ok(s),
    }
}
