//! Which triangles are off the true surface: runs the simulated town drive (the demo's),
//! then for every triangle of the final map within the slope limit prints how often it lies
//! more than 0.1 m from the true surfaces (the mean distance of four points on it), by the
//! mean variance of its corners and by how many of its lattice neighbours pass the variance
//! limit. This is the measurement behind `Layer::shown_mask`'s notch and speck rules
//! (docs/design.md §1.6). Then the same for the triangles each layer shows by its own
//! variances and those it shows only in the welded mesh, by its corners' fused variances
//! (§1.10).
//!
//! `cargo run --release --example triangle_errors -- [--frames N] [--preset NAME]`
//! (100 frames and the `default` preset by default).

#[path = "common/flags.rs"]
mod flags;

use flags::Flags;
use slamesh::outputs::mesh_weld::weld;
use slamesh::parallel::Workers;
use slamesh::run::config_file;
use slamesh_core::layer::{lattice_triangle, triangle_neighbours, Shown, TRIANGLES};
use slamesh_core::map::LayerRef;
use slamesh_core::pipeline::{Known, Scan};
use slamesh_core::{KittiCapacity, NoProbe, Pipeline};
use slamesh_sim::{Drive, SurfaceDistance};

/// Upper ends of the variance bins, as multiples of `variance_show`.
const BINS: [f32; 8] = [
    1.0 / 3.0,
    2.0 / 3.0,
    1.0,
    4.0 / 3.0,
    5.0 / 3.0,
    2.0,
    3.0,
    f32::INFINITY,
];

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let flags = Flags::from_env();
    let frames: usize = flags.parse_or("--frames", 100)?;
    let preset = flags.value("--preset").unwrap_or("default");
    let config = config_file::preset(preset).ok_or("unknown preset")?;
    let drive = Drive::town(frames, 1);
    let workers = Workers::new(0)?;
    let mut pipeline = Pipeline::<KittiCapacity>::new(config)?;
    for i in 0..drive.poses.len() {
        // A frame that fails keeps the map as it was; the counts are about the map.
        let _ = pipeline.step(
            Scan::Raw(&drive.scan(i)),
            Known::Nothing,
            &workers,
            &mut NoProbe,
        );
    }
    let truth = SurfaceDistance::new(&drive.scene);
    let table = config.lattice().table();
    let shown = Shown::new(&config.mesh);
    // The mean distance of four points of lattice triangle `t` of `l` to the true surfaces.
    let off_truth = |l: &LayerRef<'_>, t: usize| {
        let v = lattice_triangle(t).map(|j| l.layer.vertex(&table, &l.key, l.axis, j));
        [(1.0, 1.0), (4.0, 1.0), (1.0, 4.0), (1.0, 1.0 / 4.0)]
            .iter()
            .map(|&(a, b)| {
                let (a, b) = (a / 6.0, b / 6.0);
                let p = v[0] + (v[1] - v[0]) * a + (v[2] - v[0]) * b;
                truth.distance(&(drive.poses[0] * nalgebra::Point3::from(p)).coords)
            })
            .sum::<f64>()
            / 4.0
    };
    // [bin][confident neighbours] = (triangles, off by more than 0.1 m)
    let mut counts = [[(0u64, 0u64); 4]; BINS.len()];
    for l in pipeline.map().layers() {
        let slope = l.layer.slope_mask(&table, shown.min_axis_cosine);
        let variance = |t: usize| l.layer.mean_variance(&lattice_triangle(t));
        let confident = |t: usize| slope & (1 << t) != 0 && variance(t) < shown.variance;
        for t in (0..TRIANGLES).filter(|&t| slope & (1 << t) != 0) {
            let error = off_truth(&l, t);
            let bin = BINS
                .iter()
                .position(|&hi| variance(t) < hi * shown.variance)
                .unwrap_or(BINS.len() - 1);
            let around = triangle_neighbours(t)
                .iter()
                .flatten()
                .filter(|&&n| confident(n))
                .count();
            let c = &mut counts[bin][around];
            c.0 += 1;
            c.1 += u64::from(error > 0.1);
        }
    }
    print_by_variance(&counts);
    // Welded: the layers' own shown triangles against those shown by the fused variances.
    let welded = weld(pipeline.map().layers(), &config.lattice(), shown);
    let mut by_rule = [(0u64, 0u64, 0u64); 2];
    for (l, &mask) in pipeline.map().layers().zip(&welded.shown) {
        let own = l.layer.shown_mask(&table, shown);
        for t in (0..TRIANGLES).filter(|&t| mask & (1 << t) != 0) {
            let error = off_truth(&l, t);
            let c = &mut by_rule[usize::from(own & (1 << t) == 0)];
            *c = (
                c.0 + 1,
                c.1 + u64::from(error > 0.1),
                c.2 + u64::from(error > 0.2),
            );
        }
    }
    print_welded(by_rule);
    Ok(())
}

/// Triangles by variance bin and confident neighbours, with the share off the truth.
fn print_by_variance(counts: &[[(u64, u64); 4]; BINS.len()]) {
    println!("variance / limit   triangles (share > 0.1 m off) by confident neighbours 0, 1, 2, 3");
    let mut lo = 0.0;
    for (hi, row) in BINS.iter().zip(counts) {
        print!("{lo:5.2} to {hi:5.2}");
        for &(n, off) in row {
            print!("  {n:6} ({:4.1} %)", 100.0 * off as f64 / n.max(1) as f64);
        }
        println!();
        lo = *hi;
    }
}

/// The welded mesh's triangles shown by their own variances and by the fused ones only, with
/// the shares off the truth.
fn print_welded(by_rule: [(u64, u64, u64); 2]) {
    for (name, (n, off1, off2)) in ["own variances", "fused only"].iter().zip(by_rule) {
        let share = |k: u64| 100.0 * k as f64 / n.max(1) as f64;
        println!(
            "welded, shown by {name:13}: {n:7} triangles, {:4.1} % > 0.1 m off, {:4.1} % > 0.2 m",
            share(off1),
            share(off2)
        );
    }
}
