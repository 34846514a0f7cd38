//! Named mutations (issue 87): faults the test suite must catch, each a switch at one place
//! in the code, compiled only with the feature `mutants` and chosen at run time by
//! `SLAMESH_MUTANT=NAME` (`tools/named_mutations.sh` runs each against the tests that must
//! fail). Without the feature [`on`] is `false` at compile time and every switch is gone.
//!
//! Why switches rather than patches: one build serves every mutation, where a patch a mutation
//! rebuilt the crate and its tests each time (about 90 s here); cargo-mutants, which patches,
//! is the tool for the wide sweeps.

/// The mutations, each with what it breaks.
pub const NAMES: [(&str, &str); 5] = [
    (
        "edge-band",
        "navigation map: ground beside an obstacle free again (navmap/grid/occupancy.rs)",
    ),
    (
        "gyro-scale",
        "IMU: every gyro reading 10 % too large (inertial, as taken)",
    ),
    (
        "closure-unverified",
        "loop closure: a revisit's search taken without its checks (loop_closure/detect.rs)",
    ),
    (
        "stamp-f64",
        "ROS 2 node: replies stamped through f64 seconds, not the scan's nanoseconds",
    ),
    (
        "window-never-evicts",
        "sliding window: no cell ever evicted (run/window.rs)",
    ),
];

/// Whether mutation `name` is on (`SLAMESH_MUTANT=name`, with the feature `mutants`).
#[cfg(feature = "mutants")]
pub fn on(name: &str) -> bool {
    static CHOSEN: std::sync::OnceLock<Option<String>> = std::sync::OnceLock::new();
    let chosen = CHOSEN.get_or_init(|| std::env::var("SLAMESH_MUTANT").ok());
    chosen.as_deref() == Some(name)
}

/// Whether mutation `name` is on: never, without the feature `mutants`.
#[cfg(not(feature = "mutants"))]
#[inline(always)]
pub const fn on(_name: &str) -> bool {
    false
}
