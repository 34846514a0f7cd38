//! One run of the pipeline over a sequence of frames, with everything the command writes:
//! trajectories (KITTI and TUM) and `report.json` (through their sinks, [`crate::run::files`]),
//! the mesh and the map file.
//!
//! [`run`] (or a [`Run`], step by step) reads each frame from a [`FrameSource`], estimates its pose (or takes a given one),
//! extracts the mesh of the cells it updated, applies the sliding window, and records timings,
//! counts and memory. A frame that cannot be read or used is reported (its file, index and
//! reason) and skipped; the run goes on. Outputs are written at the end, each to a temporary
//! name then renamed; evicted cells are spooled to disk as they leave, so memory stays flat.
//!
//! Checkpoints: with `checkpoint_every`, the map and the run's totals are saved every so many
//! frames; with `resume`, a killed run continues from its last checkpoint and ends with the
//! same poses and mesh as an uninterrupted run (frames after the checkpoint are redone).

use crate::formats::map_file::MapWriter;
use crate::io::error::FileError;
use crate::outputs::mesh_spool::MeshSpool;
use crate::parallel::Workers;
use crate::run::budget::MemoryBudget;
use crate::run::capacity::RecentScans;
use crate::run::checkpoint::{self, Progress};
use crate::run::event::EventParts;
use crate::run::files::{self, ReportFile, RunFiles, OWN_FILES};
use crate::run::lookahead::LookAhead;
use crate::run::memory;
use crate::run::report::{FrameRecord, Summary};
use crate::run::saved_map;
use crate::run::setup::{self, Setup};
use crate::run::sink::{FnSink, FrameEvent, Sinks};
use crate::run::timing::RunClock;
use crate::run::window::Window;
use crate::run::wiring;
use crate::sources::{FrameSource, Waited};
use crate::stage::{Stages, Start};
use slamesh_core::{Capacity, Pipeline, Pose};
use std::borrow::Cow;
use std::sync::atomic::Ordering;

pub use crate::run::options::{Deskew, InitialPose, RunError, RunOptions};

/// Runs over every frame of `source`, offering each frame's event to `sinks` as it is made,
/// and writes the outputs into `opts.out`; then tells the sinks the run is over. With
/// `opts.resume`, continues from the checkpoint there. A sink that fails is the error, after
/// the outputs are written.
pub fn run_to<C: Capacity>(
    source: &mut impl FrameSource,
    opts: &RunOptions,
    sinks: Sinks<'_>,
) -> Result<Summary, RunError> {
    run_with::<C>(source, opts, sinks, Stages::new())
}

/// [`run_to`], with the caller's own `stages` after the run's (a capability of the caller's
/// that works inside the run or writes from the whole map at its end: [`crate::stage`]).
pub fn run_with<C: Capacity>(
    source: &mut impl FrameSource,
    opts: &RunOptions,
    mut sinks: Sinks<'_>,
    stages: Stages<C>,
) -> Result<Summary, RunError> {
    let mut run = if opts.resume {
        Run::<C>::resume_with(source, opts, stages)?
    } else {
        Run::<C>::start_with(source, opts, stages)?
    };
    let want_map = sinks.want_map();
    if want_map {
        run.hand_own_points();
    }
    // `wait` waits for a live source's next frame (a file's are all there), or a request.
    let mut i = run.next_frame();
    let stopped = || (opts.stop.as_ref()).is_some_and(|s| s.load(Ordering::SeqCst));
    loop {
        if stopped() {
            let summary = run.finish_interrupted(source, i)?;
            sinks.finish(&summary).map_err(RunError::Sink)?;
            return Ok(summary);
        }
        match source.wait(i) {
            Waited::Frame => {
                let record = run.step(source, i)?;
                sinks.frame(run.event(record, want_map));
                i += 1;
            }
            Waited::Request => {}
            Waited::End => break,
        }
        for r in source.requests() {
            run.serve(source, r);
        }
    }
    let summary = run.finish(source)?;
    sinks.finish(&summary).map_err(RunError::Sink)?;
    Ok(summary)
}

/// [`run_to`] with one sink: `on_frame` sees each record as it is made (for progress and
/// messages).
pub fn run<C: Capacity>(
    source: &mut impl FrameSource,
    opts: &RunOptions,
    mut on_frame: impl FnMut(&FrameRecord),
) -> Result<Summary, RunError> {
    let mut sinks = Sinks::new();
    sinks.add(FnSink::new("on_frame", |e: &FrameEvent| {
        on_frame(&e.record)
    }));
    run_to::<C>(source, opts, sinks)
}

/// A run in progress: the pipeline, its executor and window, and the spools of what it will
/// write. [`Run::start`] (or [`Run::resume`]), one [`Run::step`] per frame in order from
/// [`Run::next_frame`], then [`Run::finish`].
pub struct Run<'a, C: Capacity> {
    pub(super) opts: Cow<'a, RunOptions>,
    pub(super) pipeline: Pipeline<C>,
    pub(super) workers: Workers,
    pub(super) window: Window,
    /// The memory cap's shares, the layer budget it allows among them.
    pub(super) budget: Option<MemoryBudget>,
    /// What the run writes as it goes: the mesh's and the report's spools, the map file being
    /// saved, where its checkpoints go.
    pub(super) files: RunFiles,
    /// What a checkpoint saves: poses, skipped frames, totals.
    pub(super) progress: Progress,
    /// The stages' times and the loop's wall time.
    pub(super) clock: RunClock,
    /// The next frame, read and filtered ahead (with two threads or more).
    pub(super) ahead: LookAhead,
    /// The point counts of the last frames read (a scan far smaller is named).
    pub(super) recent: RecentScans,
    /// What the frame's event carries beside its record.
    pub(super) event: EventParts,
    /// What works inside the run beside registration, plugged in ([`crate::stage`]).
    pub(super) stages: Stages<C>,
}

impl<'a, C: Capacity> Run<'a, C> {
    /// A new run into `opts.out` (created if missing); `opts` borrowed (`&RunOptions`) or
    /// owned (`RunOptions`, for a run that outlives its caller's frame).
    pub fn start(
        source: &impl FrameSource,
        opts: impl Into<Cow<'a, RunOptions>>,
    ) -> Result<Self, RunError> {
        Self::start_with(source, opts, Stages::new())
    }

    /// [`start`](Self::start), with the caller's own `stages` after the run's.
    pub fn start_with(
        source: &impl FrameSource,
        opts: impl Into<Cow<'a, RunOptions>>,
        stages: Stages<C>,
    ) -> Result<Self, RunError> {
        let opts = opts.into();
        let setup = Setup::<C>::new(&opts, stages)?;
        let stale = OWN_FILES.into_iter().chain(setup.stages.outputs());
        files::remove_stale(&opts.out, stale);
        let spool = MeshSpool::new(
            &opts.out.join("mesh.ply"),
            opts.config.lattice(),
            &opts.config.mesh,
        )?;
        let report = ReportFile::create(&opts)?;
        let progress = Progress::new(checkpoint::fingerprint::<C>(source, &opts));
        Self::assemble(opts, setup, spool, report, progress)
    }

    /// The run killed after the checkpoint in `opts.out`, continued from it; refused when the
    /// checkpoint is missing or of another run (input, capacity, configuration, window).
    pub fn resume(
        source: &impl FrameSource,
        opts: impl Into<Cow<'a, RunOptions>>,
    ) -> Result<Self, RunError> {
        Self::resume_with(source, opts, Stages::new())
    }

    /// [`resume`](Self::resume), with the caller's own `stages` after the run's.
    pub fn resume_with(
        source: &impl FrameSource,
        opts: impl Into<Cow<'a, RunOptions>>,
        stages: Stages<C>,
    ) -> Result<Self, RunError> {
        let opts = opts.into();
        let mut setup = Setup::<C>::new(&opts, stages)?;
        let path = checkpoint::path(&opts.out);
        if !path.exists() {
            return Err(FileError::at(
                &path,
                "cannot resume: no checkpoint here (was the run started with --checkpoint-every?)",
            )
            .into());
        }
        // The checkpoint holds the whole map as it stood (a saved map's cells included).
        setup.pipeline.map_mut().clear();
        let progress = checkpoint::read(&path, setup.pipeline.map_mut())?;
        let fingerprint = checkpoint::fingerprint::<C>(source, &opts);
        if progress.fingerprint != fingerprint {
            return Err(FileError::at(
                &path,
                format!(
                    "cannot resume: the checkpoint is of another run\n  it has:   {}\n  this run: {fingerprint}",
                    progress.fingerprint
                ),
            )
            .into());
        }
        setup
            .pipeline
            .restore_progress(progress.pipeline_frames, progress.motion_model());
        let spool = MeshSpool::resume(
            &opts.out.join("mesh.ply"),
            opts.config.lattice(),
            &opts.config.mesh,
            progress.mesh,
        )?;
        let report = ReportFile::resume(&opts, progress.report_bytes)?;
        Self::assemble(opts, setup, spool, report, progress)
    }

    fn assemble(
        opts: Cow<'a, RunOptions>,
        setup: Setup<C>,
        mut spool: MeshSpool,
        report: ReportFile,
        progress: Progress,
    ) -> Result<Self, RunError> {
        if setup.budget.is_some() {
            spool.set_layers(memory::CAPPED_SET_LAYERS);
        }
        let map_path = setup
            .map_start
            .as_ref()
            .map_or_else(Vec::new, |m| m.path.clone());
        let checkpoint_path = checkpoint::path(&opts.out);
        let saved_map = match &opts.save_map {
            Some(path) => Some(MapWriter::create(
                path,
                &saved_map::info(&opts.config, &opts.preset, 0),
            )?),
            None => None,
        };
        let mut stages = setup.stages;
        stages.push_first(wiring::map_search(
            setup.map_start.as_ref().map(|_| &map_path[..]),
            opts.initial_pose,
            !progress.poses.is_empty(),
            setup.pager,
            opts.config.grid.cell_size_m,
        ));
        stages.restore(&progress.stages).map_err(|why| {
            FileError::at(&checkpoint_path, format!("not a usable checkpoint: {why}"))
        })?;
        let (window, map_layers) = (setup.window, setup.map_layers);
        let windowed = || setup::windowed(&opts, window, map_layers);
        stages.start(&Start {
            bounded: !window.is_off(),
            map: opts.map.as_deref().map(|m| (m, &map_path[..])),
            config: &opts.config,
            out: &opts.out,
            threads: opts.threads,
            windowed: match window.is_off() {
                true => None,
                false => Some(&windowed),
            },
        })?;
        let mut ahead = setup.ahead;
        if stages.need_points() {
            ahead.keep_points();
        }
        Ok(Run {
            stages,
            files: RunFiles {
                spool,
                report,
                saved_map,
                checkpoint: checkpoint_path,
                start_path: map_path,
            },
            opts,
            pipeline: setup.pipeline,
            workers: setup.workers,
            window: setup.window,
            budget: setup.budget,
            clock: RunClock::new(progress.seconds),
            progress,
            ahead,
            recent: RecentScans::default(),
            event: EventParts::default(),
        })
    }

    /// The first frame still to run (0, or the one after the checkpoint).
    pub fn next_frame(&self) -> usize {
        self.progress.next_frame
    }

    /// The pipeline as it stands.
    pub fn pipeline(&self) -> &Pipeline<C> {
        &self.pipeline
    }

    /// The poses so far: each used frame's index and pose (at its stamp), in order.
    pub fn poses(&self) -> &[(usize, Pose)] {
        &self.progress.poses
    }

    /// The body-frame motion between the last two used frames and the seconds between their
    /// stamps: what deskewing extrapolates. `None` before two frames were used.
    pub(super) fn last_motion(&self, source: &impl FrameSource) -> Option<(Pose, f64)> {
        let (before, last) = self.pipeline.motion().history();
        let [.., (a, _), (b, _)] = self.progress.poses[..] else {
            return None;
        };
        let dt = source.stamp(b) - source.stamp(a);
        Some((before?.inverse() * last?, dt))
    }

    /// Saves everything a killed run needs to continue at frame `next`.
    pub(super) fn checkpoint(&mut self, next: usize) -> Result<(), RunError> {
        let report_bytes = self.files.report.mark()?;
        self.files.spool.flush()?;
        let p = &mut self.progress;
        p.next_frame = next;
        p.pipeline_frames = self.pipeline.frames();
        p.motion = self.pipeline.motion().history();
        p.seconds = self.clock.seconds();
        p.report_bytes = report_bytes;
        p.mesh = self.files.spool.counts();
        p.stages.clear();
        self.stages.save(&mut p.stages);
        checkpoint::write(&self.files.checkpoint, p, self.pipeline.map())?;
        Ok(())
    }
}
