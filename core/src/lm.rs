//! Levenberg-Marquardt on SE(3) for point-to-plane residuals (DESIGN §1.4).
//!
//! Residual `e = nᵀ (R p + t - q)` of a correction `T = (R, t)` applied on the left;
//! perturbation `T ← exp(δ) T` with `δ = (ω, ρ)`, so `∂e/∂δ = [ (T p × n)ᵀ, nᵀ ]`
//! (= `[-nᵀ (Tp)^, nᵀ]`). Huber loss by iteratively re-weighted least squares, 6 x 6 normal
//! equations damped by `λ · diag`. Degeneracy is judged on the normal equations scaled to unit
//! diagonal, so rotation (lever arm in metres) and translation compare. Stack only.

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

/// A converged (or iteration-capped) solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Solution {
    /// The correction to apply on the left of the current pose.
    pub correction: Pose,
    /// LM iterations run.
    pub iterations: usize,
    /// Robust cost before and after.
    pub cost: (f64, f64),
    /// Smallest eigenvalue of the unit-diagonal normal equations (0 to 1-ish; small is weak).
    pub conditioning: f64,
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
    /// The residuals leave a direction unconstrained.
    Degenerate {
        /// Smallest eigenvalue of the unit-diagonal normal equations.
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

/// Normal equations `H δ = -g` and robust cost at `t`.
fn linearize(residuals: &[Residual], t: &Pose, huber: f64) -> (Matrix6<f64>, Twist, f64) {
    let mut h = Matrix6::zeros();
    let mut g = Twist::zeros();
    let mut cost = 0.0;
    for r in residuals {
        let tp = (t * nalgebra::Point3::from(r.p)).coords;
        let e = r.n.dot(&(tp - r.q));
        let (w, c) = huber_loss(e, huber);
        let rot = tp.cross(&r.n);
        let j = Twist::new(rot.x, rot.y, rot.z, r.n.x, r.n.y, r.n.z);
        let ww = w * r.weight;
        h += j * j.transpose() * ww;
        g += j * (e * ww);
        cost += c * r.weight;
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

/// Smallest eigenvalue of `h` scaled to unit diagonal (0 if a diagonal entry vanishes).
pub fn conditioning(h: &Matrix6<f64>) -> f64 {
    let max_diag = h.diagonal().max();
    if !(max_diag > 0.0) {
        return 0.0;
    }
    let mut s = Twist::zeros();
    for i in 0..6 {
        let d = h[(i, i)];
        if !(d > 1e-12 * max_diag) {
            return 0.0;
        }
        s[i] = 1.0 / libm::sqrt(d);
    }
    let scaled = Matrix6::from_fn(|i, j| h[(i, j)] * s[i] * s[j]);
    SymmetricEigen::try_new(scaled, 1e-12, 100).map_or(0.0, |e| e.eigenvalues.min())
}

/// Finds the correction `T` minimising the Huber cost of `residuals`.
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
    let huber = cfg.huber_delta_m;
    let mut t = Pose::identity();
    let (mut h, mut g, mut cost) = linearize(residuals, &t, huber);
    let initial_cost = cost;
    let cond = conditioning(&h);
    if !(cond >= cfg.degenerate_ratio) || cond == 0.0 {
        return Err(LmError::Degenerate { conditioning: cond });
    }
    let mut lambda = 1e-4;
    let mut iterations = 0;
    while iterations < cfg.max_iterations {
        iterations += 1;
        let mut a = h;
        for i in 0..6 {
            a[(i, i)] += lambda * h[(i, i)];
        }
        let Some(chol) = a.cholesky() else {
            lambda *= 10.0;
            continue;
        };
        let delta = -chol.solve(&g);
        if !delta.iter().all(|v| v.is_finite()) {
            return Err(LmError::NotFinite);
        }
        let candidate = se3_exp(&delta) * t;
        let new_cost = robust_cost(residuals, &candidate, huber);
        if new_cost <= cost {
            t = candidate;
            (h, g, cost) = linearize(residuals, &t, huber);
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
    Ok(Solution {
        correction: t,
        iterations,
        cost: (initial_cost, cost),
        conditioning: cond,
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
        assert!(matches!(
            solve(&plane, &cfg()),
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
