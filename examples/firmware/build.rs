//! Puts memory.x where the linker finds it, and makes the real-scan fixture: kitti-mini 00's
//! ten HDL-64E scans cut down to a 16-beam sensor with a narrower view, with their reference
//! poses, written into `$OUT_DIR` and included in the firmware image.
//!
//! The cut, per scan, in the order KITTI stores the points (ring by ring, each ring one turn):
//! - a new ring starts where the azimuth jumps by more than half a turn; every fourth ring
//!   is kept (16 of about 64);
//! - only the front half is kept (azimuth within ±90°), and every second point of it;
//! - coordinates are stored as little-endian `i16` centimetres (KITTI's ranges end near 80 m).
//!
//! The reference poses are `poses.txt`'s camera poses `P_i` and `calib.txt`'s `Tr`, as 12
//! numbers each (row-major `[R|t]`); the firmware takes the LiDAR's, `inv(Tr) * P_i * Tr`.
//!
//! The data folder is `SLAMESH_DATA` (a relative path is taken from the repository's root, as
//! the tests take it). Without it the fixture is empty and the firmware says it skipped the
//! real scans; with it, a missing or malformed file fails the build.
use std::{env, fs, path::PathBuf};

/// Scans of kitti-mini 00 used.
const SCANS: usize = 10;

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("OUT_DIR"));
    fs::copy("memory.x", out.join("memory.x")).expect("copy memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-env-changed=SLAMESH_DATA");

    let mut points: Vec<u8> = Vec::new();
    let mut ends: Vec<usize> = Vec::new();
    let (mut poses, mut tr): (Vec<[f64; 12]>, [f64; 12]) = (Vec::new(), [0.0; 12]);
    if let Some(data) = env::var_os("SLAMESH_DATA") {
        let mut data = PathBuf::from(data);
        if data.is_relative() {
            let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("manifest"));
            data = manifest.join("../..").join(data);
        }
        let seq = data.join("kitti-mini/00");
        for i in 0..SCANS {
            let file = seq.join(format!("velodyne/{i:06}.bin"));
            println!("cargo:rerun-if-changed={}", file.display());
            let bytes =
                fs::read(&file).unwrap_or_else(|e| panic!("{}: cannot read: {e}", file.display()));
            cut(&bytes, &mut points);
            ends.push(points.len() / 6);
        }
        (poses, tr) = camera_poses_and_tr(&seq);
    }
    fs::write(out.join("kitti16.bin"), &points).expect("write kitti16.bin");
    let mut rs = String::from("// Made by build.rs from kitti-mini 00.\n");
    rs += &format!(
        "const KITTI16_ENDS: [usize; {}] = {:?};\n",
        ends.len(),
        ends
    );
    rs += &format!("const KITTI16_TR: [f64; 12] = {tr:?};\n");
    rs += &format!(
        "const KITTI16_CAMERA_POSES: [[f64; 12]; {}] = [\n",
        poses.len()
    );
    for p in &poses {
        rs += &format!("    {p:?},\n");
    }
    rs += "];\n";
    fs::write(out.join("kitti16.rs"), rs).expect("write kitti16.rs");
}

/// Appends the 16-beam, front-half, every-second-point cut of one KITTI scan.
fn cut(bytes: &[u8], out: &mut Vec<u8>) {
    let f = |b: &[u8]| f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    let (mut ring, mut previous, mut kept) = (0usize, None::<f32>, 0usize);
    for p in bytes.chunks_exact(16) {
        let (x, y, z) = (f(&p[0..4]), f(&p[4..8]), f(&p[8..12]));
        let azimuth = y.atan2(x);
        if previous.is_some_and(|a| (azimuth - a).abs() > std::f32::consts::PI) {
            ring += 1;
        }
        previous = Some(azimuth);
        if ring % 4 != 0 || azimuth.abs() > std::f32::consts::FRAC_PI_2 {
            continue;
        }
        kept += 1;
        if kept % 2 == 0 {
            for c in [x, y, z] {
                let cm = (c * 100.0).round().clamp(i16::MIN as f32, i16::MAX as f32) as i16;
                out.extend_from_slice(&cm.to_le_bytes());
            }
        }
    }
}

/// The first [`SCANS`] lines of `poses.txt` (the camera's poses) and `calib.txt`'s `Tr`,
/// 12 numbers each; the firmware turns them into the LiDAR's poses.
fn camera_poses_and_tr(seq: &std::path::Path) -> (Vec<[f64; 12]>, [f64; 12]) {
    let read = |name: &str| {
        let file = seq.join(name);
        println!("cargo:rerun-if-changed={}", file.display());
        fs::read_to_string(&file).unwrap_or_else(|e| panic!("{}: cannot read: {e}", file.display()))
    };
    let numbers = |line: &str| -> [f64; 12] {
        let v: Vec<f64> = line
            .split_whitespace()
            .map(|w| w.parse().unwrap_or_else(|_| panic!("not a number: {w}")))
            .collect();
        v.try_into()
            .unwrap_or_else(|_| panic!("not 12 numbers: {line}"))
    };
    let calib = read("calib.txt");
    let tr = calib
        .lines()
        .find_map(|l| l.strip_prefix("Tr:"))
        .map(numbers)
        .expect("calib.txt has no Tr: line");
    let poses: Vec<[f64; 12]> = read("poses.txt").lines().take(SCANS).map(numbers).collect();
    assert_eq!(poses.len(), SCANS, "poses.txt has fewer than {SCANS} lines");
    (poses, tr)
}
