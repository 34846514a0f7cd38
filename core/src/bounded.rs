//! [`BoundedVec`]: a vector whose capacity is fixed when it is made.
//!
//! The pipeline's large buffers (a whole scan of points) do not fit on an embedded stack or in
//! a `heapless::Vec` built on the stack, so they are allocated once, at the capacity the
//! [`Capacity`](crate::Capacity) type fixes at compile time, and then never grow: a push on a
//! full vector hands the item back, as `heapless` does. Never panics.

use alloc::vec::Vec;
use core::ops::{Deref, DerefMut};

/// A vector with a capacity fixed at construction; it never reallocates.
#[derive(Debug, Clone)]
pub struct BoundedVec<T> {
    items: Vec<T>,
    capacity: usize,
}

impl<T> BoundedVec<T> {
    /// Allocates room for exactly `capacity` items, once.
    pub fn with_capacity(capacity: usize) -> Self {
        Self {
            items: Vec::with_capacity(capacity),
            capacity,
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
        self.items.len() >= self.capacity
    }

    /// Appends `item`, or hands it back when the vector is full.
    #[inline]
    pub fn push(&mut self, item: T) -> Result<(), T> {
        if self.is_full() {
            return Err(item);
        }
        self.items.push(item);
        Ok(())
    }

    /// Removes every item; the allocation stays.
    #[inline]
    pub fn clear(&mut self) {
        self.items.clear();
    }

    /// Appends default items up to `len` items in all, or up to the capacity if that is less.
    pub fn extend_default(&mut self, len: usize)
    where
        T: Default + Clone,
    {
        let len = len.min(self.capacity);
        if len > self.items.len() {
            self.items.resize(len, T::default());
        }
    }

    /// Shortens the vector to `len` items (no effect if it is shorter).
    #[inline]
    pub fn truncate(&mut self, len: usize) {
        self.items.truncate(len);
    }
}

impl<T> Deref for BoundedVec<T> {
    type Target = [T];
    #[inline]
    fn deref(&self) -> &[T] {
        &self.items
    }
}

impl<T> DerefMut for BoundedVec<T> {
    #[inline]
    fn deref_mut(&mut self) -> &mut [T] {
        &mut self.items
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn full_vector_hands_the_item_back_and_never_grows() {
        let mut v = BoundedVec::with_capacity(3);
        for i in 0..3 {
            assert_eq!(v.push(i), Ok(()));
        }
        assert_eq!(v.push(7), Err(7));
        assert_eq!(&v[..], &[0, 1, 2]);
        assert_eq!(v.capacity(), 3);
        v.clear();
        assert!(v.is_empty());
        assert_eq!(v.push(5), Ok(()));
    }
}
