//! The one list that wires a run's stages ([`crate::stage`]) from its options: the only place
//! in `run/` that names them. A stage is added here and nowhere else in `run/`.
//!
//! In the order they are called: the IMU (always: without readings, or with `--imu off`, it
//! does nothing), clearing what moves (`--dynamic on`: after each fused frame, before the mesh
//! is counted and the window evicts), the navigation map (always: without `--navmap` it only
//! removes a floor file left beside a map saved over), then loop closure (on by default where
//! the run can close loops; added once the memory cap's budget says it has room).

use crate::dynamic::Clearing;
use crate::inertial::stage::ImuStage;
use crate::loop_closure::stage::LoopClosureStage;
use crate::navmap::stage::NavMapStage;
use crate::run::options::{RunError, RunOptions};
use crate::stage::{RunStage, Stages};
use slamesh_core::Capacity;

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
