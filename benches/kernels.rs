//! Criterion benchmarks of the hot kernels: the GP of one layer, the association of one scan
//! and one LM solve. `cargo bench --manifest-path benches/Cargo.toml`.
//!
//! The scan and map are the simulated town's first two frames (no data files needed): the
//! map holds frame 0, the scan is frame 1 reconstructed at its true pose, as in the last
//! registration round.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use slamesh_core::associate::associate;
use slamesh_core::bounded::BoundedVec;
use slamesh_core::cell::{Axis, CellKey};
use slamesh_core::gp;
use slamesh_core::lm;
use slamesh_core::{Config, Pipeline, Serial};
use slamesh_sim::{Drive, SplitMix64};

/// A ground layer's points: 20 x 20 over a 1.6 m cell, gently curved, 2 cm noise.
fn ground_cell() -> Vec<(CellKey, [f32; 3])> {
    let mut rng = SplitMix64(7);
    let mut points = Vec::new();
    for i in 0..20 {
        for j in 0..20 {
            let (a, b) = (0.08 * i as f64 + 0.02, 0.08 * j as f64 + 0.02);
            let d = 0.6 + 0.05 * a - 0.03 * b + 0.04 * (a * b).sin() + rng.range(-0.02, 0.02);
            points.push((CellKey::default(), [a as f32, b as f32, d as f32]));
        }
    }
    points
}

fn gp_layer(c: &mut Criterion) {
    let config = Config::kitti();
    let lattice = config.lattice();
    let points = ground_cell();
    c.bench_function("gp/select_training (400 points)", |b| {
        b.iter(|| gp::select_training(black_box(&points), Axis::Z, lattice.cell_size))
    });
    let samples = gp::select_training(&points, Axis::Z, lattice.cell_size);
    assert_eq!(samples.len(), 36);
    // As the pipeline calls it: one working memory for all the layers.
    let mut scratch = gp::GpScratch::new();
    let below = gp::Variances::Below(config.register.variance_register);
    for (name, variances) in [
        ("gp/predict (36 samples)", gp::Variances::Exact),
        ("gp/predict (36 samples, registration)", below),
    ] {
        c.bench_function(name, |b| {
            b.iter(|| {
                let samples = black_box(&samples);
                gp::predict_in(&mut scratch, samples, &lattice, &config.gp, variances)
            })
        });
    }
}

fn registration(c: &mut Criterion) {
    let drive = Drive::town(2, 1);
    let mut pipeline = Pipeline::<slamesh_core::KittiCapacity>::new(Config::kitti()).unwrap();
    let scan = |i: usize| drive.lidar.scan(&drive.scene, &drive.poses[i]);
    pipeline.integrate_scan(&scan(0), &drive.poses[0]).unwrap();
    let mut mapped = pipeline.clone();
    mapped.integrate_scan(&scan(1), &drive.poses[1]).unwrap();
    let layers = mapped.last_scan().to_vec();
    let map = pipeline.map();
    let cfg = Config::kitti().register;
    let mut residuals = BoundedVec::with_capacity(layers.len());
    let stats = associate::<f64>(
        &layers,
        map,
        0,
        0,
        cfg.variance_register,
        &mut residuals,
        &Serial,
    );
    println!(
        "{} scan layers, {} residuals from {} vertex pairs",
        layers.len(),
        stats.residuals,
        stats.pairs
    );
    c.bench_function("associate (one scan, reach 1)", |b| {
        b.iter(|| {
            associate::<f64>(
                black_box(&layers),
                map,
                1,
                0,
                cfg.variance_register,
                &mut residuals,
                &Serial,
            )
        })
    });
    associate::<f64>(
        &layers,
        map,
        0,
        0,
        cfg.variance_register,
        &mut residuals,
        &Serial,
    );
    c.bench_function("lm/solve (one scan)", |b| {
        b.iter(|| lm::solve(black_box(&residuals), &cfg.lm).unwrap())
    });
}

criterion_group!(kernels, gp_layer, registration);
criterion_main!(kernels);
