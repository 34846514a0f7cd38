//! Levenberg-Marquardt on SE(3) for point-to-plane residuals (docs/design.md §1.4).
//!
//! Residual `e = nᵀ (R p + t - q)` of a correction `T = (R, t)` applied on the left. The
//! perturbation turns about the centroid `c` of the scan points, `T ← C exp(δ) C⁻¹ T` with
//! `C` the translation by `c` and `δ = (ω, ρ)`, so `∂e/∂δ = [ ((T p - c) × n)ᵀ, nᵀ ]`: far from
//! the world origin, rotation and translation stay as separable as they are near it. Huber
//! loss by iteratively re-weighted least squares, 6 x 6 normal equations damped by
//! `λ · diag`. Stack only.
//!
//! Degeneracy (a tunnel leaves the motion along it free, a plane leaves three directions
//! free): the normal equations are scaled to metres (rotation times the scan's RMS lever arm)
//! and divided by the residuals' total weight, so each eigenvalue is the mean squared normal
//! component along its direction. Directions below [`LmConfig::degenerate_ratio`] are
//! degenerate: the correction is solved in the other directions only (solution remapping),
//! so that the pose keeps its prediction where the geometry says nothing. The solution
//! reports how many directions were left out.

use crate::config::LmConfig;
use crate::math::{se3_exp, Pose, Twist, Vec3};
use core::fmt;
use nalgebra::{Matrix6, SymmetricEigen};

/// One combined point-to-plane residual.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Residual {
    /// Scan point (world frame, before the correction).
    pub p: Vec3,
    /// Map point.
    pub q: Vec3,
    /// Unit normal at `q`.
    pub n: Vec3,
    /// Weight (1 for a combined layer residual).
    pub weight: f64,
}

impl Residual {
    /// The signed distance `nᵀ (T p - q)`.
    #[inline]
    pub fn error(&self, t: &Pose) -> f64 {
        self.n
            .dot(&((t * nalgebra::Point3::from(self.p)).coords - self.q))
    }
}

/// How well a solve pinned the pose down: its normal equations at the pose found, for a
/// perturbation `exp(δ)` about `centre` applied on the left (rotation about `centre`, twist
/// order `(ω, ρ)`), divided by the residuals' variance estimated from the final cost
/// (`2 · cost / (residuals - 6)`): the inverse of the pose's covariance, Huber weights
/// included. All zeros when nothing was solved.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PoseInformation {
    /// The 6 x 6 information, row by row.
    pub matrix: [[f64; 6]; 6],
    /// The point the rotation is about (world frame).
    pub centre: [f64; 3],
}

/// A converged (or iteration-capped) solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Solution {
    /// The correction to apply on the left of the current pose.
    pub correction: Pose,
    /// LM iterations run.
    pub iterations: usize,
    /// Robust cost before and after.
    pub cost: (f64, f64),
    /// Smallest eigenvalue of the scaled normal equations (see the module docs): the mean
    /// squared normal component along the weakest direction, 0 to 1/3.
    pub conditioning: f64,
    /// Directions left out as degenerate (0: the correction is constrained in all six).
    pub degenerate_directions: usize,
    /// The information of the pose found.
    pub information: PoseInformation,
    /// Residuals solved over.
    pub residuals: usize,
}

impl Solution {
    /// The root mean square of the residuals at the pose found, from the final robust cost
    /// (`sqrt(2 · cost / residuals)`): beyond the Huber threshold a residual counts for less
    /// than its square.
    pub fn residual_rms(&self) -> f64 {
        libm::sqrt(2.0 * self.cost.1 / self.residuals.max(1) as f64)
    }
}

/// Why no correction was computed.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LmError {
    /// Fewer residuals than [`LmConfig::min_residuals`].
    TooFewResiduals {
        /// Residuals given.
        found: usize,
    },
    /// The residuals constrain no direction at all (or the system could not be analysed).
    Degenerate {
        /// Smallest eigenvalue of the scaled normal equations.
        conditioning: f64,
    },
    /// A residual or the system was not finite.
    NotFinite,
}

impl fmt::Display for LmError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LmError::TooFewResiduals { found } => write!(f, "too few residuals ({found})"),
            LmError::Degenerate { conditioning } => {
                write!(f, "degenerate geometry (conditioning {conditioning:.2e})")
            }
            LmError::NotFinite => write!(f, "non-finite residuals"),
        }
    }
}

impl core::error::Error for LmError {}

/// Normal equations `H δ = -g` and robust cost at `t`, for perturbations about `centre`.
fn linearize(
    residuals: &[Residual],
    t: &Pose,
    centre: &Vec3,
    huber: f64,
) -> (Matrix6<f64>, Twist, f64) {
    // The upper triangle of H, row by row: `j jᵀ` is symmetric, so 21 products a residual
    // instead of 36, each `(j_a j_b) w` as the full product computes it (the same numbers).
    let mut upper = [0.0f64; 21];
    let mut g = Twist::zeros();
    let mut cost = 0.0;
    for r in residuals {
        let tp = (t * nalgebra::Point3::from(r.p)).coords;
        let e = r.n.dot(&(tp - r.q));
        let (w, c) = huber_loss(e, huber);
        let rot = (tp - centre).cross(&r.n);
        let j = [rot.x, rot.y, rot.z, r.n.x, r.n.y, r.n.z];
        let ww = w * r.weight;
        let mut k = 0;
        for a in 0..6 {
            for b in a..6 {
                upper[k] += j[a] * j[b] * ww;
                k += 1;
            }
        }
        g += Twist::from(j) * (e * ww);
        cost += c * r.weight;
    }
    let mut h = Matrix6::zeros();
    let mut k = 0;
    for a in 0..6 {
        for b in a..6 {
            h[(a, b)] = upper[k];
            h[(b, a)] = upper[k];
            k += 1;
        }
    }
    (h, g, cost)
}

fn robust_cost(residuals: &[Residual], t: &Pose, huber: f64) -> f64 {
    residuals
        .iter()
        .map(|r| huber_loss(r.error(t), huber).1 * r.weight)
        .sum()
}

/// Huber loss of residual `e`: `(IRLS weight ρ'(e)/e, cost ρ(e))`, quadratic up to `delta`.
#[inline]
fn huber_loss(e: f64, delta: f64) -> (f64, f64) {
    let ae = libm::fabs(e);
    if ae <= delta {
        (1.0, 0.5 * e * e)
    } else {
        (delta / ae, delta * (ae - 0.5 * delta))
    }
}

/// The scaling `δ = S x` that makes `x` metres: rotation times `lever`, translation as is.
fn scaling(lever: f64) -> Twist {
    let l = 1.0 / lever;
    Twist::new(l, l, l, 1.0, 1.0, 1.0)
}

/// The eigen-decomposition of the normal equations scaled to metres by `s` and divided by
/// the residuals' total weight `weight` (see the module docs); `None` if not finite.
pub fn information(
    h: &Matrix6<f64>,
    s: &Twist,
    weight: f64,
) -> Option<SymmetricEigen<f64, nalgebra::U6>> {
    let scaled = Matrix6::from_fn(|i, j| h[(i, j)] * s[i] * s[j] / weight);
    if !scaled.iter().all(|v| v.is_finite()) {
        return None;
    }
    SymmetricEigen::try_new(scaled, 1e-12, 100)
}

/// Finds the correction `T` minimising the Huber cost of `residuals`, in the directions they
/// constrain (see the module docs).
pub fn solve(residuals: &[Residual], cfg: &LmConfig) -> Result<Solution, LmError> {
    if residuals.len() < cfg.min_residuals {
        return Err(LmError::TooFewResiduals {
            found: residuals.len(),
        });
    }
    if residuals.iter().any(|r| {
        !(r.p
            .iter()
            .chain(r.q.iter())
            .chain(r.n.iter())
            .all(|v| v.is_finite())
            && r.weight.is_finite())
    }) {
        return Err(LmError::NotFinite);
    }
    let count = residuals.len() as f64;
    let centre = residuals.iter().fold(Vec3::zeros(), |a, r| a + r.p) / count;
    let lever = libm::sqrt(
        residuals
            .iter()
            .map(|r| (r.p - centre).norm_squared())
            .sum::<f64>()
            / count,
    )
    .max(1.0);
    let s = scaling(lever);
    // Directions, judged once on the first linearization, unweighted by Huber.
    let weight: f64 = residuals.iter().map(|r| r.weight).sum();
    let (h0, _, _) = linearize(residuals, &Pose::identity(), &centre, f64::INFINITY);
    let Some(eigen) = information(&h0, &s, weight.max(1e-12)) else {
        return Err(LmError::NotFinite);
    };
    let conditioning = eigen.eigenvalues.min();
    let mut left_out = [false; 6];
    for (k, out) in left_out.iter_mut().enumerate() {
        *out = !(eigen.eigenvalues[k] >= cfg.degenerate_ratio);
    }
    if left_out.iter().all(|&o| o) {
        return Err(LmError::Degenerate { conditioning });
    }
    let run = iterate(residuals, cfg, &centre, &s, &eigen, &left_out)?;
    Ok(Solution {
        degenerate_directions: left_out.iter().filter(|&&o| o).count(),
        conditioning,
        ..run
    })
}

/// Levenberg-Marquardt from the identity, solving only in the eigen-directions of `eigen`
/// not `left_out` (the others keep the prediction). `Solution::conditioning` and
/// `degenerate_directions` are left for the caller.
fn iterate(
    residuals: &[Residual],
    cfg: &LmConfig,
    centre: &Vec3,
    s: &Twist,
    eigen: &SymmetricEigen<f64, nalgebra::U6>,
    left_out: &[bool; 6],
) -> Result<Solution, LmError> {
    let huber = cfg.huber_delta_m;
    // Projector onto the directions solved for (in the scaled variables).
    let mut keep = Matrix6::<f64>::zeros();
    for (k, &out) in left_out.iter().enumerate() {
        if !out {
            let v = eigen.eigenvectors.column(k);
            keep += v * v.transpose();
        }
    }
    let free = Matrix6::<f64>::identity() - keep;
    let about = |delta: &Twist| {
        let c = nalgebra::Translation3::from(*centre);
        c * se3_exp(delta) * c.inverse()
    };
    let mut t = Pose::identity();
    let (mut h, mut g, mut cost) = linearize(residuals, &t, centre, huber);
    let initial_cost = cost;
    let mut lambda = 1e-4;
    let mut iterations = 0;
    while iterations < cfg.max_iterations {
        iterations += 1;
        // In the scaled variables x (δ = S x): (P (H + λ diag H) P + (I - P)) x = -P g.
        let mut a = Matrix6::from_fn(|i, j| h[(i, j)] * s[i] * s[j]);
        for i in 0..6 {
            a[(i, i)] *= 1.0 + lambda;
        }
        let a = keep * a * keep + free;
        let rhs = keep * g.component_mul(s);
        let Some(chol) = a.cholesky() else {
            lambda *= 10.0;
            if lambda > 1e10 {
                break;
            }
            continue;
        };
        let delta = (-chol.solve(&rhs)).component_mul(s);
        if !delta.iter().all(|v| v.is_finite()) {
            return Err(LmError::NotFinite);
        }
        let candidate = about(&delta) * t;
        let new_cost = robust_cost(residuals, &candidate, huber);
        if new_cost <= cost {
            t = candidate;
            (h, g, cost) = linearize(residuals, &t, centre, huber);
            lambda = (lambda * 0.1).max(1e-10);
            if delta.norm() < cfg.tolerance {
                break;
            }
        } else {
            lambda *= 10.0;
            if lambda > 1e10 || delta.norm() < cfg.tolerance {
                break;
            }
        }
    }
    let variance = (2.0 * cost / (residuals.len() as f64 - 6.0).max(1.0)).max(1e-12);
    Ok(Solution {
        correction: t,
        iterations,
        cost: (initial_cost, cost),
        conditioning: 0.0,
        degenerate_directions: 0,
        information: PoseInformation {
            matrix: core::array::from_fn(|i| core::array::from_fn(|j| h[(i, j)] / variance)),
            centre: [centre.x, centre.y, centre.z],
        },
        residuals: residuals.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;
    use nalgebra::{Point3, Translation3, UnitQuaternion};

    fn cfg() -> LmConfig {
        let mut c = Config::default().register.lm;
        c.max_iterations = 50;
        c.tolerance = 1e-12;
        c
    }

    /// Exact point-to-plane pairs on the six faces of a box and a few tilted planes, seen through
    /// `truth`: scan point `p = truth⁻¹ q`.
    fn residuals(truth: &Pose) -> heapless::Vec<Residual, 128> {
        let mut v = heapless::Vec::new();
        let normals = [
            Vec3::x(),
            -Vec3::x(),
            Vec3::y(),
            -Vec3::y(),
            Vec3::z(),
            -Vec3::z(),
            Vec3::new(1.0, 1.0, 0.2).normalize(),
            Vec3::new(-0.3, 1.0, 0.5).normalize(),
        ];
        for (k, n) in normals.iter().enumerate() {
            for s in 0..12 {
                let (u, w) = (s as f64 * 0.9 - 5.0, (s * 7 % 12) as f64 * 0.6 - 3.0);
                let tangent = if n.x.abs() < 0.9 {
                    n.cross(&Vec3::x())
                } else {
                    n.cross(&Vec3::y())
                }
                .normalize();
                let bitangent = n.cross(&tangent);
                let q = n * (8.0 + k as f64) + tangent * u + bitangent * w;
                let p = truth.inverse() * Point3::from(q);
                v.push(Residual {
                    p: p.coords,
                    q,
                    n: *n,
                    weight: 1.0,
                })
                .unwrap();
            }
        }
        v
    }

    #[test]
    fn recovers_a_known_transform_to_1e_4() {
        let truth = Pose::from_parts(
            Translation3::new(0.6, -0.4, 0.15),
            UnitQuaternion::from_euler_angles(0.03, -0.05, 0.09), // 6.0 degrees in all
        );
        assert!(
            truth.translation.vector.norm() >= 0.5 && truth.rotation.angle().to_degrees() >= 5.0
        );
        let sol = solve(&residuals(&truth), &cfg()).unwrap();
        assert_eq!(sol.degenerate_directions, 0);
        let err = sol.correction * truth.inverse();
        assert!(
            err.translation.vector.norm() < 1e-4,
            "translation error {}",
            err.translation.vector.norm()
        );
        assert!(
            err.rotation.angle() < 1e-4,
            "rotation error {}",
            err.rotation.angle()
        );
        assert!(sol.cost.1 < 1e-12);
    }

    #[test]
    fn huber_resists_an_outlier() {
        let truth = Pose::translation(0.2, 0.1, -0.1);
        let mut r = residuals(&truth);
        let n0 = r[0].n;
        r[0].q += n0 * 3.0;
        let sol = solve(&r, &cfg()).unwrap();
        let err = sol.correction * truth.inverse();
        assert!(
            err.translation.vector.norm() < 0.02,
            "{}",
            err.translation.vector.norm()
        );
    }

    #[test]
    fn a_single_plane_is_degenerate() {
        let plane: heapless::Vec<Residual, 64> = (0..64)
            .map(|i| {
                let q = Vec3::new((i % 8) as f64 - 4.0, (i / 8) as f64 - 4.0, 0.0);
                Residual {
                    p: q + Vec3::new(0.0, 0.0, 0.3),
                    q,
                    n: Vec3::z(),
                    weight: 1.0,
                }
            })
            .collect();
        // The plane fixes height, roll and pitch; along it and about its normal the solution
        // keeps the prediction (the identity correction).
        let sol = solve(&plane, &cfg()).unwrap();
        assert_eq!(sol.degenerate_directions, 3);
        let t = sol.correction.translation.vector;
        assert!((t - Vec3::new(0.0, 0.0, -0.3)).norm() < 1e-9, "{t:?}");
        assert!(sol.correction.rotation.angle() < 1e-9);
        // Parallel planes twice over, and a single point: nothing constrains all six.
        let flat: heapless::Vec<Residual, 64> = plane
            .iter()
            .map(|r| Residual {
                p: Vec3::new(0.0, 0.0, 0.3),
                q: Vec3::zeros(),
                ..*r
            })
            .collect();
        assert_eq!(solve(&flat, &cfg()).unwrap().degenerate_directions, 5);
    }

    #[test]
    fn no_direction_at_all_is_an_error() {
        let none: heapless::Vec<Residual, 16> = (0..16)
            .map(|_| Residual {
                p: Vec3::zeros(),
                q: Vec3::zeros(),
                n: Vec3::zeros(),
                weight: 1.0,
            })
            .collect();
        assert!(matches!(
            solve(&none, &cfg()),
            Err(LmError::Degenerate { .. })
        ));
    }

    #[test]
    fn too_few_and_non_finite() {
        let r = residuals(&Pose::identity());
        assert_eq!(
            solve(&r[..3], &cfg()),
            Err(LmError::TooFewResiduals { found: 3 })
        );
        let mut bad = r.clone();
        bad[5].p.x = f64::NAN;
        assert_eq!(solve(&bad, &cfg()), Err(LmError::NotFinite));
    }
}
