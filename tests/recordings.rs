//! Robot recordings through the command, on the fixtures of tests/fixtures/recordings (made by
//! its make.py from kitti-mini 00 with independent writers): every container and compression
//! gives the folder run's trajectories and mesh byte for byte, with the header stamps as the
//! TUM times; a malformed cloud is skipped with a message naming the recording, topic, index
//! and reason; a recording with several clouds, or a topic of another type, is refused with
//! the topics listed. Each fixture's `/imu` topic (written by rosbags and mcap, as ROS 1 and
//! CDR) is read beside the clouds with the values written; the runs that compare with the
//! folder or the motion's deskewing leave it out (`--imu off`).

use crate::common;

use common::{scratch, slamesh_run, slamesh_run_ok};
use std::path::{Path, PathBuf};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures/recordings")
}

const RECORDINGS: [&str; 9] = [
    "bag/none.bag",
    "bag/bz2.bag",
    "bag/lz4.bag",
    "mcap/cdr-none.mcap",
    "mcap/cdr-zstd.mcap",
    "mcap/cdr-lz4.mcap",
    "mcap/ros1-lz4.mcap",
    "ros2-db3",
    "ros2-mcap",
];

#[test]
fn every_container_gives_the_folder_runs_outputs() {
    let dir = scratch("recordings-same");
    let folder = dir.join("folder");
    slamesh_run_ok(&fixtures().join("scans"), &folder, &["--no-picture"]);
    let tum = std::fs::read_to_string(folder.join("poses_tum.txt")).unwrap();
    // The folder's times.txt holds the recordings' header stamps (KITTI's times after an
    // epoch); the TUM file must carry them, not the frame index.
    assert!(
        tum.lines()
            .nth(2)
            .unwrap()
            .starts_with("1317000000.103736 "),
        "{tum}"
    );
    for rec in RECORDINGS {
        let out = dir.join(rec.replace('/', "-"));
        // The folder's scans have no point times and no IMU: compare without either.
        slamesh_run_ok(
            &fixtures().join(rec),
            &out,
            &["--no-picture", "--deskew", "off", "--imu", "off"],
        );
        for f in ["poses_kitti.txt", "poses_tum.txt", "mesh.ply"] {
            let (a, b) = (
                std::fs::read(folder.join(f)).unwrap(),
                std::fs::read(out.join(f)).unwrap(),
            );
            assert!(a == b, "{rec}: {f} differs from the folder run's");
        }
    }
}

/// Points deskewed in each frame of a run on `rec` with `--deskew auto`.
fn deskewed(rec: &str, out: &Path) -> Vec<u64> {
    slamesh_run_ok(
        &fixtures().join(rec),
        out,
        &["--no-picture", "--imu", "off"],
    );
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    // Each frame's time in the report is its header stamp (make.py: 1317000000 + times.txt).
    let stamp = report["frames"][2]["stamp"].as_f64().unwrap();
    assert!(
        (stamp - 1_317_000_000.207_338).abs() < 1e-5,
        "{rec}: {stamp}"
    );
    // Ouster's organised cloud (the MCAP cdr fixtures) has a spare column: a NaN point and a
    // no-return one a message, dropped by the reader and counted.
    let dropped = report["frames"][0]["points_dropped_by_reader"]
        .as_u64()
        .unwrap();
    let ouster = rec.starts_with("mcap/cdr");
    assert_eq!(dropped, if ouster { 2 } else { 0 }, "{rec}");
    report["frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["deskewed_points"].as_u64().unwrap())
        .collect()
}

#[test]
fn clouds_with_point_times_are_deskewed_once_the_motion_is_known() {
    let dir = scratch("recordings-deskew");
    // Velodyne's `time` (float32 seconds), Ouster's `t` (uint32 nanoseconds): the third frame
    // is the first with two frames before it, so a motion to extrapolate.
    for rec in ["bag/lz4.bag", "mcap/cdr-zstd.mcap", "ros2-mcap"] {
        let d = deskewed(rec, &dir.join(rec.replace('/', "-")));
        assert_eq!(d.len(), 3);
        assert_eq!(d[..2], [0, 0], "{rec}");
        assert!(d[2] > 3_000, "{rec}: {d:?}");
    }
    // No time field: nothing to deskew.
    assert_eq!(deskewed("ros2-db3", &dir.join("db3")), vec![0, 0, 0]);
}

#[test]
fn a_malformed_cloud_is_skipped_with_its_reason() {
    let dir = scratch("recordings-bad");
    let rec = fixtures().join("bad/short-data.mcap");
    let o = slamesh_run(&rec, &dir.join("out"), &["--no-picture"]);
    assert!(o.status.success(), "two of three frames are usable");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("short-data.mcap: topic /velodyne_points, message 1: data holds")
            && err.contains("fewer than 1 rows of"),
        "{err}"
    );
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("out/report.json")).unwrap()).unwrap();
    let summary = &report["summary"];
    assert_eq!(summary["used"], 2);
    let skipped = summary["skipped"].as_array().unwrap();
    assert_eq!(skipped.len(), 1);
    assert!(skipped[0]
        .as_str()
        .unwrap()
        .contains("message 1: data holds 3896 bytes"));
}

#[test]
fn topics_are_chosen_or_refused_by_name_and_type() {
    let dir = scratch("recordings-topics");
    let out = dir.join("out");
    let refused = |rec: &str, extra: &[&str], want: &[&str]| {
        let o = slamesh_run(&fixtures().join(rec), &out, extra);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{rec} {extra:?} must be refused");
        for w in want {
            assert!(err.contains(w), "{rec} {extra:?}: {err}");
        }
    };
    refused(
        "bad/two-clouds.mcap",
        &[],
        &[
            "several PointCloud2 topics, choose one with --topic",
            "/velodyne_points (sensor_msgs/msg/PointCloud2, 1 messages)",
            "/ouster/points",
        ],
    );
    refused(
        "bag/lz4.bag",
        &["--topic", "/imu"],
        &["topic /imu holds sensor_msgs/Imu, not sensor_msgs/PointCloud2"],
    );
    refused(
        "ros2-db3",
        &["--topic", "/nope"],
        &["no topic /nope", "/imu (sensor_msgs/msg/Imu, 3 messages)"],
    );
    refused("scans", &["--topic", "/x"], &["--topic is for recordings"]);
    // One of the two clouds, chosen by name.
    slamesh_run_ok(
        &fixtures().join("bad/two-clouds.mcap"),
        &out,
        &["--topic", "/ouster/points", "--no-picture"],
    );
}

#[test]
fn the_imu_topic_is_read_beside_the_clouds_in_every_container() {
    use slamesh::run::{FrameSource, Sample};
    use slamesh::sources::recording::{Container, Recording};
    for rec in RECORDINGS {
        let path = fixtures().join(rec);
        let container = Container::detect(&path).unwrap().unwrap();
        let mut r = Recording::open(container, None).unwrap();
        assert!(r.read_imu(None).unwrap(), "{rec}");
        let mut readings = Vec::new();
        for i in 0..r.frames() {
            r.read(i).unwrap();
            readings.extend(r.samples(i));
        }
        // make.py: a reading a microsecond before each cloud's stamp, both rates (0, 0, 9.81).
        assert_eq!(readings.len(), 3, "{rec}");
        for (i, s) in readings.iter().filter_map(Sample::imu).enumerate() {
            assert_eq!(
                (s.gyro, s.accel),
                ([0.0, 0.0, 9.81], [0.0, 0.0, 9.81]),
                "{rec}"
            );
            assert!(
                (s.stamp - r.stamp(i)).abs() < 1e-5,
                "{rec}: {} {}",
                s.stamp,
                r.stamp(i)
            );
        }
    }
    let path = fixtures().join("mcap/cdr-none.mcap");
    let mut r = Recording::open(Container::detect(&path).unwrap().unwrap(), None).unwrap();
    let e = r
        .read_imu(Some("/velodyne_points"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("holds sensor_msgs/msg/PointCloud2, not sensor_msgs/Imu"),
        "{e}"
    );
    // Through the command: the readings reach the run, counted in its summary.
    let dir = scratch("recordings-imu");
    slamesh_run_ok(&path, &dir, &["--no-picture"]);
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap();
    assert_eq!(
        report["summary"]["imu"]["readings"]["taken"], 3,
        "{}",
        report["summary"]
    );
}
