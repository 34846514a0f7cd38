//! [`CellTable`]: the map's hash table from [`CellKey`] to [`MapCell`].
//!
//! Open addressing with linear probing in a fixed array of buckets, a power of two at least
//! [`MAP_TABLE_FACTOR`] times the cell capacity, so that at most half of it is used and every
//! probe ends soon at an empty bucket. Removal shifts the entries after it back (no
//! tombstones), so the table never degrades under churn and never reallocates.
//!
//! A bucket is eight plain words, all zero when empty: a table from the global allocator is
//! zeroed by the system (its pages untouched until a cell lands there, as with a hash table
//! that only writes its control bytes), and one in caller storage is a zeroed `static`. Cells
//! are read and written by value. Iteration runs in bucket order, which depends only on the
//! keys inserted and removed and the table's size: it is deterministic.

use crate::bounded::BoundedVec;
use crate::cell::{Axis, BuildCellHasher, CellKey};
use core::hash::BuildHasher;

/// The hash table is made for this many times the cell capacity.
pub const MAP_TABLE_FACTOR: usize = 2;
/// A cell's layer slot that holds no layer.
pub(crate) const NO_LAYER: u32 = u32::MAX;

/// A map cell: which pool slots hold its layers, and when it was last seen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MapCell {
    /// Pool slots of its layers along x, y and z ([`NO_LAYER`] for none).
    pub(crate) layers: [u32; 3],
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

/// One bucket: the key's `x, y, z`, the cell's three layer slots and `last_seen`, and 1 when
/// occupied (0 when empty).
pub type Bucket = [u32; 8];

/// An empty bucket.
pub const EMPTY: Bucket = [0; 8];

/// Buckets of a table for `cells` cells: `MAP_TABLE_FACTOR` times as many, rounded up to a
/// power of two.
pub const fn buckets_for(cells: usize) -> usize {
    let n = cells.saturating_mul(MAP_TABLE_FACTOR);
    if n < 2 {
        2
    } else {
        n.next_power_of_two()
    }
}

/// The hash table (see the module's documentation).
#[derive(Debug)]
#[cfg_attr(feature = "alloc", derive(Clone))]
pub struct CellTable {
    buckets: BoundedVec<Bucket>,
    len: usize,
}

fn occupied(b: &Bucket) -> bool {
    b[7] != 0
}

fn key_of(b: &Bucket) -> CellKey {
    CellKey::new(b[0] as i32, b[1] as i32, b[2] as i32)
}

fn cell_of(b: &Bucket) -> MapCell {
    MapCell {
        layers: [b[3], b[4], b[5]],
        last_seen: b[6],
    }
}

fn bucket(key: &CellKey, cell: &MapCell) -> Bucket {
    let (l, seen) = (cell.layers, cell.last_seen);
    [
        key.x as u32,
        key.y as u32,
        key.z as u32,
        l[0],
        l[1],
        l[2],
        seen,
        1,
    ]
}

impl CellTable {
    /// A table for `cells` cells, allocated (zeroed) now.
    #[cfg(any(feature = "alloc", test))]
    pub fn with_capacity(cells: usize) -> Self {
        Self {
            buckets: BoundedVec::filled(buckets_for(cells), EMPTY),
            len: 0,
        }
    }

    /// A table in the caller's `buckets` (emptied now), using the largest power of two of
    /// them; `None` when there are fewer than two.
    pub fn in_slice(buckets: &'static mut [Bucket]) -> Option<Self> {
        let n = buckets.len();
        if n < 2 {
            return None;
        }
        let pow2 = if n.is_power_of_two() {
            n
        } else {
            n.next_power_of_two() / 2
        };
        let (used, _) = buckets.split_at_mut(pow2);
        Some(Self {
            buckets: BoundedVec::in_slice_filled(used, EMPTY),
            len: 0,
        })
    }

    /// Cells the table holds at most (half its buckets).
    pub fn max_cells(&self) -> usize {
        self.buckets.len() / 2
    }

    /// Number of cells.
    #[inline]
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether the table holds no cell.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    #[inline]
    fn mask(&self) -> usize {
        self.buckets.len().wrapping_sub(1)
    }

    #[inline]
    fn home(&self, key: &CellKey) -> usize {
        BuildCellHasher::default().hash_one(key) as usize & self.mask()
    }

    /// `Ok(bucket)` holding `key`, or `Err(bucket)`: the empty one where it would go (`None`
    /// when the table is full, which the cell limit prevents).
    fn find(&self, key: &CellKey) -> Result<usize, Option<usize>> {
        let mask = self.mask();
        let mut i = self.home(key);
        for _ in 0..self.buckets.len() {
            let b = self.buckets.get(i).ok_or(None)?;
            if !occupied(b) {
                return Err(Some(i));
            }
            if key_of(b) == *key {
                return Ok(i);
            }
            i = (i + 1) & mask;
        }
        Err(None)
    }

    /// The cell at `key`.
    #[inline]
    pub fn get(&self, key: &CellKey) -> Option<MapCell> {
        let i = self.find(key).ok()?;
        self.buckets.get(i).map(cell_of)
    }

    /// Whether a cell is at `key`.
    #[inline]
    pub fn contains(&self, key: &CellKey) -> bool {
        self.find(key).is_ok()
    }

    /// Applies `f` to the cell at `key`, if any, and returns what it returned.
    pub fn update<R>(&mut self, key: &CellKey, f: impl FnOnce(&mut MapCell) -> R) -> Option<R> {
        let i = self.find(key).ok()?;
        let b = self.buckets.get_mut(i)?;
        let mut cell = cell_of(b);
        let r = f(&mut cell);
        *b = bucket(key, &cell);
        Some(r)
    }

    /// Applies `f` to the cell at `key`, made from `new` first if there is none (then `false`
    /// is returned when the table holds [`max_cells`](Self::max_cells) already).
    pub fn upsert(&mut self, key: &CellKey, new: MapCell, f: impl FnOnce(&mut MapCell)) -> bool {
        let (i, mut cell) = match self.find(key) {
            Ok(i) => match self.buckets.get(i) {
                Some(b) => (i, cell_of(b)),
                None => return false,
            },
            Err(Some(i)) if self.len < self.max_cells() => {
                self.len += 1;
                (i, new)
            }
            Err(_) => return false,
        };
        f(&mut cell);
        match self.buckets.get_mut(i) {
            Some(b) => {
                *b = bucket(key, &cell);
                true
            }
            None => false,
        }
    }

    /// Every cell with its key, in bucket order.
    pub fn iter(&self) -> impl Iterator<Item = (CellKey, MapCell)> + '_ {
        self.buckets
            .iter()
            .filter(|b| occupied(b))
            .map(|b| (key_of(b), cell_of(b)))
    }

    /// Removes every cell for which `keep(key, cell)` is false.
    pub fn retain(&mut self, mut keep: impl FnMut(&CellKey, &MapCell) -> bool) {
        let n = self.buckets.len();
        let mask = self.mask();
        // Start after an empty bucket: no run of entries crosses it, so shifting entries back
        // never moves one past the start, and every entry is seen once.
        let Some(start) = self.buckets.iter().position(|b| !occupied(b)) else {
            return;
        };
        let mut i = (start + 1) & mask;
        let mut steps = 0;
        while steps < n {
            let Some(b) = self.buckets.get(i) else { return };
            if occupied(b) && !keep(&key_of(b), &cell_of(b)) {
                // The bucket now holds the entry shifted back into it (or is empty): look
                // at it again.
                self.remove_at(i);
                continue;
            }
            i = (i + 1) & mask;
            steps += 1;
        }
    }

    /// Empties bucket `hole`, shifting back the entries after it that probed past it.
    fn remove_at(&mut self, mut hole: usize) {
        let mask = self.mask();
        let mut j = hole;
        for _ in 0..self.buckets.len() {
            j = (j + 1) & mask;
            let Some(&b) = self.buckets.get(j) else { break };
            if !occupied(&b) {
                break;
            }
            let home = self.home(&key_of(&b));
            // `b` may move to `hole` when `hole` lies on its probe path, from `home` to `j`.
            if (j.wrapping_sub(home) & mask) >= (j.wrapping_sub(hole) & mask) {
                if let Some(h) = self.buckets.get_mut(hole) {
                    *h = b;
                }
                hole = j;
            }
        }
        if let Some(h) = self.buckets.get_mut(hole) {
            *h = EMPTY;
            self.len = self.len.saturating_sub(1);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::SplitMix64;
    use alloc::collections::BTreeMap;

    fn cell(seen: u32) -> MapCell {
        MapCell {
            layers: [seen, u32::MAX, 7],
            last_seen: seen,
        }
    }

    #[test]
    fn it_agrees_with_an_ordered_map_under_churn() {
        let slots: &'static mut [Bucket] = alloc::vec![EMPTY; 256].leak();
        let mut t = CellTable::in_slice(slots).unwrap();
        assert_eq!(t.max_cells(), 128);
        let mut truth = BTreeMap::new();
        let mut rng = SplitMix64(3);
        for round in 0..2000u32 {
            // Keys from a small range, negative ones too, so that runs collide and wrap.
            let k = |r: u64| (r % 41) as i32 - 20;
            let key = CellKey::new(k(rng.next_u64()), k(rng.next_u64()), 0);
            if rng.next_u64().is_multiple_of(3) {
                t.retain(|kk, _| *kk != key);
                truth.remove(&(key.x, key.y, key.z));
            } else {
                let added = t.upsert(&key, cell(round), |c| c.last_seen = round);
                if added {
                    truth.insert((key.x, key.y, key.z), round);
                } else {
                    assert_eq!(truth.len(), 128, "refused only when full");
                }
            }
            if round % 97 == 0 {
                t.retain(|_, c| c.last_seen % 5 != 0);
                truth.retain(|_, seen| *seen % 5 != 0);
            }
            assert_eq!(t.len(), truth.len());
        }
        for (&(x, y, z), &seen) in &truth {
            let c = t.get(&CellKey::new(x, y, z)).unwrap();
            assert_eq!(c.last_seen, seen);
        }
        assert_eq!(t.iter().count(), truth.len());
        assert!(t.get(&CellKey::new(99, 0, 0)).is_none());
        assert_eq!(t.update(&CellKey::new(99, 0, 0), |c| c.last_seen), None);
    }

    #[test]
    fn sizes_are_powers_of_two_with_room_to_spare() {
        assert_eq!(buckets_for(0), 2);
        assert_eq!(buckets_for(384), 1024);
        assert_eq!(buckets_for(262_144), 524_288);
        let odd: &'static mut [Bucket] = alloc::vec![EMPTY; 100].leak();
        assert_eq!(CellTable::in_slice(odd).unwrap().max_cells(), 32);
        let none: &'static mut [Bucket] = alloc::vec![EMPTY; 1].leak();
        assert!(CellTable::in_slice(none).is_none());
    }
}
