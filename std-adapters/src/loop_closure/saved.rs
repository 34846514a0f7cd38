//! The saved map a run started from (`run --map FILE`, `localize --update`), as loop closure
//! needs it (docs/design.md §1.14): its path, where a revisit of the earlier session is looked
//! for; its cells near such a place, the local map a revisit is checked in; and the whole map,
//! which a rebuild starts from (the saved cells stay where they are, the run's own scans are
//! fused again at their corrected poses).
//!
//! The file is read, never written; tiles are loaded on demand (a check needs a few).

use crate::formats::map_file::{tile_distance, MapFile};
use crate::io::error::FileError;
use slamesh_core::cell::CellKey;
use slamesh_core::map::MeshMap;
use slamesh_core::map_file::{tile_of, TILE_CELLS};
use slamesh_core::Pose;
use std::collections::BTreeSet;
use std::path::Path;

/// A saved map opened for loop closure.
pub struct SavedMap {
    file: MapFile,
    /// The scans fused into it: the run's pipeline counts on from there.
    pub frames: u32,
    /// Its path: the earlier session's sensor poses, in the map's frame.
    pub path: Vec<Pose>,
}

impl SavedMap {
    /// Opens the map file at `path` (its header, index and path checked).
    pub fn open(path: &Path) -> Result<Self, FileError> {
        let mut file = MapFile::open(path)?;
        let poses = std::mem::take(&mut file.poses);
        Ok(Self {
            frames: file.info.frames,
            path: poses.into_iter().map(|(_, p)| p).collect(),
            file,
        })
    }

    /// Loads every cell into `map` (a rebuild's start); returns the layers loaded.
    pub fn load_all(&mut self, map: &mut MeshMap) -> Result<usize, FileError> {
        self.file.load_all(map)
    }

    /// Loads into `map` the tiles that come within `margin_m` of any of `places` (a check's
    /// local map); returns the layers loaded.
    pub fn load_near(
        &mut self,
        places: &[Pose],
        margin_m: f64,
        map: &mut MeshMap,
    ) -> Result<usize, FileError> {
        let cell = self.file.info.lattice.cell_size;
        let tile_m = cell * f64::from(TILE_CELLS);
        let reach = (margin_m / tile_m).ceil() as i32 + 1;
        let mut tiles = BTreeSet::new();
        for p in places {
            let at = p.translation.vector;
            let Some(home) = CellKey::containing(&at, cell).map(|k| tile_of(&k)) else {
                continue;
            };
            for dx in -reach..=reach {
                for dy in -reach..=reach {
                    for dz in -reach..=reach {
                        let t = CellKey::new(home.x + dx, home.y + dy, home.z + dz);
                        if tile_distance(&t, tile_m, &at) <= margin_m {
                            tiles.insert(t);
                        }
                    }
                }
            }
        }
        let mut layers = 0;
        for t in tiles {
            layers += self.file.load_tile(t, map)?;
        }
        Ok(layers)
    }
}
