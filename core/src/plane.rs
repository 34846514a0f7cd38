//! [`Plane`]: the least-squares plane `d = f(a, b)` through samples in a cell's `(a, b, d)`
//! coordinates. The GP's mean function ([`gp`](crate::gp)) and the plane a layer's facing is
//! judged by ([`facing`](crate::facing)) are this one fit.

use crate::real::Real;

/// The plane `d = centre_d + slope_a (a - centre_a) + slope_b (b - centre_b)`.
#[derive(Debug, Clone, Copy)]
pub struct Plane<R> {
    /// The samples' mean `(a, b, d)`.
    pub centre: [R; 3],
    /// `∂d/∂a` and `∂d/∂b` (zero when not [`determined`](Self::determined)).
    pub slope: [R; 2],
    /// Whether the samples' locations determine the tilt: false when they are (nearly) on a
    /// line, or fewer than three, and the plane is flat through their mean.
    pub determined: bool,
}

impl<R: Real> Plane<R> {
    /// Least squares through `samples` (centred normal equations, 2 x 2).
    pub fn fit(samples: &[[R; 3]]) -> Plane<R> {
        let n = R::from_usize(samples.len().max(1));
        let mut c = [R::ZERO; 3];
        for s in samples {
            for k in 0..3 {
                c[k] += s[k] / n;
            }
        }
        let (mut saa, mut sab, mut sbb, mut sad, mut sbd) =
            (R::ZERO, R::ZERO, R::ZERO, R::ZERO, R::ZERO);
        for s in samples {
            let (a, b, d) = (s[0] - c[0], s[1] - c[1], s[2] - c[2]);
            saa += a * a;
            sab += a * b;
            sbb += b * b;
            sad += a * d;
            sbd += b * d;
        }
        let det = saa * sbb - sab * sab;
        // Collinear locations: det small against the spread.
        let determined = det > R::from_f64(1e-6) * (saa + sbb) * (saa + sbb) && det.is_finite();
        let slope = if determined {
            [(sad * sbb - sbd * sab) / det, (sbd * saa - sad * sab) / det]
        } else {
            [R::ZERO, R::ZERO]
        };
        Plane {
            centre: c,
            slope,
            determined,
        }
    }

    /// The plane's `d` at `(a, b)`.
    #[inline]
    pub fn at(&self, a: R, b: R) -> R {
        self.centre[2] + self.slope[0] * (a - self.centre[0]) + self.slope[1] * (b - self.centre[1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tilted_plane_is_found_and_a_line_leaves_it_flat() {
        let samples: [[f64; 3]; 4] = [
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.5],
            [0.0, 1.0, 0.8],
            [1.0, 1.0, 1.3],
        ];
        let p = Plane::fit(&samples);
        assert!(p.determined);
        assert!((p.slope[0] - 0.5).abs() < 1e-12 && (p.slope[1] + 0.2).abs() < 1e-12);
        assert!((p.at(2.0, 2.0) - 1.6).abs() < 1e-12);
        let line: [[f64; 3]; 3] = [[0.0, 0.0, 1.0], [1.0, 1.0, 2.0], [2.0, 2.0, 3.0]];
        let flat = Plane::fit(&line);
        assert!(!flat.determined && flat.slope == [0.0, 0.0]);
        assert!((flat.at(5.0, -3.0) - 2.0).abs() < 1e-12);
        assert!(!Plane::<f64>::fit(&[]).determined);
    }
}
