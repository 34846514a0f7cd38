//! Loop closure in a run whose map is a window (a memory cap, an age or a radius;
//! docs/design.md §1.14, "Under a memory cap"): the rebuild at the corrected poses keeps the
//! run's window as the run does, and what leaves it streams into outputs of the rebuild's
//! own (the mesh's spool, the map file being saved) that replace the run's when the rebuilt
//! map does: the cells that left the run's map before a correction are written again at the
//! corrected poses, none at the old ones.
//!
//! Owns what the loop-closure thread needs of the run for that ([`Streaming`]), the
//! rebuild's outputs (`RebuiltOutputs`) and their swap into the run's ([`RunOutputs`]), and
//! the bytes the thread adds under a cap ([`engine_bytes`]). Memory: the thread keeps one
//! pipeline with half the capacity's scan buffers ([`engine_limits`]: it fuses and searches
//! filtered scans only) and one map the size of the run's, which holds the local map of a
//! check or the map being rebuilt, never both: no check runs while a rebuild does.

use crate::formats::map_file::{MapInfo, MapWriter};
use crate::io::error::FileError;
use crate::outputs::mesh_spool::MeshSpool;
use slamesh_core::config::MeshConfig;
use slamesh_core::lattice::Lattice;
use slamesh_core::map::MeshMap;
use slamesh_core::{Capacity, Pose, ScanLimits};
use std::path::{Path, PathBuf};

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

/// What the loop-closure thread needs of a windowed run (see the module docs).
pub struct Streaming {
    /// The run's window rules (`run::window::Window::evict_to`).
    pub evict: Evict,
    /// Layers of the run's map (its budget and a scan's worth): the rebuilt map replaces it.
    pub map_layers: usize,
    /// The run's mesh file (`mesh.ply`), its lattice, what it shows and the layers welded
    /// together (`MeshSpool::set_layers`): the rebuild's spool is made so, and takes the run's
    /// spool files' names when it replaces the run's. `None`: the run does not spool what
    /// leaves its window (`--save-evicted` not given).
    pub mesh: Option<(PathBuf, Lattice, MeshConfig, usize)>,
    /// The map file the run saves (`--save-map`) and what its header says.
    pub save_map: Option<(PathBuf, MapInfo)>,
    /// Where the rebuild's spool files go meanwhile (the output folder).
    pub dir: PathBuf,
}

/// The scan buffers of the loop-closure thread's pipeline in a windowed run: half the
/// capacity's. Its scans are the run's filtered ones, about a third of a raw scan's points
/// (19 419 at most of 60 629 on the 1 000-frame town), and at most 1 247 cells and 1 354
/// layers there of the 32-beam class's 8 192 and 12 288; a scan past them is cut as the
/// capacity's rules say, and counted.
pub fn engine_limits<C: Capacity>() -> ScanLimits {
    ScanLimits::of::<C>().divided_by(2)
}

/// Bytes the loop-closure thread's pipeline holds in a windowed run whose map holds
/// `map_layers` layers: its scan buffers ([`engine_limits`]) and one map that size.
pub fn engine_bytes<C: Capacity>(map_layers: usize) -> usize {
    engine_limits::<C>().pipeline_bytes::<C>(map_layers)
}

/// A rebuild's outputs: what left its window, at the corrected poses.
pub(crate) struct RebuiltOutputs {
    pub(crate) spool: Option<MeshSpool>,
    pub(crate) saved_map: Option<MapWriter>,
    /// The run's mesh file, whose spool names the spool takes.
    target: Option<PathBuf>,
}

impl RebuiltOutputs {
    /// Outputs for rebuild number `n` (each has files of its own until it replaces the run's).
    pub(crate) fn create(s: &Streaming, n: usize) -> Result<Self, FileError> {
        let spool = match &s.mesh {
            Some((_, lattice, shown, set_layers)) => {
                let mut spool = MeshSpool::new(&spool_path(&s.dir, n), *lattice, shown)?;
                spool.set_layers(*set_layers);
                Some(spool)
            }
            None => None,
        };
        let saved_map = match &s.save_map {
            Some((path, info)) => Some(MapWriter::create_staged(
                path,
                info,
                &format!("rebuild-{n}"),
            )?),
            None => None,
        };
        Ok(Self {
            spool,
            saved_map,
            target: s.mesh.as_ref().map(|m| m.0.clone()),
        })
    }
}

/// The run's outputs a correction may replace.
pub struct RunOutputs<'a> {
    /// The spool of the run's mesh.
    pub spool: &'a mut MeshSpool,
    /// The map file being saved, if any.
    pub saved_map: &'a mut Option<MapWriter>,
}

impl RunOutputs<'_> {
    /// Puts the rebuild's outputs in place of the run's, whose files are removed.
    pub(crate) fn replace(&mut self, r: RebuiltOutputs) -> Result<(), FileError> {
        if let (Some(spool), Some(target)) = (r.spool, &r.target) {
            drop(std::mem::replace(self.spool, spool));
            self.spool.move_to(target)?;
        }
        if let Some(w) = r.saved_map {
            if let Some(old) = self.saved_map.replace(w) {
                old.discard();
            }
        }
        Ok(())
    }
}

/// Where rebuild number `n` of a run writing into `dir` spools its mesh until it replaces the
/// run's.
fn spool_path(dir: &Path, n: usize) -> PathBuf {
    dir.join(format!(".loop-closure.rebuild-{n}.ply"))
}
