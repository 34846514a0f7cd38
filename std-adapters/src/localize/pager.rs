//! Paging a saved map under a memory cap: `slamesh localize --memory-cap MB` keeps only the
//! tiles near the sensor resident and reads the others from the map file by tile as the sensor
//! moves (docs/design.md §1.12).
//!
//! Owns the open [`MapFile`] and the set of resident tiles. [`MapPager::around`] makes the map
//! hold the tiles nearest to a position, nearest first, as many as the layer budget allows and
//! none beyond the scan's reach; the others leave the map. A tile's layers are bounded before
//! it is read by its blocks' lengths (a layer takes at least 288 bytes), so the budget holds
//! whatever the tiles hold. The file's index (24 bytes a tile block) and the set of resident
//! tiles are the only memory besides the map. Only a map that takes no updates is paged: what
//! leaves is what the file holds.

use crate::formats::map_file::{tile_distance, MapFile};
use crate::io::error::FileError;
use slamesh_core::cell::CellKey;
use slamesh_core::map::MeshMap;
use slamesh_core::map_file::{tile_of, TILE_CELLS};
use slamesh_core::relocalize::Paging;
use slamesh_core::Pose;
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// What paging did over a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PagingStats {
    /// Tiles read from the file.
    pub tiles_loaded: usize,
    /// Tiles that left the map.
    pub tiles_dropped: usize,
    /// Layers read from the file.
    pub layers_loaded: usize,
}

/// A map paged in from its file (see the module docs).
pub struct MapPager {
    file: MapFile,
    /// Each tile's layers at most, from its blocks' lengths.
    bounds: BTreeMap<CellKey, usize>,
    resident: BTreeSet<CellKey>,
    budget_layers: usize,
    reach_m: f64,
    tile_m: f64,
    /// Where the resident set was last chosen, and a move that makes it worth choosing again.
    chosen_at: Option<nalgebra::Vector3<f64>>,
    /// The first error met while paging (the search cannot return one): the run reports it.
    error: Option<FileError>,
    stats: PagingStats,
}

impl MapPager {
    /// Opens the map file `path` for paging into maps of `budget_layers` layers, loading no
    /// tile farther than `reach_m` from the sensor (the scan's range).
    pub fn open(path: &Path, budget_layers: usize, reach_m: f64) -> Result<Self, FileError> {
        let file = MapFile::open(path)?;
        let bounds = file.tile_bounds();
        let tile_m = file.info.lattice.cell_size * f64::from(TILE_CELLS);
        Ok(Self {
            file,
            bounds,
            resident: BTreeSet::new(),
            budget_layers,
            reach_m,
            tile_m,
            chosen_at: None,
            error: None,
            stats: PagingStats::default(),
        })
    }

    /// The map file.
    pub fn file(&self) -> &MapFile {
        &self.file
    }

    /// What paging did so far.
    pub fn stats(&self) -> PagingStats {
        self.stats
    }

    /// The first error met while paging, taken.
    pub fn take_error(&mut self) -> Option<FileError> {
        self.error.take()
    }

    /// Makes `map` hold the tiles around `at` (see the module docs).
    fn page(&mut self, map: &mut MeshMap, at: &nalgebra::Vector3<f64>) -> Result<(), FileError> {
        // Choosing again costs a sort of the tiles: only after a move of an eighth of a tile.
        if self
            .chosen_at
            .is_some_and(|c| (c - at).norm() < self.tile_m / 8.0)
        {
            return Ok(());
        }
        self.chosen_at = Some(*at);
        let mut near: Vec<(f64, CellKey)> = self
            .bounds
            .keys()
            .map(|t| (tile_distance(t, self.tile_m, at), *t))
            .filter(|(d, _)| *d <= self.reach_m)
            .collect();
        near.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        let mut wanted = BTreeSet::new();
        let mut layers = 0;
        for (_, t) in near {
            let n = self.bounds.get(&t).copied().unwrap_or(0);
            if layers + n > self.budget_layers {
                break;
            }
            layers += n;
            wanted.insert(t);
        }
        let leaving: BTreeSet<CellKey> = self.resident.difference(&wanted).copied().collect();
        if !leaving.is_empty() {
            map.evict_where(|k, _| leaving.contains(&tile_of(k)), |_| {});
            self.stats.tiles_dropped += leaving.len();
        }
        for t in wanted
            .difference(&self.resident)
            .copied()
            .collect::<Vec<_>>()
        {
            self.stats.layers_loaded += self.file.load_tile(t, map)?;
            self.stats.tiles_loaded += 1;
        }
        self.resident = wanted;
        Ok(())
    }
}

impl std::fmt::Display for PagingStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} tiles read ({} layers), {} dropped",
            self.tiles_loaded, self.layers_loaded, self.tiles_dropped
        )
    }
}

impl Paging for MapPager {
    fn around(&mut self, map: &mut MeshMap, at: &Pose) {
        if self.error.is_some() {
            return;
        }
        if let Err(e) = self.page(map, &at.translation.vector) {
            self.error = Some(e);
        }
    }
}
