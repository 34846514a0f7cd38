//! # slamesh
//!
//! The std side of slamesh around the `no_std` [`slamesh_core`] pipeline: file formats, the
//! parallel cell loop, sliding-window eviction, runs with their outputs, evaluation, a
//! simulator, and the `slamesh` command (`src/main.rs`).
//!
//! | concern | module |
//! |---|---|
//! | errors naming the file, line and reason | [`file_error`] |
//! | scan inputs: folders of `.bin`/`.pcd`/`.ply`, natural order | [`scans`] ([`kitti`], [`pcd`] with [`lzf`], [`ply`]) |
//! | trajectories (KITTI, TUM) | [`trajectory`] |
//! | the mesh on disk (PLY, OBJ) | [`mesh_file`] |
//! | write-then-rename | [`atomic`] |
//! | TOML configuration | [`config_file`] |
//! | reconstruction on several threads | [`parallel`] |
//! | sliding-window eviction and the memory cap | [`window`] ([`memory`]) |
//! | time per stage | [`timing`] |
//! | a run and its outputs | [`session`]; the simulated demo [`demo`] |
//! | resuming a killed run | [`checkpoint`] |
//! | a picture of the mesh from above | [`topview`] |
//! | odometry metrics | [`eval`] |
//! | mesh precision, recall and F-score | [`mesh_eval`] |
//! | a ray-casting LiDAR simulator | [`sim`], its procedural town [`town`] |
#![deny(missing_docs)]

pub mod atomic;
pub mod checkpoint;
pub mod config_file;
pub mod demo;
pub mod eval;
pub mod file_error;
pub mod kitti;
pub mod lzf;
pub mod memory;
pub mod mesh_eval;
pub mod mesh_file;
pub mod parallel;
pub mod pcd;
pub mod ply;
pub mod scans;
pub mod session;
pub mod sim;
pub mod timing;
pub mod topview;
pub mod town;
pub mod trajectory;
pub mod window;

#[cfg(test)]
mod test_support;

pub use file_error::FileError;
pub use slamesh_core as core;
