//! What the search for a pose in a saved map costs (docs/design.md §1.13): loads a map file,
//! reads one scan, and times `Pipeline::step` (a search: `Known::Somewhere`) with the map's own candidates, then
//! with them repeated 4 and 16 times (as a path 4 and 16 times as long would give), so that
//! the time splits into a fixed part (the registrations) and a part per hypothesis; prints how
//! long a path the search covers in one second on this machine.
//!
//! `cargo run --release --example relocalize_cost -- --map FILE --scan SCAN.bin [--threads N]`

#[path = "common/flags.rs"]
mod flags;

use flags::Flags;
use slamesh::formats::kitti::read_bin;
use slamesh::parallel::Workers;
use slamesh::run::saved_map;
use slamesh_core::pipeline::{Known, Scan, Stepped};
use slamesh_core::relocalize::{AllResident, Search};
use slamesh_core::{KittiCapacity, NoProbe, Pipeline, Pose};
use std::path::PathBuf;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let flags = Flags::from_env();
    let map = PathBuf::from(flags.value("--map").ok_or("--map FILE is required")?);
    let scan = PathBuf::from(flags.value("--scan").ok_or("--scan FILE is required")?);
    let threads: usize = flags.parse_or("--threads", 1)?;
    let settings = saved_map::config_of(&map)?;
    let mut pipeline = Pipeline::<KittiCapacity>::new(settings.config)?;
    pipeline.set_map_updates(false);
    let start = saved_map::load(&map, pipeline.map_mut())?;
    let length: f64 = start
        .path
        .windows(2)
        .map(|w| (w[1].1.translation.vector - w[0].1.translation.vector).norm())
        .sum();
    let candidates =
        slamesh::localize::search::candidates(&start.path, settings.config.grid.cell_size_m);
    let points = read_bin(&scan)?;
    let workers = Workers::new(threads)?;
    println!(
        "map: {} cells, path {:.0} m, {} candidates; scan {} points; {} thread(s)",
        pipeline.map().cell_count(),
        length,
        candidates.len(),
        points.len(),
        workers.threads()
    );
    let mut rows = Vec::new();
    for k in [1usize, 4, 16] {
        let many: Vec<Pose> = (0..k).flat_map(|_| candidates.iter().copied()).collect();
        let mut times = Vec::new();
        let mut last = None;
        for _ in 0..3 {
            let mut p = pipeline.clone();
            let t = Instant::now();
            let known = Known::Somewhere {
                candidates: &many,
                search: &Search::default(),
                paging: &mut AllResident,
            };
            let Stepped::Searched(r) = p.step(Scan::Raw(&points), known, &workers, &mut NoProbe)?
            else {
                return Err("the search did not run".into());
            };
            times.push(t.elapsed().as_secs_f64());
            last = Some(r);
        }
        times.sort_by(f64::total_cmp);
        let r = last.ok_or("no run")?;
        println!(
            "x{k:>2}: {} hypotheses, {} registered: {:.1} ms (median of 3), {:?}, {:.0} % on the map",
            r.hypotheses,
            r.registered,
            times[1] * 1e3,
            r.outcome.status,
            r.hit_share * 100.0
        );
        rows.push((r.hypotheses as f64, times[1]));
    }
    // A line through the first and last: seconds = fixed + per hypothesis.
    let (a, b) = (rows[0], rows[2]);
    let per = (b.1 - a.1) / (b.0 - a.0);
    let fixed = a.1 - per * a.0;
    let per_metre = a.0 / length;
    println!(
        "fixed {:.1} ms, {:.2} us a hypothesis ({:.0} hypotheses a metre of path): one second \
         searches {:.1} km of path",
        fixed * 1e3,
        per * 1e6,
        per_metre,
        (1.0 - fixed) / per / per_metre / 1000.0
    );
    Ok(())
}
