//! [`Executor`]: how a scan's data-parallel loops are run; [`Serial`] runs them in order.
//!
//! The pipeline's only pluggable part. The stages (filter, bucketing, reconstruction,
//! association, the update's move) express their per-point, per-cell and per-layer work as
//! calls to the four primitives below; an executor decides only how the units are spread over threads. The std
//! adapters' rayon pool is one. Whatever the executor, a stage's output must be the same to the
//! bit: each primitive hands its results back in input order, and the sort orders entries
//! exactly as [`KeySorter::sort`] does.
//!
//! This module sits at the bottom of the core: it knows the bounded buffers and the sorter,
//! never a stage.

use crate::bounded::BoundedVec;
use crate::sort::{Entry, KeySorter};

/// Runs the units of a scan's loops. Each default method is the serial loop; an implementation
/// overrides any of them to spread the units over workers, giving the same result.
pub trait Executor {
    /// Maps every item with `unit` and hands the results to `sink` in item order. `init` makes
    /// the working memory a worker reuses across its items (the result must not depend on it).
    /// The results own their data (`'static`), so that an executor may keep the buffer it
    /// gathers them in from one call to the next.
    fn map_in_order<T, S, R>(
        &self,
        items: &[T],
        init: impl Fn() -> S + Sync + Send,
        unit: impl Fn(&mut S, &T) -> R + Sync + Send,
        mut sink: impl FnMut(R),
    ) where
        T: Sync,
        R: Send + 'static,
    {
        let mut scratch = init();
        for item in items {
            sink(unit(&mut scratch, item));
        }
    }

    /// Appends what `unit` keeps of `src` to `dst`, in input order. `unit` maps one item to
    /// an output or to nothing, and may count into a tally (one per worker, starting from
    /// `A::default()`), which `tally` receives in input order. `dst` must have room for
    /// `src.len()` more items; without it nothing is done and `false` is returned, so that the
    /// caller can fall back to a loop that stops when full.
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
        let mut counts = A::default();
        for item in src {
            if let Some(out) = unit(item, &mut counts) {
                // There is room for every item: cannot fail.
                let _ = dst.push(out);
            }
        }
        tally(counts);
        true
    }

    /// Changes every item in place with `unit`, which sees one item only (so the result does
    /// not depend on the order the items are visited in).
    fn update_each<T: Send>(&self, items: &mut [T], unit: impl Fn(&mut T) + Sync + Send) {
        items.iter_mut().for_each(unit);
    }

    /// Sorts filter and bucketing entries by key, in exactly [`KeySorter::sort`]'s order.
    fn sort(&self, sorter: &mut KeySorter, entries: &mut BoundedVec<Entry>) {
        sorter.sort(entries)
    }
}

/// The serial loops: every unit in order, on the caller's thread.
#[derive(Debug, Clone, Copy, Default)]
pub struct Serial;

impl Executor for Serial {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_serial_primitives_keep_input_order_and_refuse_what_does_not_fit() {
        let mut seen = [0u32; 4];
        let mut n = 0;
        Serial.map_in_order(
            &[3u32, 1, 4, 1],
            || 10u32,
            |s, x| *s + x,
            |r| {
                seen[n] = r;
                n += 1;
            },
        );
        assert_eq!(seen, [13, 11, 14, 11]);

        let mut dst = BoundedVec::<u32>::with_capacity(4);
        let _ = dst.push(7);
        let mut odd = 0;
        let even_only = |x: &u32, odd: &mut usize| {
            if x.is_multiple_of(2) {
                Some(*x)
            } else {
                *odd += 1;
                None
            }
        };
        assert!(Serial.filter_map_into(&[2, 3, 4], &mut dst, even_only, |n| odd += n));
        assert_eq!((&dst[..], odd), (&[7, 2, 4][..], 1));
        assert!(!Serial.filter_map_into(&[2, 3], &mut dst, even_only, |_| {}));
        assert_eq!(&dst[..], &[7, 2, 4]);
    }
}
