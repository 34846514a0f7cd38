//! Compile-time capacities and the memory they cost.
//!
//! A [`Capacity`] type fixes, at compile time, how much a [`Pipeline`](crate::Pipeline) can
//! hold. Every buffer is allocated once, when the pipeline is built, and never grows; when one
//! is full the owning stage drops by the rule it documents and counts the drop in
//! [`ScanStats`](crate::ScanStats), or, for the map, returns an error. The memory bound of an
//! instance is [`Capacity::memory_bytes`].

use crate::bucket::CellSpan;
use crate::cell::CellKey;
use crate::cell_table::table_bytes;
use crate::layer::Layer;
use crate::layer::ScanLayer;
use crate::lm::Residual;
use crate::math::Point;
use core::mem::size_of;

/// Bytes one map layer costs: its slot in the map's layer pool and its free-list entry.
pub const MAP_LAYER_BYTES: usize = size_of::<Layer>() + size_of::<u32>();

/// How much one pipeline can hold. Implement it for your sensor, or use a provided one.
pub trait Capacity: 'static {
    /// A short name for messages (`64-beam`, `16-beam`, ...).
    const NAME: &'static str = "custom";
    /// Points of one scan kept after the range filter (the rest are dropped in input order).
    const POINTS: usize;
    /// Cells of one scan that are reconstructed (further cells are dropped in key order).
    const SCAN_CELLS: usize;
    /// Layers of one scan (at most three per cell; further layers are dropped).
    const SCAN_LAYERS: usize;
    /// Cells in the map (a new cell past this is not inserted and is counted).
    const MAP_CELLS: usize;
    /// Layers in the map (a new layer past this is not inserted and is counted).
    const MAP_LAYERS: usize;
    /// Whether the filter and bucketing sort by radix ([`crate::sort`]), in linear time, at
    /// the cost of a second buffer of `POINTS` entries (24 bytes each); `false` keeps the
    /// comparison sort, with the same results, for the smallest memories.
    const RADIX_SORT: bool = true;

    /// IMU readings an [`ImuTrack`](crate::imu::ImuTrack) holds: a sweep and the time since the
    /// scan before (at 400 Hz, 512 cover 1.28 s: a 1 Hz scanner). A full track forgets its
    /// oldest half.
    const IMU_SAMPLES: usize = 512;

    /// Entries of the radix sort's buffer: `POINTS` or none.
    const SORT_ENTRIES: usize = if Self::RADIX_SORT { Self::POINTS } else { 0 };

    /// Bytes of the scan buffers (points, the sort's buffer, cells, layers and residuals),
    /// allocated in full by [`Pipeline::new`](crate::Pipeline::new) and touched, page by page,
    /// up to the largest scan seen.
    fn scan_bytes() -> usize {
        ScanLimits::of::<Self>().bytes::<Self>()
    }

    /// Bytes of the filter's buffers (points, the work buffer, the sort's buffer): part of
    /// [`scan_bytes`](Self::scan_bytes), and all of a
    /// [`ScanFilter`](crate::filter::ScanFilter)'s.
    fn filter_bytes() -> usize {
        ScanLimits::of::<Self>().filter_bytes::<Self>()
    }

    /// Upper bound on the heap bytes of one pipeline with these capacities: the scan buffers
    /// and a map of `MAP_CELLS` cells and `MAP_LAYERS` layers ([`map_bytes`]).
    fn memory_bytes() -> usize {
        Self::scan_bytes() + map_bytes(Self::MAP_CELLS, Self::MAP_LAYERS)
    }

    /// Upper bound on the heap bytes of a pipeline built by
    /// [`Pipeline::with_map_layers`](crate::Pipeline::with_map_layers)`(_, layers)`: the scan
    /// buffers and a map sized for that many layers and cells (each clamped to this capacity).
    fn memory_bytes_with_map_layers(layers: usize) -> usize {
        ScanLimits::of::<Self>().pipeline_bytes::<Self>(layers)
    }
}

/// The sizes of one pipeline's scan buffers: its capacity's
/// ([`ScanLimits::of`]), or a share of them for a pipeline that only fuses and searches
/// scans already filtered, far smaller than raw ones
/// ([`Pipeline::with_limits`](crate::Pipeline::with_limits)). A scan past a limit is cut by
/// the rule of the capacity's constant it stands for, and counted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ScanLimits {
    /// Points kept after the range filter ([`Capacity::POINTS`]).
    pub points: usize,
    /// Cells reconstructed ([`Capacity::SCAN_CELLS`]).
    pub cells: usize,
    /// Layers ([`Capacity::SCAN_LAYERS`]).
    pub layers: usize,
}

impl ScanLimits {
    /// Capacity `C`'s own.
    pub const fn of<C: Capacity + ?Sized>() -> Self {
        Self {
            points: C::POINTS,
            cells: C::SCAN_CELLS,
            layers: C::SCAN_LAYERS,
        }
    }

    /// Each limit divided by `d` (at least one).
    pub const fn divided_by(self, d: usize) -> Self {
        let d = if d == 0 { 1 } else { d };
        Self {
            points: self.points.div_ceil(d),
            cells: self.cells.div_ceil(d),
            layers: self.layers.div_ceil(d),
        }
    }

    /// Each limit at most capacity `C`'s.
    pub fn within<C: Capacity + ?Sized>(self) -> Self {
        Self {
            points: self.points.min(C::POINTS),
            cells: self.cells.min(C::SCAN_CELLS),
            layers: self.layers.min(C::SCAN_LAYERS),
        }
    }

    /// Bytes of the scan buffers at these limits with capacity `C`'s sort: the filter's
    /// ([`Capacity::filter_bytes`] at these points), cells, layers and residuals.
    pub fn bytes<C: Capacity + ?Sized>(&self) -> usize {
        self.filter_bytes::<C>()
            + self.cells * size_of::<CellSpan>()
            + self.layers * (size_of::<ScanLayer>() + size_of::<Residual>())
    }

    /// Upper bound on the heap bytes of a pipeline built by
    /// [`Pipeline::with_limits`](crate::Pipeline::with_limits)`(_, self, layers)`: these scan
    /// buffers and a map sized for that many layers and cells (each clamped to `C`'s).
    pub fn pipeline_bytes<C: Capacity + ?Sized>(&self, layers: usize) -> usize {
        self.bytes::<C>() + map_bytes(layers.min(C::MAP_CELLS), layers.min(C::MAP_LAYERS))
    }

    /// Entries of the radix sort's buffer: as many as points, or none ([`Capacity::RADIX_SORT`]).
    pub const fn sort_entries<C: Capacity + ?Sized>(&self) -> usize {
        if C::RADIX_SORT {
            self.points
        } else {
            0
        }
    }

    fn filter_bytes<C: Capacity + ?Sized>(&self) -> usize {
        self.points * (size_of::<Point>() + size_of::<(CellKey, Point)>())
            + self.sort_entries::<C>() * size_of::<(CellKey, Point)>()
    }
}

/// Bytes of an [`ImuTrack`](crate::imu::ImuTrack)'s buffer for capacity `C`, apart from the
/// pipeline's [`Capacity::memory_bytes`].
pub const fn imu_bytes<C: Capacity>() -> usize {
    C::IMU_SAMPLES * size_of::<crate::imu::Reading>()
}

/// Bytes of a map for `cells` cells and `layers` layers: its hash table ([`table_bytes`]: an
/// index of 4-byte slots, two or more a cell, and the packed cells) and its layer pool with the
/// free list.
pub const fn map_bytes(cells: usize, layers: usize) -> usize {
    table_bytes(cells) + layers * MAP_LAYER_BYTES
}

/// KITTI HDL-64E scans (about 125 000 points, 100 m range) and runs of a few kilometres
/// without eviction. [`Capacity::memory_bytes`]: 139.2 MB of address space, most of it the
/// map's layer pool, touched (resident) only as the map fills. Its scan layers are three times
/// the most a KITTI scan made (4 134, on the highway of sequence 01; docs/journal.md,
/// "Memory with 64-beam scans").
#[derive(Debug, Clone, Copy)]
pub struct KittiCapacity;

impl Capacity for KittiCapacity {
    const NAME: &'static str = "64-beam";
    const POINTS: usize = 140_000;
    const SCAN_CELLS: usize = 8_192;
    const SCAN_LAYERS: usize = 12_288;
    const MAP_CELLS: usize = 262_144;
    const MAP_LAYERS: usize = 393_216;
}

/// 32-beam sensors (a Velodyne VLP-32C's 60 000 points, an Ouster OS-32 at 2 048 columns'
/// 65 536) and runs of a kilometre or two without eviction: half of [`KittiCapacity`]'s
/// points and map, as many scan layers (a sensor's range, not its beams, sets how many cells
/// a scan touches), 72.2 MB of address space.
#[derive(Debug, Clone, Copy)]
pub struct Lidar32Capacity;

impl Capacity for Lidar32Capacity {
    const NAME: &'static str = "32-beam";
    const POINTS: usize = 72_000;
    const SCAN_CELLS: usize = 8_192;
    const SCAN_LAYERS: usize = 12_288;
    const MAP_CELLS: usize = 131_072;
    const MAP_LAYERS: usize = 196_608;
}

/// 16-beam sensors (a Velodyne VLP-16's 29 000 points, an Ouster OS-16 at 2 048 columns'
/// 32 768), indoors or on small robots: a quarter of [`KittiCapacity`]'s points and map,
/// 36.1 MB of address space.
#[derive(Debug, Clone, Copy)]
pub struct Lidar16Capacity;

impl Capacity for Lidar16Capacity {
    const NAME: &'static str = "16-beam";
    const POINTS: usize = 36_000;
    const SCAN_CELLS: usize = 4_096;
    const SCAN_LAYERS: usize = 6_144;
    const MAP_CELLS: usize = 65_536;
    const MAP_LAYERS: usize = 98_304;
}

/// A sparse 16-beam sensor on a microcontroller-class board: a few hundred cells, 336 KB
/// (the comparison sort: a scan of 2 048 points sorts quickly either way).
#[derive(Debug, Clone, Copy)]
pub struct SmallCapacity;

impl Capacity for SmallCapacity {
    const NAME: &'static str = "tiny";
    const POINTS: usize = 2_048;
    const SCAN_CELLS: usize = 160;
    const SCAN_LAYERS: usize = 240;
    const MAP_CELLS: usize = 384;
    const MAP_LAYERS: usize = 512;
    const RADIX_SORT: bool = false;
    const IMU_SAMPLES: usize = 128;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn footprints_stay_what_the_docs_say() {
        // The footprint table (docs/journal.md, "Sizing capacities"): bytes per unit.
        assert_eq!(
            size_of::<Point>() + size_of::<(CellKey, Point)>(),
            36,
            "per scan point"
        );
        assert_eq!(size_of::<(CellKey, Point)>(), 24, "per radix-sort entry");
        assert_eq!(
            (KittiCapacity::SORT_ENTRIES, SmallCapacity::SORT_ENTRIES),
            (KittiCapacity::POINTS, 0)
        );
        assert_eq!(size_of::<CellSpan>(), 20, "per scan cell");
        assert_eq!(
            size_of::<ScanLayer>() + size_of::<Residual>(),
            388,
            "per scan layer"
        );
        assert_eq!(
            size_of::<crate::cell_table::Slot>(),
            4,
            "per index slot (two or more a map cell)"
        );
        assert_eq!(
            size_of::<crate::cell_table::CellEntry>(),
            28,
            "per packed map cell"
        );
        assert_eq!(size_of::<Layer>() + size_of::<u32>(), 296, "per map layer");
        assert_eq!(size_of::<Layer>(), 292);
        // The documented figures, with 1 % slack for platform layout.
        let kitti = KittiCapacity::memory_bytes() as f64;
        assert!(
            (kitti - 139.2e6).abs() < 1.4e6,
            "KittiCapacity: {kitti} bytes"
        );
        for (name, bytes, documented) in [
            ("32", Lidar32Capacity::memory_bytes(), 72.2e6),
            ("16", Lidar16Capacity::memory_bytes(), 36.1e6),
        ] {
            let bytes = bytes as f64;
            assert!(
                (bytes - documented).abs() < 0.01 * documented,
                "Lidar{name}Capacity: {bytes} bytes"
            );
        }
        let small = SmallCapacity::memory_bytes() as f64;
        assert!(
            (small - 336.4e3).abs() < 3.3e3,
            "SmallCapacity: {small} bytes"
        );
    }
}
