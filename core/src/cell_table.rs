//! [`CellTable`]: the map's hash table from [`CellKey`] to [`MapCell`].
//!
//! Two arrays, both fixed when the table is made:
//! - the cells themselves, packed: one [`CellEntry`] (key, layer slots, last seen) per cell,
//!   in the first `len` places of an array of the cell capacity; a removed cell's place takes
//!   the last cell, so the array never has holes and its pages are touched only as the map
//!   grows;
//! - the index: open addressing with linear probing in an array of [`Slot`]s, a power of two
//!   at least [`MAP_TABLE_FACTOR`] times the cell capacity, so that at most half of it is used
//!   and every probe ends soon at an empty slot. A slot is 4 bytes: the cell's place plus one,
//!   with the hash's high bits above it as a tag (a probe reads the cell only when the tag
//!   matches). Removal shifts the slots after it back (no tombstones), so the table never
//!   degrades under churn and never reallocates.
//!
//! Why two arrays: the cells hash to slots all over the index, so every page of it is
//! touched (resident) after a few thousand cells. With 4-byte slots that is 2 MB for the
//! 64-beam class's 262 144 cells; with the cells stored in the slots it was 16.8 MB
//! (docs/design.md §1.8).
//!
//! An empty slot is 0: an index from the global allocator is zeroed by the system, and one in
//! caller storage is a zeroed `static`. Iteration runs in slot order, which depends only on
//! the keys inserted and removed and the table's size: it is deterministic, and the same as
//! when the cells were stored in the slots.

use crate::bounded::BoundedVec;
use crate::cell::{Axis, BuildCellHasher, CellKey};
use core::hash::BuildHasher;

/// The index is made for this many times the cell capacity.
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

/// One cell of the packed array: its key and what it holds (28 bytes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CellEntry {
    /// The cell's key.
    pub key: CellKey,
    /// The cell.
    pub cell: MapCell,
}

/// An unused [`CellEntry`] (for storage).
pub const NO_ENTRY: CellEntry = CellEntry {
    key: CellKey::new(0, 0, 0),
    cell: MapCell {
        layers: [NO_LAYER; 3],
        last_seen: 0,
    },
};

/// One slot of the index: 0 when empty, else the cell's place plus one in the low bits and a
/// tag from its hash in the rest.
pub type Slot = u32;

/// Slots of an index for `cells` cells: `MAP_TABLE_FACTOR` times as many, rounded up to a
/// power of two.
pub const fn buckets_for(cells: usize) -> usize {
    let n = cells.saturating_mul(MAP_TABLE_FACTOR);
    if n < 2 {
        2
    } else {
        n.next_power_of_two()
    }
}

/// Bytes of a table for `cells` cells: its index and its packed cells.
pub const fn table_bytes(cells: usize) -> usize {
    buckets_for(cells) * size_of::<Slot>() + cells * size_of::<CellEntry>()
}

/// The hash table (see the module's documentation).
#[derive(Debug)]
#[cfg_attr(feature = "alloc", derive(Clone))]
pub struct CellTable {
    slots: BoundedVec<Slot>,
    entries: BoundedVec<CellEntry>,
    /// Bits of a slot that hold the place plus one; the rest hold the tag.
    place_bits: u32,
}

/// Where a key is, or would go: its slot (`Ok` when the key is there) and its tag.
struct Probe {
    found: Result<usize, Option<usize>>,
    tag: u32,
}

impl CellTable {
    /// A table for `cells` cells, allocated now (the index zeroed, untouched until written).
    #[cfg(any(feature = "alloc", test))]
    pub fn with_capacity(cells: usize) -> Self {
        Self::new(
            BoundedVec::filled(buckets_for(cells), 0),
            BoundedVec::with_capacity(cells.min(u32::MAX as usize - 1)),
        )
    }

    /// A table in the caller's `slots` (emptied now; the largest power of two of them is
    /// used) and `entries`; it holds at most half the slots, and no more cells than
    /// `entries`. `None` when there are fewer than two slots.
    pub fn in_slice(slots: &'static mut [Slot], entries: &'static mut [CellEntry]) -> Option<Self> {
        let n = slots.len();
        if n < 2 {
            return None;
        }
        let pow2 = if n.is_power_of_two() {
            n
        } else {
            n.next_power_of_two() / 2
        };
        let (used, _) = slots.split_at_mut(pow2);
        let cells = entries.len().min(u32::MAX as usize - 1);
        let (entries, _) = entries.split_at_mut(cells);
        Some(Self::new(
            BoundedVec::in_slice_filled(used, 0),
            BoundedVec::in_slice(entries),
        ))
    }

    fn new(slots: BoundedVec<Slot>, entries: BoundedVec<CellEntry>) -> Self {
        let most = (slots.len() / 2).min(entries.capacity());
        Self {
            slots,
            entries,
            place_bits: u32::BITS - (most as u32).leading_zeros(),
        }
    }

    /// Cells the table holds at most (half its slots, and no more than its packed array).
    pub fn max_cells(&self) -> usize {
        (self.slots.len() / 2).min(self.entries.capacity())
    }

    /// Number of cells.
    #[inline]
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Whether the table holds no cell.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    #[inline]
    fn mask(&self) -> usize {
        self.slots.len().wrapping_sub(1)
    }

    #[inline]
    fn hash(key: &CellKey) -> u64 {
        BuildCellHasher::default().hash_one(key)
    }

    /// The tag of a hash: its high bits, as many as a slot has beside the place.
    #[inline]
    fn tag_of(&self, hash: u64) -> u32 {
        let bits = u32::BITS - self.place_bits;
        if bits == 0 {
            0
        } else {
            (hash >> (u64::BITS - bits)) as u32
        }
    }

    /// The cell's place in `entries`, if `slot` holds one.
    #[inline]
    fn place(&self, slot: Slot) -> Option<usize> {
        let low = if self.place_bits >= u32::BITS {
            slot
        } else {
            slot & ((1 << self.place_bits) - 1)
        };
        (low as usize).checked_sub(1)
    }

    #[inline]
    fn slot(&self, tag: u32, place: usize) -> Slot {
        let low = place as u32 + 1;
        if self.place_bits >= u32::BITS {
            low
        } else {
            (tag << self.place_bits) | low
        }
    }

    #[inline]
    fn slot_tag(&self, slot: Slot) -> u32 {
        slot.checked_shr(self.place_bits).unwrap_or(0)
    }

    /// The slot holding `key`, or the empty one where it would go (`None` when the index is
    /// full, which the cell limit prevents).
    fn find(&self, key: &CellKey) -> Probe {
        let hash = Self::hash(key);
        let tag = self.tag_of(hash);
        let mask = self.mask();
        let mut i = hash as usize & mask;
        for _ in 0..self.slots.len() {
            let Some(&s) = self.slots.get(i) else { break };
            let Some(place) = self.place(s) else {
                return Probe {
                    found: Err(Some(i)),
                    tag,
                };
            };
            if self.slot_tag(s) == tag && self.entries.get(place).is_some_and(|e| e.key == *key) {
                return Probe { found: Ok(i), tag };
            }
            i = (i + 1) & mask;
        }
        Probe {
            found: Err(None),
            tag,
        }
    }

    /// The packed cell that slot `i` refers to.
    #[inline]
    fn entry_at(&self, i: usize) -> Option<&CellEntry> {
        let place = self.place(*self.slots.get(i)?)?;
        self.entries.get(place)
    }

    /// The cell at `key`.
    #[inline]
    pub fn get(&self, key: &CellKey) -> Option<MapCell> {
        let i = self.find(key).found.ok()?;
        self.entry_at(i).map(|e| e.cell)
    }

    /// Whether a cell is at `key`.
    #[inline]
    pub fn contains(&self, key: &CellKey) -> bool {
        self.find(key).found.is_ok()
    }

    /// Applies `f` to the cell at `key`, if any, and returns what it returned.
    pub fn update<R>(&mut self, key: &CellKey, f: impl FnOnce(&mut MapCell) -> R) -> Option<R> {
        let i = self.find(key).found.ok()?;
        let place = self.place(*self.slots.get(i)?)?;
        self.entries.get_mut(place).map(|e| f(&mut e.cell))
    }

    /// Applies `f` to the cell at `key`, made from `new` first if there is none (then `false`
    /// is returned when the table holds [`max_cells`](Self::max_cells) already).
    pub fn upsert(&mut self, key: &CellKey, new: MapCell, f: impl FnOnce(&mut MapCell)) -> bool {
        let probe = self.find(key);
        match probe.found {
            Ok(_) => self.update(key, f).is_some(),
            Err(Some(i)) if self.len() < self.max_cells() => {
                let mut cell = new;
                f(&mut cell);
                let place = self.entries.len();
                if self.entries.push(CellEntry { key: *key, cell }).is_err() {
                    return false;
                }
                let slot = self.slot(probe.tag, place);
                match self.slots.get_mut(i) {
                    Some(s) => {
                        *s = slot;
                        true
                    }
                    None => {
                        self.entries.truncate(place);
                        false
                    }
                }
            }
            Err(_) => false,
        }
    }

    /// Every cell with its key, in slot order.
    pub fn iter(&self) -> impl Iterator<Item = (CellKey, MapCell)> + '_ {
        self.slots
            .iter()
            .filter_map(|&s| self.entries.get(self.place(s)?))
            .map(|e| (e.key, e.cell))
    }

    /// Removes every cell for which `keep(key, cell)` is false.
    pub fn retain(&mut self, mut keep: impl FnMut(&CellKey, &MapCell) -> bool) {
        let n = self.slots.len();
        let mask = self.mask();
        // Start after an empty slot: no run of entries crosses it, so shifting slots back
        // never moves one past the start, and every entry is seen once.
        let Some(start) = self.slots.iter().position(|&s| self.place(s).is_none()) else {
            return;
        };
        let mut i = (start + 1) & mask;
        let mut steps = 0;
        while steps < n {
            if let Some(e) = self.entry_at(i) {
                if !keep(&e.key, &e.cell) {
                    // The slot now holds the one shifted back into it (or is empty): look at
                    // it again.
                    self.remove_at(i);
                    continue;
                }
            }
            i = (i + 1) & mask;
            steps += 1;
        }
    }

    /// Removes the cell of slot `hole`: the last packed cell takes its place, and the slots
    /// after `hole` that probed past it shift back.
    fn remove_at(&mut self, mut hole: usize) {
        let Some(place) = self.slots.get(hole).and_then(|&s| self.place(s)) else {
            return;
        };
        self.move_last_to(place);
        let mask = self.mask();
        let mut j = hole;
        for _ in 0..self.slots.len() {
            j = (j + 1) & mask;
            let Some(&s) = self.slots.get(j) else { break };
            let Some(e) = self.place(s).and_then(|p| self.entries.get(p)) else {
                break;
            };
            let home = Self::hash(&e.key) as usize & mask;
            // The slot may move to `hole` when `hole` lies on its probe path, from `home` to `j`.
            if (j.wrapping_sub(home) & mask) >= (j.wrapping_sub(hole) & mask) {
                if let Some(h) = self.slots.get_mut(hole) {
                    *h = s;
                }
                hole = j;
            }
        }
        if let Some(h) = self.slots.get_mut(hole) {
            *h = 0;
        }
    }

    /// Drops the packed cell at `place`, moving the last one into it (and its slot with it).
    fn move_last_to(&mut self, place: usize) {
        let Some(last) = self.entries.len().checked_sub(1) else {
            return;
        };
        if place != last {
            let Some(&moved) = self.entries.get(last) else {
                return;
            };
            // The slot that refers to the last cell: on the probe path from its home.
            let mask = self.mask();
            let mut i = Self::hash(&moved.key) as usize & mask;
            for _ in 0..self.slots.len() {
                let Some(&s) = self.slots.get(i) else { return };
                if self.place(s) == Some(last) {
                    let slot = self.slot(self.slot_tag(s), place);
                    if let Some(to) = self.slots.get_mut(i) {
                        *to = slot;
                    }
                    break;
                }
                i = (i + 1) & mask;
            }
            if let Some(e) = self.entries.get_mut(place) {
                *e = moved;
            }
        }
        self.entries.truncate(last);
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
        let slots: &'static mut [Slot] = alloc::vec![0; 256].leak();
        let entries: &'static mut [CellEntry] = alloc::vec![NO_ENTRY; 128].leak();
        let mut t = CellTable::in_slice(slots, entries).unwrap();
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
        let entries = || -> &'static mut [CellEntry] { alloc::vec![NO_ENTRY; 40].leak() };
        let odd: &'static mut [Slot] = alloc::vec![0; 100].leak();
        assert_eq!(CellTable::in_slice(odd, entries()).unwrap().max_cells(), 32);
        let few: &'static mut [Slot] = alloc::vec![0; 256].leak();
        assert_eq!(
            CellTable::in_slice(few, entries()).unwrap().max_cells(),
            40,
            "no more than the packed array holds"
        );
        let none: &'static mut [Slot] = alloc::vec![0; 1].leak();
        assert!(CellTable::in_slice(none, entries()).is_none());
    }
}
