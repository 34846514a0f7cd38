//! What a run's start needs before its first frame, whether it starts anew or resumes: the
//! output folder (made here), the executor, the sliding window and the memory cap's layer
//! budget, the pipeline, and a saved map to start from: loaded whole, or, for localizing under
//! a memory cap, opened for paging ([`crate::localize::pager`]); and the run's stages
//! (`wiring`), whose memory counts under the cap.

use crate::io::error::FileError;
use crate::localize::pager::MapPager;
use crate::outputs::mesh_spool::SET_LAYERS;
use crate::parallel::Workers;
use crate::run::budget::MemoryBudget;
use crate::run::lookahead::LookAhead;
use crate::run::memory;
use crate::run::options::{InitialPose, RunError, RunOptions};
use crate::run::saved_map::{self, MapStart};
use crate::run::window::{CapTooSmall, Window};
use crate::run::wiring;
use crate::stage::lent::{Evict, Windowed};
use crate::stage::Stages;
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
    /// The memory cap's shares (its layer budget among them), when a cap is set.
    pub(crate) budget: Option<MemoryBudget>,
    pub(crate) ahead: LookAhead,
    /// Layers of the pipeline's map (its budget and a scan's worth).
    pub(crate) map_layers: usize,
    /// The run's stages, not yet told the run starts.
    pub(crate) stages: Stages<C>,
}

impl<C: Capacity> Setup<C> {
    /// The start of a run with `opts`, its stages those the options wire then `extra`.
    pub(crate) fn new(opts: &RunOptions, extra: Stages<C>) -> Result<Self, RunError> {
        let out = &opts.out;
        std::fs::create_dir_all(out)
            .map_err(|e| FileError::at(out, format!("cannot create the output folder: {e}")))?;
        let workers = Workers::new(opts.threads).map_err(RunError::Threads)?;
        let mut window = opts.window.rules();
        // With two threads or more, the next frame is read and filtered ahead on the pool;
        // under a cap too tight for the filter's buffers twice, read ahead only.
        let threads = workers.threads() > 1;
        let wanted = opts.loop_closure.is_some() && opts.loop_closure_unavailable().is_none();
        let mut stages = wiring::stages::<C>(opts);
        let Budget {
            memory,
            filter_ahead,
            closing,
        } = layer_budget::<C>(opts, threads, wanted, stages.bytes() + extra.bytes())?;
        let max_layers = memory.as_ref().map(|m| m.layers);
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
        // Asked for where the run cannot close loops: refused, naming why.
        if let Some(closing) = wiring::loop_closure::<C>(opts, wanted && !closing)? {
            stages.push(closing);
        }
        stages.extend(extra);
        Ok(Setup {
            stages,
            map_layers,
            pipeline,
            map_start,
            pager,
            workers,
            window,
            budget: memory,
            ahead: match (threads, filter_ahead) {
                (true, true) => LookAhead::new::<C>(),
                (true, false) => LookAhead::reading_only(),
                _ => LookAhead::off(),
            },
        })
    }
}

/// What a memory cap allows a run.
struct Budget {
    /// The cap's shares, the map's layer budget among them (none without a cap).
    memory: Option<MemoryBudget>,
    /// The next frame is filtered ahead.
    filter_ahead: bool,
    /// Loop closure runs.
    closing: bool,
}

/// The layer budget a memory cap allows (none without a cap), whether the next frame can
/// still be filtered ahead (`threads`: there is a pool to filter on) within it, and whether
/// loop closure (asked for: `closing`) fits too, beside the stages' `stage_bytes`. What gives way first, as the cap tightens:
/// filtering ahead, then loop closure (the run goes on without it, saying what it needs).
fn layer_budget<C: Capacity>(
    opts: &RunOptions,
    threads: bool,
    closing: bool,
    stage_bytes: usize,
) -> Result<Budget, RunError> {
    let Some(cap) = opts.window.memory_cap_mb else {
        return Ok(Budget {
            memory: None,
            filter_ahead: threads,
            closing,
        });
    };
    // The stages' memory (clearing's range image) counts with the rest of the process.
    let (cap_bytes, other) = ((cap * 1e6) as usize, memory::other_bytes() + stage_bytes);
    let too_small = |e: CapTooSmall| RunError::MemoryCapTooSmall {
        cap_mb: cap,
        class: C::NAME,
        needed_bytes: e.needed_bytes,
    };
    // Filtering ahead gives way first, then loop closure.
    let tries = [
        (threads, closing),
        (false, closing),
        (threads, false),
        (false, false),
    ];
    let mut refused: Vec<((bool, bool), CapTooSmall)> = Vec::new();
    let mut fitted = None;
    for (ahead, loops) in tries {
        match Window::max_layers::<C>(cap_bytes, other, ahead, loops) {
            Ok(budget) => {
                fitted = Some((budget, ahead, loops));
                break;
            }
            Err(e) => refused.push(((ahead, loops), e)),
        }
    }
    let Some((max_layers, filter_ahead, fits)) = fitted else {
        return Err(too_small(refused[refused.len() - 1].1));
    };
    // What the cap needed for what gave way: loop closure (filtered in line), or filtering
    // ahead.
    let need = |what: (bool, bool)| {
        let e = refused.iter().find(|r| r.0 == what).map(|r| r.1);
        e.map_or(0.0, |e| e.needed_bytes as f64 / 1e6)
    };
    if closing && !fits {
        log::warn!(
            "memory cap {cap} MB: loop closure is off (with it the {} class needs {:.0} MB)",
            C::NAME,
            need((false, true))
        );
    } else if threads && !filter_ahead {
        log::info!(
            "memory cap {cap} MB: each frame is read ahead but filtered in line \
             (filtering ahead needs a cap of {:.0} MB)",
            need((true, closing))
        );
    }
    let memory = MemoryBudget::of::<C>(cap_bytes, other, max_layers, (filter_ahead, fits));
    log::info!("{}", memory.describe());
    Ok(Budget {
        memory: Some(memory),
        filter_ahead,
        closing: fits,
    })
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

/// A run with `opts` whose map is a window (`window`, over a map of `map_layers` layers), as
/// a stage that rebuilds the map keeps it ([`Windowed`]): the window's rules, and the outputs
/// what leaves the window goes to.
pub(super) fn windowed(opts: &RunOptions, window: Window, map_layers: usize) -> Windowed {
    let set_layers = match window.max_layers {
        Some(_) => memory::CLOSING_SET_LAYERS,
        None => SET_LAYERS,
    };
    let evict: Evict = Box::new(move |map, frame, sensor, spool, saved| {
        window.evict_to(map, frame, sensor, spool, saved)
    });
    Windowed {
        evict,
        map_layers,
        mesh: (opts.window.save_evicted).then(|| {
            let c = &opts.config;
            (opts.out.join("mesh.ply"), c.lattice(), c.mesh, set_layers)
        }),
        save_map: (opts.save_map.as_ref())
            .map(|p| (p.clone(), saved_map::info(&opts.config, &opts.preset, 0))),
        dir: opts.out.clone(),
    }
}
