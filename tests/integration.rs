//! The integration tests, in one binary: one link, one build of the shared helpers, and one
//! copy of the pipeline's generic code for the capacities they share, where a binary a file
//! built and linked them some twenty times over. Each module is the file of its name beside
//! this one; `cargo test --test integration packets::` runs one of them.
//!
//! Not here: the tests that measure their own process (`memory`, `memory_64`: resident
//! memory; `no_allocation`: a counting global allocator) and the live view's (`view`, behind
//! its feature). Each has a binary of its own.

mod common;

mod architecture;
mod checkpoint;
mod closure_checks;
mod command;
mod command_outputs;
mod degenerate;
mod demo;
mod deskew;
mod docs_examples;
mod dynamic;
mod first_scan;
mod hard_motion;
mod health;
mod imu;
mod imu_data;
mod input_kinds;
mod kitti_odometry;
mod loop_closure;
mod map_persistence;
mod merge;
mod nav2_map;
mod navmap;
mod navmap_command;
mod navmap_kerbs;
mod ouster;
mod packets;
mod parallel;
mod pictures;
mod readers;
mod recordings;
mod scale;
mod single_precision;
mod sinks;
mod stages;
mod synthetic_registration;
