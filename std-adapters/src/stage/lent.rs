//! What a run lends its stages beyond a frame: its window, for a stage that rebuilds the map
//! as the run keeps it ([`Windowed`]), and, between frames, its pipeline, trajectory and
//! outputs, for a stage that moves them all ([`Between`]: a loop closed).
//!
//! Owns nothing: each is a view of the run's own state, made by the run for one call.

use crate::formats::map_file::{MapInfo, MapWriter};
use crate::io::error::FileError;
use crate::outputs::mesh_spool::MeshSpool;
use slamesh_core::config::MeshConfig;
use slamesh_core::lattice::Lattice;
use slamesh_core::map::MeshMap;
use slamesh_core::{Capacity, Pipeline, Pose};
use std::path::PathBuf;

/// The run's window rules after frame `frame` seen from a pose, applied to a map; what leaves
/// goes to the spool and the map file when given. Returns the cells evicted.
pub type Evict = Box<
    dyn FnMut(
            &mut MeshMap,
            u32,
            &Pose,
            Option<&mut MeshSpool>,
            Option<&mut MapWriter>,
        ) -> Result<usize, FileError>
        + Send,
>;

/// A run whose map is a window (a memory cap, an age or a radius), as a stage that rebuilds
/// the map keeps it: the window's rules, the map's size, and the outputs what leaves the
/// window goes to.
pub struct Windowed {
    /// The run's window rules (`run::window::Window::evict_to`).
    pub evict: Evict,
    /// Layers of the run's map (its budget and a scan's worth): a rebuilt map replaces it.
    pub map_layers: usize,
    /// The run's mesh file (`mesh.ply`), its lattice, what it shows and the layers welded
    /// together (`MeshSpool::set_layers`). `None`: the run does not spool what leaves its
    /// window (`--save-evicted` not given).
    pub mesh: Option<(PathBuf, Lattice, MeshConfig, usize)>,
    /// The map file the run saves (`--save-map`) and what its header says.
    pub save_map: Option<(PathBuf, MapInfo)>,
    /// The output folder (a stage's own files meanwhile go there).
    pub dir: PathBuf,
}

/// The run's outputs that grow as cells leave a windowed map, which a stage may replace.
pub struct RunOutputs<'a> {
    /// The spool of the run's mesh.
    pub spool: &'a mut MeshSpool,
    /// The map file being saved, if any.
    pub saved_map: &'a mut Option<MapWriter>,
}

/// The run between frames, lent to a stage that may move it as a whole
/// ([`RunStage::between`](super::RunStage::between)).
pub struct Between<'a, C: Capacity> {
    /// The pipeline: its map and motion model.
    pub pipeline: &'a mut Pipeline<C>,
    /// The trajectory so far, by frame, in order.
    pub poses: &'a mut [(usize, Pose)],
    /// The frame about to run (at the run's end, one past the last run).
    pub next_frame: usize,
    /// The outputs a rebuilt map replaces.
    pub outputs: RunOutputs<'a>,
}
