//! Helpers shared by the integration tests: the real-data folder and the `slamesh` command.
#![allow(dead_code)]

use slamesh_core::{Point, Pose};
use slamesh_sim::{sensor_pose, Lidar, Scene};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod scratch;
pub use scratch::scratch;

/// `SLAMESH_DATA/kitti-mini`; a relative `SLAMESH_DATA` is taken from the workspace root
/// (cargo runs tests in the package folder). Without the variable, prints that the test is
/// skipped and returns `None`; with it, a missing folder fails the test.
pub fn kitti_mini() -> Option<PathBuf> {
    let Some(d) = std::env::var_os("SLAMESH_DATA") else {
        println!("skipped: SLAMESH_DATA is not set");
        return None;
    };
    let d = PathBuf::from(d);
    let d = if d.is_relative() {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(d)
    } else {
        d
    };
    let k = d.join("kitti-mini");
    assert!(
        k.is_dir(),
        "SLAMESH_DATA is set but {} is missing",
        k.display()
    );
    Some(k)
}

/// The `slamesh` binary with `args`, not started. When the tests run under an emulator
/// (cross builds), `SLAMESH_TEST_RUNNER` names it (e.g. `qemu-aarch64 -L
/// /usr/aarch64-linux-gnu`) and the binary runs under it too.
pub fn slamesh_command(args: &[&str]) -> Command {
    let runner = std::env::var("SLAMESH_TEST_RUNNER").unwrap_or_default();
    let mut words = runner.split_whitespace();
    let mut command = match words.next() {
        Some(program) => {
            let mut c = Command::new(program);
            c.args(words).arg(env!("CARGO_BIN_EXE_slamesh"));
            c
        }
        None => Command::new(env!("CARGO_BIN_EXE_slamesh")),
    };
    command.args(args);
    command
}

/// Runs the `slamesh` binary with `args` (see [`slamesh_command`]).
pub fn slamesh(args: &[&str]) -> Output {
    slamesh_command(args)
        .output()
        .expect("the slamesh binary runs")
}

/// Writes `points` as a KITTI `.bin` scan (reflectance 0).
pub fn write_bin(path: &Path, points: &[slamesh_core::Point]) {
    let mut b = Vec::with_capacity(points.len() * 16);
    for p in points {
        for v in [p[0], p[1], p[2], 0.0] {
            b.extend_from_slice(&v.to_le_bytes());
        }
    }
    std::fs::write(path, b).unwrap();
}

/// Writes `scans` as KITTI `.bin` files `000000.bin`, `000001.bin`, ... into `dir/scans`
/// (created) and returns that folder.
pub fn write_scan_folder(dir: &Path, scans: &[Vec<slamesh_core::Point>]) -> PathBuf {
    let folder = dir.join("scans");
    std::fs::create_dir_all(&folder).unwrap();
    for (i, scan) in scans.iter().enumerate() {
        write_bin(&folder.join(format!("{i:06}.bin")), scan);
    }
    folder
}

/// Runs `slamesh` and fails the test, showing its output, unless it succeeds.
pub fn slamesh_ok(args: &[&str]) -> Output {
    let out = slamesh(args);
    assert!(
        out.status.success(),
        "slamesh {args:?} failed\nstdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// `slamesh run <input> --out <out> -q` plus `extra` options (not checked for success).
pub fn slamesh_run(input: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "run",
        input.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "-q",
    ];
    args.extend_from_slice(extra);
    slamesh(&args)
}

/// [`slamesh_run`] that fails the test, showing its output, unless it succeeds.
pub fn slamesh_run_ok(input: &Path, out: &Path, extra: &[&str]) -> Output {
    let o = slamesh_run(input, out, extra);
    assert!(
        o.status.success(),
        "slamesh run {} failed\nstderr:\n{}",
        input.display(),
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

/// True poses and scans of a drive down the simulated street (0.5 m and 1 degree a frame).
pub fn street_drive(frames: usize) -> (Vec<Pose>, Vec<Vec<Point>>) {
    let (scene, lidar) = (Scene::street(), Lidar::hdl64(900));
    let poses: Vec<Pose> = (0..frames)
        .map(|i| sensor_pose(0.5 * i as f64, 0.03 * i as f64, 1.73, 1.0 * i as f64))
        .collect();
    let scans = poses.iter().map(|p| lidar.scan(&scene, p)).collect();
    (poses, scans)
}

/// A run into `out` with `config` as the tests run it: two threads, a PLY mesh, the preset
/// named `default`.
pub fn test_run_options(out: &Path, config: slamesh_core::Config) -> slamesh::run::RunOptions {
    slamesh::run::RunOptions {
        out: out.to_path_buf(),
        config,
        preset: "default".into(),
        threads: 2,
        input: "test".into(),
        mesh_formats: vec![slamesh::outputs::mesh_spool::MeshFormat::Ply],
        ..slamesh::run::RunOptions::default()
    }
}

/// Runs the pipeline of capacity `C` over `drive` in-process with the default configuration,
/// two threads and `window`, into a scratch folder removed afterwards (`name` tells runs
/// apart); returns each frame's record and the summary. Every frame must be used.
pub fn run_drive<C: slamesh_core::Capacity>(
    drive: &mut slamesh_sim::Drive,
    window: slamesh::run::config_file::WindowSettings,
    name: &str,
) -> (Vec<slamesh::run::FrameRecord>, slamesh::run::Summary) {
    let frames = drive.poses.len();
    let out = scratch(name);
    let opts = slamesh::run::RunOptions {
        out: out.to_path_buf(),
        config: slamesh_core::Config::default(),
        preset: "default".into(),
        window,
        threads: 2,
        mesh_formats: vec![slamesh::outputs::mesh_spool::MeshFormat::Ply],
        given_poses: None,
        input: format!("simulated drive ({name})"),
        ..slamesh::run::RunOptions::default()
    };
    let mut records = Vec::new();
    let summary = slamesh::run::run::<C>(drive, &opts, |r| records.push(r.clone())).unwrap();
    assert_eq!(summary.used, frames, "every simulated frame is used");
    (records, summary)
}

/// Checks that a capped run evicted and that no frame's map held more layers than its
/// budget; returns the budget.
pub fn assert_within_budget(
    records: &[slamesh::run::FrameRecord],
    summary: &slamesh::run::Summary,
) -> usize {
    let budget = summary.max_layers.expect("a capped run has a layer budget");
    assert!(summary.evicted_cells > 0, "the cap forced eviction");
    for r in records {
        assert!(
            r.map_layers <= budget,
            "frame {}: {} layers > {budget}",
            r.frame,
            r.map_layers
        );
    }
    budget
}

/// A captured frame: its bytes, its original length and its capture time (s, us).
pub type Frame = (Vec<u8>, u32, [u32; 2]);

/// The frames of a legacy little-endian pcap.
pub fn capture_frames(path: &Path) -> Vec<Frame> {
    let b = std::fs::read(path).unwrap();
    let mut out = Vec::new();
    let mut off = 24;
    while off + 16 <= b.len() {
        let word = |k: usize| u32::from_le_bytes(b[off + k..off + k + 4].try_into().unwrap());
        let incl = word(8) as usize;
        out.push((
            b[off + 16..off + 16 + incl].to_vec(),
            word(12),
            [word(0), word(4)],
        ));
        off += 16 + incl;
    }
    out
}

/// Sends a capture's UDP payloads (its Ethernet frames less their 42 bytes of Ethernet, IPv4
/// and UDP headers) to `to` from another thread, at `speed` times the rate they were captured
/// at; the thread returns how many it sent.
pub fn send_capture(
    path: &Path,
    to: std::net::SocketAddr,
    speed: f64,
) -> std::thread::JoinHandle<usize> {
    send_capture_routed(path, move |_| to, speed)
}

/// As [`send_capture`], each datagram to the address `to` gives for the port the capture sent
/// it to.
pub fn send_capture_routed(
    path: &Path,
    to: impl Fn(u16) -> std::net::SocketAddr + Send + 'static,
    speed: f64,
) -> std::thread::JoinHandle<usize> {
    let frames = capture_frames(path);
    std::thread::spawn(move || {
        let socket = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let t = |f: &Frame| f64::from(f.2[0]) + f64::from(f.2[1]) * 1e-6;
        let (t0, start) = (t(&frames[0]), std::time::Instant::now());
        let mut sent = 0;
        for f in &frames {
            let due = (t(f) - t0) / speed;
            let now = start.elapsed().as_secs_f64();
            if due > now {
                std::thread::sleep(std::time::Duration::from_secs_f64(due - now));
            }
            let port = u16::from_be_bytes([f.0[36], f.0[37]]);
            socket.send_to(&f.0[42..], to(port)).unwrap();
            sent += 1;
        }
        sent
    })
}

/// A reference file of decoded points (the packet fixtures' make.py): little-endian f32 x, y,
/// z and f64 time each.
pub fn reference_points(path: &Path) -> Vec<([f32; 3], f64)> {
    let bytes = std::fs::read(path).unwrap();
    bytes
        .chunks_exact(20)
        .map(|c| {
            let f = |k: usize| f32::from_le_bytes(c[4 * k..4 * k + 4].try_into().unwrap());
            (
                [f(0), f(1), f(2)],
                f64::from_le_bytes(c[12..20].try_into().unwrap()),
            )
        })
        .collect()
}

/// Asserts that `ours` are `theirs` in the same order, each within 1 mm and 1 us; returns the
/// worst distance (m) and time difference (s).
pub fn assert_same_points(
    name: &str,
    ours: &[([f32; 3], f64)],
    theirs: &[([f32; 3], f64)],
) -> (f64, f64) {
    assert_eq!(ours.len(), theirs.len(), "{name}: as many points");
    let (mut worst_m, mut worst_s) = (0.0f64, 0.0f64);
    for (k, ((p, t), (q, u))) in ours.iter().zip(theirs).enumerate() {
        let d = (0..3)
            .map(|i| f64::from(p[i] - q[i]).powi(2))
            .sum::<f64>()
            .sqrt();
        worst_m = worst_m.max(d);
        worst_s = worst_s.max((t - u).abs());
        assert!(d < 1e-3, "{name} point {k}: {p:?} against {q:?}");
        assert!(
            (t - u).abs() < 1e-6,
            "{name} point {k}: time {t} against {u}"
        );
    }
    println!(
        "{name}: {} points; worst {:.4} mm, {:.1} ns",
        ours.len(),
        worst_m * 1e3,
        worst_s * 1e9
    );
    (worst_m, worst_s)
}

/// The positions (translations) of a KITTI-format trajectory file.
pub fn kitti_positions(path: &Path) -> Vec<[f64; 3]> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|w| w.parse().unwrap()).collect();
            [v[3], v[7], v[11]]
        })
        .collect()
}

/// Writes `d`'s scans as KITTI `.bin` files with `times.txt`, and its IMU's readings over the
/// drive as `imu0/data.csv` in EuRoC's layout beside them.
pub fn write_folder_with_imu(d: &slamesh_sim::Drive, dir: &Path) -> PathBuf {
    use slamesh::run::FrameSource;
    let scans = dir.join("velodyne");
    std::fs::create_dir_all(&scans).unwrap();
    let mut times = String::new();
    for i in 0..d.frames() {
        write_bin(&scans.join(format!("{i:06}.bin")), &d.scan(i));
        writeln!(times, "{:.6}", d.stamp(i)).unwrap();
    }
    std::fs::write(dir.join("times.txt"), times).unwrap();
    let end = d.frames() as f64 * d.period_s;
    let csv = slamesh::formats::imu_csv::encode(&d.imu_between(-1.0, end));
    std::fs::create_dir_all(dir.join("imu0")).unwrap();
    std::fs::write(dir.join("imu0").join("data.csv"), csv).unwrap();
    scans
}

/// Writes `d` in KITTI raw's drive layout under `dir`: its scans untimed as
/// `velodyne_points/data/*.bin` with mid-sweep stamps in `velodyne_points/timestamps.txt`, its
/// IMU's readings as OXTS packets in `oxts/`, on KITTI's clock (2011-09-26); returns the true
/// poses at those stamps, relative to the first.
pub fn write_kitti_raw(d: &slamesh_sim::Drive, dir: &Path) -> Vec<Pose> {
    use slamesh::formats::oxts;
    use slamesh::run::FrameSource;
    let epoch = 1_317_042_145.0;
    let data = dir.join("velodyne_points").join("data");
    std::fs::create_dir_all(&data).unwrap();
    let mut stamps = String::new();
    for i in 0..d.frames() {
        write_bin(&data.join(format!("{i:010}.bin")), &d.scan(i));
        let mid = epoch + d.stamp(i) + d.period_s / 2.0;
        writeln!(stamps, "{}", oxts::format_time(mid)).unwrap();
    }
    std::fs::write(dir.join("velodyne_points").join("timestamps.txt"), stamps).unwrap();
    let packets = dir.join("oxts").join("data");
    std::fs::create_dir_all(&packets).unwrap();
    let end = d.frames() as f64 * d.period_s;
    let mut times = String::new();
    for (k, r) in d.imu_between(-1.0, end).iter().enumerate() {
        let packet = oxts::encode_packet(r.gyro, r.accel);
        std::fs::write(packets.join(format!("{k:010}.txt")), packet).unwrap();
        writeln!(times, "{}", oxts::format_time(epoch + r.stamp)).unwrap();
    }
    std::fs::write(dir.join("oxts").join("timestamps.txt"), times).unwrap();
    let mid = |i: usize| d.pose_after(i, d.period_s / 2.0);
    (0..d.frames()).map(|i| mid(0).inverse() * mid(i)).collect()
}
