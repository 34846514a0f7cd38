//! Why the map's mesh has open edges: runs the simulated town drive (the demo's) and prints
//! the boundary edges and connected pieces (`slamesh::eval::topology`) of the final map's
//! mesh three ways: every layer on its own (no welding), welded as one set, and as
//! `mesh.ply` has it (welded in sets of at most `SET_LAYERS` layers); then the open edges of
//! the one-set mesh by cause (`slamesh::eval::seams`).
//!
//! `cargo run --release --example mesh_seams -- [--frames N] [--preset NAME] [--variance-show V]
//! [--seed S]` (100 frames, the demo's preset, `town`, and seed 1 by default).

#[path = "common/flags.rs"]
mod flags;

use flags::Flags;
use slamesh::eval::seams::seam_causes;
use slamesh::eval::topology::Topology;
use slamesh::formats::ply::read_ply_mesh;
use slamesh::outputs::mesh_spool::{MeshFormat, MeshSpool};
use slamesh::outputs::mesh_weld::weld;
use slamesh::parallel::Workers;
use slamesh::run::config_file;
use slamesh_core::layer::Shown;
use slamesh_core::pipeline::{Known, Scan};
use slamesh_core::{KittiCapacity, NoProbe, Pipeline};
use slamesh_sim::Drive;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let flags = Flags::from_env();
    let frames: usize = flags.parse_or("--frames", 100)?;
    let preset = flags.value("--preset").unwrap_or("town");
    let mut config = config_file::preset(preset).ok_or("unknown preset")?;
    if let Some(v) = flags.value("--variance-show") {
        config.mesh.variance_show = v.parse()?;
    }
    let seed: u64 = flags.parse_or("--seed", 1)?;
    let drive = Drive::town(frames, seed);
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
    let map = pipeline.map();
    let (lattice, shown) = (config.lattice(), Shown::new(&config.mesh));
    let welded = weld(map.layers(), &lattice, shown);
    // Without welding: every layer on its own.
    let mut apart = Vec::new();
    let mut base = 0u32;
    for l in map.layers() {
        let m = weld(std::iter::once(l), &lattice, shown);
        apart.extend(m.triangles.iter().map(|t| t.map(|i| i + base)));
        base += m.vertices.len() as u32;
    }
    // As `mesh.ply` has it: welded in sets of at most `SET_LAYERS` layers.
    let file = std::env::temp_dir().join(format!("slamesh-seams-{}.ply", std::process::id()));
    let mut spool = MeshSpool::new(&file, lattice, &config.mesh)?;
    spool.add_map(map)?;
    spool.finish(&[(file.clone(), MeshFormat::Ply)])?;
    let written = read_ply_mesh(&file)?.triangles;
    std::fs::remove_file(&file)?;
    for (name, triangles) in [
        ("layers apart", &apart),
        ("one set", &welded.triangles),
        ("mesh.ply", &written),
    ] {
        let t = Topology::of(triangles);
        println!(
            "{name:13}: {} triangles, {} edges, {} boundary ({:.1} %), {} non-manifold, \
             {} pieces (largest {} triangles)",
            t.triangles,
            t.edges,
            t.boundary_edges,
            100.0 * t.boundary_share(),
            t.non_manifold_edges,
            t.pieces,
            t.largest_piece
        );
    }
    println!("vertices merged by welding: {}", welded.merged);
    let c = seam_causes(map.layers(), &welded.shown, &lattice, shown);
    let share = |n: u64| 100.0 * n as f64 / c.open().max(1) as f64;
    println!("open edges by cause ({} in all):", c.open());
    for (cause, n) in [
        ("nothing seen across the cell face", c.unseen),
        ("a layer of another axis across", c.orientation),
        ("the triangle across hidden by variance", c.hidden_variance),
        ("the triangle across hidden by slope", c.hidden_slope),
        ("shown across, vertices too far to merge", c.not_merged),
    ] {
        println!("  {cause:42} {n:7} ({:.1} %)", share(n));
    }
    Ok(())
}
