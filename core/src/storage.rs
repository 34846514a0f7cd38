//! Memory the caller provides, so that the core runs with no allocator.
//!
//! [`Storage`] lends a [`Pipeline`] every buffer it needs as a `'static` slice
//! ([`Pipeline::in_storage`]). [`StaticStorage`] holds them all in one value whose size is
//! fixed at compile time by a [`Capacity`] type: name its type with
//! [`storage_for!`](crate::storage_for), put it in a `static`
//! (it is all zeroes, so it costs RAM, in `.bss`, and no flash), and lend it once:
//!
//! ```ignore
//! type Memory = slamesh_core::storage_for!(SmallCapacity);
//! static mut MEMORY: Memory = Memory::new();
//! // SAFETY (the caller's): taken once, at start-up, and used by nothing else.
//! let memory: &'static mut Memory = unsafe { &mut *core::ptr::addr_of_mut!(MEMORY) };
//! let pipeline = Pipeline::<SmallCapacity>::in_storage(config, memory.lend())?;
//! ```
//!
//! The core itself has no `unsafe`: taking a `&'static mut` out of a `static` is the
//! caller's one step (or `cortex_m::singleton!`, `static_cell`, or [`Storage::leak`] with an
//! allocator).

use crate::bounded::BoundedVec;
use crate::bounded::Empty;
use crate::bucket::CellSpan;
use crate::capacity::Capacity;
use crate::cell::{Axis, CellKey};
use crate::cell_table::buckets_for;
use crate::cell_table::{CellEntry, Slot, NO_ENTRY};
use crate::config::{Config, ConfigError};
use crate::layer::{Layer, ScanLayer};
use crate::lm::Residual;
use crate::map::{MapStorage, MeshMap};
use crate::math::{Point, Vec3};
use crate::pipeline::Pipeline;
use crate::real::Real;
use crate::sort::KeySorter;

impl Empty for u32 {
    const EMPTY: Self = 0;
}
impl Empty for i32 {
    const EMPTY: Self = 0;
}
impl Empty for u8 {
    const EMPTY: Self = 0;
}
impl Empty for f32 {
    const EMPTY: Self = 0.0;
}
impl Empty for Point {
    const EMPTY: Self = [0.0; 3];
}
impl Empty for (CellKey, Point) {
    const EMPTY: Self = (CellKey::new(0, 0, 0), [0.0; 3]);
}
impl Empty for CellSpan {
    const EMPTY: Self = CellSpan {
        key: CellKey::new(0, 0, 0),
        start: 0,
        len: 0,
    };
}
impl Empty for Layer {
    const EMPTY: Self = Layer {
        pred: [0.0; crate::lattice::VERTICES],
        var: [0.0; crate::lattice::VERTICES],
        facing: crate::facing::Facing::Unknown,
    };
}
impl Empty for ScanLayer {
    const EMPTY: Self = ScanLayer {
        key: CellKey::new(0, 0, 0),
        axis: Axis::X,
        layer: Layer::EMPTY,
    };
}
impl Empty for Residual {
    const EMPTY: Self = Residual {
        p: Vec3::new(0.0, 0.0, 0.0),
        q: Vec3::new(0.0, 0.0, 0.0),
        n: Vec3::new(0.0, 0.0, 0.0),
        weight: 0.0,
    };
}
impl Empty for CellEntry {
    const EMPTY: Self = NO_ENTRY;
}

/// Every buffer of one pipeline, lent by the caller. Each must hold at least what the
/// pipeline's capacity asks for ([`Pipeline::in_storage`](crate::Pipeline::in_storage) says
/// which one is short); longer ones are used only in part.
pub struct Storage {
    /// The kept points of a scan (`POINTS`).
    pub points: &'static mut [Point],
    /// The filter's and bucketing's keyed points (`POINTS`).
    pub work: &'static mut [(CellKey, Point)],
    /// The radix sort's spare buffer (`POINTS`, or none with the comparison sort).
    pub sort: &'static mut [(CellKey, Point)],
    /// The cells of a scan (`SCAN_CELLS`).
    pub cells: &'static mut [CellSpan],
    /// The layers of a scan (`SCAN_LAYERS`).
    pub scan: &'static mut [ScanLayer],
    /// The residuals of a registration (`SCAN_LAYERS`).
    pub residuals: &'static mut [Residual],
    /// The map: its table, layer pool and free list.
    pub map: MapStorage,
}

impl Storage {
    /// Every buffer capacity `C` asks for, from the global allocator and never freed: for a
    /// program that builds its one pipeline at start and keeps it for good, and for tests.
    #[cfg(any(feature = "alloc", test))]
    pub fn leak<C: Capacity>() -> Self {
        fn slots<T: Empty>(n: usize) -> &'static mut [T] {
            alloc::vec![T::EMPTY; n].leak()
        }
        Storage {
            points: slots(C::POINTS),
            work: slots(C::POINTS),
            sort: slots(C::SORT_ENTRIES),
            cells: slots(C::SCAN_CELLS),
            scan: slots(C::SCAN_LAYERS),
            residuals: slots(C::SCAN_LAYERS),
            map: MapStorage {
                table: slots(buckets_for(C::MAP_CELLS)),
                cells: slots(C::MAP_CELLS),
                pool: slots(C::MAP_LAYERS),
                free: slots(C::MAP_LAYERS),
            },
        }
    }
}

impl<C: Capacity, R: Real> Pipeline<C, R> {
    /// A pipeline with an empty map in the caller's `storage` ([`crate::storage`]): it takes
    /// no memory from an allocator, ever. Each buffer must hold at least what `C` asks for;
    /// the error names the first one that does not.
    pub fn in_storage(config: Config, storage: Storage) -> Result<Self, ConfigError> {
        config.validate()?;
        fn part<T>(
            slots: &'static mut [T],
            n: usize,
            field: &'static str,
        ) -> Result<&'static mut [T], ConfigError> {
            if slots.len() < n {
                return Err(ConfigError {
                    field,
                    reason: "is shorter than the capacity asks for",
                });
            }
            Ok(slots.split_at_mut(n).0)
        }
        let Storage {
            points,
            work,
            sort,
            cells,
            scan,
            residuals,
            map,
        } = storage;
        let points = part(points, C::POINTS, "storage.points")?;
        let work = part(work, C::POINTS, "storage.work")?;
        let sort = part(sort, C::SORT_ENTRIES, "storage.sort")?;
        let cells = part(cells, C::SCAN_CELLS, "storage.cells")?;
        let scan = part(scan, C::SCAN_LAYERS, "storage.scan")?;
        let residuals = part(residuals, C::SCAN_LAYERS, "storage.residuals")?;
        let table = part(map.table, buckets_for(C::MAP_CELLS), "storage.map.table")?;
        let map_cells = part(map.cells, C::MAP_CELLS, "storage.map.cells")?;
        let pool = part(map.pool, C::MAP_LAYERS, "storage.map.pool")?;
        let free = part(map.free, C::MAP_LAYERS, "storage.map.free")?;
        let map = MeshMap::in_storage(
            MapStorage {
                table,
                cells: map_cells,
                pool,
                free,
            },
            C::MAP_CELLS,
            config.lattice(),
        )
        .ok_or(ConfigError {
            field: "storage.map.table",
            reason: "needs at least two buckets",
        })?;
        Ok(Self::assemble(
            config,
            map,
            (BoundedVec::in_slice(points), BoundedVec::in_slice(work)),
            KeySorter::in_slice(sort),
            BoundedVec::in_slice(cells),
            BoundedVec::in_slice(scan),
            BoundedVec::in_slice(residuals),
        ))
    }
}

/// All of one pipeline's buffers in one value, sized by const parameters; name it for a
/// capacity type with [`storage_for!`](crate::storage_for).
pub struct StaticStorage<
    const POINTS: usize,
    const SORT: usize,
    const SCAN_CELLS: usize,
    const SCAN_LAYERS: usize,
    const BUCKETS: usize,
    const MAP_CELLS: usize,
    const MAP_LAYERS: usize,
> {
    points: [Point; POINTS],
    work: [(CellKey, Point); POINTS],
    sort: [(CellKey, Point); SORT],
    cells: [CellSpan; SCAN_CELLS],
    scan: [ScanLayer; SCAN_LAYERS],
    residuals: [Residual; SCAN_LAYERS],
    table: [Slot; BUCKETS],
    map_cells: [CellEntry; MAP_CELLS],
    pool: [Layer; MAP_LAYERS],
    free: [u32; MAP_LAYERS],
}

impl<
        const POINTS: usize,
        const SORT: usize,
        const SCAN_CELLS: usize,
        const SCAN_LAYERS: usize,
        const BUCKETS: usize,
        const MAP_CELLS: usize,
        const MAP_LAYERS: usize,
    > StaticStorage<POINTS, SORT, SCAN_CELLS, SCAN_LAYERS, BUCKETS, MAP_CELLS, MAP_LAYERS>
{
    /// All zeroes (for a `static`).
    #[allow(clippy::new_without_default)]
    pub const fn new() -> Self {
        Self {
            points: [Point::EMPTY; POINTS],
            work: [<(CellKey, Point)>::EMPTY; POINTS],
            sort: [<(CellKey, Point)>::EMPTY; SORT],
            cells: [CellSpan::EMPTY; SCAN_CELLS],
            scan: [ScanLayer::EMPTY; SCAN_LAYERS],
            residuals: [Residual::EMPTY; SCAN_LAYERS],
            table: [0; BUCKETS],
            map_cells: [NO_ENTRY; MAP_CELLS],
            pool: [Layer::EMPTY; MAP_LAYERS],
            free: [0; MAP_LAYERS],
        }
    }

    /// Its buffers, lent for good.
    pub fn lend(&'static mut self) -> Storage {
        Storage {
            points: &mut self.points,
            work: &mut self.work,
            sort: &mut self.sort,
            cells: &mut self.cells,
            scan: &mut self.scan,
            residuals: &mut self.residuals,
            map: MapStorage {
                table: &mut self.table,
                cells: &mut self.map_cells,
                pool: &mut self.pool,
                free: &mut self.free,
            },
        }
    }
}

/// The [`StaticStorage`] type for a capacity type: `storage_for!(SmallCapacity)`. Its size is
/// the capacity's [`memory_bytes`](crate::Capacity::memory_bytes), known at compile time.
#[macro_export]
macro_rules! storage_for {
    ($capacity:ty) => {
        $crate::storage::StaticStorage<
            { <$capacity as $crate::Capacity>::POINTS },
            { <$capacity as $crate::Capacity>::SORT_ENTRIES },
            { <$capacity as $crate::Capacity>::SCAN_CELLS },
            { <$capacity as $crate::Capacity>::SCAN_LAYERS },
            { $crate::cell_table::buckets_for(<$capacity as $crate::Capacity>::MAP_CELLS) },
            { <$capacity as $crate::Capacity>::MAP_CELLS },
            { <$capacity as $crate::Capacity>::MAP_LAYERS },
        >
    };
}

#[cfg(test)]
mod tests {
    use crate::capacity::SmallCapacity;
    use crate::Capacity;

    #[test]
    fn static_storage_is_the_capacitys_footprint() {
        type Memory = crate::storage_for!(SmallCapacity);
        // The arrays' alignment may pad between them by a few bytes.
        let (size, bound) = (
            core::mem::size_of::<Memory>(),
            SmallCapacity::memory_bytes(),
        );
        assert!(
            size >= bound && size <= bound + 64,
            "{size} against {bound}"
        );
    }
}
