//! The one list that wires a run's stages ([`crate::stage`]) from its options: the only place
//! in `run/` that names them. A stage is added here and nowhere else in `run/`.
//!
//! In the order they are called: the IMU (always: without readings, or with `--imu off`, it
//! does nothing), clearing what moves (`--dynamic on`: after each fused frame, before the mesh
//! is counted and the window evicts), then the navigation map (always: without `--navmap` it
//! only removes a floor file left beside a map saved over).

use crate::dynamic::Clearing;
use crate::inertial::stage::ImuStage;
use crate::navmap::stage::NavMapStage;
use crate::run::options::RunOptions;
use crate::stage::Stages;
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
