//! [`BoundedVec`]: a vector whose capacity is fixed when it is made.
//!
//! The pipeline's large buffers (a whole scan of points) do not fit on an embedded stack or in
//! a `heapless::Vec` built on the stack, so they are made once, at the capacity the
//! [`Capacity`](crate::Capacity) type fixes at compile time, and then never grow: a push on a
//! full vector hands the item back, as `heapless` does. Never panics.
//!
//! The items live in one of two places:
//! - memory taken once from the global allocator ([`BoundedVec::with_capacity`], with the
//!   `alloc` feature), freed when the vector is dropped;
//! - a `'static` slice the caller lends ([`BoundedVec::in_slice`]; see [`crate::storage`]), so
//!   that the core runs with no allocator at all.

#[cfg(feature = "alloc")]
use alloc::vec::Vec;
use core::ops::{Deref, DerefMut};

/// A value with all-zero contents that a buffer slot holds before it is written.
pub trait Empty: Copy {
    /// The value.
    const EMPTY: Self;
}

/// Where the items are.
#[derive(Debug)]
enum Items<T: 'static> {
    /// From the global allocator: the vector's own length.
    #[cfg(feature = "alloc")]
    Heap(Vec<T>),
    /// In caller storage: the first `len` of `slots`.
    Lent { slots: &'static mut [T], len: usize },
}

/// A vector with a capacity fixed at construction; it never reallocates.
#[derive(Debug)]
pub struct BoundedVec<T: 'static> {
    items: Items<T>,
    capacity: usize,
}

#[cfg(feature = "alloc")]
impl<T> BoundedVec<T> {
    /// Allocates room for exactly `capacity` items, once.
    pub fn with_capacity(capacity: usize) -> Self {
        Self {
            items: Items::Heap(Vec::with_capacity(capacity)),
            capacity,
        }
    }

    /// Allocates `len` copies of `value`, once: a full vector. For a value whose bytes are all
    /// zero (of a type the standard library knows it for, such as arrays of integers) the
    /// memory comes zeroed from the system, untouched until written.
    pub fn filled(len: usize, value: T) -> Self
    where
        T: Clone,
    {
        Self {
            items: Items::Heap(alloc::vec![value; len]),
            capacity: len,
        }
    }
}

/// Without the `alloc` feature, the unit tests still build their pipelines with
/// `with_capacity`: in leaked memory, lent as caller storage would be (so the tests run that
/// path).
#[cfg(all(test, not(feature = "alloc")))]
impl<T: Empty> BoundedVec<T> {
    /// Room for `capacity` items, in leaked memory.
    pub fn with_capacity(capacity: usize) -> Self {
        Self::in_slice(alloc::vec![T::EMPTY; capacity].leak())
    }

    /// `len` copies of `value`, in leaked memory.
    pub fn filled(len: usize, value: T) -> Self {
        Self::in_slice_filled(alloc::vec![value; len].leak(), value)
    }
}

#[cfg(feature = "alloc")]
impl<T: Clone> Clone for BoundedVec<T> {
    /// A copy in memory from the global allocator, with the same capacity (even of a vector in
    /// caller storage).
    fn clone(&self) -> Self {
        let mut items = Vec::with_capacity(self.capacity);
        items.extend_from_slice(self);
        Self {
            items: Items::Heap(items),
            capacity: self.capacity,
        }
    }
}

impl<T> BoundedVec<T> {
    /// An empty vector in `slots` (the caller's storage), with their number as its capacity.
    pub fn in_slice(slots: &'static mut [T]) -> Self {
        Self {
            capacity: slots.len(),
            items: Items::Lent { slots, len: 0 },
        }
    }

    /// A full vector of `slots`, each set to `value`.
    pub fn in_slice_filled(slots: &'static mut [T], value: T) -> Self
    where
        T: Clone,
    {
        slots.fill(value);
        let len = slots.len();
        Self {
            capacity: len,
            items: Items::Lent { slots, len },
        }
    }

    /// The fixed capacity.
    #[inline]
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Whether no more items fit.
    #[inline]
    pub fn is_full(&self) -> bool {
        self.len() >= self.capacity
    }

    /// Appends `item`, or hands it back when the vector is full.
    #[inline]
    pub fn push(&mut self, item: T) -> Result<(), T> {
        if self.is_full() {
            return Err(item);
        }
        match &mut self.items {
            #[cfg(feature = "alloc")]
            Items::Heap(v) => v.push(item),
            Items::Lent { slots, len } => match slots.get_mut(*len) {
                Some(slot) => {
                    *slot = item;
                    *len += 1;
                }
                None => return Err(item),
            },
        }
        Ok(())
    }

    /// Removes every item; the memory stays.
    #[inline]
    pub fn clear(&mut self) {
        self.truncate(0);
    }

    /// Appends default items up to `len` items in all, or up to the capacity if that is less.
    pub fn extend_default(&mut self, len: usize)
    where
        T: Default + Clone,
    {
        let len = len.min(self.capacity);
        match &mut self.items {
            #[cfg(feature = "alloc")]
            Items::Heap(v) => {
                if len > v.len() {
                    v.resize(len, T::default());
                }
            }
            Items::Lent { slots, len: n } => {
                if len > *n {
                    slots
                        .iter_mut()
                        .take(len)
                        .skip(*n)
                        .for_each(|s| *s = T::default());
                    *n = len;
                }
            }
        }
    }

    /// Shortens the vector to `len` items (no effect if it is shorter).
    #[inline]
    pub fn truncate(&mut self, len: usize) {
        match &mut self.items {
            #[cfg(feature = "alloc")]
            Items::Heap(v) => v.truncate(len),
            Items::Lent { len: n, .. } => *n = len.min(*n),
        }
    }
}

impl<T> Deref for BoundedVec<T> {
    type Target = [T];
    #[inline]
    fn deref(&self) -> &[T] {
        match &self.items {
            #[cfg(feature = "alloc")]
            Items::Heap(v) => v,
            Items::Lent { slots, len } => slots.get(..*len).unwrap_or_default(),
        }
    }
}

impl<T> DerefMut for BoundedVec<T> {
    #[inline]
    fn deref_mut(&mut self) -> &mut [T] {
        match &mut self.items {
            #[cfg(feature = "alloc")]
            Items::Heap(v) => v,
            Items::Lent { slots, len } => slots.get_mut(..*len).unwrap_or_default(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lend<T: Clone>(n: usize, value: T) -> &'static mut [T] {
        alloc::vec![value; n].leak()
    }

    #[test]
    fn full_vector_hands_the_item_back_and_never_grows() {
        let all = [
            BoundedVec::with_capacity(3),
            BoundedVec::in_slice(lend(3, 0)),
        ];
        for mut v in all {
            for i in 0..3 {
                assert_eq!(v.push(i), Ok(()));
            }
            assert_eq!(v.push(7), Err(7));
            assert_eq!(&v[..], &[0, 1, 2]);
            assert_eq!(v.capacity(), 3);
            v.truncate(1);
            assert_eq!(&v[..], &[0]);
            v.extend_default(5);
            assert_eq!(&v[..], &[0, 0, 0]);
            v.clear();
            assert!(v.is_empty());
            assert_eq!(v.push(5), Ok(()));
        }
        let full = BoundedVec::in_slice_filled(lend(4, 1u8), 9);
        assert_eq!(&full[..], &[9; 4]);
        assert!(full.is_full());
    }
}
