//! Gaussian-process reconstruction of one layer on its fixed lattice (docs/design.md §1.3).
//!
//! Training data: the cell's points binned on the `6 x 6` grid of the layer's location axes,
//! one per bin (the one closest to the bin centre), so at most 36. Kernel
//! `k(u, v) = exp(-κ |u - v|)`, noise σ_n² on the diagonal:
//! `f* = m(u*) + k*ᵀ (K + σ_n² I)⁻¹ (f - m(u))`, `σ*² = 1 - k*ᵀ (K + σ_n² I)⁻¹ k*`.
//!
//! The mean `m` is the least-squares plane through the samples (the constant mean when the
//! samples do not span a plane). docs/design.md §1.3 subtracts the constant mean of the targets; with
//! the rough exponential kernel that makes the GP fall back towards the mean between and
//! beyond samples, which bends slopes at the cell faces (see
//! `reproduces_plane_slope_and_curved_surface_within_5mm`). A plane mean is exact on planes
//! and slopes and leaves the GP only the curvature.
//! The Cholesky factor (a packed lower triangle, in f64 and an f32 copy) and the 36 x 36
//! sample-to-vertex kernel live in a [`GpScratch`] (about 13 KB, on the stack or reused
//! by the caller), no heap. Predictions are clamped into
//! the cell; a vertex outside the training inputs' bounding box gets twice its variance.

// The triangular factorization and solves read best with explicit indices.
#![allow(clippy::needless_range_loop)]

use crate::cell::{Axis, CellKey};
use crate::config::GpConfig;
use crate::lattice::{Lattice, N, VERTICES};
use crate::layer::Layer;
use crate::math::Point;
use crate::plane::Plane;
use crate::real::Real;
use core::fmt;

/// At most one training point per lattice bin.
pub const MAX_TRAINING: usize = VERTICES;
/// A layer needs at least this many training points (bins with points).
pub const MIN_TRAINING: usize = 3;

/// A training sample `(a, b, d)`: cell-local location and target (metres), in the scalar `R`
/// of the reconstruction ([`Real`]).
pub type Sample<R = f64> = [R; 3];

/// Why a layer could not be reconstructed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GpError {
    /// Fewer than [`MIN_TRAINING`] bins hold points.
    TooFewSamples,
    /// The kernel matrix is not numerically positive definite (non-finite input).
    NotPositiveDefinite,
}

impl fmt::Display for GpError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GpError::TooFewSamples => {
                write!(f, "fewer than {MIN_TRAINING} lattice bins hold points")
            }
            GpError::NotPositiveDefinite => write!(f, "kernel matrix is not positive definite"),
        }
    }
}

impl core::error::Error for GpError {}

/// Bins cell-local `points` on the lattice grid of `axis` and keeps, per bin, the point closest
/// to the bin centre, among the points of the layer's own surface.
///
/// A cell where two surfaces meet (ground and facade, the two faces of a corner) holds points
/// of both, and the other surface's points would pull this layer towards it by an amount that
/// depends on what the sensor saw: a viewpoint-dependent bias that registration turns into
/// drift. So the per-bin samples
/// are fitted with a plane, samples farther from it than `outlier_threshold` are dropped
/// (repeatedly, a few times), and bins that lost their sample take their closest point within
/// the threshold instead.
pub fn select_training<R: Real>(
    points: &[(CellKey, Point)],
    axis: Axis,
    cell_size: f64,
) -> heapless::Vec<Sample<R>, MAX_TRAINING> {
    let all = closest_per_bin(points, axis, R::from_f64(cell_size), |_| true);
    if all.len() < MIN_TRAINING {
        return all;
    }
    let mut plane = Plane::fit(&all);
    let mut limit = R::INFINITY;
    for _ in 0..OUTLIER_ROUNDS {
        let new_limit = outlier_threshold(&all, &plane);
        let mut inliers = heapless::Vec::<Sample<R>, MAX_TRAINING>::new();
        for s in all
            .iter()
            .filter(|s| (s[2] - plane.at(s[0], s[1])).abs() <= new_limit)
        {
            // No more than `all`: cannot overflow.
            let _ = inliers.push(*s);
        }
        if inliers.len() < MIN_TRAINING {
            break;
        }
        limit = new_limit;
        if inliers.len() == all.len() {
            return all;
        }
        plane = Plane::fit(&inliers);
    }
    if !limit.is_finite() {
        return all;
    }
    closest_per_bin(points, axis, R::from_f64(cell_size), |s| {
        (s[2] - plane.at(s[0], s[1])).abs() <= limit
    })
}

/// Rounds of plane fitting and outlier rejection in [`select_training`].
const OUTLIER_ROUNDS: usize = 3;
/// Samples within this distance of the fitted plane are never outliers (metres): curvature
/// within a cell and sensor noise stay in.
pub const MIN_OUTLIER_DISTANCE_M: f64 = 0.15;

/// Three robust standard deviations in medians of absolute residuals (1.4826 of them is one
/// standard deviation of a normal distribution).
const OUTLIER_SPREADS: f64 = 3.0 * 1.4826;

/// Farther from `plane` than this is an outlier: three robust standard deviations (from the
/// median absolute residual), at least [`MIN_OUTLIER_DISTANCE_M`].
fn outlier_threshold<R: Real>(samples: &[Sample<R>], plane: &Plane<R>) -> R {
    let (spreads, minimum) = (
        R::from_f64(OUTLIER_SPREADS),
        R::from_f64(MIN_OUTLIER_DISTANCE_M),
    );
    let mut r = [R::ZERO; MAX_TRAINING];
    let n = samples.len().min(MAX_TRAINING);
    let mut at_minimum = 0;
    for (ri, s) in r.iter_mut().zip(samples) {
        *ri = (s[2] - plane.at(s[0], s[1])).abs();
        at_minimum += usize::from(spreads * *ri <= minimum);
    }
    // The threshold grows with the median: when more than half the residuals give the
    // minimum, the median does too, and need not be found (most layers: their noise is a
    // few centimetres).
    if at_minimum > n / 2 {
        return minimum;
    }
    let r = &mut r[..n];
    // The median alone: selection, not a sort (the same value).
    let median = if n == 0 {
        R::ZERO
    } else {
        *r.select_nth_unstable_by(n / 2, R::total_cmp).1
    };
    (spreads * median).max(minimum)
}

/// Per lattice bin of `axis`, the point closest to the bin centre among those `keep` accepts.
fn closest_per_bin<R: Real>(
    points: &[(CellKey, Point)],
    axis: Axis,
    cell_size: R,
    keep: impl Fn(&Sample<R>) -> bool,
) -> heapless::Vec<Sample<R>, MAX_TRAINING> {
    let (ia, ib) = axis.locations();
    let bins = R::from_usize(N);
    let (bin, per_metre) = (cell_size / bins, bins / cell_size);
    let half = R::from_f64(0.5);
    // Per bin, the squared distance of its closest point so far and that point (infinitely
    // far and none at first: the points are finite, so the first one is closer).
    let mut best_dist = [R::INFINITY; VERTICES];
    let mut best = [[R::ZERO; 3]; VERTICES];
    for (_, p) in points {
        let (Some(&a), Some(&b), Some(&d)) = (p.get(ia), p.get(ib), p.get(axis.index())) else {
            continue;
        };
        let sample = [R::from_f32(a), R::from_f32(b), R::from_f32(d)];
        if !keep(&sample) {
            continue;
        }
        let [a, b, _] = sample;
        // Truncation towards zero sends negatives and NaN to 0: floor, clamped.
        let index = |v: R| (v * per_metre).to_index().min(N - 1);
        let (i, j) = (index(a), index(b));
        let (ca, cb) = (
            (R::from_usize(i) + half) * bin,
            (R::from_usize(j) + half) * bin,
        );
        let dist = (a - ca) * (a - ca) + (b - cb) * (b - cb);
        let k = i * N + j;
        if dist < best_dist[k] {
            best_dist[k] = dist;
            best[k] = sample;
        }
    }
    // The bins with a point, in order, without a branch a bin.
    let mut kept = [[R::ZERO; 3]; VERTICES];
    let mut n = 0;
    for (dist, s) in best_dist.iter().zip(&best) {
        kept[n.min(VERTICES - 1)] = *s;
        n += usize::from(*dist < R::INFINITY);
    }
    // At most VERTICES bins: the slice fits.
    heapless::Vec::from_slice(&kept[..n]).unwrap_or_default()
}

/// The exponent of the kernel `k(u, v) = exp(-κ |u - v|)` for `u - v = (da, db)`. Callers
/// fill a row of exponents, then take [`crate::math::exp`] over the row in a loop of its own,
/// which vectorizes.
#[inline]
fn kernel_exponent<R: Real>(kappa: R, da: R, db: R) -> R {
    -kappa * (da * da + db * db).sqrt()
}

/// `Σ a_i b_i` with four running sums: independent additions pipeline (and vectorize), and the
/// fixed order keeps results identical on every target.
#[inline]
fn dot<R: Real>(a: &[R], b: &[R]) -> R {
    let mut acc = [R::ZERO; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let mut tail = R::ZERO;
    for (x, y) in ca.remainder().iter().zip(cb.remainder()) {
        tail += *x * *y;
    }
    for (x, y) in ca.zip(cb) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// Which variances [`predict`] must compute exactly.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Variances {
    /// Every vertex's (the map update and the mesh weigh by them).
    Exact,
    /// Only whether each is below this threshold (registration's `variance_register`): a
    /// vertex whose variance is certainly below it gets an upper bound of its variance
    /// instead, the others their exact variance. Comparisons with the threshold give the
    /// same answers as exact variances.
    Below(f64),
}

/// Predicts the layer at the lattice vertices from `samples`.
///
/// Laid out for speed (this is most of a scan's time): the kernel between the samples and
/// all 36 vertices is one `m x 36` matrix, and the triangular solve for the variances runs
/// over its rows, so every inner loop is an independent multiply-add over 36 contiguous
/// values rather than one dependent chain per vertex.
///
/// With [`Variances::Below`], most of that solve is skipped: conditioning on more samples
/// never raises a GP's variance, so the variance given the nearest sample alone,
/// `1 - k² / (1 + σ²)`, bounds the variance given all of them, and a vertex whose bound is
/// already below the threshold needs no solve.
pub fn predict<R: Real>(
    samples: &[Sample<R>],
    lattice: &Lattice,
    cfg: &GpConfig,
    variances: Variances,
) -> Result<Layer, GpError> {
    predict_in(&mut GpScratch::new(), samples, lattice, cfg, variances)
}

/// The working memory of [`predict_in`] (about 13 KB for `f64`): the Cholesky factor in the
/// scalar `R` and in `f32`, and the sample-to-vertex kernel. A caller that predicts many layers keeps one and
/// passes it to every call, which saves clearing it each time (a few percent of a scan).
/// Every call writes what it reads: nothing of one call reaches the next.
#[derive(Debug, Clone)]
pub struct GpScratch<R = f64> {
    l: [R; PACKED],
    l32: Factor32,
    ks: VertexKernel,
}

impl<R: Real> GpScratch<R> {
    /// Cleared working memory.
    pub const fn new() -> Self {
        Self {
            l: [R::ZERO; PACKED],
            l32: [0.0; PACKED],
            ks: [[0.0; VERTICES]; MAX_TRAINING],
        }
    }
}

impl<R: Real> Default for GpScratch<R> {
    fn default() -> Self {
        Self::new()
    }
}

/// [`predict`] in the caller's working memory (the same result to the bit).
pub fn predict_in<R: Real>(
    scratch: &mut GpScratch<R>,
    samples: &[Sample<R>],
    lattice: &Lattice,
    cfg: &GpConfig,
    variances: Variances,
) -> Result<Layer, GpError> {
    let GpScratch { l, l32, ks } = scratch;
    let m = samples.len().min(MAX_TRAINING);
    let samples = samples.get(..m).unwrap_or(&[]);
    if m < MIN_TRAINING {
        return Err(GpError::TooFewSamples);
    }
    let noise = R::from_f64(cfg.sensor_noise_m * cfg.sensor_noise_m);
    let inv_diag = factorize(l, samples, R::from_f64(cfg.kappa_per_m), noise)?;
    let mean = Plane::fit(samples);
    let alpha = weights(l, &inv_diag, samples, &mean);
    // The vertices' locations.
    let mut ta = [R::ZERO; VERTICES];
    let mut tb = [R::ZERO; VERTICES];
    let table = lattice.table();
    for j in 0..VERTICES {
        let (a, b) = table.location(j);
        (ta[j], tb[j]) = (R::from_f64(a), R::from_f64(b));
    }
    vertex_kernels(ks, samples, &ta, &tb, cfg.kappa_per_m as f32);
    // Mean: f* = m(u*) + k*ᵀ α.
    let mut f = [R::ZERO; VERTICES];
    for j in 0..VERTICES {
        f[j] = mean.at(ta[j], tb[j]);
    }
    for i in 0..m {
        for j in 0..VERTICES {
            f[j] += R::from_f32(ks[i][j]) * alpha[i];
        }
    }
    let factor = extrapolation_factor(samples, &ta, &tb);
    // The factor in f32 for the variances' solves.
    for (d, v) in l32.iter_mut().zip(&l[..row_start(m)]) {
        *d = v.to_f32();
    }
    let inv_diag32 = inv_diag.map(R::to_f32);
    let var = match variances {
        Variances::Exact => exact_variances(l32, &inv_diag32, ks, m),
        Variances::Below(threshold) => bounded_variances(
            l32,
            &inv_diag32,
            ks,
            m,
            noise,
            &factor,
            R::from_f64(threshold),
        ),
    };
    let cell_size = R::from_f64(lattice.cell_size);
    let mut layer = Layer::UNKNOWN;
    for j in 0..VERTICES {
        layer.pred[j] = f[j].clamp(R::ZERO, cell_size).to_f32();
        layer.var[j] = (var[j].max(R::ZERO) * factor[j]).to_f32();
    }
    Ok(layer)
}

/// The lower-triangular Cholesky factor of K + σ² I (`noise` = σ²) of `samples`, in place in
/// rows `0..m` of `l`, row by row, packed (each row is written before it is read); returns
/// `1 / L_ii`, so that the solves multiply instead of divide.
fn factorize<R: Real>(
    l: &mut [R],
    samples: &[Sample<R>],
    kappa: R,
    noise: R,
) -> Result<[R; MAX_TRAINING], GpError> {
    let m = samples.len();
    for i in 0..m {
        let si = samples[i];
        let row = &mut l[row_start(i)..=row_start(i) + i];
        for (v, sj) in row.iter_mut().zip(samples) {
            *v = kernel_exponent(kappa, si[0] - sj[0], si[1] - sj[1]);
        }
        for v in row.iter_mut() {
            *v = v.exp();
        }
        l[row_start(i) + i] += noise;
    }
    let mut inv_diag = [R::ZERO; MAX_TRAINING];
    for i in 0..m {
        let ri = row_start(i);
        for j in 0..i {
            let rj = row_start(j);
            let v = l[ri + j] - dot(&l[ri..ri + j], &l[rj..rj + j]);
            l[ri + j] = v * inv_diag[j];
        }
        let diag = l[ri + i] - dot(&l[ri..ri + i], &l[ri..ri + i]);
        if !(diag > R::ZERO && diag.is_finite()) {
            return Err(GpError::NotPositiveDefinite);
        }
        l[ri + i] = diag.sqrt();
        inv_diag[i] = R::ONE / l[ri + i];
    }
    Ok(inv_diag)
}

/// α = (K + σ² I)⁻¹ (f - m(u)) from the factor `l` ([`factorize`]): forward, then backward
/// substitution.
fn weights<R: Real>(
    l: &[R],
    inv_diag: &[R; MAX_TRAINING],
    samples: &[Sample<R>],
    mean: &Plane<R>,
) -> [R; MAX_TRAINING] {
    let m = samples.len();
    let mut alpha = [R::ZERO; MAX_TRAINING];
    for i in 0..m {
        let s = samples[i];
        let v = s[2] - mean.at(s[0], s[1]) - dot(&l[row_start(i)..][..i], &alpha[..i]);
        alpha[i] = v * inv_diag[i];
    }
    for i in (0..m).rev() {
        let mut v = alpha[i];
        for k in i + 1..m {
            v -= l[row_start(k) + i] * alpha[k];
        }
        alpha[i] = v * inv_diag[i];
    }
    alpha
}

/// The kernel between each sample and every vertex (at `(ta, tb)`), rows `0..m` of `ks`, each
/// written whole: in f32, four lanes to a vector, as it only weighs the known α and measures
/// the variances (the factorization and α, which the predictions are sensitive to, stay in
/// `R`).
fn vertex_kernels<R: Real>(
    ks: &mut [[f32; VERTICES]],
    samples: &[Sample<R>],
    ta: &[R; VERTICES],
    tb: &[R; VERTICES],
    kappa32: f32,
) {
    let (ta32, tb32) = (ta.map(R::to_f32), tb.map(R::to_f32));
    for (row, s) in ks.iter_mut().zip(samples) {
        let (sa, sb) = (s[0].to_f32(), s[1].to_f32());
        for j in 0..VERTICES {
            let (da, db) = (ta32[j] - sa, tb32[j] - sb);
            row[j] = da * da + db * db;
        }
        for v in row.iter_mut() {
            *v = -kappa32 * crate::math::sqrt_f32(*v);
        }
        for v in row.iter_mut() {
            *v = crate::math::exp_f32(*v);
        }
    }
}

/// Per vertex: 2 outside the samples' bounding box (extrapolation doubles the variance), else 1.
fn extrapolation_factor<R: Real>(
    samples: &[Sample<R>],
    ta: &[R; VERTICES],
    tb: &[R; VERTICES],
) -> [R; VERTICES] {
    let (mut lo_a, mut hi_a, mut lo_b, mut hi_b) =
        (R::INFINITY, R::NEG_INFINITY, R::INFINITY, R::NEG_INFINITY);
    for s in samples {
        lo_a = lo_a.min(s[0]);
        hi_a = hi_a.max(s[0]);
        lo_b = lo_b.min(s[1]);
        hi_b = hi_b.max(s[1]);
    }
    let mut factor = [R::ONE; VERTICES];
    for j in 0..VERTICES {
        if ta[j] < lo_a || ta[j] > hi_a || tb[j] < lo_b || tb[j] > hi_b {
            factor[j] = R::from_f64(2.0);
        }
    }
    factor
}

/// Entries of a lower triangle of [`MAX_TRAINING`] rows, stored row after row (a full
/// square would be twice the stack to clear on every call).
const PACKED: usize = MAX_TRAINING * (MAX_TRAINING + 1) / 2;

/// Where row `i` of a packed lower triangle starts (it holds `i + 1` entries).
#[inline]
const fn row_start(i: usize) -> usize {
    i * (i + 1) / 2
}

/// The lower-triangular factor, in f32, packed.
type Factor32 = [f32; PACKED];
/// The sample-to-vertex kernel, in f32.
type VertexKernel = [[f32; VERTICES]; MAX_TRAINING];

/// `σ*² = 1 - |L⁻¹ k*|²` at every vertex, with `L⁻¹` applied to all 36 columns of `ks` at
/// once, in place (`ks` is left holding `L⁻¹ k*`).
fn exact_variances<R: Real>(
    l: &Factor32,
    inv_diag: &[f32; MAX_TRAINING],
    ks: &mut VertexKernel,
    m: usize,
) -> [R; VERTICES] {
    forward_solve(l, inv_diag, ks, m).map(|e| R::ONE - R::from_f32(e))
}

/// Columns solved together: three 128-bit vectors, kept in registers over a whole row's sum.
const BLOCK: usize = 12;

/// Applies `L⁻¹` in place to the `W` columns of `cols` (rows `0..m`; `W` a multiple of
/// [`BLOCK`]) and returns each column's `|L⁻¹ k|²`. Every column is computed by the same
/// sequence of operations whatever `W` is and wherever the column sits, so a vertex's
/// variance is the same to the bit when solved alone among a few columns or with all 36.
fn forward_solve<const W: usize>(
    l: &Factor32,
    inv_diag: &[f32; MAX_TRAINING],
    cols: &mut [[f32; W]; MAX_TRAINING],
    m: usize,
) -> [f32; W] {
    const { assert!(W.is_multiple_of(BLOCK)) };
    let mut explained = [0.0f32; W];
    for i in 0..m {
        let (done, rest) = cols.split_at_mut(i);
        let Some(row) = rest.first_mut() else { break };
        for c in (0..W).step_by(BLOCK) {
            let mut acc = [0.0f32; BLOCK];
            acc.copy_from_slice(&row[c..c + BLOCK]);
            for (x, prev) in l[row_start(i)..][..i].iter().zip(done.iter()) {
                for q in 0..BLOCK {
                    acc[q] -= x * prev[c + q];
                }
            }
            for q in 0..BLOCK {
                let v = acc[q] * inv_diag[i];
                row[c + q] = v;
                explained[c + q] += v * v;
            }
        }
    }
    explained
}

/// Variances (before the extrapolation `factor`) exact where they could reach `threshold`
/// and bounded by the nearest sample's where they cannot (see [`Variances::Below`]). The
/// vertices that need the exact value are gathered into the narrowest solve that holds them.
fn bounded_variances<R: Real>(
    l: &Factor32,
    inv_diag: &[f32; MAX_TRAINING],
    ks: &mut VertexKernel,
    m: usize,
    noise: R,
    factor: &[R; VERTICES],
    threshold: R,
) -> [R; VERTICES] {
    let mut nearest = [0.0f32; VERTICES];
    for row in &ks[..m] {
        for j in 0..VERTICES {
            // `max` by a comparison (no NaN here): see `math::sqrt_f32`.
            if row[j] > nearest[j] {
                nearest[j] = row[j];
            }
        }
    }
    let mut var = [R::ZERO; VERTICES];
    let mut exact = heapless::Vec::<usize, VERTICES>::new();
    for j in 0..VERTICES {
        let k = R::from_f32(nearest[j]);
        let bound = R::ONE - k * k / (R::ONE + noise);
        if bound * factor[j] < threshold {
            var[j] = bound;
        } else {
            // At most VERTICES vertices: cannot overflow.
            let _ = exact.push(j);
        }
    }
    match exact.len() {
        0 => {}
        1..=BLOCK => solve_some::<R, BLOCK>(l, inv_diag, ks, m, &exact, &mut var),
        n if n <= 2 * BLOCK => solve_some::<R, { 2 * BLOCK }>(l, inv_diag, ks, m, &exact, &mut var),
        _ => {
            let all = exact_variances(l, inv_diag, ks, m);
            for &j in &exact {
                var[j] = all[j];
            }
        }
    }
    var
}

/// The exact variances of the vertices `which` (at most `W`), gathered from `ks` into a
/// `W`-column solve, written into `var`.
fn solve_some<R: Real, const W: usize>(
    l: &Factor32,
    inv_diag: &[f32; MAX_TRAINING],
    ks: &VertexKernel,
    m: usize,
    which: &[usize],
    var: &mut [R; VERTICES],
) {
    let mut cols = [[0.0f32; W]; MAX_TRAINING];
    for (dst, src) in cols.iter_mut().zip(&ks[..m]) {
        for (d, &j) in dst.iter_mut().zip(which) {
            *d = src[j];
        }
    }
    let explained = forward_solve(l, inv_diag, &mut cols, m);
    for (&e, &j) in explained.iter().zip(which) {
        var[j] = R::ONE - R::from_f32(e);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    type Surface = (&'static str, fn(f64, f64) -> f64);

    const CFG: GpConfig = GpConfig {
        kappa_per_m: 1.2,
        sensor_noise_m: 0.02,
    };

    /// Samples `d = f(a, b)` on a dense grid (cell-local z layer), as a scan would.
    fn cloud(f: impl Fn(f64, f64) -> f64, extent: f64) -> heapless::Vec<(CellKey, Point), 1024> {
        let mut v = heapless::Vec::new();
        for i in 0..30 {
            for j in 0..30 {
                let (a, b) = (
                    extent * (i as f64 + 0.5) / 30.0,
                    extent * (j as f64 + 0.5) / 30.0,
                );
                v.push((CellKey::default(), [a as f32, b as f32, f(a, b) as f32]))
                    .unwrap();
            }
        }
        v
    }

    fn max_error(f: impl Fn(f64, f64) -> f64 + Copy, full_cover: bool) -> f64 {
        let lat = Lattice {
            cell_size: 1.6,
            full_cover,
        };
        let samples = select_training::<f64>(&cloud(f, 1.6), Axis::Z, 1.6);
        assert_eq!(samples.len(), 36);
        let layer = predict(&samples, &lat, &CFG, Variances::Exact).unwrap();
        (0..VERTICES)
            .map(|j| {
                let (a, b) = lat.location(j);
                libm::fabs(f64::from(layer.pred[j]) - f(a, b))
            })
            .fold(0.0, f64::max)
    }

    #[test]
    fn a_facade_meeting_the_ground_does_not_bend_the_ground_layer() {
        // Ground at d = 0.3 over the whole cell, and facade points 0.5 to 1.25 m above it in
        // the last column of bins, exactly at the bin centres: nearest to the centres, they
        // would be the samples of that column if nothing told the surfaces apart.
        let mut pts = cloud(|_, _| 0.3, 1.6);
        let bin = 1.6 / 6.0;
        for j in 0..6 {
            for k in 0..6 {
                let (b, d) = ((j as f64 + 0.5) * bin, 0.8 + 0.15 * k as f64);
                pts.push((CellKey::default(), [(5.5 * bin) as f32, b as f32, d as f32]))
                    .unwrap();
            }
        }
        let samples = select_training::<f64>(&pts, Axis::Z, 1.6);
        assert_eq!(samples.len(), 36, "every bin keeps a ground point");
        assert!(samples.iter().all(|s| libm::fabs(s[2] - 0.3) < 1e-6));
        let lat = Lattice {
            cell_size: 1.6,
            full_cover: false,
        };
        let layer = predict(&samples, &lat, &CFG, Variances::Exact).unwrap();
        assert!(layer.pred.iter().all(|&p| (p - 0.3).abs() < 1e-4));
    }

    /// A plane, a slope and a paraboloid (10 cm sag across a 1.6 m cell).
    const SURFACES: [Surface; 3] = [
        ("plane", |_, _| 0.7),
        ("slope", |a, b| 0.3 + 0.25 * a + 0.1 * b),
        ("curved", |a, b| {
            0.6 + 0.08 * ((a - 0.8) * (a - 0.8) + (b - 0.8) * (b - 0.8))
        }),
    ];

    #[test]
    fn reproduces_plane_slope_and_curved_surface_within_5mm() {
        let surfaces = SURFACES;
        for (name, f) in surfaces {
            let e = max_error(f, false);
            assert!(e < 0.005, "{name}: max error {e} m at interval centres");
        }
        // On the cell faces, half a bin beyond the outermost samples: planes and slopes are
        // exact through the plane mean; curvature beyond the data cannot be known, and the
        // paraboloid (10 cm sag across the cell) is off by under 4 cm at the corners.
        for (name, f) in surfaces {
            let e = max_error(f, true);
            let bound = if name == "curved" { 0.04 } else { 0.005 };
            assert!(e < bound, "{name}: max error {e} m on the faces");
        }
    }

    /// A slope seen with 2 cm Gaussian noise along the layer's axis (the sensor noise the GP
    /// assumes). With the design's kernel (unit signal variance against 2 cm of noise) the GP
    /// nearly interpolates its samples, so a vertex carries about one sample's noise: the
    /// layer must not amplify it, must stay unbiased (the plane through its vertices has the
    /// true slope and height within three standard errors of a fit to 36 points with that
    /// noise: 0.025 in slope, 12 mm in height), and must report small variances. Measured
    /// 2026-12-01: RMS error 22.6 mm (samples 22.6 mm), worst vertex 53 mm, slope off by
    /// 0.014 and 0.002, height at the centre off by 5.2 mm.
    #[test]
    fn noisy_samples_give_an_unbiased_layer_with_the_samples_noise() {
        let f = |a: f64, b: f64| 0.4 + 0.2 * a - 0.1 * b;
        let mut rng = crate::random::SplitMix64(7);
        let mut noisy = cloud(f, 1.6);
        for p in noisy.iter_mut() {
            let (u, v) = (rng.next_f64().max(1e-12), rng.next_f64());
            let n = 0.02 * libm::sqrt(-2.0 * libm::log(u)) * libm::cos(core::f64::consts::TAU * v);
            p.1[2] += n as f32;
        }
        let lat = Lattice {
            cell_size: 1.6,
            full_cover: false,
        };
        let samples = select_training::<f64>(&noisy, Axis::Z, 1.6);
        assert_eq!(samples.len(), 36);
        let sample_rms = libm::sqrt(
            samples
                .iter()
                .map(|s| (s[2] - f(s[0], s[1])).powi(2))
                .sum::<f64>()
                / 36.0,
        );
        let layer = predict(&samples, &lat, &CFG, Variances::Exact).unwrap();
        // Least-squares plane d = c0 + c1 a + c2 b through the vertices.
        let (mut ata, mut atd) = (
            nalgebra::Matrix3::<f64>::zeros(),
            nalgebra::Vector3::zeros(),
        );
        let mut squared = 0.0;
        let mut worst = 0.0f64;
        for j in 0..VERTICES {
            let (a, b) = lat.location(j);
            let d = f64::from(layer.pred[j]);
            let row = nalgebra::Vector3::new(1.0, a, b);
            ata += row * row.transpose();
            atd += row * d;
            squared += (d - f(a, b)).powi(2);
            worst = worst.max(libm::fabs(d - f(a, b)));
        }
        let c = ata.try_inverse().unwrap() * atd;
        let rms = libm::sqrt(squared / VERTICES as f64);
        let centre_error = libm::fabs(c[0] + 0.8 * c[1] + 0.8 * c[2] - f(0.8, 0.8));
        assert!(
            rms <= 1.05 * sample_rms,
            "layer RMS {rms} m, samples {sample_rms} m"
        );
        assert!(worst <= 0.053 * 1.15, "worst vertex {worst} m");
        assert!(
            libm::fabs(c[1] - 0.2) < 0.025 && libm::fabs(c[2] + 0.1) < 0.025,
            "slope {c}"
        );
        assert!(
            centre_error < 0.012,
            "height at the centre off by {centre_error} m"
        );
        assert!(
            layer.var.iter().all(|&v| v > 0.0 && v < 0.1),
            "{:?}",
            layer.var
        );
    }

    #[test]
    fn variance_grows_away_from_the_data() {
        // Points only in the lower-left quarter of the cell.
        let lat = Lattice {
            cell_size: 1.6,
            full_cover: false,
        };
        let samples = select_training::<f64>(&cloud(|_, _| 0.5, 0.8), Axis::Z, 1.6);
        let layer = predict(&samples, &lat, &CFG, Variances::Exact).unwrap();
        let var = |ia: usize, ib: usize| layer.var[ia * N + ib];
        // Next to a sample the exponential kernel leaves about 2κ·distance.
        assert!(var(0, 0) < 0.15, "on the data: {}", var(0, 0));
        // Moving diagonally away from the data, the variance rises strictly.
        for k in 2..N - 1 {
            assert!(
                var(k + 1, k + 1) > var(k, k),
                "at {k}: {} <= {}",
                var(k + 1, k + 1),
                var(k, k)
            );
        }
        // Outside the training box the variance is doubled, so it exceeds the prior 1.
        assert!(var(5, 5) > 1.0 && var(5, 5) <= 2.0);
    }

    #[test]
    fn bounded_variances_decide_the_threshold_as_exact_ones_do() {
        // Samples over part of the cell and some bins empty: vertices on, near and far from
        // the data, inside and outside the training box.
        let lat = Lattice {
            cell_size: 1.6,
            full_cover: false,
        };
        let mut tested = 0;
        for (extent, skip) in [(0.8, 0), (1.2, 3), (1.6, 5), (1.6, 0)] {
            let pts: heapless::Vec<_, 1024> = cloud(|a, b| 0.4 + 0.1 * a * b, extent)
                .into_iter()
                .enumerate()
                .filter(|(i, _)| skip == 0 || i % 7 != skip)
                .map(|(_, p)| p)
                .collect();
            let samples = select_training::<f64>(&pts, Axis::Z, 1.6);
            let exact = predict(&samples, &lat, &CFG, Variances::Exact).unwrap();
            for threshold in [0.1, 0.3, 0.6, 1.5] {
                let bounded = predict(&samples, &lat, &CFG, Variances::Below(threshold)).unwrap();
                assert_eq!(bounded.pred, exact.pred);
                for j in 0..VERTICES {
                    let (e, b) = (exact.var[j], bounded.var[j]);
                    assert_eq!(e < threshold as f32, b < threshold as f32, "vertex {j}");
                    if b < threshold as f32 {
                        assert!(b >= e, "a bound: {b} < {e}");
                    } else {
                        assert_eq!(b, e, "exact where it matters");
                    }
                    tested += usize::from(b != e);
                }
            }
        }
        assert!(tested > 100, "the bound was used ({tested} vertices)");
    }

    #[test]
    fn a_reused_scratch_gives_the_fresh_result_to_the_bit() {
        let lat = Lattice {
            cell_size: 1.6,
            full_cover: false,
        };
        // A big layer first, then smaller ones: rows past each call's samples hold the
        // previous call's numbers (or NaN, from a failed call).
        let dense =
            select_training::<f64>(&cloud(|a, b| 0.3 + 0.2 * a - 0.1 * b, 1.6), Axis::Z, 1.6);
        let part = select_training::<f64>(&cloud(|a, b| 0.9 - 0.05 * a * b, 0.9), Axis::Z, 1.6);
        let nan = [[0.1, 0.1, 0.1], [f64::NAN, 0.5, 0.1], [0.9, 0.9, 0.1]];
        assert!(dense.len() > part.len() && part.len() > MIN_TRAINING);
        let mut scratch = GpScratch::new();
        for samples in [&dense[..], &nan[..], &part[..], &dense[..]] {
            for v in [Variances::Exact, Variances::Below(0.3)] {
                let fresh = predict(samples, &lat, &CFG, v);
                let reused = predict_in(&mut scratch, samples, &lat, &CFG, v);
                let bits = |r: Result<Layer, GpError>| {
                    r.map(|l| (l.pred.map(f32::to_bits), l.var.map(f32::to_bits)))
                };
                assert_eq!(bits(fresh), bits(reused));
            }
        }
    }

    #[test]
    fn training_keeps_the_point_nearest_each_bin_centre() {
        let pts = [
            (CellKey::default(), [0.10f32, 0.10, 1.0]),
            (CellKey::default(), [0.14f32, 0.13, 2.0]), // nearest to (0.1333, 0.1333)
            (CellKey::default(), [1.59f32, 1.59, 3.0]),
        ];
        let s = select_training::<f64>(&pts, Axis::Z, 1.6);
        assert_eq!(s.len(), 2);
        assert_eq!(s[0][2], 2.0);
        assert_eq!(s[1][2], 3.0);
    }

    #[test]
    fn rejects_too_few_and_non_finite_samples() {
        let lat = Lattice {
            cell_size: 1.6,
            full_cover: false,
        };
        assert_eq!(
            predict(&[[0.1, 0.1, 0.1]; 2], &lat, &CFG, Variances::Exact),
            Err(GpError::TooFewSamples)
        );
        let bad = [[0.1, 0.1, 0.1], [f64::NAN, 0.5, 0.1], [0.9, 0.9, 0.1]];
        assert_eq!(
            predict(&bad, &lat, &CFG, Variances::Exact),
            Err(GpError::NotPositiveDefinite)
        );
    }

    /// The single-precision GP against the double-precision one on the same samples:
    /// planes, slopes, a curved surface and a rough one, densely and sparsely sampled, on both
    /// lattices, at two kernel widths. The points sit on a grid of 1/32 m in a 1.5 m cell, so
    /// that samples and vertices have the same coordinates in both scalars (where a vertex is
    /// exactly as far out as the outermost sample, a coordinate rounded one way or the other
    /// would decide differently whether it lies outside the samples, and double its
    /// variance). Measured 2026-12-03: predictions differ by at most 3.6e-7 m, variances by at
    /// most 8.3e-7 (of a unit signal variance; the sensor noise's is 4e-4).
    #[test]
    fn single_precision_predicts_what_double_precision_predicts() {
        let rough: Surface = ("rough", |a, b| {
            0.4 + 0.2 * a - 0.1 * b + 0.02 * libm::sin(37.0 * a + 91.0 * b)
        });
        let (mut worst_pred, mut worst_var) = (0.0f64, 0.0f64);
        for (name, f) in SURFACES.into_iter().chain([rough]) {
            for (side, full_cover, kappa) in [
                (48, false, 1.2),
                (48, true, 1.2),
                (12, false, 1.2),
                (48, false, 3.0),
            ] {
                let mut points = heapless::Vec::<(CellKey, Point), 2304>::new();
                for i in 0..side {
                    for j in 0..side {
                        let (a, b) = ((i as f64 + 0.5) / 32.0, (j as f64 + 0.5) / 32.0);
                        let _ =
                            points.push((CellKey::default(), [a as f32, b as f32, f(a, b) as f32]));
                    }
                }
                let lat = Lattice {
                    cell_size: 1.5,
                    full_cover,
                };
                let cfg = GpConfig {
                    kappa_per_m: kappa,
                    ..CFG
                };
                let s64 = select_training::<f64>(&points, Axis::Z, 1.5);
                let s32: heapless::Vec<Sample<f32>, MAX_TRAINING> =
                    s64.iter().map(|s| s.map(|v| v as f32)).collect();
                let a = predict(&s64, &lat, &cfg, Variances::Exact).unwrap();
                let b = predict(&s32, &lat, &cfg, Variances::Exact).unwrap();
                for j in 0..VERTICES {
                    worst_pred = worst_pred.max(f64::from((a.pred[j] - b.pred[j]).abs()));
                    worst_var = worst_var.max(f64::from((a.var[j] - b.var[j]).abs()));
                }
                // Registration's variances (bounds where they cannot reach the threshold)
                // decide the same vertices.
                let threshold = 0.05;
                let a = predict(&s64, &lat, &cfg, Variances::Below(threshold)).unwrap();
                let b = predict(&s32, &lat, &cfg, Variances::Below(threshold)).unwrap();
                for j in 0..VERTICES {
                    assert_eq!(
                        a.var[j] < threshold as f32,
                        b.var[j] < threshold as f32,
                        "{name}: vertex {j}"
                    );
                }
            }
        }
        assert!(worst_pred < 2e-6, "predictions differ by {worst_pred} m");
        assert!(worst_var < 1e-5, "variances differ by {worst_var}");
    }

    /// Training selection in either scalar keeps the same point per bin, from points at
    /// random places (no two equally near a bin centre), outliers among them.
    #[test]
    fn single_precision_selects_the_same_training_points() {
        let mut rng = crate::random::SplitMix64(11);
        let mut points = heapless::Vec::<(CellKey, Point), 1024>::new();
        for k in 0..600 {
            let (a, b) = (1.6 * rng.next_f64(), 1.6 * rng.next_f64());
            let d = if k % 25 == 0 {
                1.5
            } else {
                0.3 + 0.2 * a - 0.05 * b
            };
            points
                .push((CellKey::default(), [a as f32, b as f32, d as f32]))
                .unwrap();
        }
        let s64 = select_training::<f64>(&points, Axis::Z, 1.6);
        let s32 = select_training::<f32>(&points, Axis::Z, 1.6);
        assert_eq!(s64.len(), s32.len());
        for (x, y) in s64.iter().zip(&s32) {
            for k in 0..3 {
                assert_eq!(x[k] as f32, y[k], "the same point");
            }
        }
    }
}
