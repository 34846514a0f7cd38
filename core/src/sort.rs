//! Sorting entries by [`CellKey`] in linear time (filter and bucketing, docs/design.md §1.1 steps 1, 3).
//!
//! The keys of one scan lie in a small box (a 100 m range spans about 750 voxels of 0.27 m or
//! 125 cells of 1.6 m along each axis), so a key measured from the box's minimum corner packs
//! into a few dozen bits. An LSD radix sort on those bits, 11 at a time, moves the entries
//! between the caller's buffer and one of the sorter's own (sequential writes per digit, so
//! it stays in cache, unlike a permutation by index). It orders entries as [`CellKey`]'s
//! `Ord` does (x, then y, then z) and keeps equal keys in input order. When the box needs more
//! than 64 bits (points scattered over thousands of kilometres) or the entries outnumber the
//! sorter's capacity, the comparison sort takes over, with the same order of keys.

use crate::bounded::BoundedVec;
use crate::cell::CellKey;
use crate::math::Point;

/// Bits sorted per radix pass.
const DIGIT_BITS: u32 = 11;
/// Entries between two pauses of [`KeySorter::sort_pausing`].
const PAUSE_EVERY: usize = 16_384;
/// Passes for a 64-bit key.
const MAX_PASSES: usize = 64usize.div_ceil(DIGIT_BITS as usize);
/// The values one digit takes.
pub const RADIX: usize = 1 << DIGIT_BITS;
/// How many entries have each digit value (in one pass).
pub type Histogram = [u32; RADIX];

/// An entry of the filter's and bucketing's buffers: a key and a point.
pub type Entry = (CellKey, Point);

/// A reusable radix sorter for up to its capacity of entries (it owns one spare buffer).
#[derive(Debug)]
#[cfg_attr(feature = "alloc", derive(Clone))]
pub struct KeySorter {
    spare: BoundedVec<Entry>,
}

impl KeySorter {
    /// A sorter for up to `capacity` entries (its buffer is allocated now).
    #[cfg(any(feature = "alloc", test))]
    pub fn with_capacity(capacity: usize) -> Self {
        Self {
            spare: BoundedVec::with_capacity(capacity),
        }
    }

    /// A sorter whose buffer is `spare`, the caller's.
    pub fn in_slice(spare: &'static mut [Entry]) -> Self {
        Self {
            spare: BoundedVec::in_slice(spare),
        }
    }

    /// Sorts `entries` by key, equal keys in input order (in an unspecified but deterministic
    /// order when the comparison sort takes over). `entries` may come back in the sorter's
    /// buffer: both have the sorter's capacity, then.
    pub fn sort(&mut self, entries: &mut BoundedVec<Entry>) {
        self.sort_pausing(entries, || {});
    }

    /// [`sort`](Self::sort), calling `pause` after every 16 384 entries of each pass over them
    /// (the same order): a sort run beside other work can give way to it there.
    pub fn sort_pausing(&mut self, entries: &mut BoundedVec<Entry>, mut pause: impl FnMut()) {
        let Some((plan, spare)) = self.radix(entries) else {
            entries.sort_unstable_by_key(|e| e.0.sort_value());
            return;
        };
        // One pass over the entries counts the digits of every pass.
        let mut counts = [[0u32; RADIX]; MAX_PASSES];
        for piece in entries.chunks(PAUSE_EVERY) {
            for e in piece {
                for (p, count) in counts.iter_mut().enumerate().take(plan.passes) {
                    count[plan.digit(&e.0, p)] += 1;
                }
            }
            pause();
        }
        for (p, count) in counts.iter_mut().enumerate().take(plan.passes) {
            if moves_nothing(&[count]) {
                continue;
            }
            // Each digit's first slot: the entries of one digit go in input order (stable).
            let mut sum = 0;
            for c in count.iter_mut() {
                (*c, sum) = (sum, sum + *c);
            }
            for piece in entries.chunks(PAUSE_EVERY) {
                for e in piece {
                    let slot = &mut count[plan.digit(&e.0, p)];
                    if let Some(t) = spare.get_mut(*slot as usize) {
                        *t = *e;
                    }
                    *slot += 1;
                }
                pause();
            }
            core::mem::swap(entries, spare);
        }
    }

    /// For a radix sort of `entries` (at least two): its plan, and the sorter's buffer with
    /// as many entries as `entries` (a pass writes every one of them, then the two buffers
    /// are swapped). `None` when the comparison sort must take over (keys wider than 64 bits,
    /// more entries than the sorter holds) or there is nothing to sort. [`sort`](Self::sort)
    /// and a parallel sort (std adapters) both start here.
    pub fn radix(
        &mut self,
        entries: &BoundedVec<Entry>,
    ) -> Option<(RadixPlan, &mut BoundedVec<Entry>)> {
        let n = entries.len();
        let fits = self.spare.capacity() >= n && entries.capacity() == self.spare.capacity();
        if n < 2 || !fits {
            return None;
        }
        let layout = Layout::of(entries)?;
        let plan = RadixPlan {
            layout,
            passes: layout.total_bits.div_ceil(DIGIT_BITS) as usize,
        };
        // Every slot is written by a pass: only a shorter buffer needs filling.
        self.spare.truncate(n);
        self.spare.extend_default(n);
        Some((plan, &mut self.spare))
    }
}

/// The passes of one radix sort: the layout of its keys and how many digits they take.
#[derive(Debug, Clone, Copy)]
pub struct RadixPlan {
    layout: Layout,
    passes: usize,
}

impl RadixPlan {
    /// Passes, least significant digit first.
    pub fn passes(&self) -> usize {
        self.passes
    }

    /// The digit of `key` that pass `pass` sorts by.
    #[inline]
    pub fn digit(&self, key: &CellKey, pass: usize) -> usize {
        let shift = pass as u32 * DIGIT_BITS;
        let digit = self.layout.pack(key).checked_shr(shift).unwrap_or(0);
        (digit & (RADIX as u64 - 1)) as usize
    }

    /// Adds the digits of pass `pass` of `entries` to `histogram`.
    pub fn count(&self, entries: &[Entry], pass: usize, histogram: &mut Histogram) {
        for e in entries {
            histogram[self.digit(&e.0, pass)] += 1;
        }
    }
}

/// True when one digit holds every entry counted in `parts` (the histograms of one pass over
/// parts of the input): the pass would move nothing and is skipped.
pub fn moves_nothing(parts: &[&Histogram]) -> bool {
    let n: u32 = parts.iter().flat_map(|h| h.iter()).sum();
    (0..RADIX).any(|d| parts.iter().map(|h| h[d]).sum::<u32>() == n)
}

/// How a key packs into a `u64`: `(x - x0) << (by + bz) | (y - y0) << bz | (z - z0)`.
#[derive(Debug, Clone, Copy)]
struct Layout {
    min: [i64; 3],
    bits: [u32; 3],
    total_bits: u32,
}

impl Layout {
    /// The layout for the keys of `entries`, if they fit 64 bits.
    fn of(entries: &[Entry]) -> Option<Self> {
        // Written out per coordinate: rustc 1.95 (LLVM 20) with `-C target-cpu=x86-64-v3`
        // miscompiled the loop over `[k.x, k.y, k.z]` that was here into one that ran past
        // the end of `entries` (a segfault in safe code; nightly 1.97 compiles it correctly).
        // `.ci/run` builds and runs the core's tests for x86-64-v3 to catch such things.
        let (mut lo, mut hi) = ([i32::MAX; 3], [i32::MIN; 3]);
        for (k, _) in entries {
            lo = [lo[0].min(k.x), lo[1].min(k.y), lo[2].min(k.z)];
            hi = [hi[0].max(k.x), hi[1].max(k.y), hi[2].max(k.z)];
        }
        let (min, max) = (lo.map(i64::from), hi.map(i64::from));
        let width = |span: u64| u64::BITS - span.leading_zeros();
        let bits: [u32; 3] = core::array::from_fn(|c| width(max[c].abs_diff(min[c])));
        let total_bits = bits.iter().sum::<u32>();
        (total_bits <= 64).then_some(Self {
            min,
            bits,
            total_bits,
        })
    }

    #[inline]
    fn pack(&self, key: &CellKey) -> u64 {
        let rel = |v: i32, c: usize| i64::from(v).abs_diff(self.min[c]);
        // Shifts by less than 64: each part has fewer bits than the total.
        let shl = |v: u64, by: u32| v.checked_shl(by).unwrap_or(0);
        shl(rel(key.x, 0), self.bits[1] + self.bits[2])
            | shl(rel(key.y, 1), self.bits[2])
            | rel(key.z, 2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::vec::Vec;

    /// A deterministic pseudo-random sequence.
    fn lcg(seed: &mut u64) -> u64 {
        *seed = seed
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        *seed >> 33
    }

    /// Sorts `entries` and compares with a stable sort by key (alloc's); without `stable`,
    /// equal keys may come in any order.
    fn check(entries: Vec<(CellKey, u32)>, sorter: &mut KeySorter, stable: bool) {
        let mut want = entries.clone();
        want.sort_by_key(|e| e.0);
        // The entry's number rides in the point.
        let mut buffer = BoundedVec::with_capacity(sorter.spare.capacity());
        for (k, i) in &entries {
            let _ = buffer.push((*k, [*i as f32, 0.0, 0.0]));
        }
        if buffer.len() < entries.len() {
            buffer = BoundedVec::with_capacity(entries.len());
            for (k, i) in &entries {
                let _ = buffer.push((*k, [*i as f32, 0.0, 0.0]));
            }
        }
        sorter.sort(&mut buffer);
        let mut got: Vec<_> = buffer.iter().map(|(k, p)| (*k, p[0] as u32)).collect();
        if !stable {
            got.sort_by_key(|e| (e.0, e.1));
            want.sort_by_key(|e| (e.0, e.1));
        }
        assert_eq!(got, want);
    }

    #[test]
    fn sorts_like_the_key_order_and_keeps_ties_in_input_order() {
        let mut sorter = KeySorter::with_capacity(5000);
        let mut seed = 1;
        for spread in [1, 3, 40, 700, 5000] {
            let entries: Vec<_> = (0..5000u32)
                .map(|i| {
                    let mut c = || (lcg(&mut seed) % spread) as i32 - spread as i32 / 2;
                    (CellKey::new(c(), c(), c()), i)
                })
                .collect();
            check(entries, &mut sorter, true);
        }
    }

    #[test]
    fn pausing_sorts_the_same_and_pauses_after_every_piece_of_each_pass() {
        const N: usize = 40_000;
        let entries = || {
            let (mut seed, mut out) = (7, BoundedVec::with_capacity(N));
            for i in 0..N as u32 {
                let mut c = || (lcg(&mut seed) % 900) as i32 - 450;
                let _ = out.push((CellKey::new(c(), c(), c()), [i as f32, 0.0, 0.0]));
            }
            out
        };
        let (mut entries, mut plain) = (entries(), entries());
        KeySorter::with_capacity(N).sort(&mut plain);
        let mut pauses = 0;
        KeySorter::with_capacity(N).sort_pausing(&mut entries, || pauses += 1);
        assert_eq!(entries[..], plain[..]);
        // Keys of 10 bits an axis: the counting pass, then three passes of 11 bits, each in
        // three pieces (16 384, 16 384 and 7 232 entries).
        assert_eq!(pauses, 4 * 3);
    }

    #[test]
    fn falls_back_beyond_its_bits_or_capacity() {
        let mut sorter = KeySorter::with_capacity(100);
        // Keys at the ends of i32: 96 bits, more than a u64.
        let far = [i32::MIN, -5, 0, 7, i32::MAX];
        let entries: Vec<_> = (0..60u32)
            .map(|i| {
                let k = |s: u32| far[((i * s) % 5) as usize];
                (CellKey::new(k(1), k(3), k(7)), i)
            })
            .collect();
        check(entries.clone(), &mut sorter, false);
        // More entries than the sorter holds.
        let many: Vec<_> = (0..300u32)
            .map(|i| (CellKey::new((i % 7) as i32, 0, (i % 3) as i32), i))
            .collect();
        check(many, &mut sorter, false);
        check(Vec::new(), &mut sorter, true);
        check(entries[..1].to_vec(), &mut sorter, true);
    }
}
