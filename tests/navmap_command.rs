//! The navigation maps the command writes (`slamesh run --navmap`, `slamesh navmap`): the same
//! grid from a run and from the map it saved, the traversability layers as named vertex
//! properties of the navigation mesh and of the SLAM mesh, a PLY mesh's grid, a bad robot file
//! refused; a map saved during a run (the ROS 2 node's `~/save_map`) with the scans' floor
//! beside it. Read back with the Nav2 reader of [`crate::navmap`].

use crate::common::scratch;
use crate::nav2_map::Nav2Map;
use slamesh::navmap::NavMapOptions;
use slamesh::run::{run_to, RunOptions, Sinks};
use slamesh::sources::{FrameSource, Request};
use slamesh_core::{Config, KittiCapacity};
use slamesh_sim::Drive;
use std::path::Path;
use std::sync::mpsc;

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

/// The cells of `dir`'s `elevation.asc` that hold a height (ESRI ASCII grid): each cell's
/// lower-left corner in cells of the grid's size, and its height as written.
fn ascii_grid(dir: &Path) -> std::collections::HashMap<(i64, i64), String> {
    let text = std::fs::read_to_string(dir.join("elevation.asc")).unwrap();
    let mut lines = text.lines();
    let mut key = |name: &str| {
        let line = lines.next().unwrap();
        let (k, v) = line.split_once(' ').unwrap();
        assert_eq!(k, name);
        v.trim().to_string()
    };
    let (cols, rows): (usize, usize) =
        (key("ncols").parse().unwrap(), key("nrows").parse().unwrap());
    let (x, y): (f64, f64) = (
        key("xllcorner").parse().unwrap(),
        key("yllcorner").parse().unwrap(),
    );
    let size: f64 = key("cellsize").parse().unwrap();
    let none = key("NODATA_value");
    let mut cells = std::collections::HashMap::new();
    for (r, line) in lines.enumerate() {
        for (c, v) in line.split_whitespace().enumerate() {
            if v != none {
                let at = (
                    (x / size).round() as i64 + c as i64,
                    (y / size).round() as i64 + (rows - 1 - r) as i64,
                );
                cells.insert(at, v.to_string());
            }
        }
        assert_eq!(line.split_whitespace().count(), cols);
    }
    cells
}

/// `run --navmap` and `navmap` of the map it saved write the same occupancy grid (the same
/// mesh, the same path, the scans' floor the run kept beside the map); without that floor the
/// saved map's grid is the mesh's alone; `navmap` of its PLY mesh grows the ground from the
/// largest floor; a bad robot file is refused, naming it.
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
    let floor = run_out.join("site.floor");
    assert!(floor.is_file(), "the scans' floor beside the map");
    slamesh_ok(&["navmap", &s(&saved), "--out", &s(&from_map), "-q"]);
    // `navmap.json` says how many cells the scans' floor gave.
    let floor_cells = |dir: &Path| {
        let json = std::fs::read_to_string(dir.join("navmap.json")).unwrap();
        let v: serde_json::Value = serde_json::from_str(&json).unwrap();
        v["scans_floor_cells"].as_u64().unwrap()
    };
    assert!(floor_cells(&run_out) > 0);
    assert_eq!(floor_cells(&from_map), floor_cells(&run_out));
    let (ran, loaded) = (Nav2Map::read(&run_out), Nav2Map::read(&from_map));
    assert_eq!(
        (ran.width, ran.height, ran.origin, ran.resolution),
        (
            loaded.width,
            loaded.height,
            loaded.origin,
            loaded.resolution
        )
    );
    assert!(
        ran.pixels == loaded.pixels,
        "the run's grid and the saved map's differ"
    );
    assert_eq!(ascii_grid(&run_out), ascii_grid(&from_map));
    // A second session in that map, saved again: the first one's floor carried beside it.
    let (again, resaved) = (dir.join("again"), dir.join("again").join("site2.slamesh"));
    slamesh_ok(&[
        "localize",
        &s(&input),
        "--map",
        &s(&saved),
        "--update",
        "--out",
        &s(&again),
        "-q",
        "--no-picture",
        "--navmap",
        "--save-map",
        &s(&resaved),
    ]);
    let floors = |p: &Path| {
        slamesh::navmap::floor_file::FloorFile::read(p)
            .unwrap()
            .count
    };
    assert!(floors(&again.join("site2.floor")) > floors(&floor));
    // A damaged floor file is passed over, named; the grid is then the mesh's alone.
    let kept = std::fs::read(&floor).unwrap();
    std::fs::write(&floor, &kept[..kept.len() / 2]).unwrap();
    let alone = dir.join("alone");
    let out = slamesh(&["navmap", &s(&saved), "--out", &s(&alone)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && err.contains("site.floor"), "{err}");
    assert_eq!(floor_cells(&alone), 0);
    // They agree but where the scans' floor stood raised where the mesh has no surface
    // (`navmap::raised`): occupied from the run, unknown (or beyond the map) from the mesh
    // alone; and the ground beside such a cell or in its shadow is unknown, so the run's
    // elevation is the mesh's less those cells.
    let loaded = Nav2Map::read(&alone);
    assert_eq!(ran.resolution, loaded.resolution);
    // The cell of `map` a cell of `ran` lies over, by the grids' lower-left corners.
    let over = |map: &Nav2Map, col: usize, row: usize| {
        let cells = |a: f64, b: f64| ((a - b) / ran.resolution).round() as i64;
        let c = col as i64 + cells(ran.origin[0], map.origin[0]);
        let up = (ran.height - 1 - row) as i64 + cells(ran.origin[1], map.origin[1]);
        ((0..map.width as i64).contains(&c) && (0..map.height as i64).contains(&up))
            .then(|| map.value(c as usize, map.height - 1 - up as usize))
    };
    let mut raised = 0;
    for row in 0..ran.height {
        for col in 0..ran.width {
            let (a, b) = (ran.value(col, row), over(&loaded, col, row).unwrap_or(-1));
            if a != b {
                // Raised, or free ground next to a raised cell or in its shadow: never freer.
                assert!(
                    a == 100 || (a, b) == (-1, 0),
                    "cell ({col}, {row}): {a}, {b}"
                );
                raised += usize::from(a == 100);
            }
        }
    }
    println!("cells the scans' floor raised: {raised}");
    let (ran_z, loaded_z) = (ascii_grid(&run_out), ascii_grid(&alone));
    assert!(ran_z.len() > 100);
    for (cell, z) in &ran_z {
        assert_eq!(loaded_z.get(cell), Some(z), "elevation at {cell:?}");
    }
    // The navigation mesh: the ground with its layers as named vertex properties.    // The navigation mesh: the ground with its layers as named vertex properties.
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
}

/// A drive that asks the run to save its map (as the ROS 2 node's `~/save_map` does) once each
/// frame of `at` has been read, and keeps the ways the answers come back.
struct SavingAt {
    drive: Drive,
    at: Vec<usize>,
    due: bool,
    answers: Vec<mpsc::Receiver<Result<String, String>>>,
}

impl SavingAt {
    fn new(drive: Drive, at: &[usize]) -> SavingAt {
        SavingAt {
            drive,
            at: at.to_vec(),
            due: false,
            answers: Vec::new(),
        }
    }

    /// The answers, in the order asked.
    fn answers(&self) -> Vec<String> {
        (self.answers.iter())
            .map(|rx| rx.recv().unwrap().unwrap())
            .collect()
    }
}

impl FrameSource for SavingAt {
    fn frames(&self) -> usize {
        self.drive.frames()
    }
    fn label(&self, i: usize) -> String {
        self.drive.label(i)
    }
    fn stamp(&self, i: usize) -> f64 {
        self.drive.stamp(i)
    }
    fn read(&mut self, i: usize) -> Result<Vec<slamesh_core::Point>, slamesh::FileError> {
        self.due |= self.at.contains(&i);
        self.drive.read(i)
    }
    fn requests(&mut self) -> Vec<Request> {
        if !std::mem::take(&mut self.due) {
            return Vec::new();
        }
        let (tx, rx) = mpsc::channel();
        self.answers.push(rx);
        vec![Request::SaveMap(tx)]
    }
}

/// The floors a save's answer says it wrote beside the map.
fn floors_said(answer: &str) -> usize {
    let (_, after) = answer.split_once("floor beside it, ").expect(answer);
    after.split(' ').next().unwrap().parse().expect(answer)
}

#[test]
fn a_map_saved_during_a_run_keeps_the_scans_floor_beside_it() {
    use crate::common::slamesh_ok;
    let dir = scratch("navmap-saved-during");
    for navmap in [true, false] {
        let out = dir.join(if navmap { "navmap" } else { "plain" });
        std::fs::create_dir_all(&out).unwrap();
        // A floor file from an earlier save: replaced, or without the navigation map removed.
        let floor = out.join("map.floor");
        std::fs::write(&floor, b"from an earlier save").unwrap();
        let opts = RunOptions {
            out: out.clone(),
            config: Config::default(),
            threads: 2,
            picture: false,
            navmap: navmap.then(NavMapOptions::default),
            ..RunOptions::default()
        };
        let mut source = SavingAt::new(Drive::town(12, 1), &[8]);
        run_to::<KittiCapacity>(&mut source, &opts, Sinks::new()).unwrap();
        let answer = source.answers().remove(0);
        let map = out.join("map.slamesh");
        assert!(map.is_file(), "{answer}");
        if !navmap {
            assert!(!floor.exists() && answer.contains("removed"), "{answer}");
            continue;
        }
        assert!(answer.contains("the scans' floor beside it"), "{answer}");
        // `slamesh navmap` on the map reads it (a floor file from another save is passed over).
        let grid = dir.join("grid");
        let s = |p: &Path| p.to_str().unwrap().to_string();
        slamesh_ok(&["navmap", &s(&map), "--out", &s(&grid), "-q"]);
        let json = std::fs::read_to_string(grid.join("navmap.json")).unwrap();
        let v: serde_json::Value = serde_json::from_str(&json).unwrap();
        let cells = v["scans_floor_cells"].as_u64().unwrap();
        assert!(cells > 1_000, "{cells} cells of the scans' floor; {answer}");
        println!("{answer}; `slamesh navmap` read {cells} cells of it");
    }
}

#[test]
fn saves_during_a_session_from_a_map_keep_the_floor_that_map_kept() {
    use slamesh::navmap::floor_file::FloorFile;
    let dir = scratch("navmap-saved-again");
    let site = dir.join("site.slamesh");
    let opts = |out: &str, map: Option<&Path>| RunOptions {
        out: dir.join(out),
        config: Config::default(),
        threads: 2,
        picture: false,
        navmap: Some(NavMapOptions::default()),
        map: map.map(Path::to_path_buf),
        save_map: Some(site.clone()),
        ..RunOptions::default()
    };
    run_to::<KittiCapacity>(&mut Drive::town(12, 1), &opts("first", None), Sinks::new()).unwrap();
    let first = FloorFile::read(&dir.join("site.floor")).unwrap().count;
    // The second session maps on from the site and saves it in place, twice during the run:
    // the first save replaces the floor file the session started from, and the second must
    // still carry that file's floors.
    let mut source = SavingAt::new(Drive::town(12, 1), &[4, 8]);
    run_to::<KittiCapacity>(&mut source, &opts("second", Some(&site)), Sinks::new()).unwrap();
    let said: Vec<usize> = source.answers().iter().map(|a| floors_said(a)).collect();
    let last = FloorFile::read(&dir.join("site.floor")).unwrap().count;
    println!("first session {first} floors; saves during the second {said:?}; at its end {last}");
    assert!(
        first < said[0] && said[0] <= said[1] && said[1] <= last,
        "first session {first} floors; saves during the second {said:?}; at its end {last}"
    );
}

#[test]
fn a_map_that_does_not_read_is_named_and_leaves_no_folder_behind() {
    let dir = scratch("navmap-bad-map");
    let bad = dir.join("bad.slamesh");
    std::fs::write(&bad, "not a map").unwrap();
    let out = dir.join("out");
    let o = crate::common::slamesh(&[
        "navmap",
        bad.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("bad.slamesh"), "{err}");
    assert!(!out.exists(), "the folder it made is gone");
}
