//! # slamesh-sim
//!
//! A small ray-casting LiDAR simulator with ground truth, for slamesh's demo, tests and
//! benchmarks; not part of the library a robot links. Deterministic: the same seed gives the
//! same scene, poses and scans.
//!
//! | what | module |
//! |---|---|
//! | the world: boxes, spheres, ground relief; ray casting | [`scene`] |
//! | a spinning multi-beam scanner | [`lidar`] |
//! | true poses and the noisy scans along them | [`drive`] |
//! | an IMU on the scanner, a vibrating body | [`imu`] |
//! | a procedural town and its loop | [`town`] |
//! | an office floor and a walk through it | [`office`] |
//! | a yard with kerbs and ramps, for the navigation maps | [`yard`] |
//! | cars, people and parked cars that leave, and each point's truth | [`traffic`] |
//! | the exact distance to the true surfaces (mesh precision) | [`truth`] |
#![deny(missing_docs)]

pub mod drive;
pub mod imu;
pub mod lidar;
pub mod office;
pub mod scene;
pub mod town;
pub mod traffic;
pub mod truth;
pub mod yard;

pub use drive::{sensor_pose, Drive};
pub use imu::{ImuModel, Vibration};
pub use lidar::Lidar;
pub use scene::{OrientedBox, Scene, Sphere, Terrain};
pub use slamesh_core::random::SplitMix64;
pub use traffic::{Label, Traffic, TrafficCounts};
pub use truth::SurfaceDistance;
