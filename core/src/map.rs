//! The mesh map: world-fixed cells, each with up to three layers (docs/design.md §1.5).
//!
//! Owns its memory, all taken once when it is made, from the global allocator
//! ([`MeshMap::with_capacity`], feature `alloc`) or from the caller's storage
//! ([`MeshMap::in_storage`]):
//! - a hash table from [`CellKey`] to [`MapCell`] ([`CellTable`]): the cells packed in an
//!   array of the cell capacity, and an index of [`MAP_TABLE_FACTOR`] times as many 4-byte
//!   slots, so that it never grows and at most half of it is used;
//! - a pool of [`Layer`]s with a free list; a cell refers to its layers by pool index.
//!
//! A new cell past the cell capacity, or a new layer past the layer capacity, is refused with
//! [`MapError`]; nothing is overwritten. Iteration order is deterministic (a fixed hasher).

use crate::bounded::BoundedVec;
use crate::cell::{Axis, CellKey};
use crate::cell_table::{CellEntry, CellTable, Slot, NO_LAYER};
pub use crate::cell_table::{MapCell, MAP_TABLE_FACTOR};
use crate::lattice::Lattice;
use crate::layer::Layer;
use core::fmt;

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
    /// The frame its cell was last seen in.
    pub last_seen: u32,
}

/// World-fixed cells with their fused layers.
#[derive(Debug)]
#[cfg_attr(feature = "alloc", derive(Clone))]
pub struct MeshMap {
    cells: CellTable,
    pool: BoundedVec<Layer>,
    free: BoundedVec<u32>,
    max_cells: usize,
    lattice: Lattice,
}

/// The caller's memory for a map ([`MeshMap::in_storage`]).
pub struct MapStorage {
    /// The hash table's index ([`buckets_for`](crate::cell_table::buckets_for) of the cells).
    pub table: &'static mut [Slot],
    /// The hash table's packed cells: one a cell.
    pub cells: &'static mut [CellEntry],
    /// The layer pool: one slot a layer.
    pub pool: &'static mut [Layer],
    /// The free list: as long as the pool.
    pub free: &'static mut [u32],
}

impl MeshMap {
    /// An empty map for at most `max_cells` cells and `max_layers` layers, allocated now.
    #[cfg(any(feature = "alloc", test))]
    pub fn with_capacity(max_cells: usize, max_layers: usize, lattice: Lattice) -> Self {
        let max_layers = max_layers.min(NO_LAYER as usize);
        let cells = CellTable::with_capacity(max_cells);
        Self {
            max_cells: max_cells.min(cells.max_cells()),
            cells,
            pool: BoundedVec::with_capacity(max_layers),
            free: BoundedVec::with_capacity(max_layers),
            lattice,
        }
    }

    /// An empty map in the caller's `storage`, for at most `max_cells` cells (and no more than
    /// half the table's buckets) and as many layers as both the pool and the free list hold;
    /// `None` when the table has fewer than two buckets.
    pub fn in_storage(storage: MapStorage, max_cells: usize, lattice: Lattice) -> Option<Self> {
        let cells = CellTable::in_slice(storage.table, storage.cells)?;
        let layers = storage
            .pool
            .len()
            .min(storage.free.len())
            .min(NO_LAYER as usize);
        let (pool, _) = storage.pool.split_at_mut(layers);
        let (free, _) = storage.free.split_at_mut(layers);
        Some(Self {
            max_cells: max_cells.min(cells.max_cells()),
            cells,
            pool: BoundedVec::in_slice(pool),
            free: BoundedVec::in_slice(free),
            lattice,
        })
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
    pub fn cell(&self, key: &CellKey) -> Option<MapCell> {
        self.cells.get(key)
    }

    /// The layer along `axis` in cell `key`.
    #[inline]
    pub fn layer(&self, key: &CellKey, axis: Axis) -> Option<&Layer> {
        let slot = *self.cells.get(key)?.layers.get(axis.index())?;
        self.pool.get(slot as usize)
    }

    /// [`layer`](Self::layer), when the cell was last seen at or after frame `since`.
    pub fn layer_seen_since(&self, key: &CellKey, axis: Axis, since: u32) -> Option<&Layer> {
        let cell = self.cells.get(key)?;
        if cell.last_seen < since {
            return None;
        }
        let slot = *cell.layers.get(axis.index())?;
        self.pool.get(slot as usize)
    }

    /// The layer along `axis` in cell `key`, mutably; marks the cell seen at `frame`.
    pub fn layer_mut(&mut self, key: &CellKey, axis: Axis, frame: u32) -> Option<&mut Layer> {
        let slot = self.cells.update(key, |cell| {
            cell.last_seen = cell.last_seen.max(frame);
            cell.layers.get(axis.index()).copied()
        })??;
        if slot == NO_LAYER {
            return None;
        }
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
        if !self.cells.contains(&key) && self.cells.len() >= self.max_cells {
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
        let new = MapCell {
            layers: [NO_LAYER; 3],
            last_seen: frame,
        };
        let stored = self.cells.upsert(&key, new, |cell| {
            cell.last_seen = cell.last_seen.max(frame);
            if let Some(s) = cell.layers.get_mut(axis.index()) {
                *s = slot;
            }
        });
        if !stored {
            // Not reached (the cell limit is checked above): give the slot back.
            let _ = self.free.push(slot);
            return Err(MapError::CellsFull);
        }
        Ok(())
    }

    /// Every layer, in the map's deterministic order.
    pub fn layers(&self) -> impl Iterator<Item = LayerRef<'_>> + '_ {
        self.cells.iter().flat_map(move |(key, cell)| {
            Axis::ALL.into_iter().filter_map(move |axis| {
                let slot = *cell.layers.get(axis.index())?;
                Some(LayerRef {
                    key,
                    axis,
                    layer: self.pool.get(slot as usize)?,
                    last_seen: cell.last_seen,
                })
            })
        })
    }

    /// Shows each layer in turn to `f`, to change, in the map's deterministic order; the
    /// cells' last-seen frames are left as they are.
    pub fn update_layers(&mut self, mut f: impl FnMut(&CellKey, Axis, &mut Layer)) {
        let pool = &mut self.pool;
        for (key, cell) in self.cells.iter() {
            for axis in Axis::ALL {
                let Some(&slot) = cell.layers.get(axis.index()) else {
                    continue;
                };
                if let Some(layer) = pool.get_mut(slot as usize) {
                    f(&key, axis, layer);
                }
            }
        }
    }

    /// Every cell with its key, in the map's deterministic order.
    pub fn cells(&self) -> impl Iterator<Item = (CellKey, MapCell)> + '_ {
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
                        last_seen: cell.last_seen,
                    });
                    // The free list has the pool's capacity: it cannot be full.
                    let _ = free.push(slot);
                }
            }
            false
        });
        before - self.cells.len()
    }

    /// Removes every cell ([`evict_where`](Self::evict_where) of all, shown to no one): the
    /// map is empty, its capacity kept for the next use.
    pub fn clear(&mut self) {
        self.evict_where(|_, _| true, |_| {});
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
        // Cleared, it is empty and holds as much as before.
        m.clear();
        assert!(m.is_empty());
        assert_eq!((m.cell_count(), m.layer_count()), (0, 0));
        for x in 0..2 {
            m.insert_layer(CellKey::new(x, 0, 0), Axis::Z, Layer::UNKNOWN, 3)
                .unwrap();
        }
        assert_eq!(m.cell_count(), 2);
    }

    #[test]
    fn the_map_keeps_its_limits_under_churn() {
        let mut m = MeshMap::with_capacity(64, 64, LAT);
        for round in 0..50u32 {
            for i in 0..64 {
                let key = CellKey::new(i + 64 * round as i32, 0, 0);
                m.insert_layer(key, Axis::Z, Layer::UNKNOWN, round).unwrap();
            }
            assert_eq!((m.cell_count(), m.layer_count()), (64, 64));
            m.evict_where(|_, c| c.last_seen == round, |_| {});
            assert!(m.is_empty());
        }
    }
}
