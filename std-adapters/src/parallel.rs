//! The core's [`Executor`] on a rayon thread pool: a scan's per-point, per-cell and per-layer
//! loops and its radix sort spread over the pool's threads.
//!
//! Only how the units are run differs from the core's [`Serial`]: the stages hand the same units
//! (a point's preparation or placement, a cell's reconstruction, a layer's association) to
//! [`Executor::map_in_order`] and [`Executor::filter_map_into`], and both hand the results back
//! in input order. The radix sort's passes take their plan, digits and skip rule from the core's
//! [`KeySorter::radix`], [`RadixPlan`](slamesh_core::sort::RadixPlan) and [`moves_nothing`];
//! only the parts run at once. All give bit-identical results (`tests/parallel.rs`).
//!
//! Besides: [`Yielding`], the serial loops for a task that runs on the pool beside the
//! pipeline and gives way to its parallel loops, and [`Workers::install_beside`], which runs
//! the pipeline on the pool while the calling thread does something else.

use rayon::prelude::*;
use slamesh_core::bounded::BoundedVec;
use slamesh_core::executor::{Executor, Serial};
use slamesh_core::sort::{moves_nothing, Entry, Histogram, KeySorter, RADIX};

/// Most points a task of the parallel filter and placement takes.
const POINTS_PER_TASK: usize = 8192;
/// Fewest points a task of the parallel filter and placement takes, so that a task outweighs
/// its scheduling: a bucketed scan of 20 000 points is cut into about 20 tasks, enough for
/// 16 threads, where tasks of [`POINTS_PER_TASK`] made three.
const MIN_POINTS_PER_TASK: usize = 1024;
/// Layers a task of the update's move (`Executor::update_each`) takes at least, so that a
/// task outweighs its scheduling.
const LAYERS_PER_TASK: usize = 256;
/// Fewest entries per part of a parallel sort (fewer are sorted serially): a bucketed 64-beam
/// scan (about 20 000 points) is sorted in one or two parts, a raw scan filtered ahead (about
/// 120 000) in up to seven.
const MIN_SORT_PART: usize = 16_384;
/// [`MIN_SORT_PART`] below [`SPREAD_FROM`] threads.
const MIN_SORT_PART_ON_TWO: usize = 65_536;
/// Threads from which the pool's loops are cut finely (`task_len`, `MIN_SORT_PART`) and
/// the filter run ahead spreads its own loops over the pool (`run/lookahead.rs`). On two
/// threads the second one filters the next frame most of the time: a task handed to it waits,
/// and bucketing whose sort was split in two took a quarter longer (docs/journal.md, "All
/// the cores"), so there the tasks stay long and the filter yields.
pub const SPREAD_FROM: usize = 3;

/// Reconstructs cells on a dedicated rayon pool.
#[derive(Debug)]
pub struct Rayon {
    pool: rayon::ThreadPool,
    spare: Spare,
}

/// The buffers [`Rayon::map_in_order`] gathered results in, one per result type, kept empty
/// for the next call: a scan's loops then allocate nothing once the largest scan has been
/// seen, and the allocator's free memory does not grow with a megabyte of results a round
/// (docs/journal.md, "Memory with 64-beam scans").
#[derive(Debug, Default)]
struct Spare(std::sync::Mutex<Vec<Box<dyn std::any::Any + Send>>>);

impl Spare {
    /// The kept buffer for `R` (empty), or a new one.
    fn take<R: Send + 'static>(&self) -> Vec<R> {
        let Ok(mut kept) = self.0.lock() else {
            return Vec::new();
        };
        match kept.iter().position(|b| b.is::<Vec<R>>()) {
            Some(i) => kept
                .swap_remove(i)
                .downcast::<Vec<R>>()
                .map(|b| *b)
                .unwrap_or_default(),
            None => Vec::new(),
        }
    }

    /// Keeps `buffer` (emptied) for the next [`take`](Self::take) of its type.
    fn keep<R: Send + 'static>(&self, mut buffer: Vec<R>) {
        buffer.clear();
        if let Ok(mut kept) = self.0.lock() {
            kept.push(Box::new(buffer));
        }
    }
}

impl Rayon {
    /// A pool of `threads` threads (0: one per core).
    pub fn new(threads: usize) -> Result<Self, rayon::ThreadPoolBuildError> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()?;
        Ok(Self {
            pool,
            spare: Spare::default(),
        })
    }

    /// Number of threads in the pool.
    pub fn threads(&self) -> usize {
        self.pool.current_num_threads()
    }

    /// Runs `job` on the pool, as a task of its own: a thread that takes it works on it
    /// until it is done, and the pool's other threads share what else comes meanwhile.
    pub fn spawn(&self, job: impl FnOnce() + Send + 'static) {
        self.pool.spawn(job);
    }
}

impl Executor for Rayon {
    fn map_in_order<T, S, R>(
        &self,
        items: &[T],
        init: impl Fn() -> S + Sync + Send,
        unit: impl Fn(&mut S, &T) -> R + Sync + Send,
        sink: impl FnMut(R),
    ) where
        T: Sync,
        R: Send + 'static,
    {
        let mut results: Vec<R> = self.spare.take();
        self.pool.install(|| {
            items
                .par_iter()
                .map_init(&init, &unit)
                .collect_into_vec(&mut results)
        });
        results.drain(..).for_each(sink);
        self.spare.keep(results);
    }

    fn update_each<T: Send>(&self, items: &mut [T], unit: impl Fn(&mut T) + Sync + Send) {
        self.pool.install(|| {
            items
                .par_iter_mut()
                .with_min_len(LAYERS_PER_TASK)
                .for_each(unit)
        });
    }

    /// [`OnThisPool`]'s, on this pool.
    fn filter_map_into<T, U, A>(
        &self,
        src: &[T],
        dst: &mut BoundedVec<U>,
        unit: impl Fn(&T, &mut A) -> Option<U> + Sync + Send,
        tally: impl FnMut(A),
    ) -> bool
    where
        T: Sync,
        U: Default + Clone + Send,
        A: Default + Send,
    {
        // The tallies are handed over here: `tally` need not be `Send`.
        let mut tallies = Vec::new();
        let fits = self
            .pool
            .install(|| OnThisPool.filter_map_into(src, dst, unit, |a| tallies.push(a)));
        tallies.into_iter().for_each(tally);
        fits
    }

    fn sort(&self, sorter: &mut KeySorter, entries: &mut BoundedVec<Entry>) {
        let threads = self.threads();
        self.pool
            .install(|| sort_in_parts(sorter, entries, threads));
    }
}

/// Points a task of a parallel filter or placement takes out of `n` on `threads` threads: about
/// four tasks a thread, between [`MIN_POINTS_PER_TASK`] and [`POINTS_PER_TASK`]
/// ([`POINTS_PER_TASK`] below [`SPREAD_FROM`] threads). Any length gives the same result (the
/// kept outputs are closed up in input order).
fn task_len(n: usize, threads: usize) -> usize {
    if threads < SPREAD_FROM {
        return POINTS_PER_TASK;
    }
    n.div_ceil(4 * threads)
        .clamp(MIN_POINTS_PER_TASK, POINTS_PER_TASK)
}

/// `src` cut into tasks of `task` items on the current pool, each writing the outputs `unit`
/// keeps to the front of its own stretch of `dst` (as long as `src`): each task's count kept
/// and tally, in order.
fn filter_in_tasks<T, U, A>(
    src: &[T],
    dst: &mut [U],
    task: usize,
    unit: &(impl Fn(&T, &mut A) -> Option<U> + Sync),
) -> Vec<(usize, A)>
where
    T: Sync,
    U: Send,
    A: Default + Send,
{
    dst.par_chunks_mut(task)
        .zip(src.par_chunks(task))
        .map(|(d, s)| {
            let mut counts = A::default();
            let mut kept = 0;
            for item in s {
                if let Some(out) = unit(item, &mut counts) {
                    d[kept] = out;
                    kept += 1;
                }
            }
            (kept, counts)
        })
        .collect()
}

/// Closes up what [`filter_in_tasks`] wrote from `start` on (tasks of `task` items), in order,
/// and hands each task's tally to `tally`.
fn close_up<U, A>(
    dst: &mut BoundedVec<U>,
    start: usize,
    task: usize,
    per_task: Vec<(usize, A)>,
    mut tally: impl FnMut(A),
) {
    // A slot is written only after the value it held has moved.
    let mut end = start;
    let mut tallies = Vec::with_capacity(per_task.len());
    for (k, (kept, r)) in per_task.into_iter().enumerate() {
        let from = start + k * task;
        if from != end {
            for i in 0..kept {
                dst.swap(end + i, from + i);
            }
        }
        end += kept;
        tallies.push(r);
    }
    dst.truncate(end);
    tallies.into_iter().for_each(&mut tally);
}

/// [`KeySorter::sort`]'s order, its passes cut into up to `threads` parts of at least
/// [`MIN_SORT_PART`] entries ([`MIN_SORT_PART_ON_TWO`] below [`SPREAD_FROM`] threads) run at once on the
/// current pool (fewer: serially).
fn sort_in_parts(sorter: &mut KeySorter, entries: &mut BoundedVec<Entry>, threads: usize) {
    let min_part = match threads {
        ..SPREAD_FROM => MIN_SORT_PART_ON_TWO,
        _ => MIN_SORT_PART,
    };
    let parts = threads.min(entries.len() / min_part);
    if parts < 2 {
        return sorter.sort(entries);
    }
    let Some((plan, spare)) = sorter.radix(entries) else {
        return sorter.sort(entries);
    };
    let part_len = entries.len().div_ceil(parts);
    for pass in 0..plan.passes() {
        let counts: Vec<Histogram> = entries
            .par_chunks(part_len)
            .map(|part| {
                let mut h = [0u32; RADIX];
                plan.count(part, pass, &mut h);
                h
            })
            .collect();
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
            });
        std::mem::swap(entries, spare);
    }
}

/// The filter's and the sort's loops spread over the pool the calling thread works for, for a
/// job spawned on a run's pool beside the pipeline (the look-ahead's filter on more than two
/// threads): its tasks share the pool's threads with the pipeline's. Its other loops are
/// serial. The same results as [`Serial`], in the same order.
#[derive(Debug, Clone, Copy, Default)]
pub struct OnThisPool;

impl Executor for OnThisPool {
    /// `src` is cut into tasks (`task_len`); each task writes what it keeps to the front of
    /// its own stretch of `dst`, and the stretches are then closed up in order.
    fn filter_map_into<T, U, A>(
        &self,
        src: &[T],
        dst: &mut BoundedVec<U>,
        unit: impl Fn(&T, &mut A) -> Option<U> + Sync + Send,
        tally: impl FnMut(A),
    ) -> bool
    where
        T: Sync,
        U: Default + Clone + Send,
        A: Default + Send,
    {
        let start = dst.len();
        if src.len() > dst.capacity() - start {
            return false;
        }
        dst.extend_default(start + src.len());
        let task = task_len(src.len(), rayon::current_num_threads());
        let per_task = filter_in_tasks(src, &mut dst[start..], task, &unit);
        close_up(dst, start, task, per_task, tally);
        true
    }

    fn sort(&self, sorter: &mut KeySorter, entries: &mut BoundedVec<Entry>) {
        sort_in_parts(sorter, entries, rayon::current_num_threads());
    }
}

/// The core's serial loops for a task run on the pool beside the pipeline (the look-ahead's
/// filter): between pieces of its work (a task's worth of points, 16 384 entries of a pass of
/// the sort) the thread runs all the pool has waiting (`give_way`), so the pipeline's parallel
/// loops still get both threads, and the task's own work fills the stretches where the
/// pipeline runs serially. The same results as [`Serial`], in the same order.
#[derive(Debug, Clone, Copy, Default)]
pub struct Yielding;

impl Executor for Yielding {
    fn filter_map_into<T, U, A>(
        &self,
        src: &[T],
        dst: &mut BoundedVec<U>,
        unit: impl Fn(&T, &mut A) -> Option<U> + Sync + Send,
        mut tally: impl FnMut(A),
    ) -> bool
    where
        T: Sync,
        U: Default + Clone + Send,
        A: Default + Send,
    {
        if src.len() > dst.capacity() - dst.len() {
            return false;
        }
        for part in src.chunks(POINTS_PER_TASK) {
            // Fits: the whole did.
            Serial.filter_map_into(part, dst, &unit, &mut tally);
            give_way();
        }
        true
    }

    fn sort(&self, sorter: &mut KeySorter, entries: &mut BoundedVec<Entry>) {
        sorter.sort_pausing(entries, give_way);
    }
}

/// Runs what the pool has waiting, until nothing is: the pipeline's parallel loops go first.
fn give_way() {
    while rayon::yield_now() == Some(rayon::Yield::Executed) {}
}

/// The executor for a thread count: the core's serial loops for one thread, a rayon pool for
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

    /// Runs `f` on one of the pool's threads while this thread runs `here` (for
    /// [`Workers::Serial`], `here` then `f`, both on this thread); `f`'s result. On the pool,
    /// `f`'s parallel loops run inside it and its serial parts leave no thread waiting beside
    /// the pool's; `here` need not be `Send`: reading the next frame from a source, say.
    pub fn install_beside<R: Send>(&self, f: impl FnOnce() -> R + Send, here: impl FnOnce()) -> R {
        match self {
            Workers::Serial => {
                here();
                f()
            }
            Workers::Pool(r) => {
                let mut out = None;
                r.pool.in_place_scope(|s| {
                    s.spawn(|_| out = Some(f()));
                    here();
                });
                // The scope returns once its task has run (or passes on its panic).
                out.expect("a rayon scope waits for its tasks")
            }
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

impl Executor for Workers {
    fn map_in_order<T, S, R>(
        &self,
        items: &[T],
        init: impl Fn() -> S + Sync + Send,
        unit: impl Fn(&mut S, &T) -> R + Sync + Send,
        sink: impl FnMut(R),
    ) where
        T: Sync,
        R: Send + 'static,
    {
        match self {
            Workers::Serial => Serial.map_in_order(items, init, unit, sink),
            Workers::Pool(r) => r.map_in_order(items, init, unit, sink),
        }
    }

    fn update_each<T: Send>(&self, items: &mut [T], unit: impl Fn(&mut T) + Sync + Send) {
        match self {
            Workers::Serial => Serial.update_each(items, unit),
            Workers::Pool(r) => r.update_each(items, unit),
        }
    }

    fn filter_map_into<T, U, A>(
        &self,
        src: &[T],
        dst: &mut BoundedVec<U>,
        unit: impl Fn(&T, &mut A) -> Option<U> + Sync + Send,
        tally: impl FnMut(A),
    ) -> bool
    where
        T: Sync,
        U: Default + Clone + Send,
        A: Default + Send,
    {
        match self {
            Workers::Serial => Serial.filter_map_into(src, dst, unit, tally),
            Workers::Pool(r) => r.filter_map_into(src, dst, unit, tally),
        }
    }

    fn sort(&self, sorter: &mut KeySorter, entries: &mut BoundedVec<Entry>) {
        match self {
            Workers::Serial => Serial.sort(sorter, entries),
            Workers::Pool(r) => r.sort(sorter, entries),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::Cell;

    #[test]
    fn install_beside_runs_both_and_returns_the_pool_task_s_result() {
        for threads in [1, 2] {
            let workers = Workers::new(threads).unwrap();
            // `here` holds a `Cell` (not `Sync`): it stays on this thread.
            let read = Cell::new(false);
            let on_pool = workers.install_beside(
                || rayon::current_thread_index().is_some(),
                || read.set(true),
            );
            assert!(read.get());
            assert_eq!(on_pool, threads > 1, "{threads} thread(s)");
        }
    }

    #[test]
    fn the_yielding_and_pool_loops_give_the_serial_ones_results() {
        let pool = Rayon::new(2).unwrap();
        let src: Vec<u32> = (0..20_000).collect();
        let unit = |x: &u32, n: &mut usize| {
            *n += 1;
            (!x.is_multiple_of(3)).then_some(x * 2)
        };
        let (mut serial, mut yielding) = (
            BoundedVec::with_capacity(src.len()),
            BoundedVec::with_capacity(src.len()),
        );
        let (mut seen_serial, mut seen_yielding) = (0, 0);
        assert!(Serial.filter_map_into(&src, &mut serial, unit, |n| seen_serial += n));
        pool.pool.install(|| {
            assert!(Yielding.filter_map_into(&src, &mut yielding, unit, |n| seen_yielding += n));
        });
        assert_eq!(
            (serial[..].to_vec(), seen_serial),
            (yielding[..].to_vec(), seen_yielding)
        );
        // Spread over the pool of the calling thread, in tasks of every length it may choose.
        for threads in [2, 3, 16] {
            let pool = Rayon::new(threads).unwrap();
            let mut spread = BoundedVec::with_capacity(src.len());
            let mut seen_spread = 0;
            pool.pool.install(|| {
                assert!(OnThisPool.filter_map_into(&src, &mut spread, unit, |n| seen_spread += n));
            });
            assert_eq!(
                (serial[..].to_vec(), seen_serial),
                (spread[..].to_vec(), seen_spread),
                "{threads} threads"
            );
        }
        // Too many for the room left: refused, as the serial loop refuses.
        let mut small = BoundedVec::with_capacity(10);
        assert!(!Yielding.filter_map_into(&src, &mut small, unit, |_| {}));
    }
}
