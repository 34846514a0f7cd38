//! The navigation map against the simulator's truth (`slamesh::navmap`): a run with `navmap`
//! on writes Nav2's `map.yaml` + `map.pgm`, read back here by a reader of its own (the PGM's
//! header and bytes, the YAML's keys), and each cell is compared with the scene's boxes and
//! spheres standing between a step and the robot's height above the true ground.
//!
//! - occupied cells where the sensor saw (a true scan point in the cell): their IoU with the
//!   truth's;
//! - free cells that hold an obstacle (the error that crashes robots): counted, at most 0.5 %;
//! - unknown stays unknown: `free_thresh` below 205's 0.196.
//!
//! With `SLAMESH_NAVMAP_DIAG=DIR` set, each scored run also leaves its files in `DIR/NAME/`
//! (the grid, the mesh as `mesh.ply`, the poses) and `cells.csv`: every seen cell that is
//! occupied in the map or the truth, by kind (`hit`, `false`: occupied where the truth has
//! nothing, `missed`), its column and row (from the bottom) in the grid and its centre in the
//! world. `tools/navmap_cells.py DIR/NAME` counts
//! them and draws `cells.png`. `SLAMESH_NAVMAP_SEED=S` drives the town and the office of seed
//! `S` instead of the tests' own (1 and 2), to judge a change of the grid over other drives;
//! the asserted bounds hold for the tests' own seeds.

use crate::common::scratch;
use crate::nav2_map::Nav2Map;
use nalgebra::{Point3, Rotation3, Vector3};
use slamesh::navmap::background::{Background, Seen};
use slamesh::navmap::live::{Cells, LiveGrid};
use slamesh::navmap::tiled_mesh::TiledMesh;
use slamesh::navmap::{NavMapOptions, Robot};
use slamesh::run::sink::SinkFault;
use slamesh::run::{run_to, FrameEvent, RunOptions, Sink, Sinks, Summary};
use slamesh_core::layer::Shown;
use slamesh_core::{Config, KittiCapacity, Pose};
use slamesh_sim::scene::Scene;
use slamesh_sim::Drive;
use std::collections::HashSet;
use std::path::Path;
use std::sync::{Arc, Mutex};

/// The folder `SLAMESH_NAVMAP_DIAG` names, if set: where the scored runs leave their files
/// and cells (see the module).
fn diagnostics() -> Option<std::path::PathBuf> {
    std::env::var_os("SLAMESH_NAVMAP_DIAG").map(std::path::PathBuf::from)
}

/// The drive's seed: `SLAMESH_NAVMAP_SEED` if set (see the module), else `own`.
fn seed_or(own: u64) -> u64 {
    std::env::var("SLAMESH_NAVMAP_SEED")
        .ok()
        .map(|s| s.parse().expect("SLAMESH_NAVMAP_SEED: a whole number"))
        .unwrap_or(own)
}

/// The grid the ROS 2 node keeps current (`ros2::occupancy`, with the node's window and its
/// default `map_every` of 10 scans), fed as the node feeds it: the mesh's tiles from each
/// frame's map update, the scans' points and poses. Its last grid goes to `last`.
struct LiveSink {
    tiles: TiledMesh,
    grid: Background<()>,
}

impl LiveSink {
    fn new(config: &Config, how: NavMapOptions, last: Arc<Mutex<Option<Cells>>>) -> LiveSink {
        // The node's window and the inner square it keeps (`ros2::occupancy`'s `WINDOW_M` and
        // `KEEP_M`; the ROS 2 node is a feature these tests do not need).
        let (window_m, keep_m) = (30.0, 20.0);
        let out = move |g: &LiveGrid, ()| {
            *last.lock().unwrap() = g.cells();
            true
        };
        LiveSink {
            tiles: TiledMesh::new(config.lattice().table(), Shown::new(&config.mesh)),
            grid: Background::new("live-grid", 10, how, (window_m, keep_m), Box::new(out)),
        }
    }
}

impl Sink for LiveSink {
    fn name(&self) -> String {
        "live grid".into()
    }

    fn wants_map(&self) -> bool {
        true
    }

    fn frame(&mut self, e: Arc<FrameEvent>) -> Result<(), SinkFault> {
        if let Some(u) = &e.map {
            if let Some((path, _)) = &u.closed {
                self.tiles.clear();
                self.grid.correct(path);
            }
            self.tiles.update(&u.layers);
            let seen = Seen {
                kept: e.pose.as_ref().unwrap_or(&u.pose),
                pose: &u.pose,
                points: &u.own_points,
            };
            self.grid.scan(&self.tiles, Some(seen), ());
        }
        Ok(())
    }

    fn finish(&mut self, _: Option<&Summary>) -> Result<Option<String>, SinkFault> {
        self.grid.finish(&self.tiles, ());
        Ok(None)
    }
}

/// Whether something of `scene` stands at world `(x, y)` between `lo` and `hi` above the
/// ground.
fn obstacle_at(scene: &Scene, x: f64, y: f64, lo: f64, hi: f64) -> bool {
    let g = scene.ground_height(x, y);
    let (lo, hi) = (g + lo, g + hi);
    let boxes = scene.boxes.iter().any(|b| {
        let (dx, dy) = (x - b.centre[0], y - b.centre[1]);
        let (c, s) = (b.yaw.cos(), b.yaw.sin());
        let (lx, ly) = (c * dx + s * dy, -s * dx + c * dy);
        lx.abs() <= b.half[0]
            && ly.abs() <= b.half[1]
            && b.centre[2] - b.half[2] <= hi
            && b.centre[2] + b.half[2] >= lo
    });
    boxes
        || scene.spheres.iter().any(|s| {
            let d2 = (x - s.centre[0]).powi(2) + (y - s.centre[1]).powi(2);
            let h = (s.radius * s.radius - d2).max(-1.0);
            h >= 0.0 && s.centre[2] - h.sqrt() <= hi && s.centre[2] + h.sqrt() >= lo
        })
}

/// The objects of `scene` that may stand over `map` (`to_world` takes its frame to the
/// world's): the truth looked up per cell, among a few hundred objects instead of the town's
/// thousands.
fn near_the_map(scene: &Scene, map: &Nav2Map, to_world: &dyn Fn(f64, f64) -> Point3<f64>) -> Scene {
    let (w, h) = (
        map.width as f64 * map.resolution,
        map.height as f64 * map.resolution,
    );
    let corners = [(0.0, 0.0), (w, 0.0), (0.0, h), (w, h)]
        .map(|(dx, dy)| to_world(map.origin[0] + dx, map.origin[1] + dy));
    let lo = corners
        .iter()
        .fold([f64::MAX; 2], |m, c| [m[0].min(c.x), m[1].min(c.y)]);
    let hi = corners
        .iter()
        .fold([f64::MIN; 2], |m, c| [m[0].max(c.x), m[1].max(c.y)]);
    let within = |c: &[f64; 3], reach: f64| {
        (lo[0] - reach..=hi[0] + reach).contains(&c[0])
            && (lo[1] - reach..=hi[1] + reach).contains(&c[1])
    };
    let mut near = scene.clone();
    near.boxes
        .retain(|b| within(&b.centre, b.half[0].hypot(b.half[1])));
    near.spheres.retain(|s| within(&s.centre, s.radius));
    near
}

/// Whether a path of free cells, each beside the last, joins pixels `from` and `to` (column,
/// row) of `map`.
pub(crate) fn free_path(map: &Nav2Map, from: (usize, usize), to: (usize, usize)) -> bool {
    let mut seen = vec![false; map.width * map.height];
    let mut queue = vec![from];
    while let Some((c, r)) = queue.pop() {
        if seen[r * map.width + c] || map.value(c, r) != 0 {
            continue;
        }
        if (c, r) == to {
            return true;
        }
        seen[r * map.width + c] = true;
        let (c, r) = (c as i64, r as i64);
        for (c2, r2) in [(c - 1, r), (c + 1, r), (c, r - 1), (c, r + 1)] {
            if (0..map.width as i64).contains(&c2) && (0..map.height as i64).contains(&r2) {
                queue.push((c2 as usize, r2 as usize));
            }
        }
    }
    false
}

/// How a navigation map compares with the truth.
#[derive(Debug)]
struct Scores {
    iou: f64,
    /// The IoU when an occupied cell next to a truth one (and a truth cell next to an
    /// occupied one) counts as found.
    iou_within_a_cell: f64,
    free: usize,
    free_with_obstacle: usize,
    occupied: usize,
    /// The share of free cells along each of the segments asked for (world, z = 0 up).
    free_along: Vec<f64>,
    /// Whether free cells join each segment's two ends (side by side, not corner to corner):
    /// a planner finds a way between them.
    passable: Vec<bool>,
}

/// Free cells on an obstacle, at most: today 0 in the town (30 frames) and the office (520)
/// on their seeds, and at most 1 over seeds 1 to 5 of each (`SLAMESH_NAVMAP_SEED`); without
/// the obstacle's edge band (the named mutation `edge-band`) 8 and 22.
const MAX_FREE_ON_OBSTACLE: usize = 2;

impl Scores {
    /// At most 0.5 % of the free cells hold an obstacle (issue 56's target) and at most
    /// [`MAX_FREE_ON_OBSTACLE`] (today's level), and the occupied cells' IoU is at least `iou`
    /// (issue 56 asks 0.9; a floor under what is measured, so that the grid does not slip
    /// back) and within a cell at least `iou_within_a_cell`.
    fn assert_within(&self, iou: f64, iou_within_a_cell: f64) {
        let bad = self.free_with_obstacle as f64 / self.free as f64;
        assert!(
            bad <= 0.005 && self.free_with_obstacle <= MAX_FREE_ON_OBSTACLE,
            "{} free cells ({:.3} %) hold an obstacle",
            self.free_with_obstacle,
            bad * 100.0
        );
        assert!(
            self.iou >= iou && self.iou_within_a_cell >= iou_within_a_cell,
            "occupied IoU {:.3} ({:.3} within a cell)",
            self.iou,
            self.iou_within_a_cell
        );
    }
}

/// A drive's navigation map, made as `slamesh run --navmap` makes it, and its frame.
pub(crate) struct Mapped {
    pub(crate) map: Nav2Map,
    /// The first sensor pose: the map's frame.
    first: Pose,
    /// The map frame turned level (up: the world's z seen from the first pose).
    level: Rotation3<f64>,
}

impl Mapped {
    /// Runs `frames` of `drive` with the navigation map on (up: the true gravity in the map's
    /// frame), with the configuration fitted to the scene's scale from the first scan as the
    /// command fits it (`slamesh run`'s default preset: 0.5 m cells indoors), and reads the
    /// map back.
    fn of(drive: &Drive, frames: usize, robot: Robot, name: &str) -> Mapped {
        Mapped::with_live(drive, frames, robot, name, false, false).0
    }

    /// [`of`](Self::of), and with `live` the grid the ROS 2 node keeps current during the run
    /// too ([`LiveSink`]), as it is at the end; with `saved`, the grid `slamesh navmap` makes
    /// of the map the run saved (`--save-map`, the scans' floor beside it; up: the map's z).
    pub(crate) fn with_live(
        drive: &Drive,
        frames: usize,
        robot: Robot,
        name: &str,
        live: bool,
        saved: bool,
    ) -> (Mapped, Option<Mapped>, Option<Mapped>) {
        let dir = scratch(name);
        let first: Pose = drive.poses[0];
        let up = first.rotation.inverse() * Vector3::z();
        let config = slamesh::run::scale::fit(&Config::default(), &drive.scan(0))
            .map_or_else(Config::default, |f| f.config);
        let how = NavMapOptions {
            robot,
            resolution_m: 0.1,
            up: Some((up, "the simulator's gravity".into())),
        };
        let opts = RunOptions {
            out: dir.to_path_buf(),
            config,
            threads: 2,
            mesh_formats: match diagnostics() {
                Some(_) => vec![slamesh::outputs::mesh_spool::MeshFormat::Ply],
                None => Vec::new(),
            },
            navmap: Some(how.clone()),
            save_map: saved.then(|| dir.join("site.slamesh")),
            ..RunOptions::default()
        };
        let last = Arc::new(Mutex::new(None));
        let mut sinks = Sinks::new();
        if live {
            sinks.add(LiveSink::new(&config, how, last.clone()));
        }
        let summary = run_to::<KittiCapacity>(&mut drive.clone(), &opts, sinks).unwrap();
        assert_eq!(summary.used, frames);
        let map = Nav2Map::read(&dir);
        assert!(
            map.free_thresh < 50.0 / 255.0,
            "unknown (205) must not load as free"
        );
        let from_map = saved.then(|| {
            let (site, out) = (dir.join("site.slamesh"), dir.join("from-map"));
            let s = |p: &Path| p.to_str().unwrap().to_string();
            crate::common::slamesh_ok(&["navmap", &s(&site), "--out", &s(&out), "-q"]);
            Mapped {
                map: Nav2Map::read(&out),
                first,
                level: Rotation3::identity(),
            }
        });
        if let Some(diag) = diagnostics() {
            // Copied, not renamed: the scratch folder may lie on another file system.
            let keep = diag.join(name);
            std::fs::create_dir_all(&keep).unwrap();
            for f in std::fs::read_dir(&dir).unwrap() {
                let f = f.unwrap().path();
                if f.is_file() {
                    std::fs::copy(&f, keep.join(f.file_name().unwrap())).unwrap();
                }
            }
        }
        let level = Rotation3::rotation_between(&up, &Vector3::z()).unwrap();
        let live = live.then(|| {
            let cells = last.lock().unwrap().take().expect("the live grid was made");
            Mapped {
                map: Nav2Map::of_live(&cells, 0.1),
                first,
                level,
            }
        });
        (Mapped { map, first, level }, live, from_map)
    }

    /// Grid frame `(x, y)` to the world: the level frame turned back to the map's, then the
    /// first pose.
    fn to_world(&self, x: f64, y: f64) -> Point3<f64> {
        self.first * (self.level.inverse() * Point3::new(x, y, 0.0))
    }

    /// The grid cell (column, row from the bottom) holding world point `w`.
    pub(crate) fn cell(&self, w: &Point3<f64>) -> (i64, i64) {
        let g = self.level * self.first.inverse_transform_point(w);
        (
            ((g.x - self.map.origin[0]) / self.map.resolution).floor() as i64,
            ((g.y - self.map.origin[1]) / self.map.resolution).floor() as i64,
        )
    }

    /// The image pixel (column, row top-down) of world `(x, y, 0)`, if inside it.
    pub(crate) fn pixel(&self, x: f64, y: f64) -> Option<(usize, usize)> {
        let (col, row) = self.cell(&Point3::new(x, y, 0.0));
        let row = self.map.height as i64 - 1 - row;
        ((0..self.map.width as i64).contains(&col) && (0..self.map.height as i64).contains(&row))
            .then_some((col as usize, row as usize))
    }
}

/// The cells of `mapped`'s grid a true scan point of `drive`'s first `frames` fell in.
pub(crate) fn seen_cells(mapped: &Mapped, drive: &Drive, frames: usize) -> HashSet<(i64, i64)> {
    (0..frames)
        .flat_map(|i| drive.true_points(i))
        .map(|p| mapped.cell(&Point3::new(p[0] as f64, p[1] as f64, p[2] as f64)))
        .collect()
}

/// For each of `segments` (world, z = 0 up): the share of free cells along it, and whether
/// free cells join its two ends (side by side, not corner to corner).
fn along(mapped: &Mapped, segments: &[([f64; 2], [f64; 2])]) -> (Vec<f64>, Vec<bool>) {
    let map = &mapped.map;
    let free_at = |x: f64, y: f64| {
        mapped
            .pixel(x, y)
            .is_some_and(|(c, r)| map.value(c, r) == 0)
    };
    let free_along = segments
        .iter()
        .map(|&(a, b)| {
            let n = 100;
            let free = (0..=n)
                .filter(|&k| {
                    let f = k as f64 / n as f64;
                    free_at(a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]))
                })
                .count();
            free as f64 / (n + 1) as f64
        })
        .collect();
    let passable = segments
        .iter()
        .map(
            |&(a, b)| match (mapped.pixel(a[0], a[1]), mapped.pixel(b[0], b[1])) {
                (Some(from), Some(to)) => free_path(map, from, to),
                _ => false,
            },
        )
        .collect();
    (free_along, passable)
}

/// Runs `frames` of `drive` with the navigation map on ([`Mapped::of`]) and scores the map
/// against the scene.
fn score(
    drive: Drive,
    frames: usize,
    robot: Robot,
    name: &str,
    segments: &[([f64; 2], [f64; 2])],
) -> Scores {
    let mapped = Mapped::of(&drive, frames, robot, name);
    let map = &mapped.map;
    let scene = near_the_map(&drive.scene, map, &|x, y| mapped.to_world(x, y));
    let seen = seen_cells(&mapped, &drive, frames);
    let (step, height) = (robot.max_step_m, robot.height_m);
    let truth_at = |col: usize, row: usize| {
        let [x, y] = map.centre(col, row);
        // The truth over the cell: its centre and eight points around it.
        let r = map.resolution * 0.45;
        [-r, 0.0, r].iter().any(|dx| {
            [-r, 0.0, r].iter().any(|dy| {
                let w = mapped.to_world(x + dx, y + dy);
                obstacle_at(&scene, w.x, w.y, step, height)
            })
        })
    };
    let mut cells = String::from("kind,column,row,x,y\n");
    let (mut both, mut either, mut free, mut free_bad, mut occupied) = (0, 0, 0, 0, 0);
    let (mut near_both, mut near_either) = (0, 0);
    for row in 0..map.height {
        for col in 0..map.width {
            let truth = truth_at(col, row);
            let ours = map.value(col, row);
            if seen.contains(&(col as i64, (map.height - 1 - row) as i64)) {
                both += usize::from(truth && ours == 100);
                either += usize::from(truth || ours == 100);
                if truth || ours == 100 {
                    let kind = match (truth, ours == 100) {
                        (true, true) => "hit",
                        (false, _) => "false",
                        (true, false) => "missed",
                    };
                    let [x, y] = map.centre(col, row);
                    let w = mapped.to_world(x, y);
                    let up = map.height - 1 - row;
                    cells += &format!("{kind},{col},{up},{:.3},{:.3}\n", w.x, w.y);
                }
                // Within a cell: an occupied cell next to a truth one counts as found.
                let near = |want: &dyn Fn(usize, usize) -> bool| {
                    (-1i64..=1).any(|dr| {
                        (-1i64..=1).any(|dc| {
                            let (r2, c2) = (row as i64 + dr, col as i64 + dc);
                            (0..map.height as i64).contains(&r2)
                                && (0..map.width as i64).contains(&c2)
                                && want(c2 as usize, r2 as usize)
                        })
                    })
                };
                if truth || ours == 100 {
                    near_either += 1;
                    near_both += usize::from(if truth {
                        near(&|c, r| map.value(c, r) == 100)
                    } else {
                        near(&|c, r| {
                            let [x, y] = map.centre(c, r);
                            let w = mapped.to_world(x, y);
                            obstacle_at(&scene, w.x, w.y, step, height)
                        })
                    });
                }
            }
            free += usize::from(ours == 0);
            free_bad += usize::from(ours == 0 && truth);
            occupied += usize::from(ours == 100);
        }
    }
    if let Some(diag) = diagnostics() {
        std::fs::write(diag.join(name).join("cells.csv"), cells).unwrap();
    }
    let (free_along, passable) = along(&mapped, segments);
    Scores {
        free_along,
        passable,
        iou: both as f64 / either.max(1) as f64,
        iou_within_a_cell: near_both as f64 / near_either.max(1) as f64,
        free,
        free_with_obstacle: free_bad,
        occupied,
    }
}

#[test]
fn the_town_s_navigation_map_against_the_truth() {
    let frames = 30;
    let s = score(
        Drive::town(frames, seed_or(1)),
        frames,
        Robot::WHEELED,
        "navmap-town",
        &[],
    );
    println!("town, {frames} frames: {s:?}");
    assert!(s.free > 40_000 && s.occupied > 2_000, "{s:?}");
    // Issue 56's targets: at most 0.5 % (met: no free cell holds one) and an IoU of 0.9
    // (not met: 0.87, 0.95 within a cell; docs/journal.md, "Where voxel cells' seams cross").
    s.assert_within(0.85, 0.93);
}

#[test]
fn the_office_s_navigation_map_against_the_truth() {
    // Round room A and along the corridor into room B: the doorways (x 14 and 18, 2.5 m wide)
    // and the corridor between them, on its centre line (y 4.5) and 0.6 m to either side.
    let frames = 520;
    let corridor = [
        ([13.0, 4.5], [19.0, 4.5]),
        ([13.0, 3.9], [19.0, 3.9]),
        ([13.0, 5.1], [19.0, 5.1]),
        // Through room A's doorway to where the walk has reached by its last scan (x 15.3:
        // from 15.5 the corridor is not seen on that line).
        ([12.0, 4.5], [15.3, 4.5]),
    ];
    let s = score(
        Drive::office(frames, seed_or(2)),
        frames,
        Robot::WHEELED,
        "navmap-office",
        &corridor,
    );
    println!("office, {frames} frames: {s:?}");
    // The truth has about 1 150 occupied cells where the walk saw.
    assert!(s.free > 4_000 && s.occupied > 1_000, "{s:?}");
    // 0.66, 0.95 within a cell measured (docs/journal.md, "Unsure level surfaces"); any
    // change to the map's layers moves the walk, and this IoU, by a few hundredths. Most of
    // the office's faces lie on the cells' edges, where the truth takes the cell behind and
    // the map's millimetres decide (docs/journal.md, "Where the office's false cells come
    // from").
    s.assert_within(0.62, 0.93);
    // A planner finds its way from room A through the doorway into the corridor the walk
    // went along. (The corridor's far end, seen from its start by 16 beams, is mostly
    // unknown: docs/journal.md, "Maps a planner reads".)
    assert!(s.passable[3], "no free way through the doorway: {s:?}");
    println!(
        "free along the corridor's lines to x 19 and the walked one: {:?}",
        s.free_along
    );
}
