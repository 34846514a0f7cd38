//! The ROS 2 node's `map` (docs/design.md §1.18, `ros2::occupancy`), measured without DDS: a
//! simulated town drive through the command's run loop with a sink that does what the node's
//! does for `map`: keeps the mesh's tiles from each frame's map update, counts the scans' own
//! points' floor, and makes the grid around the sensor again every `--every` scans on its
//! worker thread ([`LiveMap`]), then once at the end.
//!
//! Prints the updates' count, median and 95th percentile (ms), the cells' memory and the
//! last grid's size and counts.
//!
//! `cargo run --release --example navmap_live -- [--frames N] [--every K] [--seed S]`

#[path = "common/flags.rs"]
mod flags;

use flags::Flags;
use slamesh::navmap::background::Seen;
use slamesh::navmap::NavMapOptions;
use slamesh::ros2::mesh_tiles::MeshTiles;
use slamesh::ros2::messages::{Header, OccupancyGrid};
use slamesh::ros2::occupancy::LiveMap;
use slamesh::run::sink::SinkFault;
use slamesh::run::{config_file, run_to, FrameEvent, RunOptions, Sink, Sinks, Summary};
use slamesh_core::layer::Shown;
use slamesh_core::{KittiCapacity, Pose};
use slamesh_sim::Drive;
use std::sync::{Arc, Mutex};

type Costs = ([usize; 4], (usize, f64, f64, u64, usize));

/// The node's `map` work, without its publisher.
struct Grid {
    tiles: MeshTiles,
    map: LiveMap,
    /// The last grid made.
    grid: Arc<Mutex<Option<OccupancyGrid>>>,
    /// The last grid's width, height, free and occupied cells; the updates' count, median
    /// and 95th percentile (ms); the cells' bytes.
    last: Arc<Mutex<Option<Costs>>>,
}

impl Sink for Grid {
    fn name(&self) -> String {
        "map".into()
    }
    fn wants_map(&self) -> bool {
        true
    }
    fn frame(&mut self, e: Arc<FrameEvent>) -> Result<(), SinkFault> {
        if let Some(u) = &e.map {
            self.tiles.update(&u.layers);
        }
        // As the node does: the scan's own points at the pose they were registered at.
        let seen = (e.pose.as_ref().zip(e.map.as_ref())).map(|(kept, u)| Seen {
            kept,
            pose: &u.pose,
            points: &u.own_points,
        });
        self.map.scan(&self.tiles, seen, Header::default());
        Ok(())
    }
    fn finish(&mut self, _: Option<&Summary>) -> Result<Option<String>, SinkFault> {
        self.map.finish(&self.tiles, Header::default());
        let grid = (self.grid.lock().map_err(|e| e.to_string())?)
            .take()
            .ok_or("no grid")?;
        let count = |v: i8| grid.data.iter().filter(|c| **c == v).count();
        *self.last.lock().map_err(|e| e.to_string())? = Some((
            [
                grid.info.width as usize,
                grid.info.height as usize,
                count(0),
                count(100),
            ],
            self.map.costs(),
        ));
        Ok(None)
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let flags = Flags::from_env();
    let frames: usize = flags.parse_or("--frames", 300)?;
    let every: usize = flags.parse_or("--every", 10)?;
    let seed: u64 = flags.parse_or("--seed", 1)?;
    let config = config_file::preset("default").ok_or("no default preset")?;
    let out = std::env::temp_dir().join(format!("slamesh-navmap-live-{}", std::process::id()));
    let opts = RunOptions {
        out: out.clone(),
        config,
        preset: "default".into(),
        threads: 0,
        input: "simulated town".into(),
        ..RunOptions::default()
    };
    let last = Arc::new(Mutex::new(None));
    let made = Arc::new(Mutex::new(None));
    let slot = made.clone();
    let keep = Box::new(move |g| slot.lock().map(|mut s| *s = Some(g)).is_ok());
    let map = LiveMap::new(every, Pose::identity(), NavMapOptions::default(), keep);
    let grid = Grid {
        tiles: MeshTiles::new(config.lattice().table(), Shown::new(&config.mesh)),
        map,
        grid: made,
        last: last.clone(),
    };
    let mut sinks = Sinks::new();
    sinks.add(grid);
    let mut drive = Drive::town(frames, seed);
    let summary = run_to::<KittiCapacity>(&mut drive, &opts, sinks)?;
    std::fs::remove_dir_all(&out)?;
    println!("{} frames, {:.1} s", summary.used, summary.seconds);
    if let Some(([w, h, free, occupied], (n, median, p95, skipped, bytes))) =
        *last.lock().map_err(|e| e.to_string())?
    {
        println!(
            "{n} updates ({skipped} skipped): median {median:.1} ms, 95th percentile {p95:.1} \
             ms; cells {:.1} MB",
            bytes as f64 / 1e6
        );
        println!("the last grid: {w} x {h} cells, {free} free, {occupied} occupied");
    }
    Ok(())
}
