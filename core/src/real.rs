//! The scalar of the hot arithmetic: `f64`, or `f32` for chips whose FPU has single
//! precision only (docs/design.md §1.17).
//!
//! The Gaussian-process reconstruction of every layer ([`crate::gp`]) is most of a scan's
//! arithmetic, and it is written once, generic over [`Real`]. A
//! [`Pipeline`](crate::Pipeline)'s second type parameter picks it at compile time:
//! `Pipeline<C>` is `Pipeline<C, f64>`, the host's choice; `Pipeline<C, f32>` is the firmware's.
//! On a Cortex-M4F every `f64` operation is a call into a software routine of tens of
//! instructions, every `f32` one a single FPU instruction.
//!
//! What stays `f64` in both (poses, their composition and the Levenberg-Marquardt solve) is
//! listed, with why, in docs/design.md §1.17. This trait holds only what the generic code
//! needs; each method is the operation of the same name on the primitive.

use core::cmp::Ordering;
use core::fmt::Debug;
use core::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// A floating-point scalar: [`f64`] or [`f32`].
pub trait Real:
    Copy
    + Debug
    + Default
    + PartialOrd
    + Send
    + Sync
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + 'static
{
    /// 0.
    const ZERO: Self;
    /// 1.
    const ONE: Self;
    /// +∞.
    const INFINITY: Self;
    /// -∞.
    const NEG_INFINITY: Self;
    /// The name for messages and tables (`f64`, `f32`).
    const NAME: &'static str;
    /// Whether this is `f32`: code whose single-precision form is a different algorithm, not
    /// the same one in other numbers (keeping world coordinates out of `f32`, say), branches
    /// on it; the branch is decided at compile time.
    const SINGLE: bool;

    /// The nearest value to `v` (`as`).
    fn from_f64(v: f64) -> Self;
    /// `v` exactly.
    fn from_f32(v: f32) -> Self;
    /// `n` rounded to the nearest value (`as`).
    fn from_usize(n: usize) -> Self;
    /// Widened to `f64` (exact).
    fn to_f64(self) -> f64;
    /// Narrowed to `f32` (`as`).
    fn to_f32(self) -> f32;
    /// Truncated towards zero, negatives and NaN to 0, saturating (`as usize`).
    fn to_index(self) -> usize;
    /// `√self` ([`crate::math::sqrt`] or [`crate::math::sqrt_f32`]).
    fn sqrt(self) -> Self;
    /// `e^self` ([`crate::math::exp`] or [`crate::math::exp_f32`]).
    fn exp(self) -> Self;
    /// `|self|`.
    fn abs(self) -> Self;
    /// The larger (the other if one is NaN).
    fn max(self, other: Self) -> Self;
    /// The smaller (the other if one is NaN).
    fn min(self, other: Self) -> Self;
    /// `self` clamped into `[lo, hi]`.
    fn clamp(self, lo: Self, hi: Self) -> Self;
    /// Neither infinite nor NaN.
    fn is_finite(self) -> bool;
    /// IEEE 754 total order.
    fn total_cmp(&self, other: &Self) -> Ordering;
}

macro_rules! real {
    ($t:ty, $single:expr, $sqrt:path, $exp:path, $fabs:path, $max:path, $min:path) => {
        impl Real for $t {
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;
            const INFINITY: Self = <$t>::INFINITY;
            const NEG_INFINITY: Self = <$t>::NEG_INFINITY;
            const NAME: &'static str = stringify!($t);
            const SINGLE: bool = $single;

            #[inline]
            fn from_f64(v: f64) -> Self {
                v as $t
            }
            #[inline]
            fn from_f32(v: f32) -> Self {
                <$t>::from(v)
            }
            #[inline]
            fn from_usize(n: usize) -> Self {
                n as $t
            }
            #[inline]
            fn to_f64(self) -> f64 {
                f64::from(self)
            }
            #[inline]
            fn to_f32(self) -> f32 {
                self as f32
            }
            #[inline]
            fn to_index(self) -> usize {
                self as usize
            }
            #[inline]
            fn sqrt(self) -> Self {
                $sqrt(self)
            }
            #[inline]
            fn exp(self) -> Self {
                $exp(self)
            }
            #[inline]
            fn abs(self) -> Self {
                $fabs(self)
            }
            #[inline]
            fn max(self, other: Self) -> Self {
                $max(self, other)
            }
            #[inline]
            fn min(self, other: Self) -> Self {
                $min(self, other)
            }
            #[inline]
            fn clamp(self, lo: Self, hi: Self) -> Self {
                <$t>::clamp(self, lo, hi)
            }
            #[inline]
            fn is_finite(self) -> bool {
                <$t>::is_finite(self)
            }
            #[inline]
            fn total_cmp(&self, other: &Self) -> Ordering {
                <$t>::total_cmp(self, other)
            }
        }
    };
}

real!(
    f64,
    false,
    crate::math::sqrt,
    crate::math::exp,
    libm::fabs,
    f64::max,
    f64::min
);
real!(
    f32,
    true,
    crate::math::sqrt_f32,
    crate::math::exp_f32,
    libm::fabsf,
    max_f32,
    min_f32
);

/// `f32::max` by comparisons: the same value (NaN loses), but a chip without a
/// floating-point maximum instruction (the Cortex-M4F) calls a library routine for `f32::max`.
#[inline]
fn max_f32(a: f32, b: f32) -> f32 {
    if b > a || a.is_nan() {
        b
    } else {
        a
    }
}

/// `f32::min` by comparisons (see [`max_f32`]).
#[inline]
fn min_f32(a: f32, b: f32) -> f32 {
    if b < a || a.is_nan() {
        b
    } else {
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The generic operations are the primitives' own, for both scalars.
    fn agrees<R: Real>(tolerance: f64) {
        for v in [0.0, 0.25, 1.0, 2.5, 9.0, 100.0] {
            let r = R::from_f64(v);
            assert!((r.sqrt().to_f64() - libm::sqrt(v)).abs() <= tolerance * (1.0 + libm::sqrt(v)));
            let e = R::from_f64(-v / 4.0).exp().to_f64();
            assert!((e - libm::exp(-v / 4.0)).abs() <= tolerance * libm::exp(-v / 4.0));
        }
        assert_eq!(R::from_f64(-3.5).abs().to_f64(), 3.5);
        assert_eq!(R::from_f64(2.9).to_index(), 2);
        assert_eq!(R::from_f64(-2.9).to_index(), 0);
        assert_eq!(R::from_usize(7).to_f64(), 7.0);
        assert!(!R::INFINITY.is_finite() && R::ONE.is_finite());
        assert_eq!(R::from_f64(5.0).clamp(R::ZERO, R::ONE), R::ONE);
        let nan = R::from_f64(f64::NAN);
        for (a, b) in [(1.0, 2.0), (2.0, 1.0), (-3.0, -3.0)] {
            let (x, y) = (R::from_f64(a), R::from_f64(b));
            assert_eq!(x.max(y).to_f64(), a.max(b));
            assert_eq!(x.min(y).to_f64(), a.min(b));
            assert_eq!(x.max(nan), x);
            assert_eq!(nan.max(x), x);
            assert_eq!(x.min(nan), x);
            assert_eq!(nan.min(x), x);
        }
    }

    #[test]
    fn both_scalars_compute_the_primitive_operations() {
        agrees::<f64>(4.0 * f64::EPSILON);
        agrees::<f32>(4.0 * f64::from(f32::EPSILON));
    }
}
