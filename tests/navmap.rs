//! The navigation map against the simulator's truth (`slamesh::navmap`): a run with `navmap`
//! on writes Nav2's `map.yaml` + `map.pgm`, read back here by a reader of its own (the PGM's
//! header and bytes, the YAML's keys), and each cell is compared with the scene's boxes and
//! spheres standing between a step and the robot's height above the true ground.
//!
//! - occupied cells where the sensor saw (a true scan point in the cell): their IoU with the
//!   truth's;
//! - free cells that hold an obstacle (the error that crashes robots): counted, at most 0.5 %;
//! - unknown stays unknown: `free_thresh` below 205's 0.196.

use crate::common::scratch;
use nalgebra::{Point3, Rotation3, Vector3};
use slamesh::navmap::{NavMapOptions, Robot};
use slamesh::run::{run, RunOptions};
use slamesh_core::{Config, KittiCapacity, Pose};
use slamesh_sim::scene::Scene;
use slamesh_sim::Drive;
use std::collections::HashSet;
use std::path::Path;

/// A Nav2 map as `map_server` reads it: its pixels (rows top-down), size, resolution and the
/// lower-left pixel's corner.
struct Nav2Map {
    pixels: Vec<u8>,
    width: usize,
    height: usize,
    resolution: f64,
    origin: [f64; 2],
    free_thresh: f64,
}

impl Nav2Map {
    fn read(dir: &Path) -> Nav2Map {
        let yaml = std::fs::read_to_string(dir.join("map.yaml")).unwrap();
        let key = |k: &str| {
            yaml.lines()
                .find_map(|l| l.strip_prefix(&format!("{k}: ")))
                .unwrap_or_else(|| panic!("map.yaml has no {k}"))
                .to_string()
        };
        assert_eq!(key("image"), "map.pgm");
        assert_eq!(key("mode"), "trinary");
        assert_eq!(key("negate"), "0");
        let origin: Vec<f64> = key("origin")
            .trim_matches(|c| c == '[' || c == ']')
            .split(',')
            .map(|v| v.trim().parse().unwrap())
            .collect();
        let pgm = std::fs::read(dir.join("map.pgm")).unwrap();
        // P5, a comment, width height, 255, then the bytes.
        let mut fields = Vec::new();
        let mut at = 0;
        while fields.len() < 4 {
            while pgm[at].is_ascii_whitespace() {
                at += 1;
            }
            if pgm[at] == b'#' {
                while pgm[at] != b'\n' {
                    at += 1;
                }
                continue;
            }
            let start = at;
            while !pgm[at].is_ascii_whitespace() {
                at += 1;
            }
            fields.push(String::from_utf8(pgm[start..at].to_vec()).unwrap());
        }
        assert_eq!((fields[0].as_str(), fields[3].as_str()), ("P5", "255"));
        let (width, height) = (fields[1].parse().unwrap(), fields[2].parse().unwrap());
        let pixels = pgm[at + 1..].to_vec();
        assert_eq!(pixels.len(), width * height);
        Nav2Map {
            pixels,
            width,
            height,
            resolution: key("resolution").parse().unwrap(),
            origin: [origin[0], origin[1]],
            free_thresh: key("free_thresh").parse().unwrap(),
        }
    }

    /// map_server's reading of pixel `(col, row)`: 100 occupied, 0 free, -1 unknown.
    fn value(&self, col: usize, row: usize) -> i8 {
        let occ = (255.0 - self.pixels[row * self.width + col] as f64) / 255.0;
        if occ > 0.65 {
            100
        } else if occ < self.free_thresh {
            0
        } else {
            -1
        }
    }

    /// The centre of pixel `(col, row)` in the grid's frame.
    fn centre(&self, col: usize, row: usize) -> [f64; 2] {
        [
            self.origin[0] + (col as f64 + 0.5) * self.resolution,
            self.origin[1] + ((self.height - 1 - row) as f64 + 0.5) * self.resolution,
        ]
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
fn near_the_map(
    scene: &Scene,
    map: &Nav2Map,
    to_world: &impl Fn(f64, f64) -> Point3<f64>,
) -> Scene {
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
fn free_path(map: &Nav2Map, from: (usize, usize), to: (usize, usize)) -> bool {
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

impl Scores {
    /// At most 0.5 % of the free cells hold an obstacle (issue 56's target), and the occupied
    /// cells' IoU within a cell is at least `iou_within_a_cell`.
    fn assert_within(&self, iou_within_a_cell: f64) {
        let bad = self.free_with_obstacle as f64 / self.free as f64;
        assert!(
            bad <= 0.005,
            "{:.3} % of free cells hold an obstacle",
            bad * 100.0
        );
        assert!(
            self.iou_within_a_cell >= iou_within_a_cell,
            "occupied IoU {:.3} ({:.3} within a cell)",
            self.iou,
            self.iou_within_a_cell
        );
    }
}

/// Runs `frames` of `drive` with the navigation map on (up: the true gravity in the map's
/// frame), reads the map back and scores it against the scene.
fn score(
    drive: Drive,
    frames: usize,
    robot: Robot,
    name: &str,
    segments: &[([f64; 2], [f64; 2])],
) -> Scores {
    let dir = scratch(name);
    let first: Pose = drive.poses[0];
    // The map's frame is the first sensor pose's: up there is the world's z seen from it.
    let up = first.rotation.inverse() * Vector3::z();
    // The configuration fitted to the scene's scale from the first scan, as the command
    // fits it (`slamesh run`'s default preset): 0.5 m cells indoors.
    let first_scan = drive.scan(0);
    let config = slamesh::run::scale::fit(&Config::default(), &first_scan)
        .map_or_else(Config::default, |f| f.config);
    let opts = RunOptions {
        out: dir.clone(),
        config,
        threads: 2,
        mesh_formats: Vec::new(),
        navmap: Some(NavMapOptions {
            robot,
            resolution_m: 0.1,
            up: Some((up, "the simulator's gravity".into())),
        }),
        ..RunOptions::default()
    };
    let mut source = drive.clone();
    let summary = run::<KittiCapacity>(&mut source, &opts, |_| {}).unwrap();
    assert_eq!(summary.used, frames);
    let map = Nav2Map::read(&dir);
    assert!(
        map.free_thresh < 50.0 / 255.0,
        "unknown (205) must not load as free"
    );
    // Grid frame -> world: the level frame turned back to the map's, then the first pose.
    let level = Rotation3::rotation_between(&up, &Vector3::z()).unwrap();
    let to_world = |x: f64, y: f64| first * (level.inverse() * Point3::new(x, y, 0.0));
    let to_grid = |w: &Point3<f64>| level * first.inverse_transform_point(w);
    let scene = near_the_map(&drive.scene, &map, &to_world);
    let mut seen: HashSet<(i64, i64)> = HashSet::new();
    let cell = |g: Point3<f64>| {
        (
            ((g.x - map.origin[0]) / map.resolution).floor() as i64,
            ((g.y - map.origin[1]) / map.resolution).floor() as i64,
        )
    };
    for i in 0..frames {
        for p in drive.true_points(i) {
            seen.insert(cell(to_grid(&Point3::new(
                p[0] as f64,
                p[1] as f64,
                p[2] as f64,
            ))));
        }
    }
    let (step, height) = (robot.max_step_m, robot.height_m);
    let (mut both, mut either, mut free, mut free_bad, mut occupied) = (0, 0, 0, 0, 0);
    let (mut near_both, mut near_either) = (0, 0);
    for row in 0..map.height {
        for col in 0..map.width {
            let [x, y] = map.centre(col, row);
            // The truth over the cell: its centre and eight points around it.
            let r = map.resolution * 0.45;
            let truth = [-r, 0.0, r].iter().any(|dx| {
                [-r, 0.0, r].iter().any(|dy| {
                    let w = to_world(x + dx, y + dy);
                    obstacle_at(&scene, w.x, w.y, step, height)
                })
            });
            let ours = map.value(col, row);
            let c = (col as i64, (map.height - 1 - row) as i64);
            if seen.contains(&c) {
                both += usize::from(truth && ours == 100);
                either += usize::from(truth || ours == 100);
                // Within a cell: an occupied cell next to a truth one counts as found.
                let near = |want: bool| {
                    (-1i64..=1).any(|dr| {
                        (-1i64..=1).any(|dc| {
                            let (r2, c2) = (row as i64 + dr, col as i64 + dc);
                            let inside = (0..map.height as i64).contains(&r2)
                                && (0..map.width as i64).contains(&c2);
                            inside
                                && if want {
                                    map.value(c2 as usize, r2 as usize) == 100
                                } else {
                                    let [x2, y2] = map.centre(c2 as usize, r2 as usize);
                                    let w = to_world(x2, y2);
                                    obstacle_at(&scene, w.x, w.y, step, height)
                                }
                        })
                    })
                };
                if truth || ours == 100 {
                    near_either += 1;
                    near_both += usize::from(if truth { near(true) } else { near(false) });
                }
            }
            free += usize::from(ours == 0);
            free_bad += usize::from(ours == 0 && truth);
            occupied += usize::from(ours == 100);
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
    // World (z = 0 up) to the image's column and row, if inside it.
    let pixel = |x: f64, y: f64| {
        let (col, row) = cell(to_grid(&Point3::new(x, y, 0.0)));
        let row = map.height as i64 - 1 - row;
        ((0..map.width as i64).contains(&col) && (0..map.height as i64).contains(&row))
            .then_some((col as usize, row as usize))
    };
    let free_at = |x: f64, y: f64| pixel(x, y).is_some_and(|(c, r)| map.value(c, r) == 0);
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
        .map(|&(a, b)| match (pixel(a[0], a[1]), pixel(b[0], b[1])) {
            (Some(from), Some(to)) => free_path(&map, from, to),
            _ => false,
        })
        .collect();
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
        Drive::town(frames, 1),
        frames,
        Robot::WHEELED,
        "navmap-town",
        &[],
    );
    println!("town, {frames} frames: {s:?}");
    assert!(s.free > 40_000 && s.occupied > 2_000, "{s:?}");
    // Issue 56's targets: at most 0.5 % (met: 0.02 % measured) and an IoU of 0.9 (not met:
    // 0.64, 0.77 within a cell; docs/benchmarks.md, "Low rises and unsure standing surfaces").
    s.assert_within(0.72);
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
        // Through room A's doorway to where the walk has reached by its last scan.
        ([12.0, 4.5], [15.5, 4.5]),
    ];
    let s = score(
        Drive::office(frames, 2),
        frames,
        Robot::WHEELED,
        "navmap-office",
        &corridor,
    );
    println!("office, {frames} frames: {s:?}");
    assert!(s.free > 4_000 && s.occupied > 2_000, "{s:?}");
    // 0.53, 0.83 within a cell measured.
    s.assert_within(0.78);
    // A planner finds its way from room A through the doorway into the corridor the walk
    // went along. (The corridor's far end, seen from its start by 16 beams, is mostly
    // unknown: docs/benchmarks.md, "Maps a planner reads".)
    assert!(s.passable[3], "no free way through the doorway: {s:?}");
    println!(
        "free along the corridor's lines to x 19 and the walked one: {:?}",
        s.free_along
    );
}

/// A mesh PLY's vertices with `ground` and `cost` among their properties: ground vertices
/// that are not lethal lie in free cells of `grid` (the map's z up: the grid's frame is the
/// map's), vertices off the ground are lethal, and both kinds are there.
fn check_mesh_layers(path: &Path, grid: &Nav2Map) {
    let bytes = std::fs::read(path).unwrap();
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let header = String::from_utf8_lossy(&bytes[..end]);
    let mut count = 0;
    // Each vertex property's name and size in bytes.
    let mut props: Vec<(String, usize)> = Vec::new();
    for line in header.lines() {
        let w: Vec<&str> = line.split_whitespace().collect();
        match w.as_slice() {
            ["element", "vertex", n] => count = n.parse().unwrap(),
            ["element", ..] if count > 0 => break,
            ["property", kind, name] => {
                props.push((name.to_string(), if *kind == "uchar" { 1 } else { 4 }))
            }
            _ => {}
        }
    }
    let at = |name: &str| {
        let k = props.iter().position(|(n, _)| n == name).unwrap();
        props[..k].iter().map(|p| p.1).sum::<usize>()
    };
    let stride: usize = props.iter().map(|p| p.1).sum();
    let (x, y, ground, cost) = (at("x"), at("y"), at("ground"), at("cost"));
    for layer in ["slope_deg", "step_m", "roughness_m", "border"] {
        at(layer);
    }
    let float = |v: usize, off: usize| {
        let i = end + v * stride + off;
        f32::from_le_bytes(bytes[i..i + 4].try_into().unwrap())
    };
    let (mut on_ground, mut off_ground) = (0, 0);
    for v in 0..count {
        let (g, c) = (float(v, ground), float(v, cost));
        if g == 0.0 {
            assert_eq!(c, 1.0, "a vertex off the ground is lethal");
            off_ground += 1;
        } else if c < 1.0 {
            // The cell as the grid finds it (x over the resolution, floored), less the corner's.
            let cell = |at: usize, origin: f64| {
                let c = (float(v, at) as f64 / grid.resolution).floor();
                (c - (origin / grid.resolution).round()) as usize
            };
            let (col, row) = (cell(x, grid.origin[0]), cell(y, grid.origin[1]));
            assert_eq!(
                grid.value(col, grid.height - 1 - row),
                0,
                "vertex {v} of {path:?}"
            );
            on_ground += 1;
        }
    }
    assert!(
        on_ground > 100 && off_ground > 100,
        "{on_ground} {off_ground}"
    );
}

/// `run --navmap` and `navmap` of the map it saved write the same occupancy grid (the same
/// mesh, the same path); `navmap` of its PLY mesh grows the ground from the largest floor;
/// a bad robot file is refused, naming it.
#[test]
fn the_command_s_navigation_maps() {
    use crate::common::{slamesh, slamesh_ok};
    let dir = scratch("navmap-command");
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/recordings/scans");
    let (run_out, from_map, from_ply) = (dir.join("run"), dir.join("map"), dir.join("ply"));
    let saved = run_out.join("site.slamesh");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    slamesh_ok(&[
        "run",
        &s(&input),
        "--out",
        &s(&run_out),
        "-q",
        "--no-picture",
        "--navmap",
        "--save-map",
        &s(&saved),
    ]);
    slamesh_ok(&["navmap", &s(&saved), "--out", &s(&from_map), "-q"]);
    for f in ["map.pgm", "map.yaml", "elevation.asc", "navmesh.ply"] {
        assert_eq!(
            std::fs::read(run_out.join(f)).unwrap(),
            std::fs::read(from_map.join(f)).unwrap(),
            "{f}"
        );
    }
    // The navigation mesh: the ground with its layers as named vertex properties.
    let navmesh = run_out.join("navmesh.ply");
    let mesh = slamesh::formats::ply::read_ply_mesh(&navmesh).unwrap();
    assert!(mesh.vertices.len() > 100 && mesh.triangles.len() > mesh.vertices.len());
    let bytes = std::fs::read(&navmesh).unwrap();
    let header = String::from_utf8_lossy(&bytes[..600]);
    for layer in ["slope_deg", "step_m", "roughness_m", "border", "cost"] {
        assert!(
            header.contains(&format!("property float {layer}\n")),
            "{layer}"
        );
    }
    // The layers on the SLAM mesh's own vertices, in the run's mesh and in the command's.
    let run_grid = Nav2Map::read(&run_out);
    for mesh in [run_out.join("mesh.ply"), from_map.join("mesh.ply")] {
        check_mesh_layers(&mesh, &run_grid);
    }
    let report = std::fs::read_to_string(run_out.join("report.json")).unwrap();
    assert!(report.contains("\"navmap\"") && report.contains("first scan taken as level"));
    slamesh_ok(&[
        "navmap",
        &s(&run_out.join("mesh.ply")),
        "--out",
        &s(&from_ply),
        "-q",
    ]);
    let grid = Nav2Map::read(&from_ply);
    assert!(grid.pixels.contains(&254) && grid.pixels.contains(&0));
    let robot = dir.join("robot.toml");
    std::fs::write(&robot, "max_step_m = 3.0\n").unwrap();
    let refused = slamesh(&[
        "navmap",
        &s(&saved),
        "--out",
        &s(&from_ply),
        "--robot",
        &s(&robot),
    ]);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(
        !refused.status.success() && err.contains("robot.toml") && err.contains("height_m"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
