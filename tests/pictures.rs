//! The pictures: `run` draws `topview.png` of its mesh and path (hill-shaded, its start and
//! end marked, with a scale bar, a colour scale and a legend), and `render` draws any mesh from
//! above or obliquely. A map of a building is drawn without its roof, so the floor and walls
//! under the path show; a street open to the sky is drawn whole; `render --clip-above` cuts
//! any mesh at a height.

use crate::common;

use common::{scratch, slamesh, slamesh_ok, slamesh_run_ok, street_drive, write_scan_folder};
use slamesh::formats::ply::read_ply_mesh;
use slamesh::formats::trajectory::read_kitti;
use slamesh::outputs::topview::map::{self, MapPicture};
use slamesh_core::{Point, Pose};
use slamesh_sim::Drive;
use std::path::Path;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

fn png_pixels(path: &Path) -> (u32, u32, Vec<[u8; 3]>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    let pixels = buf[..info.buffer_size()]
        .chunks(3)
        .map(|c| [c[0], c[1], c[2]])
        .collect();
    (info.width, info.height, pixels)
}

#[test]
fn the_demo_draws_its_picture_as_a_run_does_with_the_true_path() {
    let dir = scratch("demo-picture");
    let out = dir.join("demo");
    slamesh_ok(&[
        "demo",
        "--frames",
        "40",
        "--out",
        out.to_str().unwrap(),
        "-q",
    ]);
    let (w, h, pixels) = png_pixels(&out.join("topview.png"));
    assert!((995..=1005).contains(&w.max(h)), "{w} x {h}: a run's size");
    let count = |c: [u8; 3]| pixels.iter().filter(|p| **p == c).count();
    assert!(count([60, 220, 60]) > 0, "a start marker");
    assert!(count([230, 40, 40]) > 5, "the estimated path");
    // The legend's black box holds three lines (the path, the true path, start and end): 22
    // pixels a line from y = 8 and x = 8, so its third line's row is black at its left edge.
    assert_eq!(
        pixels[74 * w as usize + 10],
        [0, 0, 0],
        "a legend of three lines"
    );
    assert!(
        count([255, 255, 255]) > 50,
        "the legend's text and the true path"
    );
}

#[test]
fn run_draws_a_picture_of_its_mesh_and_path() {
    let dir = scratch("picture");
    let (_, scans) = street_drive(4);
    let scans_dir = write_scan_folder(&dir, &scans);
    let out = dir.join("out");
    slamesh_run_ok(&scans_dir, &out, &[]);
    let (w, h, pixels) = png_pixels(&out.join("topview.png"));
    // The path (1.5 m) and 40 m around it, plus a 5 m margin: about 91 by 90 m, 1 000
    // pixels on the long side.
    assert_eq!(w.max(h), 1001, "{w} x {h}");
    let red = pixels.iter().filter(|p| **p == [230, 40, 40]).count();
    // The start (green) and end (white) markers over the path's ends.
    assert!(pixels.contains(&[60, 220, 60]), "a start marker");
    let background = pixels.iter().filter(|p| **p == [24, 24, 28]).count();
    let mesh = pixels.len() - red - background;
    // 1.5 m of path at about 11 pixels a metre, its ends under the markers; the street's
    // mesh covers a good share.
    assert!(red > 5, "{red} path pixels");
    assert!(
        mesh > pixels.len() / 20,
        "{mesh} of {} pixels show the mesh",
        pixels.len()
    );
    assert!(pixels.contains(&[255, 255, 255]), "a scale bar");
    // `render` draws the same mesh from above and obliquely, with a scale bar.
    let mesh_ply = out.join("mesh.ply");
    for view in ["top", "oblique"] {
        let png = out.join(format!("{view}.png"));
        let args = ["render", s(&mesh_ply), "--view", view, "--out", s(&png)];
        let o = slamesh_ok(&[&args[..], &["--pixels", "400"]].concat());
        assert!(text(&o.stdout).contains("scale bar"), "{}", text(&o.stdout));
        let (w, h, pixels) = png_pixels(&png);
        assert_eq!(w.max(h), 401, "{view}: {w} x {h}");
        let plain = [[24, 24, 28], [255, 255, 255], [0, 0, 0]];
        let drawn = pixels.iter().filter(|p| !plain.contains(p)).count();
        assert!(drawn > pixels.len() / 20, "{view}: {drawn} pixels drawn");
        assert!(pixels.contains(&[255, 255, 255]), "{view}: a scale bar");
    }
    let o = slamesh(&[
        "render",
        s(&mesh_ply),
        "--view",
        "oblique",
        "--elevation",
        "95",
    ]);
    assert!(!o.status.success());
    assert!(
        text(&o.stderr).contains("between 5 and 90"),
        "{}",
        text(&o.stderr)
    );
}

/// The run's mesh and path drawn as the run draws its picture.
fn picture(
    out: &Path,
) -> (
    slamesh::outputs::topview::TopView,
    Option<map::Cut>,
    Vec<Pose>,
) {
    let mesh = read_ply_mesh(&out.join("mesh.ply")).unwrap();
    let path = read_kitti(&out.join("poses_kitti.txt")).unwrap();
    let triangles: Vec<[Point; 3]> = mesh
        .triangles
        .iter()
        .map(|t| t.map(|i| mesh.vertices[i as usize]))
        .collect();
    let how = MapPicture {
        pixels: 1000,
        margin_m: 40.0,
        z_lo: -3.0,
        z_top: 20.0,
    };
    let (view, cut) = map::draw::<()>(
        |f| {
            triangles.iter().for_each(|t| f(*t));
            Ok(())
        },
        &path,
        None,
        how,
    )
    .unwrap();
    (view, cut, path)
}

/// What a picture shows on a grid every 0.5 m within 6 m of the path: for each drawn point,
/// its height against the sensor's (the path's nearest pose).
fn heights_near_path(view: &slamesh::outputs::topview::TopView, path: &[Pose]) -> Vec<f32> {
    let mut out = Vec::new();
    let mut seen = std::collections::HashSet::new();
    for p in path.iter().step_by(5) {
        let t = p.translation.vector;
        for i in -12..=12 {
            for j in -12..=12 {
                let (x, y) = (t.x + 0.5 * f64::from(i), t.y + 0.5 * f64::from(j));
                if !seen.insert(((x * 2.0).round() as i64, (y * 2.0).round() as i64)) {
                    continue;
                }
                if let Some(z) = view.height_at(x, y) {
                    out.push(z - t.z as f32);
                }
            }
        }
    }
    out
}

/// A walk through the simulated office (3 m ceilings): drawn whole, its picture around the
/// path would be mostly ceiling; the run's picture cuts the ceiling away and shows the floor,
/// what stands on it and the walls' lower parts. `render --clip-above` cuts its mesh too.
#[test]
fn an_indoor_map_is_drawn_without_its_roof() {
    let dir = scratch("pictures-office");
    let drive = Drive::office(120, 1);
    let scans: Vec<_> = (0..120).map(|i| drive.scan(i)).collect();
    let folder = write_scan_folder(&dir, &scans);
    let out = dir.join("run");
    slamesh_run_ok(&folder, &out, &[]);
    assert!(out.join("topview.png").is_file());
    let (view, cut, path) = picture(&out);
    let cut = cut.expect("the office's ceiling is cut away");
    let shown = heights_near_path(&view, &path);
    let above = shown
        .iter()
        .filter(|z| **z > map::KEEP_ABOVE_M + 0.01)
        .count();
    let floor = shown.iter().filter(|z| **z < -0.5).count();
    assert_eq!(above, 0, "nothing drawn above the cut");
    assert!(
        floor * 2 > shown.len(),
        "mostly floor: {floor} of {}",
        shown.len()
    );
    // Drawn whole, the same neighbourhood shows the ceiling.
    let mesh = read_ply_mesh(&out.join("mesh.ply")).unwrap();
    let mut whole = slamesh::outputs::topview::TopView::new([-50.0, -50.0], [50.0, 50.0], 1000);
    whole.triangles(
        mesh.triangles
            .iter()
            .map(|t| t.map(|i| mesh.vertices[i as usize])),
        -3.0,
        3.0,
    );
    let uncut = heights_near_path(&whole, &path);
    let ceiling = uncut.iter().filter(|z| **z > 1.0).count();
    assert!(
        ceiling * 2 > uncut.len(),
        "uncut, mostly ceiling: {ceiling} of {}",
        uncut.len()
    );
    println!(
        "{}; {floor} of {} points near the path show the floor (uncut: {ceiling} of {} the ceiling)",
        cut.describe(),
        shown.len(),
        uncut.len()
    );

    let png = dir.join("render.png");
    let o = slamesh_ok(&[
        "render",
        out.join("mesh.ply").to_str().unwrap(),
        "--out",
        png.to_str().unwrap(),
        "--clip-above",
        "1.0",
    ]);
    assert!(png.is_file());
    let said = String::from_utf8_lossy(&o.stdout);
    assert!(said.contains("wrote"), "{said}");
}

/// A drive down the simulated street, open to the sky: nothing is cut.
#[test]
fn a_street_is_drawn_whole() {
    let dir = scratch("pictures-street");
    let (_, scans) = street_drive(20);
    let folder = write_scan_folder(&dir, &scans);
    let out = dir.join("run");
    slamesh_run_ok(&folder, &out, &[]);
    let (_, cut, _) = picture(&out);
    assert!(cut.is_none(), "a street has no roof");
}
