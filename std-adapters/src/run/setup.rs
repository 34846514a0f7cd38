//! What a run's start needs before its first frame, whether it starts anew or resumes: the
//! output folder (made here), the executor, the sliding window and the memory cap's layer
//! budget, the pipeline, and a saved map to start from: loaded whole, or, for localizing under
//! a memory cap, opened for paging ([`crate::run::map_pager`]); and loop closure's thread.

use crate::io::error::FileError;
use crate::loop_closure::LoopClosure;
use crate::parallel::Workers;
use crate::run::lookahead::LookAhead;
use crate::run::map_pager::MapPager;
use crate::run::memory;
use crate::run::options::{InitialPose, RunError, RunOptions};
use crate::run::saved_map::{self, MapStart};
use crate::run::window::{CapTooSmall, Window};
use slamesh_core::motion::ConstantVelocity;
use slamesh_core::{Capacity, Pipeline};
use std::path::Path;

/// See the module docs.
pub(crate) struct Setup<C: Capacity> {
    pub(crate) pipeline: Pipeline<C>,
    /// The saved map the run started from.
    pub(crate) map_start: Option<MapStart>,
    /// The saved map, paged in under the memory cap (localizing only).
    pub(crate) pager: Option<MapPager>,
    pub(crate) workers: Workers,
    pub(crate) window: Window,
    pub(crate) max_layers: Option<usize>,
    pub(crate) ahead: LookAhead,
    /// Loop closure's thread, when on.
    pub(crate) closer: Option<LoopClosure<C>>,
}

impl<C: Capacity> Setup<C> {
    pub(crate) fn new(opts: &RunOptions) -> Result<Self, RunError> {
        let out = &opts.out;
        std::fs::create_dir_all(out)
            .map_err(|e| FileError::at(out, format!("cannot create the output folder: {e}")))?;
        let workers = Workers::new(opts.threads).map_err(RunError::Threads)?;
        let mut window = opts.window.rules();
        // With two threads or more, the next frame is read and filtered ahead on the pool;
        // under a cap too tight for the filter's buffers twice, read ahead only.
        let threads = workers.threads() > 1;
        let (max_layers, filter_ahead) = layer_budget::<C>(opts, threads)?;
        window.max_layers = max_layers;
        let map_layers = max_layers.map_or(C::MAP_LAYERS, Window::map_layers::<C>);
        let mut pipeline =
            Pipeline::<C>::with_map_layers(opts.config, map_layers).map_err(RunError::Config)?;
        pipeline.set_map_updates(!opts.localize_only);
        if opts.localize_only {
            // A fixed map's cells never age: a window would only lose them (the pager, when
            // there is one, keeps the map within the cap).
            window = Window::default();
        }
        let (mut map_start, mut pager) = (None, None);
        if let Some(path) = &opts.map {
            let start = match max_layers.filter(|_| opts.localize_only) {
                Some(budget) => {
                    let p = MapPager::open(path, budget, opts.config.filter.range_max_m)?;
                    let start = paged_start(path, &p, budget);
                    pager = Some(p);
                    start
                }
                None => loaded_start(path, &mut pipeline)?,
            };
            let motion = start_motion(path, &start, opts.initial_pose)?;
            pipeline.restore_progress(start.frames, motion);
            map_start = Some(start);
        }
        let closer = loop_closer(opts)?;
        Ok(Setup {
            closer,
            pipeline,
            map_start,
            pager,
            workers,
            window,
            max_layers,
            ahead: match (threads, filter_ahead) {
                (true, true) => LookAhead::new::<C>(),
                (true, false) => LookAhead::reading_only(),
                _ => LookAhead::off(),
            },
        })
    }
}

/// The layer budget a memory cap allows (none without a cap), and whether the next frame can
/// still be filtered ahead (`threads`: there is a pool to filter on) within it.
fn layer_budget<C: Capacity>(
    opts: &RunOptions,
    threads: bool,
) -> Result<(Option<usize>, bool), RunError> {
    let Some(cap) = opts.window.memory_cap_mb else {
        return Ok((None, threads));
    };
    let (cap_bytes, other) = ((cap * 1e6) as usize, memory::other_bytes());
    let too_small = |e: CapTooSmall| RunError::MemoryCapTooSmall {
        cap_mb: cap,
        class: C::NAME,
        needed_bytes: e.needed_bytes,
    };
    match Window::max_layers::<C>(cap_bytes, other, threads) {
        Ok(budget) => Ok((Some(budget), threads)),
        Err(e) if threads => {
            let budget = Window::max_layers::<C>(cap_bytes, other, false).map_err(too_small)?;
            log::info!(
                "memory cap {cap} MB: each frame is read ahead but filtered in line \
                 (filtering ahead needs a cap of {:.0} MB)",
                e.needed_bytes as f64 / 1e6
            );
            Ok((Some(budget), false))
        }
        Err(e) => Err(too_small(e)),
    }
}

/// A saved map opened for paging within `budget` layers: where it starts (nothing resident).
fn paged_start(path: &Path, p: &MapPager, budget: usize) -> MapStart {
    let f = p.file();
    log::info!(
        "map {}: {} tile blocks, {} poses of path, {:.1} MB, paged by tile \
         within a budget of {budget} layers",
        path.display(),
        f.index.len(),
        f.poses.len(),
        f.bytes as f64 / 1e6
    );
    MapStart {
        frames: f.info.frames,
        path: f.poses.clone(),
        layers: 0,
        bytes: f.bytes,
        load_s: 0.0,
    }
}

/// A saved map loaded whole into `pipeline`'s map.
fn loaded_start<C: Capacity>(
    path: &Path,
    pipeline: &mut Pipeline<C>,
) -> Result<MapStart, RunError> {
    let start = saved_map::load(path, pipeline.map_mut())?;
    log::info!(
        "map {}: {} cells, {} layers, {} poses of path, {:.1} MB, loaded in {:.2} s",
        path.display(),
        pipeline.map().cell_count(),
        start.layers,
        start.path.len(),
        start.bytes as f64 / 1e6,
        start.load_s
    );
    Ok(start)
}

/// The motion model a run from a saved map starts with: moving as the map's path last moved
/// (`--initial-pose end`), else at rest.
fn start_motion(
    path: &Path,
    start: &MapStart,
    initial: Option<InitialPose>,
) -> Result<ConstantVelocity, RunError> {
    if initial != Some(InitialPose::MapEnd) {
        return Ok(ConstantVelocity::new());
    }
    let [.., before, last] = start.path[..] else {
        return Err(FileError::at(
            path,
            "--initial-pose end: the map's path has fewer than two poses",
        )
        .into());
    };
    Ok(ConstantVelocity::from_history(Some(before.1), Some(last.1)))
}

/// Loop closure's thread when asked for; refused, naming why, where the run cannot close
/// loops ([`RunOptions::loop_closure_unavailable`]).
fn loop_closer<C: Capacity>(opts: &RunOptions) -> Result<Option<LoopClosure<C>>, RunError> {
    match (opts.loop_closure, opts.loop_closure_unavailable()) {
        (Some(_), Some(reason)) => Err(RunError::Config(slamesh_core::ConfigError {
            field: "loop closure",
            reason,
        })),
        (Some(s), None) => Ok(Some(LoopClosure::start(
            opts.config,
            s,
            &opts.out.join(".loop-closure.scans"),
            opts.map.as_deref(),
        )?)),
        (None, _) => Ok(None),
    }
}
