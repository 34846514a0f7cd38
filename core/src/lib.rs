//! # slamesh-core
//!
//! The `no_std` heart of slamesh, a Rust implementation of SLAMesh (Ruan et al., ICRA 2023):
//! LiDAR odometry that localizes against the triangle mesh it builds.
//!
//! A scan goes through the stages below, one module each; [`pipeline`] composes them and holds
//! no math of its own (docs/design.md §1.1):
//!
//! | stage | module |
//! |---|---|
//! | range filter, voxel down-sampling | [`filter`] |
//! | constant-velocity prediction | [`motion`] |
//! | the IMU's rotation as a prior and for deskewing | [`imu`] |
//! | deskewing a sweep (points' times from their azimuths where a scan has none) | [`deskew`] ([`spin`]) |
//! | up from the accelerometer, to level the map | [`gravity`] |
//! | bucketing points into world-fixed cells | [`bucket`] (keys in [`cell`], sorted by [`sort`]) |
//! | layer choice by PCA | [`pca`] |
//! | Gaussian-process reconstruction of a layer | [`gp`] on the [`lattice`] |
//! | location-indexed association, residual combination | [`associate`] |
//! | Levenberg-Marquardt on SE(3) | [`lm`] (SE(3) helpers in [`math`]) |
//! | inverse-variance map fusion | [`fusion`] into the [`map`] |
//! | triangles | [`mesh`] |
//!
//! The reconstruction's arithmetic is generic over its scalar ([`real`]): `f64` by default,
//! `f32` for a single-precision FPU, chosen by the pipeline's second type parameter.
//!
//! A caller can observe stage boundaries (to time them) through a [`stage::Probe`].
//!
//! ## Guarantees
//! - No panics on input data: bad points are dropped and counted, a full container returns an
//!   error or drops by the rule its module documents.
//! - Bounded memory: every buffer is taken once, when a [`Pipeline`] is built, with the
//!   capacities of its [`Capacity`] type, and never grows ([`bounded`]). The map's hash table
//!   is sized so that it never reallocates ([`map`], [`cell_table`]). The footprint is
//!   [`Capacity::memory_bytes`].
//! - No clock, file, thread or randomness: the same scans give the same poses and mesh.
//!
//! The crate needs no `std`. With the `alloc` feature (default) [`Pipeline::new`] takes its
//! buffers from the global allocator; without it, [`Pipeline::in_storage`] builds a pipeline
//! in memory the caller lends ([`storage`]: a `static` sized at compile time by the capacity
//! type), and nothing in the crate can allocate.
#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
// `!(v < limit)` is how the core rejects NaN together with large values: keep it.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
#![cfg_attr(
    not(test),
    deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)
)]

#[cfg(any(feature = "alloc", test))]
extern crate alloc;

pub mod associate;
pub mod azimuth;
pub mod bounded;
pub mod bucket;
pub mod capacity;
pub mod cell;
pub mod cell_table;
pub mod clearing;
pub mod config;
pub mod deskew;
pub mod executor;
pub mod facing;
pub mod filter;
pub mod fusion;
pub mod gp;
pub mod gravity;
pub mod imu;
pub mod lattice;
pub mod layer;
pub mod lm;
pub mod log;
pub mod map;
pub mod map_file;
pub mod math;
pub mod mesh;
pub mod motion;
pub mod pca;
pub mod pipeline;
pub mod plane;
pub mod random;
pub mod real;
pub mod reconstruct;
pub mod recovery;
pub mod relocalize;
pub mod sort;
pub mod spin;
pub mod stage;
pub mod storage;

pub use capacity::{
    Capacity, KittiCapacity, Lidar16Capacity, Lidar32Capacity, ScanLimits, SmallCapacity,
};
pub use config::{Config, ConfigError};
pub use executor::{Executor, Serial};
pub use math::{Point, Pose};
pub use pipeline::{MapRestart, Pipeline, RegistrationStatus, ScanError, ScanOutcome, ScanStats};
pub use real::Real;
pub use stage::{NoProbe, Probe, Stage};
