//! A run: frames in, poses and a mesh out, with everything the command writes and the rules
//! that keep a long run small.
//!
//! | what | module |
//! |---|---|
//! | configuration files: presets, parameters, the window's settings | [`config_file`] |
//! | why a configuration or one of its values was refused | [`config_error`] |
//! | the capacity classes and how to choose one | [`capacity`] |
//! | the run loop: start or resume, a step per frame | [`session`] |
//! | the run's end: the map file, the stages' files, the mesh, the summary, the report | `finish` |
//! | one frame as named stages: read, prepare, register, update the map, record | `step` |
//! | a frame's scan on its way to the pipeline: read, deskewed, checked, its given pose or prior | `prepare` |
//! | what a frame's event carries beside its record, from its step to its event | `event` |
//! | why a frame was skipped | [`frame_error`] |
//! | a live source's requests between frames: save the map, relocalize | `requests` |
//! | one way out: what a run produces, fanned out to its sinks (bounded queues for slow ones) | [`sink`] |
//! | the per-frame records, the summary, the frames' health | [`report`] |
//! | what became of a frame: its registration status, or skipped | [`status`] |
//! | the run's own files as sinks: `report.json`, the trajectories | [`files`] |
//! | time per stage | [`timing`] |
//! | sliding-window eviction and the memory cap | [`window`] ([`memory`]) |
//! | saving and resuming a killed run | [`checkpoint`] |
//! | starting from a saved map: loading it, where to search for the first pose | [`saved_map`] |
//! | what a start needs: folder, executor, window, pipeline, the saved map | `setup` |
//! | the one list that wires the run's stages ([`crate::stage`]) from its options | `wiring` |

pub mod budget;
pub mod capacity;
pub mod checkpoint;
pub mod config_error;
pub mod config_file;
mod event;
pub mod files;
mod finish;
pub mod frame_error;
pub mod lookahead;
pub mod memory;
pub mod options;
mod prepare;
pub mod report;
mod requests;
pub mod saved_map;
pub mod scale;
pub mod session;
mod setup;
pub mod sink;
pub mod status;
mod step;
pub mod timing;
pub mod window;
mod wiring;

pub use crate::sources::{FrameSource, Input, Sample};
pub use frame_error::{FrameError, FrameFault};
pub use report::{FrameRecord, Summary};
pub use session::{run, run_to, run_with, Run, RunError, RunOptions};
pub use sink::{FrameEvent, Sink, Sinks};
pub use status::FrameStatus;
