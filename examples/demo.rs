//! A drive down a simulated street: SLAM on ray-cast HDL-64E-like scans, compared with the
//! true poses. Needs no data.
//!
//! `cargo run --release --example demo`

use slamesh::eval::consecutive_errors;
use slamesh::sim::{sensor_pose, Lidar, Scene};
use slamesh_core::{Config, KittiCapacity, Pipeline};
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let scene = Scene::street();
    let lidar = Lidar::hdl64(1800);
    // 30 scans at 10 Hz: accelerating from standstill to 10 m/s, a gentle curve.
    let mut truth = Vec::new();
    let (mut x, mut y, mut yaw) = (-18.0f64, 0.0f64, 0.0f64);
    for i in 0..30 {
        truth.push(sensor_pose(x, y, 1.73, yaw.to_degrees()));
        let speed = (0.1 * i as f64).min(1.0);
        yaw = 0.08 * (i as f64 / 30.0 * std::f64::consts::PI).sin();
        x += speed * yaw.cos();
        y += speed * yaw.sin();
    }
    let mut pipeline = Pipeline::<KittiCapacity>::new(Config::default())?;
    let mut estimate = Vec::new();
    let mut ms = Vec::new();
    for (i, t) in truth.iter().enumerate() {
        let scan = lidar.scan(&scene, t);
        let start = Instant::now();
        let out = pipeline.process_scan(&scan)?;
        ms.push(start.elapsed().as_secs_f64() * 1e3);
        // Express the estimate in the world frame of the truth (the first scan defines ours).
        estimate.push(truth[0] * out.t_world_sensor);
        println!("scan {i:2}: {:6} points, {:?}", scan.len(), out.status);
    }
    let e = consecutive_errors(&estimate, &truth);
    let last = estimate
        .last()
        .zip(truth.last())
        .map(|(e, t)| (t.inverse() * e).translation.vector.norm())
        .unwrap_or(0.0);
    ms.sort_by(f64::total_cmp);
    println!(
        "\n{} scans, {:.1} m driven",
        truth.len(),
        (truth[0].inverse() * truth[truth.len() - 1])
            .translation
            .vector
            .norm()
    );
    println!(
        "mean consecutive-frame error: {:.2} cm, {:.4} deg",
        e.mean_translation_m * 100.0,
        e.mean_rotation_deg
    );
    println!("end-point error: {:.2} cm", last * 100.0);
    println!(
        "map: {} cells, {} layers, {} triangles",
        pipeline.map().cell_count(),
        pipeline.map().layer_count(),
        pipeline.triangles().count()
    );
    println!("median {:.1} ms per scan (one thread)", ms[ms.len() / 2]);
    Ok(())
}
