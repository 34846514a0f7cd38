//! The checkpoint reader on arbitrary bytes (`run --resume`): the progress, the map and the
//! stages' state (the IMU's) are checked as they are read; whatever loads fits the map it
//! went into.
#![no_main]

use libfuzzer_sys::fuzz_target;
use slamesh::inertial::stage::ImuStage;
use slamesh::inertial::ImuOptions;
use slamesh::run::checkpoint;
use slamesh::stage::Stages;
use slamesh_core::lattice::Lattice;
use slamesh_core::map::MeshMap;
use slamesh_core::KittiCapacity;

fuzz_target!(|data: &[u8]| {
    let lattice = Lattice {
        cell_size: 1.6,
        full_cover: true,
    };
    let mut map = MeshMap::with_capacity(256, 512, lattice);
    let Ok(progress) = checkpoint::parse(data, &mut map) else {
        return;
    };
    assert!(map.cell_count() <= 256);
    let fresh = || {
        let mut stages = Stages::<KittiCapacity>::new();
        stages.push(Box::new(ImuStage::new::<KittiCapacity>(ImuOptions::default())));
        stages
    };
    let mut stages = fresh();
    if stages.restore(&progress.stages).is_ok() {
        // What was restored saves, and that restores to the same state.
        let mut saved = Vec::new();
        stages.save(&mut saved);
        let mut back = fresh();
        assert_eq!(back.restore(&saved), Ok(()));
        let mut again = Vec::new();
        back.save(&mut again);
        assert_eq!(again, saved);
        let _ = back.summaries();
    }
});
