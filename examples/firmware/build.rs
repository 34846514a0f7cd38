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
//! The reference poses are the LiDAR's, `inv(Tr) * P_i * Tr` from `poses.txt` and
//! `calib.txt`, relative to the first scan, as 12 numbers (row-major `[R|t]`).
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
    let mut poses: Vec<[f64; 12]> = Vec::new();
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
        poses = lidar_poses(&seq);
    }
    fs::write(out.join("kitti16.bin"), &points).expect("write kitti16.bin");
    let mut rs = String::from("// Made by build.rs from kitti-mini 00.\n");
    rs += &format!(
        "const KITTI16_ENDS: [usize; {}] = {:?};\n",
        ends.len(),
        ends
    );
    rs += &format!("const KITTI16_POSES: [[f64; 12]; {}] = [\n", poses.len());
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

/// The LiDAR's poses relative to the first scan.
fn lidar_poses(seq: &std::path::Path) -> Vec<[f64; 12]> {
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
    let tr_line = calib
        .lines()
        .find_map(|l| l.strip_prefix("Tr:"))
        .expect("calib.txt has no Tr: line");
    let tr = numbers(tr_line);
    let poses = read("poses.txt");
    let lidar: Vec<[f64; 12]> = poses
        .lines()
        .take(SCANS)
        .map(|l| mul(&mul(&inverse(&tr), &numbers(l)), &tr))
        .collect();
    assert_eq!(lidar.len(), SCANS, "poses.txt has fewer than {SCANS} lines");
    let first = inverse(&lidar[0]);
    lidar.iter().map(|p| mul(&first, p)).collect()
}

/// `a * b` of two rigid transforms as row-major `[R|t]`.
fn mul(a: &[f64; 12], b: &[f64; 12]) -> [f64; 12] {
    let mut c = [0.0; 12];
    for r in 0..3 {
        for k in 0..4 {
            let mut s = if k == 3 { a[r * 4 + 3] } else { 0.0 };
            for j in 0..3 {
                s += a[r * 4 + j] * b[j * 4 + k];
            }
            c[r * 4 + k] = s;
        }
    }
    c
}

/// The inverse of a rigid transform `[R|t]`: `[Rᵀ|-Rᵀt]`.
fn inverse(a: &[f64; 12]) -> [f64; 12] {
    let mut c = [0.0; 12];
    for r in 0..3 {
        for k in 0..3 {
            c[r * 4 + k] = a[k * 4 + r];
        }
        c[r * 4 + 3] = -(0..3).map(|j| a[j * 4 + r] * a[j * 4 + 3]).sum::<f64>();
    }
    c
}
