//! Loop closure in a run whose map is a window (a memory cap, an age or a radius;
//! docs/design.md §1.14, "Under a memory cap"): the rebuild at the corrected poses keeps the
//! run's window as the run does, and what leaves it streams into outputs of the rebuild's
//! own (the mesh's spool, the map file being saved) that replace the run's when the rebuilt
//! map does: the cells that left the run's map before a correction are written again at the
//! corrected poses, none at the old ones.
//!
//! Owns the rebuild's outputs (`RebuiltOutputs`) and their swap into the run's (`replace`;
//! the run's window and outputs are what it lends its stages, [`crate::stage::lent`]), and
//! the bytes the thread adds under a cap ([`engine_bytes`]). Memory: the thread keeps one
//! pipeline with half the capacity's scan buffers ([`engine_limits`]: it fuses and searches
//! filtered scans only) and one map the size of the run's, which holds the local map of a
//! check or the map being rebuilt, never both: no check runs while a rebuild does.

use crate::formats::map_file::MapWriter;
use crate::io::error::FileError;
use crate::outputs::mesh_spool::MeshSpool;
use crate::stage::lent::{RunOutputs, Windowed};
use slamesh_core::{Capacity, ScanLimits};
use std::path::{Path, PathBuf};

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
    pub(crate) fn create(s: &Windowed, n: usize) -> Result<Self, FileError> {
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

/// Puts a rebuild's outputs `r` in place of the run's `outputs`, whose files are removed.
pub(crate) fn replace(outputs: &mut RunOutputs<'_>, r: RebuiltOutputs) -> Result<(), FileError> {
    if let (Some(spool), Some(target)) = (r.spool, &r.target) {
        drop(std::mem::replace(outputs.spool, spool));
        outputs.spool.move_to(target)?;
    }
    if let Some(w) = r.saved_map {
        if let Some(old) = outputs.saved_map.replace(w) {
            old.discard();
        }
    }
    Ok(())
}

/// Where rebuild number `n` of a run writing into `dir` spools its mesh until it replaces the
/// run's.
fn spool_path(dir: &Path, n: usize) -> PathBuf {
    dir.join(format!(".loop-closure.rebuild-{n}.ply"))
}
