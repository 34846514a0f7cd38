//! What a run is asked to do ([`RunOptions`], [`Deskew`]) and why it may not start or finish
//! ([`RunError`]).

use crate::formats::trajectory::Trajectory;
use crate::io::error::FileError;
use crate::loop_closure::settings::LoopSettings;
use crate::outputs::mesh_spool::{MeshColour, MeshFormat};
use crate::run::config_file::WindowSettings;
use crate::run::sink::SinkError;
use slamesh_core::{Config, ConfigError};
use std::fmt;
use std::path::PathBuf;

/// How to run. The default is the default configuration, one thread per core, no mesh file,
/// no window, no checkpoints.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Output folder (created if missing).
    pub out: PathBuf,
    /// Pipeline configuration, used as it is: the command fits its default preset's cells to
    /// the first scan's scale ([`crate::run::scale::fit`]: 0.5 m cells indoors), and a caller
    /// running an indoor or hand-held source with [`Config::default`]'s 1.6 m cells should
    /// do the same.
    pub config: Config,
    /// Name of the preset it came from (for the report).
    pub preset: String,
    /// Sliding-window eviction.
    pub window: WindowSettings,
    /// Reconstruction threads (1: serial; 0: one per core).
    pub threads: usize,
    /// Mesh files to write (`mesh.ply`, `mesh.obj`; none: no mesh file).
    pub mesh_formats: Vec<MeshFormat>,
    /// What colours the PLY mesh's vertices.
    pub mesh_colour: MeshColour,
    /// Poses to mesh with instead of estimating them (meshing only): matched to frames by
    /// time when the trajectory has stamps (TUM), by line otherwise.
    pub given_poses: Option<Trajectory>,
    /// What the input was (for the report).
    pub input: String,
    /// Write a checkpoint after every this many frames ([`crate::run::checkpoint`]).
    pub checkpoint_every: Option<usize>,
    /// Continue from the checkpoint in `out` instead of starting over.
    pub resume: bool,
    /// Also write `topview.png`: the mesh from above, coloured by height, with the path.
    pub picture: bool,
    /// Whether to deskew scans whose points carry times.
    pub deskew: Deskew,
    /// A saved map to start from (`--map`, [`crate::run::saved_map`]): the run maps on from
    /// it, in its frame (or only localizes in it, with `localize_only`).
    pub map: Option<PathBuf>,
    /// Register against the map without fusing scans into it (`slamesh localize` without
    /// `--update`).
    pub localize_only: bool,
    /// Where the sensor starts in the map (`--initial-pose`); without it, a run from a saved
    /// map searches the map for the first frame's pose.
    pub initial_pose: Option<InitialPose>,
    /// Write the map to this file at the end (`--save-map`): every cell, those a window
    /// evicted included.
    pub save_map: Option<PathBuf>,
    /// Close loops with these settings ([`crate::loop_closure`]; `None`: off, this struct's
    /// default; the command's default is on where [`RunOptions::loop_closure_unavailable`]
    /// allows). Pair it with `config.map.stale_after_frames` ([`LoopSettings::configure`]).
    pub loop_closure: Option<LoopSettings>,
    /// Also write a navigation map (`--navmap`: Nav2's `map.yaml` + `map.pgm`, the elevation
    /// grids, [`crate::navmap`]) from the mesh at the end.
    pub navmap: Option<crate::navmap::NavMapOptions>,
    /// Clear from the map what the scans see through (`--dynamic`, [`crate::dynamic`]):
    /// cars and people that moved on; `None`: off.
    pub dynamic: Option<slamesh_core::clearing::ClearingConfig>,
    /// What to do with an IMU's readings when the source gives them (`--imu`,
    /// [`crate::inertial`]): by default, use them.
    pub imu: crate::inertial::ImuOptions,
    /// Set (by Ctrl-C, for the command) to end the run after the frame in progress: it writes
    /// what it has, marked as interrupted ([`crate::run::Summary::interrupted`]).
    pub stop: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
}

impl RunOptions {
    /// Why this run cannot close loops, if it cannot. Each rebuild of the map fuses every
    /// scan of the run again into an empty map (or the saved map it started from, loaded
    /// whole: so not both a saved map and a window or memory cap), so it needs a map it may
    /// change (not `localize` without `--update`) and every scan of the run: not a resumed
    /// run's ([`RESUMED_WITHOUT_LOOP_CLOSURE`]). Under a memory cap it also needs room
    /// (`run::window::loop_closure_bytes`): where the cap has none, the run goes on without
    /// it, saying so.
    pub fn loop_closure_unavailable(&self) -> Option<&'static str> {
        self.loop_closure_unavailable_from_start()
            .or(self.resume.then_some(RESUMED_WITHOUT_LOOP_CLOSURE))
    }

    /// [`RunOptions::loop_closure_unavailable`] for the run as it was started: the same
    /// reasons but resuming. A resumed run whose start could close loops was configured for
    /// them ([`LoopSettings::configure`]), and keeps that configuration to resume.
    pub fn loop_closure_unavailable_from_start(&self) -> Option<&'static str> {
        if self.given_poses.is_some() {
            Some("the poses are given")
        } else if self.map.is_some() && self.window.is_windowed() {
            Some("a rebuild loads the saved map whole, so not under a memory cap or window")
        } else if self.localize_only {
            Some("the map is fixed (localize without --update)")
        } else {
            None
        }
    }
}

/// Why a resumed run does not close loops. Its configuration is still the one the run had
/// when it was checkpointed ([`LoopSettings::configure`] included), so that it resumes.
pub const RESUMED_WITHOUT_LOOP_CLOSURE: &str =
    "a resumed run has not kept the scans before its checkpoint, which a rebuild needs";

/// `--initial-pose`: where a run from a saved map starts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum InitialPose {
    /// About here: the first frame's search tries this pose first, then the map's path
    /// ([`crate::run::saved_map`]), so a wrong guess costs a search, not the run.
    Near(slamesh_core::Pose),
    /// Where the map's path ends, moving as it last moved: a session that continues the one
    /// that saved the map, scan for scan as one run over both would (no search).
    MapEnd,
}

/// `--deskew`: whether and how scans whose points carry times are deskewed before
/// registration ([`slamesh_core::deskew`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Deskew {
    /// With the IMU's rotations when its readings cover the sweep ([`Deskew::Imu`]), otherwise
    /// with the motion model ([`Deskew::Motion`]).
    #[default]
    Auto,
    /// With the IMU's rotations at each point's time and the last step's velocity; a sweep
    /// the readings do not cover (or a run without an IMU) falls back to the motion model.
    Imu,
    /// With the motion between the last two used frames, once two were used; the IMU's
    /// readings still give the registration its prior.
    Motion,
    /// Never.
    Off,
}

/// Why a run could not start or finish.
#[derive(Debug)]
pub enum RunError {
    /// The pipeline's configuration is invalid.
    Config(ConfigError),
    /// The worker threads could not be started.
    Threads(rayon::ThreadPoolBuildError),
    /// The memory cap is below what the capacity needs with an empty map.
    MemoryCapTooSmall {
        /// The cap asked for (MB).
        cap_mb: f64,
        /// The capacity class's name ([`Capacity::NAME`](slamesh_core::Capacity::NAME)).
        class: &'static str,
        /// What the capacity needs with an empty map, the process's memory and headroom.
        needed_bytes: usize,
    },
    /// An input or output file could not be read or written.
    File(FileError),
    /// A sink failed ([`crate::run::sink`]); the run's own outputs were written.
    Sink(SinkError),
}

impl fmt::Display for RunError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RunError::Config(e) => write!(f, "configuration: {}: {}", e.field, e.reason),
            RunError::Threads(e) => write!(f, "configuration: threads: {e}"),
            RunError::MemoryCapTooSmall {
                cap_mb,
                class,
                needed_bytes,
            } => write!(
                f,
                "configuration: memory cap {cap_mb} MB is below what the {class} capacity class \
                 needs: {:.0} MB (its scan buffers, a map of two scans' layers, and the rest of \
                 the process); a smaller class (--capacity) needs less, if the scans fit it",
                *needed_bytes as f64 / 1e6
            ),
            RunError::File(e) => write!(f, "{e}"),
            RunError::Sink(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for RunError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            RunError::Config(e) => Some(e),
            RunError::Threads(e) => Some(e),
            RunError::File(e) => Some(e),
            RunError::Sink(e) => Some(e),
            RunError::MemoryCapTooSmall { .. } => None,
        }
    }
}

impl From<FileError> for RunError {
    fn from(e: FileError) -> Self {
        RunError::File(e)
    }
}

/// A run borrows its options ([`Run::start`](crate::run::Run::start) with `&opts`)...
impl<'a> From<&'a RunOptions> for std::borrow::Cow<'a, RunOptions> {
    fn from(opts: &'a RunOptions) -> Self {
        std::borrow::Cow::Borrowed(opts)
    }
}

/// ... or owns them, to outlive the caller's frame (the Python module's pipeline).
impl From<RunOptions> for std::borrow::Cow<'_, RunOptions> {
    fn from(opts: RunOptions) -> Self {
        std::borrow::Cow::Owned(opts)
    }
}
