//! Math types and the one copy of the SE(3) helpers.
//!
//! Poses are [`Pose`] (`Isometry3<f64>`), named by frames: `t_world_sensor` maps sensor-frame
//! points into the world. Points are stored as `f32` ([`Point`]); all estimation math is `f64`.
//! Tangent vectors of SE(3) are ordered `(ω, ρ)`: rotation first, as in docs/design.md §1.4.

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3, Vector6};

/// A 3-D point as stored in buffers (metres, `f32`).
pub type Point = [f32; 3];
/// A 3-vector for estimation math.
pub type Vec3 = Vector3<f64>;
/// A 3x3 matrix.
pub type Mat3 = Matrix3<f64>;
/// A rigid transform, named by frames (`t_world_sensor`).
pub type Pose = Isometry3<f64>;
/// An SE(3) tangent vector `(ω, ρ)`.
pub type Twist = Vector6<f64>;

/// Widens a stored point to an estimation vector.
#[inline]
pub fn to_vec3(p: &Point) -> Vec3 {
    Vec3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]))
}

/// Narrows an estimation vector to a stored point.
#[inline]
pub fn to_point(v: &Vec3) -> Point {
    [v.x as f32, v.y as f32, v.z as f32]
}

/// The skew-symmetric matrix `v^` with `v^ w = v × w`.
#[inline]
pub fn skew(v: &Vec3) -> Mat3 {
    Mat3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// The exponential map of SE(3): the transform `exp(ξ)` for `ξ = (ω, ρ)`.
///
/// Rotation by Rodrigues' formula, translation `V ρ` with
/// `V = I + (1 - cos θ)/θ² ω^ + (θ - sin θ)/θ³ ω^²` (series near θ = 0).
pub fn se3_exp(xi: &Twist) -> Pose {
    let omega = Vec3::new(xi[0], xi[1], xi[2]);
    let rho = Vec3::new(xi[3], xi[4], xi[5]);
    let theta2 = omega.norm_squared();
    let theta = libm::sqrt(theta2);
    let w = skew(&omega);
    let (b, c) = if theta < 1e-6 {
        (0.5 - theta2 / 24.0, 1.0 / 6.0 - theta2 / 120.0)
    } else {
        (
            (1.0 - libm::cos(theta)) / theta2,
            (theta - libm::sin(theta)) / (theta2 * theta),
        )
    };
    let v = Mat3::identity() + w * b + w * w * c;
    Isometry3::from_parts(
        Translation3::from(v * rho),
        UnitQuaternion::from_scaled_axis(omega),
    )
}

/// The logarithm of SE(3), the inverse of [`se3_exp`]: `ξ = (ω, ρ)` with `ω` the rotation's
/// scaled axis (|ω| < π) and `ρ = V⁻¹ t`, where
/// `V⁻¹ = I - ω^/2 + (1 - θ sin θ / (2 (1 - cos θ)))/θ² ω^²` (series near θ = 0).
pub fn se3_log(pose: &Pose) -> Twist {
    let omega = pose.rotation.scaled_axis();
    let theta2 = omega.norm_squared();
    let theta = libm::sqrt(theta2);
    let w = skew(&omega);
    let c = if theta < 1e-4 {
        1.0 / 12.0 + theta2 / 720.0
    } else {
        (1.0 - theta * libm::sin(theta) / (2.0 * (1.0 - libm::cos(theta)))) / theta2
    };
    let v_inv = Mat3::identity() - w * 0.5 + w * w * c;
    let rho = v_inv * pose.translation.vector;
    Twist::new(omega.x, omega.y, omega.z, rho.x, rho.y, rho.z)
}

/// The smallest rotation that turns `up` onto the z axis: what makes a frame whose up is `up`
/// level, its heading kept (up side down, a half turn about x).
pub fn level_rotation(up: &Vec3) -> UnitQuaternion<f64> {
    UnitQuaternion::rotation_between(up, &Vec3::z())
        .unwrap_or_else(|| UnitQuaternion::from_axis_angle(&Vec3::x_axis(), core::f64::consts::PI))
}

/// Most iterations [`svd3`] lets nalgebra's SVD take. A 3 x 3 matrix converges in a handful;
/// nalgebra's `svd` iterates until it does, without a limit, and no input may hold a run (the
/// core's other iterative decompositions are bounded too).
const SVD_MAX_ITERATIONS: usize = 200;

/// The singular value decomposition of `h` (with `U` and `Vᵀ` when `vectors`), as nalgebra's
/// `svd` computes it (its tolerance, 5 ε) but within `SVD_MAX_ITERATIONS` (200); `None` when `h`
/// is not finite or the decomposition does not converge within them.
pub fn svd3(h: &Mat3, vectors: bool) -> Option<nalgebra::SVD<f64, nalgebra::U3, nalgebra::U3>> {
    if !h.iter().all(|v| v.is_finite()) {
        return None;
    }
    h.try_svd(vectors, vectors, 5.0 * f64::EPSILON, SVD_MAX_ITERATIONS)
}

/// The rotation `R` that best maps vectors `aₖ` onto `bₖ` in the least-squares sense (Kabsch),
/// from their cross-covariance `h = Σ aₖ bₖᵀ`; always proper (no reflection). The identity
/// when `h` is not finite or its decomposition fails.
pub fn best_rotation(h: &Mat3) -> Rotation3<f64> {
    let Some(svd) = svd3(h, true) else {
        return Rotation3::identity();
    };
    match (svd.u, svd.v_t) {
        (Some(u), Some(v_t)) => {
            let v = v_t.transpose();
            let d = (v * u.transpose()).determinant().signum();
            Rotation3::from_matrix_unchecked(
                v * Mat3::from_diagonal(&Vec3::new(1.0, 1.0, d)) * u.transpose(),
            )
        }
        _ => Rotation3::identity(),
    }
}

/// How far the 3 x 3 of a pose read from numbers may be from a rotation (`‖MᵀM − I‖`,
/// Frobenius) and still be taken for one: rows written with 9 significant digits are within
/// 1e-8. Farther, it is not a rotation; and an entry of -3.8e50 made nalgebra's
/// re-orthonormalisation loop for ever (`slamesh eval` hung on that line: the `trajectory`
/// fuzz target's find).
const ROTATION_TOLERANCE: f64 = 0.01;

/// A pose from 12 row-major `[R | t]` numbers; `None` unless they are finite and `R` is a
/// rotation to within `ROTATION_TOLERANCE` (0.01, no reflection). The rotation is
/// re-orthonormalised (KITTI files carry 9 significant digits).
pub fn pose_from_row(v: &[f64]) -> Option<Pose> {
    if v.len() != 12 || !v.iter().all(|x| x.is_finite()) {
        return None;
    }
    let m = Matrix3::new(v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10]);
    let off = (m.transpose() * m - Matrix3::identity()).norm();
    if !(off <= ROTATION_TOLERANCE && m.determinant() > 0.0) {
        return None;
    }
    let r = Rotation3::from_matrix_eps(&m, 1e-12, 100, Rotation3::identity());
    let t = Translation3::new(v[3], v[7], v[11]);
    Some(Pose::from_parts(
        t,
        UnitQuaternion::from_rotation_matrix(&r),
    ))
}

/// `pose` with its rotation quaternion scaled back to unit length.
///
/// Composing poses loses a few ulps of the quaternion's norm each time, and the constant
/// velocity model (`T · T_prev⁻¹ · T`, where the inverse is a conjugate that keeps the error)
/// multiplies that error by about 2.4 per frame: without this, a run diverges after about 40
/// frames. Every pose the pipeline keeps goes through here.
pub fn renormalized(mut pose: Pose) -> Pose {
    pose.rotation.renormalize();
    pose
}

/// `e^x`, branch-free, within 2 ulp of the true value on `[-708, 709]` (clamped outside it;
/// NaN stays NaN).
///
/// The GP kernel evaluates about 2 000 exponentials per layer, and `libm::exp` (a port of the
/// FreeBSD routine, with a division and branches) was 44 % of a KITTI scan's time. This one
/// is Cody-Waite range reduction `x = k ln 2 + r`, `|r| ≤ ln 2 / 2`, a degree-12 Taylor
/// polynomial for `e^r` (truncation below 2e-16) and `2^k` built in the exponent bits, with
/// `k` taken from the bits of a shifted sum instead of a float-to-int conversion, so that
/// loops over it vectorize.
#[inline]
pub fn exp(x: f64) -> f64 {
    const LOG2_E: f64 = core::f64::consts::LOG2_E;
    // ln 2 split so that k · LN2_HI is exact for |k| < 2^11.
    const LN2_HI: f64 = 0.693_147_180_369_123_8;
    const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
    // 1.5 · 2^52: adding it rounds to an integer kept in the low mantissa bits.
    const SHIFT: f64 = 6_755_399_441_055_744.0;
    let x = x.clamp(-708.0, 709.0);
    let t = x * LOG2_E + SHIFT;
    let k = t - SHIFT;
    let r = (x - k * LN2_HI) - k * LN2_LO;
    // Horner on the Taylor coefficients 1/n!.
    let mut p = 1.0 / 479_001_600.0;
    for c in [
        1.0 / 39_916_800.0,
        1.0 / 3_628_800.0,
        1.0 / 362_880.0,
        1.0 / 40_320.0,
        1.0 / 5_040.0,
        1.0 / 720.0,
        1.0 / 120.0,
        1.0 / 24.0,
        1.0 / 6.0,
        0.5,
        1.0,
        1.0,
    ] {
        p = p * r + c;
    }
    let k_int = (t.to_bits() as i64).wrapping_sub(SHIFT.to_bits() as i64);
    p * f64::from_bits((k_int.wrapping_add(1023) as u64) << 52)
}

/// `e^x` in `f32`, branch-free, within 2 ulp of the true value on `[-87, 88]` (clamped
/// outside it; NaN stays NaN): [`exp`]'s method with a degree-7 polynomial, four lanes to a
/// 128-bit vector where [`exp`] has two.
#[inline]
pub fn exp_f32(x: f32) -> f32 {
    const LOG2_E: f32 = core::f32::consts::LOG2_E;
    // ln 2 split so that k · LN2_HI is exact for |k| < 2^8.
    const LN2_HI: f32 = 0.693_145_75;
    const LN2_LO: f32 = 1.428_606_8e-6;
    // 1.5 · 2^23: adding it rounds to an integer kept in the low mantissa bits.
    const SHIFT: f32 = 12_582_912.0;
    let x = x.clamp(-87.0, 88.0);
    let t = x * LOG2_E + SHIFT;
    let k = t - SHIFT;
    let r = (x - k * LN2_HI) - k * LN2_LO;
    let mut p = 1.0 / 5_040.0;
    for c in [
        1.0 / 720.0,
        1.0 / 120.0,
        1.0 / 24.0,
        1.0 / 6.0,
        0.5,
        1.0,
        1.0,
    ] {
        p = p * r + c;
    }
    let k_int = (t.to_bits() as i32).wrapping_sub(SHIFT.to_bits() as i32);
    p * f32::from_bits((k_int.wrapping_add(127) as u32) << 23)
}

/// `√q` in `f64`: `libm::sqrt`, except in a build for AVX (`-C target-cpu=x86-64-v3` or
/// `native` on x86-64), which takes [`sqrt_soft`].
///
/// `libm::sqrt` is one `sqrtsd` in inline assembly, and its legacy SSE encoding among the AVX
/// instructions of such a build stalls Intel CPUs at every call: the GP's kernel took 5.6
/// times as long (docs/journal.md, "Built for the CPU at hand, again"). Elsewhere the one
/// instruction is the fastest root, so the default build's results are `libm`'s to the bit.
#[inline]
pub fn sqrt(q: f64) -> f64 {
    #[cfg(not(target_feature = "avx"))]
    {
        libm::sqrt(q)
    }
    #[cfg(target_feature = "avx")]
    {
        sqrt_soft(q)
    }
}

/// `√q` in `f64` for `q ≥ 0`, within 1 ulp, branch-free (NaN for NaN or negative `q`; 0 for
/// `q` below 1e-300, so that no step meets a subnormal number, which Intel CPUs take a hundred
/// times as long over): [`sqrt_f32`]'s method, the bit-level estimate of `1/√q` and four
/// Newton steps, times `q`, then one Newton step on the root.
#[inline]
pub fn sqrt_soft(q: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let q_safe = q.max(TINY);
    let mut r = f64::from_bits(0x5fe6_eb50_c7b5_37a9_u64.wrapping_sub(q_safe.to_bits() >> 1));
    for _ in 0..4 {
        r *= 1.5 - 0.5 * q_safe * r * r;
    }
    let y = q_safe * r;
    let root = y + 0.5 * r * (q_safe - y * y);
    if q >= TINY {
        root
    } else if q >= 0.0 {
        0.0
    } else {
        f64::NAN
    }
}

/// `√q` in `f32` for `q ≥ 0`, within 2 ulp, branch-free (NaN for NaN or negative `q`).
///
/// `core` has no `sqrt` (and `libm::sqrtf` is one scalar instruction a call, which keeps
/// loops from vectorizing): the bit-level estimate of `1/√q`, three Newton steps, times `q`.
#[inline]
pub fn sqrt_f32(q: f32) -> f32 {
    // Below the smallest normal the estimate is meaningless: such a q's root is 0 to f32's
    // precision for our purposes (distances in metres).
    // `q.max(MIN_POSITIVE)` by a comparison (NaN gives MIN_POSITIVE either way): a chip
    // without a floating-point maximum instruction calls a routine for `max`.
    let q_safe = if q > f32::MIN_POSITIVE {
        q
    } else {
        f32::MIN_POSITIVE
    };
    let mut r = f32::from_bits(0x5f37_5a86_u32.wrapping_sub(q_safe.to_bits() >> 1));
    for _ in 0..3 {
        r *= 1.5 - 0.5 * q_safe * r * r;
    }
    let root = q_safe * r;
    if q >= 0.0 {
        root
    } else {
        f32::NAN
    }
}

/// The eigenvalues of a symmetric 3 x 3 matrix, smallest first, and a unit eigenvector of the
/// smallest, in closed form (the trigonometric solution of the characteristic cubic, then the
/// largest cross product of two rows of `a - λ₁ I`). `None` when that is ill-conditioned: the
/// two smallest eigenvalues within `1e-9` of the largest apart (the smallest's eigenvector is
/// then ill-defined), or a non-finite entry. Reads the lower triangle.
///
/// For the one 3 x 3 matrix a cell's layer choice decomposes, in place of nalgebra's iterative
/// `SymmetricEigen` (4 % of a KITTI scan's time): reconstruction on kitti-mini 01, one thread,
/// went from 28.0 to 26.5 ms a scan, with the same layers (docs/journal.md).
pub fn symmetric_eigen3(a: &Mat3) -> Option<([f64; 3], Vec3)> {
    let (a00, a11, a22) = (a[(0, 0)], a[(1, 1)], a[(2, 2)]);
    let (a10, a20, a21) = (a[(1, 0)], a[(2, 0)], a[(2, 1)]);
    let off = a10 * a10 + a20 * a20 + a21 * a21;
    let q = (a00 + a11 + a22) / 3.0;
    let p2 = (a00 - q) * (a00 - q) + (a11 - q) * (a11 - q) + (a22 - q) * (a22 - q) + 2.0 * off;
    if !(p2.is_finite() && q.is_finite()) {
        return None;
    }
    let values = if p2 == 0.0 {
        [q; 3]
    } else {
        let p = libm::sqrt(p2 / 6.0);
        // det((a - q I) / p) / 2, the cosine of three times the angle.
        let (b00, b11, b22) = ((a00 - q) / p, (a11 - q) / p, (a22 - q) / p);
        let (b10, b20, b21) = (a10 / p, a20 / p, a21 / p);
        let det = b00 * (b11 * b22 - b21 * b21) - b10 * (b10 * b22 - b21 * b20)
            + b20 * (b10 * b21 - b11 * b20);
        let phi = libm::acos((det / 2.0).clamp(-1.0, 1.0)) / 3.0;
        let largest = q + 2.0 * p * libm::cos(phi);
        let smallest = q + 2.0 * p * libm::cos(phi + 2.0 * core::f64::consts::FRAC_PI_3);
        [smallest, 3.0 * q - smallest - largest, largest]
    };
    let scale = libm::fabs(values[0]).max(libm::fabs(values[2]));
    if !(values[1] - values[0] > 1e-9 * scale) {
        return None;
    }
    let m = *a - Mat3::identity() * values[0];
    let rows = [
        Vec3::new(m[(0, 0)], m[(1, 0)], m[(2, 0)]),
        Vec3::new(m[(1, 0)], m[(1, 1)], m[(2, 1)]),
        Vec3::new(m[(2, 0)], m[(2, 1)], m[(2, 2)]),
    ];
    let crosses = [
        rows[0].cross(&rows[1]),
        rows[0].cross(&rows[2]),
        rows[1].cross(&rows[2]),
    ];
    let best = crosses
        .iter()
        .max_by(|x, y| x.norm_squared().total_cmp(&y.norm_squared()))?;
    let norm = best.norm();
    if !(norm > 0.0 && norm.is_finite()) {
        return None;
    }
    Some((values, best / norm))
}

/// `pose` turned by `yaw` radians about the world's vertical through its position (the
/// guesses of recovery and of the search in a known map).
#[inline]
pub fn turned_in_yaw(pose: &Pose, yaw: f64) -> Pose {
    let r = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), yaw);
    Pose::from_parts(pose.translation, r * pose.rotation)
}

/// The angle `a` (radians) brought into `(-π, π]`.
#[inline]
pub fn wrapped_angle(a: f64) -> f64 {
    use core::f64::consts::{PI, TAU};
    let a = libm::fmod(a, TAU);
    if a > PI {
        a - TAU
    } else if a <= -PI {
        a + TAU
    } else {
        a
    }
}

/// Rotation angle of a pose in radians, in `[0, π]`.
#[inline]
pub fn rotation_angle(pose: &Pose) -> f64 {
    pose.rotation.angle()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn best_rotation_finds_a_turn_and_gives_up_on_what_does_not_decompose() {
        // Vectors turned a quarter about z: their cross-covariance gives the turn back.
        let turn = Rotation3::from_axis_angle(&Vec3::z_axis(), core::f64::consts::FRAC_PI_2);
        let a = [Vec3::x(), Vec3::y(), Vec3::new(1.0, 1.0, 1.0)];
        let h = a
            .iter()
            .fold(Mat3::zeros(), |h, v| h + v * (turn * v).transpose());
        assert!((best_rotation(&h).matrix() - turn.matrix()).norm() < 1e-12);
        // Not finite: no decomposition, the identity.
        let h = Mat3::from_element(f64::INFINITY);
        assert!(svd3(&h, true).is_none());
        assert_eq!(best_rotation(&h), Rotation3::identity());
    }

    #[test]
    fn a_pose_row_is_a_rotation_and_a_translation_or_nothing() {
        // kitti-mini 00's second camera pose, as its poses.txt writes it.
        let row = [
            0.999991,
            -0.00316351,
            -0.00274942,
            -0.00135393,
            0.00316045,
            0.999994,
            -0.00111659,
            -0.0248245,
            0.00275294,
            0.00110789,
            0.999996,
            0.672716,
        ];
        let p = pose_from_row(&row).unwrap();
        assert!(
            (p.translation.vector - Vec3::new(-0.00135393, -0.0248245, 0.672716)).norm() < 1e-15
        );
        assert!(p.rotation.angle() > 0.003 && p.rotation.angle() < 0.006);
        // Not a rotation: scaled, mirrored, or an entry far out (nalgebra's
        // re-orthonormalisation looped for ever on -3.8e50, the fuzz target's input).
        let scaled = row.map(|x| 2.0 * x);
        let mut mirrored = row;
        mirrored[0] = -mirrored[0];
        let mut far = row;
        far[2] = -3.8e50;
        for bad in [scaled, mirrored, far] {
            assert_eq!(pose_from_row(&bad), None, "{bad:?}");
        }
        assert_eq!(pose_from_row(&row[..11]), None);
    }

    #[test]
    fn exp_of_pure_translation_and_rotation() {
        let t = se3_exp(&Twist::new(0.0, 0.0, 0.0, 1.0, 2.0, 3.0));
        assert!((t.translation.vector - Vec3::new(1.0, 2.0, 3.0)).norm() < 1e-12);
        let r = se3_exp(&Twist::new(
            0.0,
            0.0,
            core::f64::consts::FRAC_PI_2,
            0.0,
            0.0,
            0.0,
        ));
        let x = r * nalgebra::Point3::new(1.0, 0.0, 0.0);
        assert!((x.coords - Vec3::new(0.0, 1.0, 0.0)).norm() < 1e-12);
    }

    #[test]
    fn exp_matches_screw_motion() {
        // Rotating by π/2 about z while moving ρ = (0, 0, 1): the screw axis is z, so the
        // translation is exactly (0, 0, 1) (V maps the axis onto itself).
        let t = se3_exp(&Twist::new(
            0.0,
            0.0,
            core::f64::consts::FRAC_PI_2,
            0.0,
            0.0,
            1.0,
        ));
        assert!((t.translation.vector - Vec3::new(0.0, 0.0, 1.0)).norm() < 1e-12);
        // ρ = (1, 0, 0), θ = π/2 about z: V ρ = (sin θ/θ, (1 - cos θ)/θ, 0).
        let th = core::f64::consts::FRAC_PI_2;
        let t = se3_exp(&Twist::new(0.0, 0.0, th, 1.0, 0.0, 0.0));
        let want = Vec3::new(libm::sin(th) / th, (1.0 - libm::cos(th)) / th, 0.0);
        assert!((t.translation.vector - want).norm() < 1e-12);
    }

    #[test]
    fn exp_is_within_two_ulp_of_libm() {
        let mut worst = 0.0f64;
        for i in -200_000..=200_000 {
            let x = f64::from(i) * 1e-4 + 1.234_567e-7;
            let (ours, reference) = (exp(x), libm::exp(x));
            worst = worst.max(libm::fabs(ours - reference) / reference);
        }
        assert!(worst < 4.5e-16, "relative error {worst}");
        assert_eq!(exp(0.0), 1.0);
        assert!(exp(-1e6) >= 0.0 && exp(-1e6) < 1e-300);
        assert!(exp(1e6).is_finite() && exp(1e6) > 1e307);
        assert!(exp(f64::NAN).is_nan());
    }

    #[test]
    fn f32_exp_and_the_square_roots_are_within_their_ulp() {
        let ulp = |v: f32| f64::from(f32::EPSILON) * libm::fabs(f64::from(v));
        let mut worst = 0.0f64;
        for i in -100_000..=100_000 {
            let x = i as f32 * 8e-4 + 1.234_567e-5;
            let reference = libm::exp(f64::from(x));
            worst = worst.max(libm::fabs(f64::from(exp_f32(x)) - reference) / ulp(exp_f32(x)));
        }
        assert!(worst <= 2.0, "exp_f32: {worst} ulp");
        assert_eq!(exp_f32(0.0), 1.0);
        assert!(exp_f32(f32::NAN).is_nan() && exp_f32(-1e6) >= 0.0);
        let mut worst = 0.0f64;
        for i in 0..200_000 {
            let q = i as f32 * 1e-4 + 1e-7;
            let reference = libm::sqrt(f64::from(q));
            worst = worst.max(libm::fabs(f64::from(sqrt_f32(q)) - reference) / ulp(sqrt_f32(q)));
        }
        assert!(worst <= 2.0, "sqrt_f32: {worst} ulp");
        assert!(sqrt_f32(0.0) < 1e-18 && sqrt_f32(-1.0).is_nan() && sqrt_f32(f32::NAN).is_nan());
        // f64 over twelve decades: squared distances in m² and the Cholesky diagonal.
        let ulp64 = |v: f64| f64::from_bits(v.to_bits() + 1) - v;
        let mut worst = 0.0f64;
        for i in 0..1_200_000 {
            let q = libm::exp10(i as f64 * 1e-5 - 6.0) * (1.0 + 1e-3 * (i % 7) as f64);
            worst = worst.max(libm::fabs(sqrt_soft(q) - libm::sqrt(q)) / ulp64(libm::sqrt(q)));
        }
        assert!(worst <= 1.0, "sqrt_soft: {worst} ulp");
        for r in [sqrt, sqrt_soft] {
            assert!(r(0.0) == 0.0 && r(-1.0).is_nan() && r(f64::NAN).is_nan());
            assert_eq!(r(4.0), 2.0);
        }
    }

    #[test]
    fn log_inverts_exp() {
        for xi in [
            Twist::new(0.0, 0.0, 0.0, 1.0, -2.0, 0.5),
            Twist::new(0.3, -0.2, 0.9, 1.0, -2.0, 0.5),
            Twist::new(1e-7, 0.0, -2e-7, 0.1, 0.0, 0.0),
            Twist::new(0.0, 2.5, 0.0, 0.0, 0.0, 3.0),
        ] {
            let back = se3_log(&se3_exp(&xi));
            assert!((back - xi).norm() < 1e-9, "{xi} -> {back}");
        }
    }

    #[test]
    fn the_closed_form_eigen_decomposition_agrees_with_nalgebra() {
        // A plane's scatter, a slanted plane's, a line's (refused: the two smallest are equal),
        // a diagonal matrix and one with equal eigenvalues (refused).
        let r = nalgebra::Rotation3::from_euler_angles(0.3, -0.7, 1.1).into_inner();
        let cases = [
            Mat3::from_diagonal(&Vec3::new(0.2, 0.15, 1e-4)),
            r * Mat3::from_diagonal(&Vec3::new(0.2, 0.15, 1e-4)) * r.transpose(),
            r * Mat3::from_diagonal(&Vec3::new(0.3, 0.02, 0.001)) * r.transpose(),
            r * Mat3::from_diagonal(&Vec3::new(0.3, 1e-6, 1e-6)) * r.transpose(),
            Mat3::from_diagonal(&Vec3::new(0.5, 0.5, 0.5)),
        ];
        for (i, a) in cases.iter().enumerate() {
            let reference = nalgebra::SymmetricEigen::new(*a);
            let mut order = [0usize, 1, 2];
            order.sort_by(|&x, &y| reference.eigenvalues[x].total_cmp(&reference.eigenvalues[y]));
            match symmetric_eigen3(a) {
                Some((values, normal)) => {
                    assert!(i < 3, "case {i} should be refused");
                    for (v, &k) in values.iter().zip(&order) {
                        assert!(libm::fabs(v - reference.eigenvalues[k]) < 1e-12, "case {i}");
                    }
                    let expected = reference.eigenvectors.column(order[0]);
                    assert!(
                        libm::fabs(libm::fabs(normal.dot(&expected)) - 1.0) < 1e-9,
                        "case {i}"
                    );
                }
                None => assert!(i >= 3, "case {i} refused"),
            }
        }
        assert!(symmetric_eigen3(&Mat3::from_element(f64::NAN)).is_none());
    }

    #[test]
    fn skew_is_cross_product() {
        let a = Vec3::new(0.3, -1.0, 2.0);
        let b = Vec3::new(-0.5, 0.25, 4.0);
        assert!((skew(&a) * b - a.cross(&b)).norm() < 1e-12);
    }
}
