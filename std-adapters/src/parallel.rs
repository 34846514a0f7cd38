//! Parallel filter, bucketing, reconstruction and association: the per-point, per-cell and
//! per-layer loops on a rayon thread pool.
//!
//! Only the loops differ from the core's serial [`Serial`](slamesh_core::reconstruct::Serial):
//! each cell goes through the same [`reconstruct_cell`], and the layers are appended in cell
//! order by the same [`append_layers`]; each scan layer goes through the same
//! [`Associator::layer`], collected in scan order by the same [`associate::collect`]; each
//! raw point through the same [`Preparation::point`], collected in input order by the same
//! [`filter::collect`]; each scan point through the same [`Placement::point`], in input order
//! as [`bucket::collect`] keeps them. The radix sort's passes take their plan, digits and
//! skip rule from the core's [`KeySorter::radix`], [`RadixPlan`](slamesh_core::sort::RadixPlan)
//! and [`moves_nothing`]; only the parts run at once. All give bit-identical results (tested).

use rayon::prelude::*;
use slamesh_core::associate::{self, AssociateStats, Associator};
use slamesh_core::bounded::BoundedVec;
use slamesh_core::bucket::{self, CellSpan, Placement};
use slamesh_core::cell::CellKey;
use slamesh_core::filter::{self, Dropped, FilterStats, Preparation};
use slamesh_core::gp::GpScratch;
use slamesh_core::lm::Residual;
use slamesh_core::map::MeshMap;
use slamesh_core::reconstruct::{append_layers, reconstruct_cell, CellLoop, Purpose, ScanLayer};
use slamesh_core::sort::{moves_nothing, Entry, Histogram, KeySorter, RADIX};
use slamesh_core::{Config, Point};

/// Raw points per task of the parallel filter.
const POINTS_PER_TASK: usize = 8192;
/// Fewest entries per part of a parallel sort (fewer are sorted serially).
const MIN_SORT_PART: usize = 8192;

/// Reconstructs cells on a dedicated rayon pool.
#[derive(Debug)]
pub struct Rayon {
    pool: rayon::ThreadPool,
}

impl Rayon {
    /// A pool of `threads` threads (0: one per core).
    pub fn new(threads: usize) -> Result<Self, rayon::ThreadPoolBuildError> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()?;
        Ok(Self { pool })
    }

    /// Number of threads in the pool.
    pub fn threads(&self) -> usize {
        self.pool.current_num_threads()
    }

    /// Appends what `task` keeps of `src` to `dst`, in input order, as a serial loop would.
    /// `src` is cut into tasks of [`POINTS_PER_TASK`]; each task writes its kept items to the
    /// front of its own stretch of `dst` and returns how many it kept and its counts, and
    /// the stretches are then closed up in order. `dst` must have room for all of `src`.
    fn filter_map_in_place<T: Sync, R: Send>(
        &self,
        src: &[T],
        dst: &mut BoundedVec<(CellKey, Point)>,
        task: impl Fn(&[T], &mut [(CellKey, Point)]) -> (usize, R) + Sync,
    ) -> Vec<R> {
        let start = dst.len();
        dst.extend_default(start + src.len());
        let per_task: Vec<(usize, R)> = self.pool.install(|| {
            dst[start..]
                .par_chunks_mut(POINTS_PER_TASK)
                .zip(src.par_chunks(POINTS_PER_TASK))
                .map(|(d, s)| task(s, d))
                .collect()
        });
        let mut end = start;
        let mut counts = Vec::with_capacity(per_task.len());
        for (k, (kept, r)) in per_task.into_iter().enumerate() {
            let from = start + k * POINTS_PER_TASK;
            dst.copy_within(from..from + kept, end);
            end += kept;
            counts.push(r);
        }
        dst.truncate(end);
        counts
    }
}

impl CellLoop for Rayon {
    fn run(
        &self,
        cells: &[CellSpan],
        bucketed: &[(CellKey, Point)],
        map: &MeshMap,
        cfg: &Config,
        purpose: Purpose,
        out: &mut BoundedVec<ScanLayer>,
    ) -> usize {
        let per_cell: Vec<_> = self.pool.install(|| {
            cells
                .par_iter()
                .map_init(GpScratch::new, |scratch, c| {
                    reconstruct_cell(scratch, c.points(bucketed), c.key, map, cfg, purpose)
                })
                .collect()
        });
        per_cell
            .into_iter()
            .map(|layers| append_layers(out, layers))
            .sum()
    }

    fn prepare_points(
        &self,
        raw: &[Point],
        prep: &Preparation,
        work: &mut BoundedVec<(CellKey, Point)>,
        stats: &mut FilterStats,
    ) {
        if raw.len() > work.capacity() - work.len() {
            // Some would not fit: the serial loop drops them in input order.
            return filter::collect(raw.iter().map(|p| prep.point(p)), work, stats);
        }
        let per_task = self.filter_map_in_place(raw, work, |src, dst| {
            let mut s = FilterStats::default();
            for p in src {
                match prep.point(p) {
                    Ok(e) => {
                        dst[s.kept] = e;
                        s.kept += 1;
                    }
                    Err(Dropped::NonFinite) => s.non_finite += 1,
                    Err(Dropped::OutOfRange) => s.out_of_range += 1,
                }
            }
            (s.kept, s)
        });
        for s in per_task {
            stats.non_finite += s.non_finite;
            stats.out_of_range += s.out_of_range;
        }
    }

    fn sort(&self, sorter: &mut KeySorter, entries: &mut BoundedVec<Entry>) {
        let parts = self.threads().min(entries.len() / MIN_SORT_PART);
        if parts < 2 {
            return sorter.sort(entries);
        }
        let Some((plan, spare)) = sorter.radix(entries) else {
            return sorter.sort(entries);
        };
        let part_len = entries.len().div_ceil(parts);
        for pass in 0..plan.passes() {
            let counts: Vec<Histogram> = self.pool.install(|| {
                entries
                    .par_chunks(part_len)
                    .map(|part| {
                        let mut h = [0u32; RADIX];
                        plan.count(part, pass, &mut h);
                        h
                    })
                    .collect()
            });
            if moves_nothing(&counts.iter().collect::<Vec<_>>()) {
                continue;
            }
            // The output cut into one run per (digit, part), digit after digit, part after
            // part, each as long as the part's count of the digit: each part fills its own
            // runs in input order, so the pass is stable.
            let mut runs: Vec<Vec<&mut [Entry]>> =
                counts.iter().map(|_| Vec::with_capacity(RADIX)).collect();
            let mut rest: &mut [Entry] = &mut spare[..];
            for d in 0..RADIX {
                for (part_runs, count) in runs.iter_mut().zip(&counts) {
                    let (run, tail) = std::mem::take(&mut rest).split_at_mut(count[d] as usize);
                    part_runs.push(run);
                    rest = tail;
                }
            }
            self.pool.install(|| {
                entries
                    .par_chunks(part_len)
                    .zip(runs.par_iter_mut())
                    .for_each(|(part, runs)| {
                        for e in part {
                            let run = &mut runs[plan.digit(&e.0, pass)];
                            if let Some((slot, tail)) = std::mem::take(run).split_first_mut() {
                                *slot = *e;
                                *run = tail;
                            }
                        }
                    })
            });
            std::mem::swap(entries, spare);
        }
    }

    fn place_points(
        &self,
        points: &[Point],
        placement: &Placement,
        out: &mut BoundedVec<(CellKey, Point)>,
    ) {
        if points.len() > out.capacity() - out.len() {
            // Some would not fit: the serial loop keeps the first ones.
            return bucket::collect(points.iter().map(|p| placement.point(p)), out);
        }
        self.filter_map_in_place(points, out, |src, dst| {
            let mut kept = 0;
            for e in src.iter().filter_map(|p| placement.point(p)) {
                dst[kept] = e;
                kept += 1;
            }
            (kept, ())
        });
    }

    fn associate(
        &self,
        scan: &[ScanLayer],
        map: &MeshMap,
        reach: u32,
        variance_register: f64,
        out: &mut BoundedVec<Residual>,
    ) -> AssociateStats {
        let a = Associator::new(map, reach, variance_register);
        let per_layer: Vec<_> = self
            .pool
            .install(|| scan.par_iter().map(|s| a.layer(s)).collect());
        associate::collect(per_layer.into_iter(), out)
    }
}

/// The cell loop for a thread count: the core's serial loop for one thread, a rayon pool for
/// more (0: one thread per core).
#[derive(Debug)]
pub enum Workers {
    /// The core's serial loop.
    Serial,
    /// A rayon pool.
    Pool(Rayon),
}

impl Workers {
    /// Workers for `threads` threads.
    pub fn new(threads: usize) -> Result<Self, rayon::ThreadPoolBuildError> {
        Ok(match threads {
            1 => Workers::Serial,
            n => Workers::Pool(Rayon::new(n)?),
        })
    }

    /// Number of threads.
    pub fn threads(&self) -> usize {
        match self {
            Workers::Serial => 1,
            Workers::Pool(r) => r.threads(),
        }
    }

    /// `Σ count(item)` over `items` (a sum of integers: the same in any order).
    pub fn sum<T: Sync>(&self, items: &[T], count: impl Fn(&T) -> usize + Sync) -> usize {
        match self {
            Workers::Serial => items.iter().map(count).sum(),
            Workers::Pool(r) => r.pool.install(|| items.par_iter().map(&count).sum()),
        }
    }
}

impl CellLoop for Workers {
    fn run(
        &self,
        cells: &[CellSpan],
        bucketed: &[(CellKey, Point)],
        map: &MeshMap,
        cfg: &Config,
        purpose: Purpose,
        out: &mut BoundedVec<ScanLayer>,
    ) -> usize {
        match self {
            Workers::Serial => {
                slamesh_core::reconstruct::Serial.run(cells, bucketed, map, cfg, purpose, out)
            }
            Workers::Pool(r) => r.run(cells, bucketed, map, cfg, purpose, out),
        }
    }

    fn associate(
        &self,
        scan: &[ScanLayer],
        map: &MeshMap,
        reach: u32,
        variance_register: f64,
        out: &mut BoundedVec<Residual>,
    ) -> AssociateStats {
        match self {
            Workers::Serial => associate::associate(scan, map, reach, variance_register, out),
            Workers::Pool(r) => r.associate(scan, map, reach, variance_register, out),
        }
    }

    fn prepare_points(
        &self,
        raw: &[Point],
        prep: &Preparation,
        work: &mut BoundedVec<(CellKey, Point)>,
        stats: &mut FilterStats,
    ) {
        match self {
            Workers::Serial => filter::collect(raw.iter().map(|p| prep.point(p)), work, stats),
            Workers::Pool(r) => r.prepare_points(raw, prep, work, stats),
        }
    }

    fn sort(&self, sorter: &mut KeySorter, entries: &mut BoundedVec<Entry>) {
        match self {
            Workers::Serial => sorter.sort(entries),
            Workers::Pool(r) => r.sort(sorter, entries),
        }
    }

    fn place_points(
        &self,
        points: &[Point],
        placement: &Placement,
        out: &mut BoundedVec<(CellKey, Point)>,
    ) {
        match self {
            Workers::Serial => bucket::collect(points.iter().map(|p| placement.point(p)), out),
            Workers::Pool(r) => r.place_points(points, placement, out),
        }
    }
}
