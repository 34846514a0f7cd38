//! # slamesh
//!
//! The std side of slamesh around the `no_std` [`slamesh_core`] pipeline. Its folders follow
//! the data flow:
//!
//! | concern | module |
//! |---|---|
//! | readers and writers, one module per format | [`io`] |
//! | the core's loops on several threads | [`parallel`] |
//! | a run: frame source, run loop, report, window, checkpoint | [`run`] |
//! | odometry and mesh accuracy | [`eval`] |
//! | loop closure: revisits found, the pose graph, the map rebuilt | [`loop_closure`] |
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
pub mod eval;
pub mod io;
pub mod loop_closure;
pub mod parallel;
pub mod run;
#[cfg(feature = "view")]
pub mod view;

#[cfg(test)]
mod test_support;

pub use io::FileError;
pub use slamesh_core as core;
