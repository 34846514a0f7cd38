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

use crate::dynamic::Clearing;
use crate::formats::map_file::MapWriter;
use crate::formats::mesh_records::VertexProperties;
use crate::inertial::Inertial;
use crate::io::error::FileError;
use crate::loop_closure::streaming::RunOutputs;
use crate::loop_closure::LoopClosure;
use crate::navmap::files::NavMapSummary;
use crate::navmap::floor_file::{self, FloorFile};
use crate::navmap::hits::Hits;
use crate::navmap::layers::OnMesh;
use crate::outputs::mesh_spool::{MeshCounts, MeshFormat, MeshSpool};
use crate::parallel::Workers;
use crate::run::budget::MemoryBudget;
use crate::run::checkpoint::{self, Progress};
use crate::run::files::{ReportFile, Trajectories};
use crate::run::lookahead::LookAhead;
use crate::run::map_pager::MapPager;
use crate::run::memory;
use crate::run::report::{spreads, write_topview, FrameRecord, Summary};
use crate::run::saved_map;
use crate::run::setup::Setup;
use crate::run::sink::{FnSink, FrameEvent, MapUpdate, Sinks};
use crate::run::timing::StageTimer;
use crate::run::window::Window;
use crate::sources::{FrameSource, Sample, Waited};
use slamesh_core::lm::PoseInformation;
use slamesh_core::{Capacity, Pipeline, Point, Pose};
use std::borrow::Cow;
use std::path::PathBuf;
use std::time::Instant;

pub use crate::run::options::{Deskew, InitialPose, RunError, RunOptions};

/// Runs over every frame of `source`, offering each frame's event to `sinks` as it is made,
/// and writes the outputs into `opts.out`; then tells the sinks the run is over. With
/// `opts.resume`, continues from the checkpoint there. A sink that fails is the error, after
/// the outputs are written.
pub fn run_to<C: Capacity>(
    source: &mut impl FrameSource,
    opts: &RunOptions,
    mut sinks: Sinks<'_>,
) -> Result<Summary, RunError> {
    let mut run = if opts.resume {
        Run::<C>::resume(source, opts)?
    } else {
        Run::<C>::start(source, opts)?
    };
    let want_map = sinks.want_map();
    if want_map {
        run.hand_own_points();
    }
    // `wait` waits for a live source's next frame (a file's are all there), or a request.
    let mut i = run.next_frame();
    loop {
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
    pub(super) spool: MeshSpool,
    /// `report.json`, its frame records spooled as they come.
    pub(super) report: ReportFile,
    pub(super) checkpoint_path: PathBuf,
    /// What a checkpoint saves: poses, skipped frames, totals.
    pub(super) progress: Progress,
    pub(super) timer: StageTimer,
    /// The next frame, read and filtered ahead (with two threads or more).
    pub(super) ahead: LookAhead,
    pub(super) started: Instant,
    /// Loop seconds before this process (from the checkpoint when resuming).
    pub(super) seconds_before: f64,
    /// Started from a saved map with no pose given: where to search for the pose, until a
    /// frame finds it ([`saved_map::candidates`]).
    pub(super) search: Option<Vec<Pose>>,
    /// The path of the saved map the run started from (a map it saves keeps it first).
    pub(super) map_path: Vec<(f64, Pose)>,
    /// The map file being written (`save_map`): cells a window evicts go in as they leave.
    pub(super) saved_map: Option<MapWriter>,
    /// The saved map paged in under the memory cap (localizing only).
    pub(super) pager: Option<MapPager>,
    /// Loop closure's thread, when on.
    pub(super) closer: Option<LoopClosure<C>>,
    /// The raw point counts of the last frames read (a scan far smaller is named).
    pub(super) recent_points: std::collections::VecDeque<usize>,
    /// The samples that are not scans that came with the last frame, for its event.
    pub(super) samples: Vec<Sample>,
    /// How well the last used frame's registration pinned its pose down (for a sink's
    /// covariance).
    pub(super) information: Option<PoseInformation>,
    /// The IMU's readings and what they give the frames.
    pub(super) inertial: Inertial,
    /// The floor as the scans' points saw it, for the navigation map (with `navmap` only).
    pub(super) hits: Option<Hits>,
    /// What the map the run started from kept beside it ([`floor_file`]; with `navmap`
    /// only), read at the start: a save during the run may replace that file.
    pub(super) carried_floor: Option<FloorFile>,
    /// What moves, cleared from the map after each fused frame (`--dynamic`).
    pub(super) clearing: Option<Clearing>,
    /// The last used frame's own points, for its event's map update
    /// ([`hand_own_points`](Self::hand_own_points)); `None`: not kept.
    pub(super) own_points: Option<Vec<Point>>,
}

impl<'a, C: Capacity> Run<'a, C> {
    /// A new run into `opts.out` (created if missing); `opts` borrowed (`&RunOptions`) or
    /// owned (`RunOptions`, for a run that outlives its caller's frame).
    pub fn start(
        source: &impl FrameSource,
        opts: impl Into<Cow<'a, RunOptions>>,
    ) -> Result<Self, RunError> {
        let opts = opts.into();
        let setup = Setup::<C>::new(&opts)?;
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
        let opts = opts.into();
        let mut setup = Setup::<C>::new(&opts)?;
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
        let search = match &setup.map_start {
            Some(_) if progress.poses.is_empty() => {
                saved_map::search_from(&map_path, opts.initial_pose, &opts.config)
            }
            _ => None,
        };
        let checkpoint_path = checkpoint::path(&opts.out);
        let mut inertial = Inertial::new::<C>(opts.imu);
        if !progress.imu.is_empty() {
            inertial.restore(&progress.imu).map_err(|why| {
                FileError::at(&checkpoint_path, format!("not a usable checkpoint: {why}"))
            })?;
        }
        let saved_map = match &opts.save_map {
            Some(path) => Some(MapWriter::create(
                path,
                &saved_map::info(&opts.config, &opts.preset, 0),
            )?),
            None => None,
        };
        // The scans' floor grows with the area driven: not in a run whose memory a window
        // bounds (its grid is the mesh's alone, as from a saved map).
        let hits = (opts.navmap.as_ref())
            .filter(|_| setup.window.is_off())
            .map(|n| Hits::new(n.resolution_m, &n.up().0));
        let mut ahead = setup.ahead;
        if hits.is_some() {
            // The floor counts the scan's own points.
            ahead.keep_points();
        }
        let carried_floor = (opts.navmap.as_ref())
            .and(opts.map.as_deref())
            .and_then(|m| floor_file::read_beside(m, &map_path));
        Ok(Run {
            clearing: opts.dynamic.map(Clearing::new),
            hits,
            carried_floor,
            own_points: None,
            closer: setup.closer,
            search,
            map_path,
            saved_map,
            pager: setup.pager,
            opts,
            pipeline: setup.pipeline,
            workers: setup.workers,
            window: setup.window,
            budget: setup.budget,
            spool,
            report,
            checkpoint_path,
            seconds_before: progress.seconds,
            progress,
            timer: StageTimer::new(),
            ahead,
            started: Instant::now(),
            recent_points: Default::default(),
            samples: Vec::new(),
            information: None,
            inertial,
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

    /// From now on a used frame's own points go to its event's map update
    /// ([`MapUpdate::own_points`]; moved, not copied), and a frame filtered ahead keeps them.
    pub fn hand_own_points(&mut self) {
        self.own_points = Some(Vec::new());
        self.ahead.keep_points();
    }

    /// What the sinks are told of the frame `record` describes: its pose at its stamp when it
    /// was used, the samples that came with it, and with `want_map` the map as it changed it
    /// (the whole map and the corrected path when loops were closed with it).
    pub fn event(&mut self, record: FrameRecord, want_map: bool) -> FrameEvent {
        let samples = std::mem::take(&mut self.samples);
        let information = self.information.take();
        let poses = &self.progress.poses;
        let pose = (record.error.is_none())
            .then(|| {
                poses
                    .last()
                    .filter(|(j, _)| *j == record.frame)
                    .map(|(_, p)| *p)
            })
            .flatten();
        let map = match (
            want_map && record.error.is_none(),
            record.loop_closures.is_empty(),
        ) {
            (false, _) => None,
            (true, true) => MapUpdate::of(&self.pipeline, record.frame, record.stamp),
            (true, false) => MapUpdate::after_closure(
                &self.pipeline,
                record.frame,
                record.stamp,
                poses.iter().map(|(_, p)| *p).collect(),
                record.loop_closures.iter().map(|c| c.describe()).collect(),
            ),
        };
        let own = self.own_points.as_mut().map(std::mem::take);
        let map = map.map(|u| MapUpdate {
            own_points: own.unwrap_or_default(),
            ..u
        });
        FrameEvent {
            record,
            pose,
            map,
            samples,
            information: pose.and(information),
        }
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
        let report_bytes = self.report.mark()?;
        self.spool.flush()?;
        let p = &mut self.progress;
        p.next_frame = next;
        p.pipeline_frames = self.pipeline.frames();
        p.motion = self.pipeline.motion().history();
        p.seconds = self.seconds_before + self.started.elapsed().as_secs_f64();
        p.report_bytes = report_bytes;
        p.mesh = self.spool.counts();
        p.imu.clear();
        self.inertial.save(&mut p.imu);
        checkpoint::write(&self.checkpoint_path, p, self.pipeline.map())?;
        Ok(())
    }

    /// Writes the trajectories, the mesh files and `report.json`, removes the spools and the
    /// checkpoint, and sums the run up.
    pub fn finish(mut self, source: &impl FrameSource) -> Result<Summary, RunError> {
        let (pipeline, poses) = (&mut self.pipeline, &mut self.progress.poses);
        let outputs = RunOutputs {
            spool: &mut self.spool,
            saved_map: &mut self.saved_map,
        };
        let loop_closure =
            (self.closer.take()).map(|c| c.finish(pipeline, poses, source.frames(), outputs));
        self.progress.seconds = self.seconds_before + self.started.elapsed().as_secs_f64();
        let Progress {
            poses,
            skipped,
            evicted_cells,
            used_ms,
            seconds,
            ..
        } = self.progress;
        let (health, cost_by_outcome) = self.report.health()?;
        // The scan buffers go before the mesh is welded: writing needs no more than the run.
        drop(std::mem::take(&mut self.ahead));
        let frames_seen = self.pipeline.frames();
        let map = self.pipeline.into_map();
        let out = &self.opts.out;
        // A run that used no frame writes its report (with every frame's reason) and no empty
        // trajectory, mesh or picture.
        if let Some(p) = &self.pager {
            log::info!("map paged: {}", p.stats());
        }
        let stamps: Vec<f64> = poses.iter().map(|(i, _)| source.stamp(*i)).collect();
        let stamped = poses.iter().zip(&stamps).map(|((_, p), t)| (*t, *p));
        let shown_as = self.opts.save_map.as_deref().unwrap_or(out);
        let start = std::mem::take(&mut self.map_path);
        let carried = self.carried_floor.take();
        let floors = scans_floor(&self.opts, &start, &stamps, self.hits.take(), carried);
        saved_map::finish(
            self.saved_map.take(),
            start,
            &map,
            stamped,
            frames_seen,
            shown_as,
        )?;
        let up = self.inertial.navmap_up();
        let (counts, navmap) = write_mesh(self.spool, &map, &self.opts, &poses, up, floors)?;
        let summary = Summary {
            frames: source.frames(),
            used: poses.len(),
            skipped,
            seconds,
            hz: poses.len() as f64 / seconds.max(1e-9),
            threads: self.workers.threads(),
            capacity: C::NAME.to_string(),
            stage_ms: spreads(&used_ms),
            cost_by_outcome,
            mesh_vertices: counts.vertices,
            mesh_triangles: counts.triangles,
            map_cells: map.cell_count(),
            map_layers: map.layer_count(),
            evicted_cells,
            max_layers: self.budget.as_ref().map(|b| b.layers),
            memory_budget: self.budget.map(|b| MemoryBudget {
                peak_mb: memory::peak_rss_bytes().map(memory::mb),
                ..b
            }),
            peak_rss_mb: memory::peak_rss_bytes().map(memory::mb),
            health,
            loop_closure,
            input: source.input_report(),
            navmap,
            imu: self.inertial.summary(),
            dynamic: self.clearing.as_ref().map(Clearing::totals),
            poses,
            stamps,
        };
        Trajectories::new(out).write(&summary)?;
        self.report.write(&summary)?;
        // The run is complete: nothing is left to resume.
        let _ = std::fs::remove_file(&self.checkpoint_path);
        Ok(summary)
    }
}

/// The floor the scans saw: this run's `hits`, what the map the run started from kept beside
/// it (`carried`), and the path the map saved now will have (`start`, the start map's, then
/// this run's `stamps`), which its floor file goes with. A floor file beside the map to be
/// saved goes with the map saved there before: where none is written (no scans' floor) it is
/// removed.
fn scans_floor(
    opts: &RunOptions,
    start: &[(f64, Pose)],
    stamps: &[f64],
    hits: Option<Hits>,
    carried: Option<FloorFile>,
) -> ScansFloor {
    let saved_path = floor_file::MapPath {
        poses: (start.len() + stamps.len()) as u64,
        last_stamp: (stamps.last().or(start.last().map(|(t, _)| t))).map_or(0.0, |t| *t),
    };
    if let (Some(saved), None) = (&opts.save_map, &hits) {
        if let Some(stale) = floor_file::remove_beside(saved) {
            log::info!(
                "removed {}: it went with the map saved before",
                stale.display()
            );
        }
    }
    ScansFloor {
        hits,
        carried,
        saved_path,
    }
}

/// The floor the scans saw, for the navigation map and beside the saved map.
struct ScansFloor {
    /// This run's, moved with the path as it ends.
    hits: Option<Hits>,
    /// What the map the run started from kept beside it.
    carried: Option<FloorFile>,
    /// The path of the map the run saves, which its floor file goes with.
    saved_path: floor_file::MapPath,
}

/// Writes the mesh files, the picture and the navigation map from `spool` with `map`'s cells
/// added; none when no frame was used (`poses` empty). `up` is the IMU's up for the
/// navigation map and what gave it, when it gave one. With `--save-map` and the scans' floor,
/// that floor goes beside the map file ([`floor_file`]).
fn write_mesh(
    mut spool: MeshSpool,
    map: &slamesh_core::map::MeshMap,
    opts: &RunOptions,
    poses: &[(usize, Pose)],
    up: Option<(nalgebra::Vector3<f64>, String)>,
    scans: ScansFloor,
) -> Result<(MeshCounts, Option<NavMapSummary>), RunError> {
    let ScansFloor {
        hits,
        carried,
        saved_path,
    } = scans;
    let (out, used) = (&opts.out, !poses.is_empty());
    spool.add_map(map)?;
    spool.colour_by(opts.mesh_colour);
    if opts.picture && used {
        let path: Vec<Pose> = poses.iter().map(|(_, p)| *p).collect();
        write_topview(&mut spool, &path, &out.join("topview.png"))?;
    }
    let navmap = match (&opts.navmap, used) {
        (Some(how), true) => {
            let path: Vec<_> = poses.iter().map(|(_, p)| p.translation.vector).collect();
            let mut how = how.clone();
            if how.up.is_none() {
                how.up = up;
            }
            if let Some(h) = &hits {
                log::debug!("navigation map: the scans' floor took {} bytes", h.bytes());
            }
            let floors = |each: &mut dyn FnMut(crate::navmap::hits::ScanFloor)| {
                floor_file::each_kept(carried.as_ref(), hits.as_ref(), poses, each)
            };
            let (summary, grid) = crate::navmap::make(&mut spool, &floors, &path, &how, out)?;
            if let (Some(saved), Some(_)) = (&opts.save_map, &hits) {
                let beside = floor_file::beside(saved);
                let n = floor_file::write(&beside, how.resolution_m, saved_path, &floors)?;
                log::info!(
                    "the scans' floor saved to {}: {n} floor cells",
                    beside.display()
                );
            }
            drop(hits);
            summary.map(|s| (s, grid, how.robot))
        }
        _ => None,
    };
    let outputs: Vec<(PathBuf, MeshFormat)> = opts
        .mesh_formats
        .iter()
        .filter(|_| used)
        .map(|&f| (out.join(f.file_name()), f))
        .collect();
    // With a navigation map, its layers on the mesh's vertices.
    let mut layers = (navmap.as_ref()).map(|(_, g, robot)| OnMesh::new(g, *robot));
    let extra = layers.as_mut().map(|l| l as &mut dyn VertexProperties);
    let counts = spool.finish_with(&outputs, extra)?;
    drop(layers);
    Ok((counts, navmap.map(|(s, _, _)| s)))
}
