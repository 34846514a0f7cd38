//! No lock-in by a bad first scan: a scan far smaller than the ones after it (a partial sweep,
//! a cut-off file) that starts the map is dropped from it as soon as the next scan cannot
//! register against what it gave (`slamesh_core::MapRestart`). The run then goes on as if it
//! had started at that next scan, and says so.

use crate::common;

use common::{kitti_mini, scratch, slamesh_run};
use std::path::Path;

/// The first 64 points of `seq`'s first scan (one stretch of a beam: a few cells' worth), then
/// every scan of `seq`, as a folder under `dir`.
fn with_short_first_scan(seq: &Path, dir: &Path) -> std::path::PathBuf {
    let scans = dir.join("velodyne");
    std::fs::create_dir_all(&scans).unwrap();
    let mut files: Vec<_> = std::fs::read_dir(seq.join("velodyne"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    let first = std::fs::read(&files[0]).unwrap();
    std::fs::write(scans.join("000000.bin"), &first[..64 * 16]).unwrap();
    for (i, f) in files.iter().enumerate() {
        std::fs::copy(f, scans.join(format!("{:06}.bin", i + 1))).unwrap();
    }
    dir.to_path_buf()
}

/// The run in `out` is the run in `plain` after its first frame: every later pose to the last
/// digit written, and the same mesh.
fn same_after_the_first(out: &Path, plain: &Path) {
    let poses = |d: &Path| std::fs::read_to_string(d.join("poses_kitti.txt")).unwrap();
    let with = poses(out);
    let with: Vec<&str> = with.lines().collect();
    assert_eq!(with[1..], poses(plain).lines().collect::<Vec<_>>()[..]);
    let mesh = |d: &Path| std::fs::read(d.join("mesh.ply")).unwrap();
    assert!(mesh(out) == mesh(plain), "the same mesh");
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

#[test]
fn a_short_first_scan_does_not_turn_the_trajectory() {
    let Some(k) = kitti_mini() else { return };
    let dir = scratch("first-scan");
    for seq in ["00", "03"] {
        let input = with_short_first_scan(&k.join(seq), &dir.join(seq));
        let (out, plain) = (
            dir.join(format!("out{seq}")),
            dir.join(format!("plain{seq}")),
        );
        // --strict: the run vouches for every pose from the first full scan on.
        let o = slamesh_run(&input, &out, &["--threads", "2", "--strict"]);
        let stderr = text(&o.stderr);
        assert!(o.status.success(), "{seq}: {stderr}");
        assert!(
            stderr.contains("frame 1 (") && stderr.contains("the map starts again here: frame 0"),
            "{seq}: the restart is said: {stderr}"
        );
        let o = slamesh_run(&k.join(seq), &plain, &["--threads", "2"]);
        assert!(o.status.success(), "{}", text(&o.stderr));
        // Today the frames after the short scan are the run without it to the last digit
        // written: the map restarts empty, with no motion history, at the short scan's pose.
        let poses = |d: &Path| std::fs::read_to_string(d.join("poses_kitti.txt")).unwrap();
        let (with, without) = (poses(&out), poses(&plain));
        let with: Vec<&str> = with.lines().collect();
        assert_eq!(with[1..], without.lines().collect::<Vec<_>>()[..], "{seq}");
        let mesh = |d: &Path| std::fs::read(d.join("mesh.ply")).unwrap();
        assert!(mesh(&out) == mesh(&plain), "{seq}: the same mesh");
        // The report names the restart on the frame that made it.
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap())
                .unwrap();
        let (frame0, frame1) = (&report["frames"][0], &report["frames"][1]);
        assert_eq!(frame0["status"], "FirstScan", "{seq}");
        assert_eq!(frame1["status"], "FirstScan", "{seq}");
        let started = format!("started it with {} points", frame0["points_kept"]);
        let reason = frame1["reason"].as_str().unwrap_or_default();
        assert!(reason.contains(&started), "{seq}: {reason}");
    }
}

#[test]
fn a_first_file_that_is_no_scan_is_refused_with_its_reason_and_decides_nothing() {
    let Some(k) = kitti_mini() else { return };
    let dir = scratch("first-scan-absurd");
    let seq = k.join("00");
    let scans = dir.join("in").join("velodyne");
    std::fs::create_dir_all(&scans).unwrap();
    // Text whose size fits three 16-byte points: as float32, coordinates of about 1e22 m.
    let text_file = b"0123456789 abcdefghijklmnopqrstuvwxyz ABCDEFGHI\n";
    assert_eq!(text_file.len(), 48);
    std::fs::write(scans.join("000000.bin"), text_file).unwrap();
    for i in 0..10 {
        let from = seq.join("velodyne").join(format!("{i:06}.bin"));
        std::fs::copy(from, scans.join(format!("{:06}.bin", i + 1))).unwrap();
    }
    let (out, plain) = (dir.join("out"), dir.join("plain"));
    let o = slamesh_run(&dir.join("in"), &out, &["--threads", "2"]);
    let stderr = text(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert!(
        stderr.contains("000000.bin") && stderr.contains("beyond any LiDAR's"),
        "refused, named, with its reason: {stderr}"
    );
    let o = slamesh_run(&seq, &plain, &["--threads", "2"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    // It decided nothing (scale, capacity, the map): the scans after it are the run without it
    // (a skipped frame keeps a line of the pose before, here the start's).
    same_after_the_first(&out, &plain);
}

#[test]
fn a_partial_first_sweep_does_not_decide_the_scale() {
    let Some(k) = kitti_mini() else { return };
    let dir = scratch("first-scan-partial");
    let seq = k.join("00");
    let scans = dir.join("in").join("velodyne");
    std::fs::create_dir_all(&scans).unwrap();
    // The first scan's points within 6 m (the road around the car, some 3 % of them): alone
    // its median range would shrink the default preset's cells to under a metre.
    let first = std::fs::read(seq.join("velodyne").join("000000.bin")).unwrap();
    let near: Vec<u8> = first
        .chunks_exact(16)
        .filter(|p| {
            let c = |k: usize| f32::from_le_bytes(p[4 * k..4 * k + 4].try_into().unwrap());
            (c(0) * c(0) + c(1) * c(1) + c(2) * c(2)).sqrt() < 6.0
        })
        .flatten()
        .copied()
        .collect();
    assert!(near.len() / 16 > 1000, "{} points", near.len() / 16);
    std::fs::write(scans.join("000000.bin"), &near).unwrap();
    for i in 0..10 {
        let from = seq.join("velodyne").join(format!("{i:06}.bin"));
        std::fs::copy(from, scans.join(format!("{:06}.bin", i + 1))).unwrap();
    }
    let (out, plain) = (dir.join("out"), dir.join("plain"));
    let o = slamesh_run(&dir.join("in"), &out, &["--threads", "2"]);
    let stderr = text(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert!(
        stderr.contains("000000.bin: frame 0:")
            && stderr.contains("(it does not choose the scale)"),
        "the partial sweep named and passed over: {stderr}"
    );
    let o = slamesh_run(&seq, &plain, &["--threads", "2"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    // The map restarts at frame 1 (as for a short scan), at the scale of the whole scans: the
    // scans after it are the run without it to the last digit written. At the partial sweep's
    // scale every pose and the mesh would differ.
    same_after_the_first(&out, &plain);
}
