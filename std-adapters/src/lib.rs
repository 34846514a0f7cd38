//! # slamesh
//!
//! The std side of slamesh around the `no_std` [`slamesh_core`] pipeline. Its rooms follow
//! the data flow, lowest first; a room imports only from rooms below it (docs/design.md §2.1,
//! checked by `tests/architecture.rs`):
//!
//! | concern | module |
//! |---|---|
//! | file errors and write-then-rename | [`io`] |
//! | the core's loops on several threads | [`parallel`] |
//! | named mutations the tests must catch (feature `mutants`) | [`mutants`] |
//! | file formats, one module each, reader and writer together | [`formats`] |
//! | one way in: where frames come from (folders, recordings, captures, live packets) | [`sources`] |
//! | what a run writes beside its report: the mesh, the picture | [`outputs`] |
//! | what works inside a run beside registration, plugged in: the stage interface | [`stage`] |
//! | a run: its stages, sinks, configuration, report, window, checkpoint | [`run`] |
//! | odometry and mesh accuracy | [`eval`] |
//! | loop closure: revisits found, the pose graph, the map rebuilt | [`loop_closure`] |
//! | a pose found in a saved map, the map paged under a memory cap | [`localize`] |
//! | two saved maps made one (`slamesh merge`) | [`merge`] |
//! | the IMU in a run: its readings, the prior and the deskew they give | [`inertial`] |
//! | the simulated demo (feature `sim`) | `demo` |
//! | the `slamesh` command, one file per subcommand (feature `cli`) | `cli` |
//! | the live view and its recording for the Foxglove app (feature `view`) | `view` |
//!
//! The `slamesh` command (`src/main.rs`, which calls [`cli::main`]) is built on these; the
//! Python module (`python/`) runs the same subcommands through [`cli::run_args`]. The simulator is its own crate, `slamesh-sim`, linked only with the `sim` feature
//! (on by default, for `slamesh demo`); a robot's build can leave it out with
//! `default-features = false`.
#![deny(missing_docs)]

#[cfg(feature = "cli")]
pub mod cli;
#[cfg(feature = "sim")]
pub mod demo;
pub mod dynamic;
pub mod eval;
pub mod formats;
pub mod inertial;
pub mod io;
pub mod localize;
pub mod loop_closure;
pub mod merge;
pub mod mutants;
pub mod navmap;
pub mod outputs;
pub mod parallel;
#[cfg(feature = "ros2")]
pub mod ros2;
pub mod run;
pub mod sources;
pub mod stage;
#[cfg(feature = "view")]
pub mod view;

#[cfg(test)]
mod test_support;

pub use io::FileError;
pub use slamesh_core as core;
