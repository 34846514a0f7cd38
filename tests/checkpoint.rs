//! `run --checkpoint-every N` and `--resume`: a run killed (SIGKILL) after a checkpoint,
//! then resumed, ends with the same trajectories and mesh as a run never interrupted, with
//! the sliding window evicting and saving cells on the way. Resuming without a checkpoint, or
//! with other settings, is a clear error.

use crate::common;

use common::{
    scratch, slamesh_command, slamesh_run, slamesh_run_ok, write_bin, write_folder_with_imu,
};
use slamesh::formats::ply::read_ply_mesh;
use slamesh::run::FrameSource;
use slamesh_sim::{Drive, ImuModel, Vibration};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

const FRAMES: usize = 24;
const OPTIONS: [&str; 6] = [
    "--threads",
    "1",
    "--evict-after",
    "3",
    "--save-evicted",
    "--preset=kitti",
];

/// The mesh's triangles as sorted corner bit patterns (the order of cells in the file may
/// differ: a resumed map is rebuilt in another order).
fn triangles(path: &Path) -> Vec<[[u32; 3]; 3]> {
    let mesh = read_ply_mesh(path).unwrap();
    let mut t: Vec<[[u32; 3]; 3]> = mesh
        .triangle_corners()
        .map(|c| c.map(|p| p.map(f32::to_bits)))
        .collect();
    t.sort_unstable();
    t
}

/// Runs the scans in `input` into `dir/whole`, then into `dir/cut` with a checkpoint every 3
/// frames, kills that run (SIGKILL) after its second checkpoint and resumes it, both with
/// `options`. Returns the two output folders and a copy of the checkpoint the kill left;
/// checks that the two wrote the same trajectories.
fn whole_and_resumed(input: &Path, dir: &Path, options: &[&str]) -> (PathBuf, PathBuf, PathBuf) {
    let (whole, cut) = (dir.join("whole"), dir.join("cut"));
    slamesh_run_ok(input, &whole, options);
    let mut args = vec![
        "run",
        input.to_str().unwrap(),
        "--out",
        cut.to_str().unwrap(),
        "-q",
        "--checkpoint-every",
        "3",
    ];
    args.extend_from_slice(options);
    let mut child = slamesh_command(&args)
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let checkpoint = cut.join("checkpoint.bin");
    let deadline = Instant::now() + Duration::from_secs(600);
    let mut seen = None;
    while Instant::now() < deadline {
        let m = checkpoint.metadata().and_then(|m| m.modified()).ok();
        if seen.is_some() && m != seen {
            break;
        }
        if seen.is_none() {
            seen = m;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(checkpoint.exists(), "no checkpoint within the deadline");
    let saved = dir.join("saved-checkpoint.bin");
    std::fs::copy(&checkpoint, &saved).unwrap();
    assert!(
        !cut.join("report.json").exists(),
        "the run finished before it was killed"
    );
    let mut resume = vec!["--checkpoint-every", "3", "--resume"];
    resume.extend_from_slice(options);
    slamesh_run_ok(input, &cut, &resume);
    for name in ["poses_kitti.txt", "poses_tum.txt"] {
        assert_eq!(
            std::fs::read_to_string(whole.join(name)).unwrap(),
            std::fs::read_to_string(cut.join(name)).unwrap(),
            "{name} differs after resuming"
        );
    }
    (whole, cut, saved)
}

#[test]
fn a_killed_run_resumes_to_the_same_outputs() {
    let dir = scratch("checkpoint");
    let input = dir.join("scans");
    std::fs::create_dir_all(&input).unwrap();
    let mut drive = Drive::town(FRAMES, 3);
    for i in 0..FRAMES {
        write_bin(&input.join(format!("{i:06}.bin")), &drive.read(i).unwrap());
    }
    let (whole, cut, saved) = whole_and_resumed(&input, &dir, &OPTIONS);
    let checkpoint = cut.join("checkpoint.bin");
    let mesh = triangles(&whole.join("mesh.ply"));
    assert!(mesh.len() > 1000, "a real mesh: {} triangles", mesh.len());
    assert_eq!(mesh, triangles(&cut.join("mesh.ply")));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(cut.join("report.json")).unwrap()).unwrap();
    let frames: Vec<u64> = report["frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f["frame"].as_u64().unwrap())
        .collect();
    assert_eq!(frames, (0..FRAMES as u64).collect::<Vec<_>>());
    assert!(report["summary"]["evicted_cells"].as_u64().unwrap() > 0);
    assert!(!checkpoint.exists(), "a finished run leaves no checkpoint");

    // Nothing to resume now; and the checkpoint of this run does not resume another one.
    let mut resume = vec!["--checkpoint-every", "3", "--resume"];
    resume.extend_from_slice(&OPTIONS);
    let o = slamesh_run(&input, &cut, &resume);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("checkpoint.bin") && err.contains("no checkpoint"),
        "{err}"
    );
    std::fs::copy(&saved, &checkpoint).unwrap();
    let other = ["--resume", "--preset=meshing", "--threads", "1"];
    let o = slamesh_run(&input, &cut, &other);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("checkpoint is of another run"), "{err}");
}

/// A run with an IMU (the shaken car, its readings in `imu0/data.csv` beside the scans) killed
/// and resumed writes what it writes uninterrupted: the readings held, the gyro's bias and the
/// checks carry across the checkpoint.
#[test]
fn a_killed_run_with_an_imu_resumes_to_the_same_outputs() {
    let dir = scratch("checkpoint-imu");
    let drive = Drive::car(FRAMES, 1)
        .shaken(Vibration::rough_road())
        .with_imu(ImuModel::mems(200.0, 7));
    let input = write_folder_with_imu(&drive, &dir);
    let (whole, cut, _) = whole_and_resumed(&input, &dir, &["--threads", "1"]);
    assert_eq!(
        triangles(&whole.join("mesh.ply")),
        triangles(&cut.join("mesh.ply"))
    );
    let imu = |out: &Path| {
        let text = std::fs::read_to_string(out.join("report.json")).unwrap();
        let report: serde_json::Value = serde_json::from_str(&text).unwrap();
        report["summary"]["imu"].clone()
    };
    let (a, b) = (imu(&whole), imu(&cut));
    assert_eq!(a["prior_frames"], FRAMES - 1, "{a}");
    assert_eq!(a, b);
}

/// Ctrl-C (SIGINT) on a run over files: it stops after the frame in progress, writes what it
/// has (trajectories, mesh, `report.json` saying where it stopped), leaves none of its spools
/// behind and exits with status 130.
#[test]
fn a_run_stopped_by_ctrl_c_writes_what_it_has() {
    let dir = scratch("ctrl-c");
    let input = dir.join("scans");
    std::fs::create_dir_all(&input).unwrap();
    let frames = 60;
    let mut drive = Drive::town(frames, 3);
    for i in 0..frames {
        write_bin(&input.join(format!("{i:06}.bin")), &drive.read(i).unwrap());
    }
    let out = dir.join("out");
    let (input_s, out_s) = (input.to_str().unwrap(), out.to_str().unwrap());
    let child = slamesh_command(&["run", input_s, "--out", out_s, "-q", "--threads", "1"])
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // After a few frames: the report's spool holds a line a frame.
    let spool = out.join(".report.frames.spool");
    let deadline = Instant::now() + Duration::from_secs(300);
    while Instant::now() < deadline {
        let lines = std::fs::read_to_string(&spool).map_or(0, |s| s.lines().count());
        if lines >= 3 {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    let pid = child.id().to_string();
    let sent = std::process::Command::new("kill")
        .args(["-INT", &pid])
        .status();
    assert!(sent.unwrap().success());
    let done = child.wait_with_output().unwrap();
    let said = String::from_utf8_lossy(&done.stderr);
    assert_eq!(done.status.code(), Some(130), "{said}");
    assert!(said.contains("interrupted before frame"), "{said}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let before = report["summary"]["interrupted"]
        .as_u64()
        .expect("where it stopped") as usize;
    assert!(
        (3..frames).contains(&before),
        "stopped before frame {before}"
    );
    let poses = std::fs::read_to_string(out.join("poses_kitti.txt")).unwrap();
    assert_eq!(
        poses.lines().count(),
        before,
        "a pose for each frame it ran"
    );
    assert_eq!(report["frames"].as_array().unwrap().len(), before);
    assert!(
        read_ply_mesh(&out.join("mesh.ply"))
            .unwrap()
            .triangles
            .len()
            > 100
    );
    let left: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(left.is_empty(), "spools left behind: {left:?}");
}
