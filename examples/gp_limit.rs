//! How far the GP reconstruction is from this CPU's limit (docs/journal.md, "The GP's
//! physical limit"). For each KITTI scan of a sequence: the map update's reconstruction (every
//! layer, exact variances) of the scan at the sensor pose, with the `default` preset fitted to
//! the scene as `slamesh run` fits it. Prints:
//! - layers a scan and training samples a layer (`m`, at most 36);
//! - the floating-point operations of one layer's GP, counted from `m` (an add or a multiply
//!   is one; an `exp` or a square root is counted apart, with its measured cost);
//! - the time `predict_in` takes a layer, and so the rate it reaches;
//! - this CPU's rate on the same kinds of loop, measured here: the multiply-adds of the f64
//!   factorization and of the f32 solves, in L1, as the build vectorises them;
//! - the least time a reconstruction could take at those rates, against what it takes.
//!
//! `cargo run --release --example gp_limit -- [--sequence DIR]` (kitti-mini 00 under
//! SLAMESH_DATA, ../shared/data by default).

#[path = "common/flags.rs"]
mod flags;

use flags::Flags;
use slamesh::run::config_file;
use slamesh::run::scale;
use slamesh::sources::scans::{read_scan, ScanFolder};
use slamesh_core::bounded::BoundedVec;
use slamesh_core::bucket::{bucket, Placement};
use slamesh_core::filter::ScanFilter;
use slamesh_core::gp::{predict_in, select_training, GpScratch, Sample, Variances};
use slamesh_core::math::{exp, exp_f32, sqrt_f32};
use slamesh_core::pca::{choose_layers, Shape};
use slamesh_core::sort::KeySorter;
use slamesh_core::{Capacity, Config, KittiCapacity, Pose, Serial};
use std::hint::black_box;
use std::time::Instant;

/// What one layer's GP with `m` samples and 36 vertices computes, as `gp::predict_in` does it
/// with exact variances.
#[derive(Default, Clone, Copy)]
struct Work {
    /// Additions and multiplications in f64: the kernel matrix's exponents, the Cholesky
    /// factor, α.
    f64_ops: f64,
    /// The same in f32: sample-to-vertex distances, the mean and k*ᵀ α at each vertex, the
    /// variances' solves.
    f32_ops: f64,
    /// `exp` and square roots in f64 (the kernel matrix) and in f32 (sample to vertex).
    transcendental_f64: f64,
    transcendental_f32: f64,
}

impl Work {
    fn of(m: usize) -> Self {
        let (m, v) = (m as f64, 36.0);
        let half = m * (m + 1.0) / 2.0;
        Work {
            // Exponents 5 each; Cholesky's dot products, two a term; α's two substitutions.
            f64_ops: 5.0 * half + m * m * m / 3.0 + 2.0 * m * m,
            // Distances 4 each; the plane mean 4 a vertex; k*ᵀ α 2 a term; L⁻¹ on 36 columns
            // (m² each) and a squared norm per column.
            f32_ops: 4.0 * m * v + 4.0 * v + 2.0 * m * v + v * m * m + 2.0 * m * v,
            transcendental_f64: half,
            transcendental_f32: m * v,
        }
    }

    fn add(self, o: Work) -> Work {
        Work {
            f64_ops: self.f64_ops + o.f64_ops,
            f32_ops: self.f32_ops + o.f32_ops,
            transcendental_f64: self.transcendental_f64 + o.transcendental_f64,
            transcendental_f32: self.transcendental_f32 + o.transcendental_f32,
        }
    }
}

/// Multiply-adds a second in L1: `y = y * a + x` over 1 024 values, as the compiler
/// vectorises it for this build, two operations each.
fn rate<T: Copy + std::ops::Mul<Output = T> + std::ops::Add<Output = T>>(one: T) -> f64 {
    let x = [one; 1024];
    let mut y = [one; 1024];
    let reps = 200_000;
    let t = Instant::now();
    for _ in 0..reps {
        let a = black_box(one);
        for (y, x) in y.iter_mut().zip(&x) {
            *y = *y * a + *x;
        }
        black_box(&mut y);
    }
    2.0 * 1024.0 * reps as f64 / t.elapsed().as_secs_f64()
}

/// Seconds per value of `f` applied over an array of 1 024, as the GP applies `exp` and
/// square roots to a row (the compiler may vectorise it).
fn per_value<T: Copy>(from: impl Fn(usize) -> T, f: impl Fn(T) -> T) -> f64 {
    let start: Vec<T> = (0..1024).map(from).collect();
    let mut row = start.clone();
    let reps = 20_000;
    let t = Instant::now();
    for _ in 0..reps {
        row.copy_from_slice(&start);
        for v in row.iter_mut() {
            *v = f(*v);
        }
        black_box(&mut row);
    }
    t.elapsed().as_secs_f64() / (reps as f64 * 1024.0)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let flags = Flags::from_env();
    let data = std::env::var("SLAMESH_DATA").unwrap_or_else(|_| "../shared/data".into());
    let dir = flags
        .value("--sequence")
        .map_or_else(|| format!("{data}/kitti-mini/00"), str::to_string);
    let folder = ScanFolder::open(std::path::Path::new(&dir))?;
    let first = read_scan(&folder.paths[0])?;
    let base = config_file::preset("default").ok_or("no default preset")?;
    let config = scale::fit(&base, &first).map_or(base, |f| f.config);
    let lattice = config.lattice();
    let layers = training_samples(&folder, &config)?;
    let scans = folder.paths.len() as f64;
    let mean_m = layers.iter().map(|s| s.len() as f64).sum::<f64>() / layers.len() as f64;
    let w = layers
        .iter()
        .fold(Work::default(), |w, s| w.add(Work::of(s.len())));
    let n = layers.len() as f64;
    let flops = w.f64_ops + w.f32_ops;
    println!(
        "{dir}: {:.0} layers a scan, {mean_m:.1} samples a layer",
        n / scans
    );
    println!(
        "a layer: {:.0} additions and multiplications ({:.0} in f64), {:.0} exp and as many \
         square roots ({:.0} in f64)",
        flops / n,
        w.f64_ops / n,
        (w.transcendental_f64 + w.transcendental_f32) / n,
        w.transcendental_f64 / n
    );
    // The GP as the pipeline runs it, every layer five times.
    let mut scratch = GpScratch::new();
    let reps = 5;
    let t = Instant::now();
    for _ in 0..reps {
        for s in &layers {
            black_box(predict_in(&mut scratch, s, &lattice, &config.gp, Variances::Exact).ok());
        }
    }
    let per_layer = t.elapsed().as_secs_f64() / (reps as f64 * n);
    // This CPU: multiply-adds in L1; exp and roots over a row.
    let (f64_rate, f32_rate) = (rate(1.0f64), rate(1.0f32));
    let exp64 = per_value(|i| -(i as f64) * 1e-3, exp);
    let root64 = per_value(|i| i as f64, f64::sqrt);
    let exp32 = per_value(|i| -(i as f32) * 1e-3, exp_f32);
    let root32 = per_value(|i| i as f32, sqrt_f32);
    println!(
        "this CPU: {:.2} GFLOP/s in f64, {:.2} in f32 (y = y a + x in L1); over a row, exp {:.1} ns and \
         square root {:.1} ns in f64, {:.1} and {:.1} ns in f32",
        f64_rate / 1e9,
        f32_rate / 1e9,
        exp64 * 1e9,
        root64 * 1e9,
        exp32 * 1e9,
        root32 * 1e9
    );
    let least = (w.f64_ops / f64_rate
        + w.f32_ops / f32_rate
        + w.transcendental_f64 * (exp64 + root64)
        + w.transcendental_f32 * (exp32 + root32))
        / n;
    println!(
        "a layer: {:.2} us measured, {:.2} us at those rates ({:.0} % of the limit; \
         {:.2} GFLOP/s reached)",
        per_layer * 1e6,
        least * 1e6,
        100.0 * least / per_layer,
        flops / n / per_layer / 1e9
    );
    println!(
        "a scan's update reconstruction (one core): {:.2} ms of GP measured, {:.2} ms at the limit",
        per_layer * n / scans * 1e3,
        least * n / scans * 1e3
    );
    Ok(())
}

/// Every layer's training samples, over all the scans of `folder`, as the pipeline would
/// reconstruct them at the identity pose.
fn training_samples(
    folder: &ScanFolder,
    config: &Config,
) -> Result<Vec<Vec<Sample>>, Box<dyn std::error::Error>> {
    let lattice = config.lattice();
    let mut filter = ScanFilter::new::<KittiCapacity>();
    let mut work = BoundedVec::with_capacity(KittiCapacity::POINTS);
    let mut sorter = KeySorter::with_capacity(KittiCapacity::SORT_ENTRIES);
    let mut cells = BoundedVec::with_capacity(KittiCapacity::SCAN_CELLS);
    let mut layers: Vec<Vec<Sample>> = Vec::new();
    for path in &folder.paths {
        let raw = read_scan(path)?;
        let points = filter.filter(&raw, config, &Serial).points.to_vec();
        let placement = Placement::<f64>::new(&Pose::identity(), config.grid.cell_size_m);
        let min_points = config.grid.min_points;
        bucket(
            &points,
            &placement,
            min_points,
            &mut work,
            &mut sorter,
            &mut cells,
            &Serial,
        );
        for c in cells.iter() {
            let pts = c.points(&work);
            if let Shape::Surface(axes) = choose_layers::<f64>(pts) {
                for axis in axes {
                    layers.push(select_training(pts, axis, lattice.cell_size).to_vec());
                }
            }
        }
    }
    Ok(layers)
}
