//! The mesh map: world-fixed cells, each with up to three layers (docs/design.md §1.5).
//!
//! Owns its memory, all allocated once by [`MeshMap::with_capacity`]:
//! - a hash table from [`CellKey`] to [`MapCell`], made for [`MAP_TABLE_FACTOR`] times the
//!   cell capacity so that hashbrown never has to grow it (with at most half of its room used,
//!   clearing deleted entries is always done in place);
//! - a pool of [`Layer`]s with a free list; a cell refers to its layers by pool index.
//!
//! A new cell past the cell capacity, or a new layer past the layer capacity, is refused with
//! [`MapError`]; nothing is overwritten. Iteration order is deterministic (a fixed hasher).

use crate::bounded::BoundedVec;
use crate::cell::{Axis, BuildCellHasher, CellKey};
use crate::lattice::Lattice;
use crate::layer::Layer;
use core::fmt;
use hashbrown::HashMap;

/// The hash table is made for this many times the cell capacity.
pub const MAP_TABLE_FACTOR: usize = 2;
const NO_LAYER: u32 = u32::MAX;

/// A map cell: which pool slots hold its layers, and when it was last seen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MapCell {
    layers: [u32; 3],
    /// Index of the last frame that observed this cell (for eviction).
    pub last_seen: u32,
}

impl MapCell {
    /// Whether the cell has a layer along `axis`.
    #[inline]
    pub fn has(&self, axis: Axis) -> bool {
        self.layers
            .get(axis.index())
            .is_some_and(|&i| i != NO_LAYER)
    }

    /// The axes of the cell's layers.
    pub fn axes(&self) -> impl Iterator<Item = Axis> + '_ {
        Axis::ALL.into_iter().filter(|a| self.has(*a))
    }
}

/// Why the map refused an insertion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MapError {
    /// The map holds its capacity of cells.
    CellsFull,
    /// The layer pool is full.
    LayersFull,
}

impl fmt::Display for MapError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MapError::CellsFull => write!(f, "map cell capacity reached"),
            MapError::LayersFull => write!(f, "map layer capacity reached"),
        }
    }
}

impl core::error::Error for MapError {}

/// A layer of the map seen from outside: where it is and what it holds.
#[derive(Debug, Clone, Copy)]
pub struct LayerRef<'a> {
    /// Its cell.
    pub key: CellKey,
    /// Its axis.
    pub axis: Axis,
    /// Its predictions and variances.
    pub layer: &'a Layer,
}

/// World-fixed cells with their fused layers.
#[derive(Debug, Clone)]
pub struct MeshMap {
    cells: HashMap<CellKey, MapCell, BuildCellHasher>,
    pool: BoundedVec<Layer>,
    free: BoundedVec<u32>,
    max_cells: usize,
    lattice: Lattice,
}

impl MeshMap {
    /// An empty map for at most `max_cells` cells and `max_layers` layers, allocated now.
    pub fn with_capacity(max_cells: usize, max_layers: usize, lattice: Lattice) -> Self {
        let max_layers = max_layers.min(NO_LAYER as usize);
        Self {
            cells: HashMap::with_capacity_and_hasher(
                max_cells.saturating_mul(MAP_TABLE_FACTOR),
                BuildCellHasher::default(),
            ),
            pool: BoundedVec::with_capacity(max_layers),
            free: BoundedVec::with_capacity(max_layers),
            max_cells,
            lattice,
        }
    }

    /// The lattice the map's layers are placed on.
    #[inline]
    pub fn lattice(&self) -> &Lattice {
        &self.lattice
    }

    /// Number of cells.
    #[inline]
    pub fn cell_count(&self) -> usize {
        self.cells.len()
    }

    /// Number of layers.
    #[inline]
    pub fn layer_count(&self) -> usize {
        self.pool.len() - self.free.len()
    }

    /// Whether the map has no cell.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.cells.is_empty()
    }

    /// The cell at `key`.
    #[inline]
    pub fn cell(&self, key: &CellKey) -> Option<&MapCell> {
        self.cells.get(key)
    }

    /// The layer along `axis` in cell `key`.
    #[inline]
    pub fn layer(&self, key: &CellKey, axis: Axis) -> Option<&Layer> {
        let slot = *self.cells.get(key)?.layers.get(axis.index())?;
        self.pool.get(slot as usize)
    }

    /// The layer along `axis` in cell `key`, mutably; marks the cell seen at `frame`.
    pub fn layer_mut(&mut self, key: &CellKey, axis: Axis, frame: u32) -> Option<&mut Layer> {
        let cell = self.cells.get_mut(key)?;
        cell.last_seen = cell.last_seen.max(frame);
        let slot = *cell.layers.get(axis.index())?;
        self.pool.get_mut(slot as usize)
    }

    /// Stores `layer` along `axis` in cell `key` (creating the cell), replacing any layer
    /// there, and marks the cell seen at `frame`.
    pub fn insert_layer(
        &mut self,
        key: CellKey,
        axis: Axis,
        layer: Layer,
        frame: u32,
    ) -> Result<(), MapError> {
        if let Some(existing) = self.layer_mut(&key, axis, frame) {
            *existing = layer;
            return Ok(());
        }
        if !self.cells.contains_key(&key) && self.cells.len() >= self.max_cells {
            return Err(MapError::CellsFull);
        }
        let slot = if let Some(&slot) = self.free.last() {
            self.free.truncate(self.free.len() - 1);
            if let Some(l) = self.pool.get_mut(slot as usize) {
                *l = layer;
            }
            slot
        } else {
            let slot = self.pool.len() as u32;
            self.pool.push(layer).map_err(|_| MapError::LayersFull)?;
            slot
        };
        let cell = self.cells.entry(key).or_insert(MapCell {
            layers: [NO_LAYER; 3],
            last_seen: frame,
        });
        cell.last_seen = cell.last_seen.max(frame);
        if let Some(s) = cell.layers.get_mut(axis.index()) {
            *s = slot;
        }
        Ok(())
    }

    /// Every layer, in the map's deterministic order.
    pub fn layers(&self) -> impl Iterator<Item = LayerRef<'_>> + '_ {
        self.cells.iter().flat_map(move |(key, cell)| {
            Axis::ALL.into_iter().filter_map(move |axis| {
                let slot = *cell.layers.get(axis.index())?;
                Some(LayerRef {
                    key: *key,
                    axis,
                    layer: self.pool.get(slot as usize)?,
                })
            })
        })
    }

    /// Every cell with its key, in the map's deterministic order.
    pub fn cells(&self) -> impl Iterator<Item = (&CellKey, &MapCell)> + '_ {
        self.cells.iter()
    }

    /// Removes every cell for which `evict(key, cell)` is true, first showing each of its
    /// layers to `on_evicted` (to save them), and returns how many cells left. Their layer
    /// slots are reused.
    pub fn evict_where(
        &mut self,
        mut evict: impl FnMut(&CellKey, &MapCell) -> bool,
        mut on_evicted: impl FnMut(LayerRef<'_>),
    ) -> usize {
        let (pool, free) = (&self.pool, &mut self.free);
        let before = self.cells.len();
        self.cells.retain(|key, cell| {
            if !evict(key, cell) {
                return true;
            }
            for axis in Axis::ALL {
                let Some(&slot) = cell.layers.get(axis.index()) else {
                    continue;
                };
                if let Some(layer) = pool.get(slot as usize) {
                    on_evicted(LayerRef {
                        key: *key,
                        axis,
                        layer,
                    });
                    // The free list has the pool's capacity: it cannot be full.
                    let _ = free.push(slot);
                }
            }
            false
        });
        before - self.cells.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LAT: Lattice = Lattice {
        cell_size: 1.6,
        full_cover: false,
    };

    #[test]
    fn capacity_is_enforced_and_slots_are_reused() {
        let mut m = MeshMap::with_capacity(2, 3, LAT);
        m.insert_layer(CellKey::new(0, 0, 0), Axis::Z, Layer::UNKNOWN, 0)
            .unwrap();
        m.insert_layer(CellKey::new(0, 0, 0), Axis::X, Layer::UNKNOWN, 0)
            .unwrap();
        m.insert_layer(CellKey::new(1, 0, 0), Axis::Z, Layer::UNKNOWN, 1)
            .unwrap();
        assert_eq!(
            m.insert_layer(CellKey::new(2, 0, 0), Axis::Z, Layer::UNKNOWN, 1),
            Err(MapError::CellsFull)
        );
        assert_eq!(
            m.insert_layer(CellKey::new(1, 0, 0), Axis::Y, Layer::UNKNOWN, 1),
            Err(MapError::LayersFull)
        );
        assert_eq!((m.cell_count(), m.layer_count()), (2, 3));

        let mut seen = 0;
        let gone = m.evict_where(|_, c| c.last_seen == 0, |_| seen += 1);
        assert_eq!((gone, seen), (1, 2));
        assert_eq!((m.cell_count(), m.layer_count()), (1, 1));
        m.insert_layer(CellKey::new(5, 5, 5), Axis::Y, Layer::UNKNOWN, 2)
            .unwrap();
        m.insert_layer(CellKey::new(5, 5, 5), Axis::Z, Layer::UNKNOWN, 2)
            .unwrap();
        assert_eq!(m.layer_count(), 3);
        assert!(m.cell(&CellKey::new(5, 5, 5)).unwrap().has(Axis::Y));
    }

    #[test]
    fn table_never_reallocates_under_churn() {
        // `capacity()` counts tombstones against the room left and so moves with the group
        // width (16 on x86-64, 8 on aarch64); the allocation itself must not change.
        let mut m = MeshMap::with_capacity(64, 64, LAT);
        let size = m.cells.allocation_size();
        for round in 0..50u32 {
            for i in 0..64 {
                let key = CellKey::new(i + 64 * round as i32, 0, 0);
                m.insert_layer(key, Axis::Z, Layer::UNKNOWN, round).unwrap();
            }
            m.evict_where(|_, c| c.last_seen == round, |_| {});
            assert_eq!(m.cells.allocation_size(), size);
        }
    }
}
