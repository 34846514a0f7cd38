//! The one list that wires a run's stages ([`crate::stage`]) from its options: the only place
//! in `run/` that names them. A stage is added here and nowhere else in `run/`.
//!
//! In the order they are called: the IMU (always: without readings, or with `--imu off`, it
//! does nothing), clearing what moves (`--dynamic on`: after each fused frame, before the mesh
//! is counted and the window evicts), the navigation map (always: without `--navmap` it only
//! removes a floor file left beside a map saved over), then loop closure (on by default where
//! the run can close loops; added once the memory cap's budget says it has room). Before them
//! all, the search for the pose in a saved map and its pager (every run: a live run may be
//! asked to relocalize), added once the run knows where it starts.

use crate::dynamic::Clearing;
use crate::inertial::stage::ImuStage;
use crate::localize::pager::MapPager;
use crate::localize::search::candidates;
use crate::localize::stage::MapSearch;
use crate::loop_closure::stage::LoopClosureStage;
use crate::navmap::stage::NavMapStage;
use crate::run::options::{InitialPose, RunError, RunOptions};
use crate::stage::{RunStage, Stages};
use slamesh_core::{Capacity, Pose};

/// The stages a run with `opts` has.
pub(super) fn stages<C: Capacity>(opts: &RunOptions) -> Stages<C> {
    let mut stages = Stages::new();
    stages.push(Box::new(ImuStage::new::<C>(opts.imu)));
    if let Some(config) = opts.dynamic {
        stages.push(Box::new(Clearing::new(config)));
    }
    stages.push(Box::new(NavMapStage::new(opts.navmap.clone())));
    stages
}

/// Loop closure's stage when `opts` ask for it, but where the memory cap had no room for it
/// (`gave_way`, said where the cap was split); refused, naming why, where the run cannot close
/// loops ([`RunOptions::loop_closure_unavailable`]).
pub(super) fn loop_closure<C: Capacity>(
    opts: &RunOptions,
    gave_way: bool,
) -> Result<Option<Box<dyn RunStage<C>>>, RunError> {
    match (opts.loop_closure, opts.loop_closure_unavailable()) {
        _ if gave_way => Ok(None),
        (Some(_), Some(reason)) => Err(RunError::Config(slamesh_core::ConfigError {
            field: "loop closure",
            reason,
        })),
        (Some(s), None) => Ok(Some(Box::new(LoopClosureStage::<C>::new(s)))),
        (None, _) => Ok(None),
    }
}

/// The search for the pose in a saved map whose path is `path`, from the first frame unless
/// the run goes on from the map's end (`--initial-pose end`) or resumes after its pose was
/// found (`found`): near the pose given first, then along the path. `pager`: the map is paged
/// under a memory cap.
pub(super) fn map_search<C: Capacity>(
    path: Option<&[(f64, Pose)]>,
    initial: Option<InitialPose>,
    found: bool,
    pager: Option<MapPager>,
    spacing_m: f64,
) -> Box<dyn RunStage<C>> {
    let hint = match initial {
        Some(InitialPose::Near(p)) => Some(p),
        _ => None,
    };
    let search = path
        .filter(|_| !found && initial != Some(InitialPose::MapEnd))
        .map(|path| {
            hint.into_iter()
                .chain(candidates(path, spacing_m))
                .collect()
        });
    Box::new(MapSearch::new(search, pager))
}
