//! Loop closure (docs/design.md §1.14): when the sensor comes back to where it has been, the
//! drift between the two visits is found, spread over the trajectory by a pose graph, and the
//! map is rebuilt at the corrected poses so that the revisited street is one surface.
//!
//! | what | module |
//! |---|---|
//! | the settings | [`settings`] |
//! | the scans kept for later, on disk | [`spool`] |
//! | which earlier frames a keyframe may revisit, and the check | [`detect`] |
//! | the saved map a run started from: its path, its cells near a revisit | [`saved`] |
//! | the pose graph and its solver | [`graph`] |
//! | a windowed run's rebuild: its window and outputs | [`streaming`] |
//! | loop closure as one of a run's stages | [`stage`] |
//! | the thread that does all of it | `worker` |
//!
//! A run hands each frame it used to a [`LoopClosure`] ([`LoopClosure::observe`]: the pose and
//! the filtered scan) and asks before each frame whether a correction is ready
//! ([`LoopClosure::apply`]): a cheap, non-blocking look at a channel. Everything else runs on
//! the loop-closure thread, so a frame never waits for it. A correction moves every pose of
//! the trajectory, moves the pipeline's motion history with the newest, and swaps in the
//! rebuilt map. Without a revisit nothing is ever sent, and the run's outputs are those of a
//! run without loop closure, byte for byte.
//!
//! What is kept: each frame's filtered scan on disk (6 bytes a point, removed at the end),
//! and in memory 3 poses a frame, the keyframe graph, the local map of a check (at most
//! 60 000 layers) and, while the map is rebuilt, a second map. In a run whose map is a window
//! (a memory cap) the local map and the map being rebuilt are one map the size of the run's,
//! with half a pipeline's scan buffers ([`streaming`]).

pub mod detect;
pub mod graph;
pub mod saved;
pub mod settings;
pub mod spool;
pub mod stage;
pub mod streaming;
mod worker;

use crate::io::error::FileError;
use crate::stage::lent::{RunOutputs, Windowed};
use saved::SavedMap;
use serde::{Deserialize, Serialize};
use settings::LoopSettings;
use slamesh_core::lm::PoseInformation;
use slamesh_core::map::MeshMap;
use slamesh_core::motion::ConstantVelocity;
use slamesh_core::{Capacity, Config, Pipeline, Point, Pose};
use spool::ScanSpool;
use std::path::Path;
use std::sync::mpsc::{channel, Receiver, Sender};
use std::thread::JoinHandle;
use streaming::RebuiltOutputs;

/// One loop closed: which frames, how sure, how large the correction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Closure {
    /// The frame that came back.
    pub frame: usize,
    /// The earlier frame (a keyframe) it was found near, or with `in_saved_map` the pose of
    /// the saved map's path (its index).
    pub with_frame: usize,
    /// Found in the saved map the run started from (the earlier session), not in this run.
    #[serde(default)]
    pub in_saved_map: bool,
    /// Share of the scan's points on the earlier map's surfaces at the pose found.
    pub hit_share: f64,
    /// The same on its walls.
    pub wall_share: f64,
    /// The best pose elsewhere's share (the search's ambiguity check).
    pub runner_up_share: f64,
    /// How far the pose found is from the odometry's (m).
    pub correction_m: f64,
    /// How far it is turned from it (degrees).
    pub correction_deg: f64,
    /// Where the frame was found (m, in the world as corrected until then).
    pub position: [f64; 3],
    /// The frame before which the run applied the correction.
    pub applied_at_frame: Option<usize>,
}

impl Closure {
    /// One line for the log.
    pub fn describe(&self) -> String {
        format!(
            "loop closed with {} {} (found at frame {}): {:.0} % of the scan on the earlier \
             map ({:.0} % on walls, the best elsewhere {:.0} %), correction {:.2} m, {:.2} deg",
            if self.in_saved_map {
                "the saved map's path at pose"
            } else {
                "frame"
            },
            self.with_frame,
            self.frame,
            100.0 * self.hit_share,
            100.0 * self.wall_share,
            100.0 * self.runner_up_share,
            self.correction_m,
            self.correction_deg
        )
    }
}

/// To the loop-closure thread.
enum ToWorker {
    /// A frame the run used: its index, pose and filtered scan (sensor frame).
    Frame {
        frame: usize,
        counter: u32,
        pose: Pose,
        information: Box<PoseInformation>,
        points: Vec<Point>,
    },
    /// The run applied a correction whose `last` was `correction`; the map the rebuilt one
    /// replaced comes back.
    Applied {
        correction: Pose,
        returned: Option<Box<MeshMap>>,
    },
    /// No more frames: finish what is pending.
    Finish,
}

/// From the loop-closure thread: a correction, or the end.
struct Corrected {
    /// The map rebuilt at the corrected poses (when any moved enough).
    rebuilt: Option<Box<MeshMap>>,
    /// A windowed run's: the outputs of what left the rebuilt map's window.
    outputs: Option<RebuiltOutputs>,
    /// For each frame the thread knows (in order), what to multiply its pose by on the left.
    per_frame: Vec<(usize, Pose)>,
    /// The same for every later frame.
    last: Pose,
    /// The closures accepted since the last correction.
    closures: Vec<Closure>,
    /// The thread is done (nothing else in this message).
    done: bool,
    /// Bytes of scans spooled so far.
    spool_bytes: u64,
}

impl Corrected {
    fn done(spool_bytes: u64) -> Self {
        Self {
            rebuilt: None,
            outputs: None,
            per_frame: Vec::new(),
            last: Pose::identity(),
            closures: Vec::new(),
            done: true,
            spool_bytes,
        }
    }
}

/// What the run learns from [`LoopClosure::finish`]: its part of the run's summary
/// (`loop_closure`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct LoopReport {
    /// Every closure accepted, in order.
    pub closures: Vec<Closure>,
    /// Corrections applied, and how many of them swapped in a rebuilt map.
    pub corrections: usize,
    /// See `corrections`.
    pub rebuilds: usize,
    /// Bytes of scans the spool held at the end.
    pub spool_bytes: u64,
    /// Why loop closure stopped before the run ended, if it did (the run went on without it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stopped: Option<String>,
}

/// The run's end of loop closure.
pub struct LoopClosure<C: Capacity> {
    to_worker: Sender<ToWorker>,
    from_worker: Receiver<Corrected>,
    thread: Option<JoinHandle<Result<(), FileError>>>,
    report: LoopReport,
    /// The pipelines it corrects hold capacity `C`'s buffers.
    _capacity: std::marker::PhantomData<fn() -> C>,
}

impl<C: Capacity> LoopClosure<C> {
    /// Starts the loop-closure thread, spooling scans to `spool_path`; `saved_map`: the map
    /// file the run started from (its path is searched for revisits too, and a rebuild keeps
    /// its cells); `streaming`: the run's window and outputs, when its map is a window;
    /// `threads`: the run's thread count (0: one per core), which a rebuild still under way
    /// after the run's last frame uses.
    pub fn start(
        config: Config,
        s: LoopSettings,
        spool_path: &Path,
        saved_map: Option<&Path>,
        streaming: Option<Windowed>,
        threads: usize,
    ) -> Result<Self, FileError> {
        let spool = ScanSpool::create(spool_path, (s.spool_budget_mb * 1e6) as u64)?;
        let saved = saved_map.map(SavedMap::open).transpose()?;
        let (to_worker, rx) = channel();
        let (tx, from_worker) = channel();
        let worker = worker::Worker::<C>::new(config, s, spool, tx, saved, streaming, threads)?;
        let thread = std::thread::Builder::new()
            .name("slamesh-loop-closure".into())
            .spawn(move || worker.run(rx))
            .map_err(|e| FileError::at(spool_path, format!("cannot start loop closure: {e}")))?;
        Ok(Self {
            to_worker,
            from_worker,
            thread: Some(thread),
            report: LoopReport::default(),
            _capacity: std::marker::PhantomData,
        })
    }

    /// Hands the thread a frame the run used: its pose, how well its registration pinned
    /// that down, and the filtered scan it fused. `counter` is the pipeline's frame count
    /// after it ([`Pipeline::frames`]).
    pub fn observe(
        &mut self,
        frame: usize,
        counter: u32,
        (pose, information): (&Pose, &PoseInformation),
        points: &[Point],
    ) {
        let _ = self.to_worker.send(ToWorker::Frame {
            frame,
            counter,
            pose: *pose,
            information: Box::new(*information),
            points: points.to_vec(),
        });
    }

    /// Applies a correction if one is ready (never waits): the trajectory `poses` (by frame,
    /// in order) and the pipeline's motion history move, and a rebuilt map replaces the
    /// pipeline's (in a windowed run with its outputs: `outputs`). `next_frame` is the frame
    /// about to run. Returns the closures it brought.
    pub fn apply(
        &mut self,
        pipeline: &mut Pipeline<C>,
        poses: &mut [(usize, Pose)],
        next_frame: usize,
        outputs: &mut RunOutputs<'_>,
    ) -> Vec<Closure> {
        match self.from_worker.try_recv() {
            Ok(c) if !c.done => self.take(c, pipeline, poses, next_frame, outputs),
            _ => Vec::new(),
        }
    }

    fn take(
        &mut self,
        c: Corrected,
        pipeline: &mut Pipeline<C>,
        poses: &mut [(usize, Pose)],
        next_frame: usize,
        outputs: &mut RunOutputs<'_>,
    ) -> Vec<Closure> {
        let mut known = c.per_frame.iter().peekable();
        for (frame, pose) in poses.iter_mut() {
            while known.peek().is_some_and(|(f, _)| f < frame) {
                known.next();
            }
            let k = match known.peek() {
                Some((f, k)) if f == frame => k,
                _ => &c.last,
            };
            *pose = k * *pose;
        }
        let (before, last) = pipeline.motion().history();
        let moved =
            ConstantVelocity::from_history(before.map(|p| c.last * p), last.map(|p| c.last * p));
        pipeline.restore_progress(pipeline.frames(), moved);
        let mut returned = c.rebuilt;
        if let Some(map) = &mut returned {
            std::mem::swap(pipeline.map_mut(), map);
            self.report.rebuilds += 1;
        }
        if let Some(o) = c.outputs {
            if let Err(e) = streaming::replace(outputs, o) {
                log::warn!("loop closure: the rebuilt outputs: {e}");
            }
        }
        self.report.corrections += 1;
        self.report.spool_bytes = c.spool_bytes;
        let _ = self.to_worker.send(ToWorker::Applied {
            correction: c.last,
            returned,
        });
        let mut closures = c.closures;
        for cl in &mut closures {
            cl.applied_at_frame = Some(next_frame);
        }
        self.report.closures.extend(closures.iter().cloned());
        closures
    }

    /// Waits for the thread to finish what is pending, applies its last corrections, and
    /// says what loop closure did. `next_frame` is one past the last frame run. A thread that
    /// stopped early is logged and named in the report, not an error.
    pub fn finish(
        mut self,
        pipeline: &mut Pipeline<C>,
        poses: &mut [(usize, Pose)],
        next_frame: usize,
        outputs: &mut RunOutputs<'_>,
    ) -> LoopReport {
        let _ = self.to_worker.send(ToWorker::Finish);
        while let Ok(c) = self.from_worker.recv() {
            if c.done {
                self.report.spool_bytes = c.spool_bytes;
                break;
            }
            self.take(c, pipeline, poses, next_frame, outputs);
        }
        // A thread that stopped (its spool could not be written, say) costs the closures it
        // would have found, not the run: the outputs are written all the same.
        if let Some(t) = self.thread.take() {
            match t.join() {
                Ok(Ok(())) => {}
                Ok(Err(e)) => {
                    log::warn!("loop closure stopped early: {e}");
                    self.report.stopped = Some(e.to_string());
                }
                Err(_) => {
                    log::warn!("loop closure stopped early: its thread failed");
                    self.report.stopped = Some("its thread failed".into());
                }
            }
        }
        self.report
    }
}
