//! A revisit's checks (docs/design.md §1.14, `loop_closure::detect`): a keyframe's scan searched
//! in the local map of the frames near it is a closure only when the search vouches for the
//! pose it found.

use slamesh::loop_closure::settings::LoopSettings;
use slamesh::run::FrameSource;
use slamesh_core::{Config, KittiCapacity, Pose};
use slamesh_sim::Drive;

/// A revisit's checks (`detect::search`): the search of a keyframe's scan in the local map of
/// the frames near it is a closure only when the search settled on a pose it could vouch for,
/// within the drift's reach. A scan of the same street is found where it was taken; a scan of
/// another place entirely (the office) searched in the street's map is no closure, whatever
/// pose the search ended on. (The named mutation `closure-unverified`, which takes every
/// search's pose, fails this.)
#[test]
fn a_revisit_is_a_closure_only_when_the_search_vouches_for_it() {
    use slamesh::loop_closure::detect::{search, verify, Past, Revisit};
    let s = LoopSettings::default();
    let mut config = Config::default();
    s.configure(&mut config);
    let mut pipeline = slamesh_core::Pipeline::<KittiCapacity>::new(config).unwrap();
    let mut street = Drive::town(12, 5);
    let to_first = street.poses[0].inverse();
    let truth: Vec<Pose> = street.poses.iter().map(|p| to_first * p).collect();
    let past: Vec<Past> = (0..10)
        .map(|index| Past {
            index,
            pose: truth[index],
            travelled_m: (truth[index].translation.vector - truth[0].translation.vector).norm(),
        })
        .collect();
    let revisit = Revisit {
        near: past[4..8].to_vec(),
        submap: past.clone(),
    };
    // The keyframe: frame 6 again, 200 m of path later, the odometry 0.4 m off.
    let mut pose = truth[6];
    pose.translation.vector.x += 0.4;
    let travelled = 200.0;
    let same = street.read(6).unwrap();
    let found = verify(&s, &mut pipeline, &same, &pose, travelled, &revisit, |i| {
        street.read(i)
    })
    .unwrap()
    .expect("the street's own scan found in its map");
    let off = (found.pose.translation.vector - truth[6].translation.vector).norm();
    assert!(off < 0.1, "found {off:.3} m from where the scan was taken");
    // The office's first scan, searched in the same local map (still built).
    let elsewhere = Drive::office(1, 5).read(0).unwrap();
    let taken = search(&s, &mut pipeline, &elsewhere, &pose, travelled, &revisit);
    assert!(
        taken.is_none(),
        "another place's scan taken as a closure: {:?}",
        taken.map(|v| (v.pose.translation.vector, v.found.outcome.status))
    );
}
