//! # slamesh
//!
//! The std side of slamesh: file readers and evaluation around the `no_std`
//! [`slamesh_core`] pipeline.
//!
//! - [`kitti`]: KITTI odometry `.bin` scans, `poses.txt` and `calib.txt`.
//! - [`eval`]: odometry error metrics against reference poses.
//! - [`parallel`]: the reconstruction loop on a rayon pool.
//! - [`sim`]: a ray-casting LiDAR simulator for tests with ground truth.
#![deny(missing_docs)]

pub mod eval;
pub mod kitti;
pub mod parallel;
pub mod sim;

pub use slamesh_core as core;
