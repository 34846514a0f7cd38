//! The pictures: `run` draws `topview.png` of its mesh and path (hill-shaded, with a scale
//! bar), and `render` draws any mesh from above or obliquely. The data is a simulated street.

mod common;

use common::{scratch, slamesh, slamesh_ok, slamesh_run_ok, street_drive, write_scan_folder};
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
    let background = pixels.iter().filter(|p| **p == [24, 24, 28]).count();
    let mesh = pixels.len() - red - background;
    // 1.5 m of path at about 11 pixels a metre; the street's mesh covers a good share.
    assert!(red > 20, "{red} path pixels");
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
    std::fs::remove_dir_all(&dir).unwrap();
}
