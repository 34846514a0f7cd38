//! Honest health through the command: a frame that is not registered normally is named on the
//! terminal (frame, file, status, reason with its parameter), rate-limited; the closing lines
//! count the frames by status; `report.json` has a health section; `--strict` fails the run
//! and lists the frames; an unusable scan's message gives the range limits and parameters;
//! `-v`, `-q` and `RUST_LOG` set what is said.

use crate::common;

use common::{scratch, slamesh_command, slamesh_run, write_bin};
use slamesh_core::Point;
use slamesh_sim::{sensor_pose, Lidar, Scene};
use std::path::{Path, PathBuf};

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// A small patch of wall 60 m away: points enough, but nothing the map holds to match.
fn far_patch() -> Vec<Point> {
    (0..400)
        .map(|k| [60.0, -1.0 + 0.1 * (k % 20) as f32, 0.1 * (k / 20) as f32])
        .collect()
}

/// Writes into `dir/scans` (returned) frames 0 and 1 of the street, then `far` frames of
/// [`far_patch`], then one frame whose points are all within 1 m of the sensor.
fn write_frames(dir: &Path, far: usize) -> PathBuf {
    let dir = dir.join("scans");
    std::fs::create_dir_all(&dir).unwrap();
    let (scene, lidar) = (Scene::street(), Lidar::hdl64(900));
    for i in 0..2 {
        let scan = lidar.scan(&scene, &sensor_pose(0.3 * i as f64, 0.0, 1.73, 0.0));
        write_bin(&dir.join(format!("{i:03}.bin")), &scan);
    }
    for i in 2..2 + far {
        write_bin(&dir.join(format!("{i:03}.bin")), &far_patch());
    }
    let near: Vec<Point> = (0..50).map(|k| [0.5, 0.01 * k as f32, -0.2]).collect();
    write_bin(&dir.join(format!("{:03}.bin", 2 + far)), &near);
    dir
}

#[test]
fn frames_not_registered_are_named_counted_reported_and_fail_a_strict_run() {
    let dir = scratch("health");
    let scans = write_frames(&dir, 2);
    let out = dir.join("out");
    // The original's parameters (`fast`): the default preset fits the nearest range to the
    // scene, and these messages name the configured one.
    let o = slamesh_run(&scans, &out, &["--preset", "fast"]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let (stdout, stderr) = (text(&o.stdout), text(&o.stderr));
    let named = |frame: usize| {
        stderr.lines().any(|l| {
            l.starts_with("slamesh: warning: frame ")
                && l.contains(&format!("frame {frame} ("))
                && l.contains(&format!("{frame:03}.bin): TooFewResiduals: "))
                && l.contains("fewer than register.lm.min_residuals = 10")
        })
    };
    assert!(named(2) && named(3), "{stderr}");
    assert!(
        stderr.contains("004.bin: frame 4: empty scan: none of 50 points usable (50 closer than filter.range_min_m = 1.2 m"),
        "{stderr}"
    );
    assert!(
        stdout.contains("frames by status: 1 FirstScan, 1 Converged, 2 TooFewResiduals, 1 Skipped"),
        "{stdout}"
    );
    assert!(
        stdout.contains("3 frame(s) not registered normally"),
        "{stdout}"
    );

    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let health = &report["summary"]["health"];
    assert_eq!(
        health["counts"],
        serde_json::json!([
            ["FirstScan", 1],
            ["Converged", 1],
            ["TooFewResiduals", 2],
            ["Skipped", 1]
        ])
    );
    let listed: Vec<(u64, &str)> = health["not_registered"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| (n["frame"].as_u64().unwrap(), n["status"].as_str().unwrap()))
        .collect();
    assert_eq!(
        listed,
        [
            (2, "TooFewResiduals"),
            (3, "TooFewResiduals"),
            (4, "Skipped")
        ]
    );
    assert!(report["frames"][2]["reason"]
        .as_str()
        .unwrap()
        .contains("register.lm.min_residuals"));
    assert!(report["frames"][1]["reason"].is_null());

    // --strict: the outputs are written, the run fails and lists the frames.
    let strict = dir.join("strict");
    let o = slamesh_run(&scans, &strict, &["--strict", "--preset", "fast"]);
    assert!(!o.status.success());
    let stderr = text(&o.stderr);
    for frame in ["frame 2 (", "frame 3 (", "frame 4 ("] {
        assert!(
            stderr
                .lines()
                .any(|l| l.starts_with("slamesh: error: ") && l.contains(frame)),
            "{frame}: {stderr}"
        );
    }
    assert!(
        stderr.contains("--strict: 3 frame(s) not registered normally"),
        "{stderr}"
    );
    assert!(strict.join("poses_kitti.txt").is_file());
}

#[test]
fn a_long_stretch_of_bad_frames_does_not_flood_the_terminal() {
    let dir = scratch("health-flood");
    let scans = write_frames(&dir, 40);
    let o = slamesh_run(&scans, &dir.join("out"), &[]);
    assert!(o.status.success());
    let stderr = text(&o.stderr);
    let warnings = stderr
        .lines()
        .filter(|l| l.contains("TooFewResiduals"))
        .count();
    // Ten at once, then one a second: the run takes well under the seconds 30 more would need.
    assert!(
        (10..=15).contains(&warnings),
        "{warnings} warnings:\n{stderr}"
    );
    assert!(stderr.contains("more frame warnings held back"), "{stderr}");
    let stdout = text(&o.stdout);
    assert!(stdout.contains("40 TooFewResiduals"), "{stdout}");
}

#[test]
fn verbosity_follows_v_q_and_rust_log() {
    let dir = scratch("health-verbosity");
    let scans = write_frames(&dir, 1);
    let run = |extra: &[&str], rust_log: Option<&str>| {
        let out = dir.join("out");
        let mut args = vec![
            "run",
            scans.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let mut c = slamesh_command(&args);
        c.env_remove("RUST_LOG");
        if let Some(v) = rust_log {
            c.env("RUST_LOG", v);
        }
        text(&c.output().unwrap().stderr)
    };
    let normal = run(&[], None);
    assert!(
        normal.contains("slamesh: 4 scan files (times assumed 10 Hz"),
        "{normal}"
    );
    assert!(!normal.contains("slamesh: debug: "), "{normal}");
    let verbose = run(&["-v"], None);
    assert!(
        verbose.contains("slamesh: debug: frame 1: Converged, "),
        "{verbose}"
    );
    let quiet = run(&["-q"], None);
    assert!(
        !quiet.contains("frames from") && quiet.contains("TooFewResiduals"),
        "{quiet}"
    );
    let only_errors = run(&[], Some("error"));
    assert!(!only_errors.contains("slamesh: warning: "), "{only_errors}");
}

#[test]
fn recovered_frames_are_named_and_counted_but_do_not_fail_a_strict_run() {
    let dir = scratch("health-recovered");
    let scans = dir.join("scans");
    std::fs::create_dir_all(&scans).unwrap();
    let drive = slamesh_sim::Drive::carried(6, slamesh_sim::town::Carried::HANDHELD, 1);
    for i in 0..6 {
        write_bin(&scans.join(format!("{i:03}.bin")), &drive.scan(i));
    }
    let out = dir.join("out");
    // Without the scans' azimuth profiles, which spare these frames recovery.
    let config = dir.join("no-profiles.toml");
    std::fs::write(
        &config,
        "preset = \"default\"\n[register.recovery]\nprofile_turn_max_deg = 0\n",
    )
    .unwrap();
    let o = slamesh_run(
        &scans,
        &out,
        &["--strict", "--config", config.to_str().unwrap()],
    );
    let (stdout, stderr) = (text(&o.stdout), text(&o.stderr));
    assert!(o.status.success(), "{stderr}");
    assert!(
        stderr
            .lines()
            .any(|l| l.starts_with("slamesh: warning: frame ")
                && l.contains(".bin): Recovered: registration from its first start")
                && l.contains("register.recovery")),
        "{stderr}"
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let health = &report["summary"]["health"];
    let recovered = health["counts"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c[0] == "Recovered")
        .and_then(|c| c[1].as_u64())
        .unwrap_or(0);
    assert!(recovered >= 1, "{health}");
    assert!(
        stdout.contains(&format!("{recovered} Recovered")),
        "{stdout}"
    );
    assert_eq!(health["not_registered"], serde_json::json!([]));
}
