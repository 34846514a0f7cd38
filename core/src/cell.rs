//! World-fixed cells: integer keys, axes, and the one copy of the neighbour rule.
//!
//! A cell is the axis-aligned cube `[k·s, (k+1)·s)` per axis for edge `s = cell_size`
//! (docs/design.md §1). Keys are `i32` per axis; a point whose key would not fit is rejected by
//! [`CellKey::containing`] rather than wrapped.

use crate::math::Vec3;

/// One of the three coordinate axes; a layer predicts the coordinate along its axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Axis {
    /// x
    X = 0,
    /// y
    Y = 1,
    /// z
    Z = 2,
}

impl Axis {
    /// All three axes, in index order.
    pub const ALL: [Axis; 3] = [Axis::X, Axis::Y, Axis::Z];

    /// 0, 1 or 2.
    #[inline]
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The axis with index `i % 3`.
    #[inline]
    pub const fn from_index(i: usize) -> Axis {
        match i % 3 {
            0 => Axis::X,
            1 => Axis::Y,
            _ => Axis::Z,
        }
    }

    /// The two location axes `(a, b)` of a layer along this axis, ordered so that
    /// `(a, b, self)` is a cyclic permutation of `(x, y, z)`: then `e_a × e_b = e_self`.
    #[inline]
    pub const fn locations(self) -> (usize, usize) {
        match self {
            Axis::X => (1, 2),
            Axis::Y => (2, 0),
            Axis::Z => (0, 1),
        }
    }
}

/// Integer index of a world-fixed cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CellKey {
    /// Index along x.
    pub x: i32,
    /// Index along y.
    pub y: i32,
    /// Index along z.
    pub z: i32,
}

impl CellKey {
    /// A key from its three indices.
    #[inline]
    pub const fn new(x: i32, y: i32, z: i32) -> Self {
        Self { x, y, z }
    }

    /// The key as one integer with the same order as the key's own (`x`, then `y`, then `z`):
    /// sorting by it is one comparison instead of three.
    #[inline]
    pub fn sort_value(&self) -> u128 {
        let u = |v: i32| (v as u32 ^ 0x8000_0000) as u128;
        (u(self.x) << 64) | (u(self.y) << 32) | u(self.z)
    }

    /// The cell containing world point `p`, or `None` when `p` is not finite or its index does
    /// not fit an `i32`.
    #[inline]
    pub fn containing(p: &Vec3, cell_size: f64) -> Option<Self> {
        // Without branches per coordinate (`libm::floor` was 2 % of a scan's time, and the
        // per-coordinate branches as much again): the range test refuses NaN too; within it,
        // floor is truncation (saturating `as`), one less below zero.
        // One division, three multiplications (a key may differ from `floor(p / cell_size)`
        // only for a point within an ulp of a face; every key comes from here).
        let inv = 1.0 / cell_size;
        let q = [p.x * inv, p.y * inv, p.z * inv];
        let inside = |v: f64| (v >= f64::from(i32::MIN)) & (v < f64::from(i32::MAX));
        let floor = |v: f64| {
            let t = v as i32;
            t.wrapping_sub(i32::from(f64::from(t) > v))
        };
        (inside(q[0]) & inside(q[1]) & inside(q[2]))
            .then(|| Self::new(floor(q[0]), floor(q[1]), floor(q[2])))
    }

    /// The index along `axis`.
    #[inline]
    pub const fn get(&self, axis: Axis) -> i32 {
        match axis {
            Axis::X => self.x,
            Axis::Y => self.y,
            Axis::Z => self.z,
        }
    }

    /// The cell `steps` cells away along `axis` (`self ± i·e_axis`, docs/design.md §1.4), or `None` on
    /// overflow.
    #[inline]
    pub fn offset(&self, axis: Axis, steps: i32) -> Option<Self> {
        let mut k = *self;
        match axis {
            Axis::X => k.x = k.x.checked_add(steps)?,
            Axis::Y => k.y = k.y.checked_add(steps)?,
            Axis::Z => k.z = k.z.checked_add(steps)?,
        }
        Some(k)
    }

    /// The world coordinates of the cell's centre (for a key of tiles, `cell_size` the tile's
    /// side: the tile's centre).
    #[inline]
    pub fn centre(&self, cell_size: f64) -> Vec3 {
        self.min_corner(cell_size).add_scalar(0.5 * cell_size)
    }

    /// The world coordinates of the cell's minimum corner.
    #[inline]
    pub fn min_corner(&self, cell_size: f64) -> Vec3 {
        Vec3::new(
            f64::from(self.x) * cell_size,
            f64::from(self.y) * cell_size,
            f64::from(self.z) * cell_size,
        )
    }
}

/// A fixed, deterministic hasher for cell keys (FxHash-style multiply-rotate).
///
/// Deterministic so that the map iterates in the same order on every run and platform.
#[derive(Debug, Clone, Copy, Default)]
pub struct CellHasher {
    hash: u64,
}

impl core::hash::Hasher for CellHasher {
    #[inline]
    fn finish(&self) -> u64 {
        // Final avalanche so that every bit, the table's low ones too, depends on all keys.
        let mut h = self.hash;
        h ^= h >> 33;
        h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
        h ^= h >> 33;
        h
    }

    #[inline]
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }

    #[inline]
    fn write_u32(&mut self, i: u32) {
        self.write_u64(u64::from(i));
    }

    #[inline]
    fn write_i32(&mut self, i: i32) {
        self.write_u64(u64::from(i as u32));
    }

    #[inline]
    fn write_i64(&mut self, i: i64) {
        self.write_u64(i as u64);
    }

    #[inline]
    fn write_u64(&mut self, i: u64) {
        self.hash = (self.hash.rotate_left(5) ^ i).wrapping_mul(0x517c_c1b7_2722_0a95);
    }
}

/// `BuildHasher` for [`CellHasher`].
pub type BuildCellHasher = core::hash::BuildHasherDefault<CellHasher>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_floor_toward_negative_infinity() {
        let k = CellKey::containing(&Vec3::new(-0.1, 0.0, 1.7), 1.6).unwrap();
        assert_eq!(k, CellKey::new(-1, 0, 1));
        assert!(CellKey::containing(&Vec3::new(f64::NAN, 0.0, 0.0), 1.6).is_none());
        assert!(CellKey::containing(&Vec3::new(1e12, 0.0, 0.0), 1.6).is_none());
    }

    #[test]
    fn sort_value_orders_like_the_key() {
        let v = [i32::MIN, -7, -1, 0, 1, 9, i32::MAX];
        let mut keys = alloc::vec::Vec::new();
        for x in v {
            for y in v {
                for z in v {
                    keys.push(CellKey::new(x, y, z));
                }
            }
        }
        for a in &keys {
            for b in &keys {
                assert_eq!(a.cmp(b), a.sort_value().cmp(&b.sort_value()), "{a:?} {b:?}");
            }
        }
    }

    #[test]
    fn offset_checks_overflow() {
        let k = CellKey::new(i32::MAX, 0, 0);
        assert!(k.offset(Axis::X, 1).is_none());
        assert_eq!(k.offset(Axis::Y, -2), Some(CellKey::new(i32::MAX, -2, 0)));
    }

    #[test]
    fn location_axes_are_right_handed() {
        for axis in Axis::ALL {
            let (a, b) = axis.locations();
            let mut ea = Vec3::zeros();
            let mut eb = Vec3::zeros();
            ea[a] = 1.0;
            eb[b] = 1.0;
            assert_eq!(ea.cross(&eb)[axis.index()], 1.0);
        }
    }
}
