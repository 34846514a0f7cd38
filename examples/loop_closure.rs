//! What loop closure changes (docs/design.md §1.14, docs/journal.md "Loop closure"): for
//! runs over a simulated town drive written by `write_drive`, the trajectory's end-point
//! error and ATE against the truth, the mesh's precision, recall and F1 against the true
//! surfaces, and the duplicated surfaces (one surface mapped twice, `eval::duplicates`) in
//! the whole map and within 60 m of where the drive came back.
//!
//! ```text
//! cargo run --release --example write_drive -- --out /tmp/campus --path campus --frames 3000
//! slamesh run /tmp/campus --out /tmp/campus-off --save-map /tmp/campus-off/map.slamesh
//! slamesh run /tmp/campus --out /tmp/campus-on --save-map /tmp/campus-on/map.slamesh --loop-closure on
//! cargo run --release --example loop_closure -- --path campus --frames 3000 --runs /tmp/campus-off,/tmp/campus-on
//! ```
//!
//! `--paced DIR --out OUT [--hz 10]` instead runs the KITTI-format folder DIR with loop
//! closure on as a live sensor would give it (each frame no sooner than its time at `--hz`),
//! and prints for each closure the frame it was found at and the frame it was applied before:
//! how long a correction takes to reach the tracking when the pipeline is not behind.
//!
//! `--oracle RUN` instead asks what the best closure could do on the drive (`--path`,
//! `--frames`): it takes RUN's trajectory as odometry (a run with no closure; for the pure
//! odometry, one with `map.stale_after_frames = 300`), joins every 5th frame that revisits
//! the path (within 3 m of a frame 100 m or more behind) to that earlier frame by a loop
//! edge carrying the *true* relative pose, solves the pose graph of every frame with the
//! loop-closure thread's weights (and with the odometry's weights 10 times stiffer and
//! looser), and prints the ATE before and after: the figure no detection can beat, since
//! its loop edges are exact and placed at every revisit.
//!
//! `--path campus|block|round` and `--frames N` (and `--seed S`, 1 by default) must be those
//! the drive was written with; each run folder (`--runs`, comma-separated) needs `poses_kitti.txt`, `mesh.ply` and
//! `map.slamesh`. `--closure-frame F` names the frame the drive comes back at (for the
//! duplicates near it; default: the first frame within 10 m of an earlier one 100 m behind).

#[path = "common/flags.rs"]
mod flags;

use flags::Flags;
use slamesh::demo::true_surface_scores;
use slamesh::eval::duplicates::duplicated_near;
use slamesh::eval::duplicates::duplicated_surfaces;
use slamesh::eval::odometry::{ate_rmse, distances_along, end_drift};
use slamesh::formats::map_file::MapFile;
use slamesh::formats::ply::read_ply_mesh;
use slamesh::formats::trajectory::read_kitti;
use slamesh::loop_closure::graph::{Edge, PoseGraph};
use slamesh::loop_closure::settings::LoopSettings;
use slamesh::loop_closure::{stage, LoopReport};
use slamesh::run::{FrameSource, Input, Run, RunOptions};
use slamesh_core::KittiCapacity;
use slamesh_core::Pose;
use slamesh_sim::Drive;
use std::path::PathBuf;
use std::time::{Duration, Instant};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let flags = Flags::from_env();
    if let Some(input) = flags.value("--paced") {
        return paced(&flags, input);
    }
    let oracle_run = flags.value("--oracle").map(PathBuf::from);
    let frames: usize = flags.parse_or("--frames", 1000)?;
    let seed: u64 = flags.parse_or("--seed", 1)?;
    let drive = match flags.value("--path") {
        Some("campus") => Drive::town_along(slamesh_sim::town::campus_path(), frames, seed),
        Some("block") => Drive::town_along(slamesh_sim::town::block_path(), frames, seed),
        Some("round") => Drive::town_round(frames, seed),
        _ => return Err("--path campus|block|round is required".into()),
    };
    let to_first = drive.poses[0].inverse();
    let truth: Vec<Pose> = drive.poses.iter().map(|p| to_first * p).collect();
    if let Some(run) = oracle_run {
        return oracle(&run, &truth);
    }
    let runs: Vec<PathBuf> = flags
        .value("--runs")
        .ok_or("--runs DIR,DIR,... is required")?
        .split(',')
        .map(PathBuf::from)
        .collect();
    let back = match flags.value("--closure-frame") {
        Some(f) => f.parse()?,
        None => comes_back(&truth).ok_or("the drive never comes back: --closure-frame F")?,
    };
    println!(
        "{} frames; the drive comes back at frame {back}; truth for the mesh from every 5th frame",
        truth.len()
    );
    println!("run | end point (m) | ATE (m) | P / R / F1 at 0.1 m | duplicates: all, within 60 m of the return");
    for run in &runs {
        let estimate = read_kitti(&run.join("poses_kitti.txt"))?;
        let n = estimate.len().min(truth.len());
        let (end_m, _) = end_drift(&estimate[..n], &truth[..n]);
        let ate = ate_rmse(&estimate[..n], &truth[..n]);
        let mesh: Vec<_> = read_ply_mesh(&run.join("mesh.ply"))?
            .triangle_corners()
            .collect();
        let (s, _) = true_surface_scores(&drive, &mesh, 1, &[0.1]);
        let map = MapFile::open(&run.join("map.slamesh"))?.load_new()?;
        let max_var = 0.3;
        let all = duplicated_surfaces(&map, max_var, 0.3, |_| true);
        let near = duplicated_near(&map, max_var, 0.3, &truth[back], 60.0);
        println!(
            "{} | {end_m:.3} | {ate:.4} | {:.3} / {:.3} / {:.3} | {all}, {near}",
            run.display(),
            s[0].precision,
            s[0].recall,
            s[0].f1
        );
    }
    Ok(())
}

/// The first frame within 10 m of a frame more than 100 m of path behind it.
fn comes_back(poses: &[Pose]) -> Option<usize> {
    let travelled = distances_along(poses);
    (0..poses.len()).find(|&i| {
        (0..i).any(|j| {
            travelled[i] - travelled[j] > 100.0
                && (poses[i].translation.vector - poses[j].translation.vector).norm() < 10.0
        })
    })
}

/// The `--oracle` figures (see the module docs).
fn oracle(run: &std::path::Path, truth: &[Pose]) -> Result<(), Box<dyn std::error::Error>> {
    let estimate = read_kitti(&run.join("poses_kitti.txt"))?;
    let n = estimate.len().min(truth.len());
    let (estimate, truth) = (&estimate[..n], &truth[..n]);
    let travelled = distances_along(truth);
    println!(
        "{}: {n} frames; ATE {:.4} m, end point {:.3} m before",
        run.display(),
        ate_rmse(estimate, truth),
        end_drift(estimate, truth).0
    );
    // The thread's weights, then the odometry's rotation and translation each 10 times
    // stiffer and looser: the bound should not hang on one choice of weights.
    let base = LoopSettings::default();
    for (rotation, translation) in [(1.0, 1.0), (0.1, 1.0), (10.0, 1.0), (1.0, 0.1), (1.0, 10.0)] {
        let s = LoopSettings {
            odometry_sigma_deg: base.odometry_sigma_deg * rotation,
            odometry_sigma_m: base.odometry_sigma_m * translation,
            ..base
        };
        let (graph, loops) = exact_loops(&s, estimate, truth, &travelled)?;
        println!(
            "  odometry sigmas x{rotation} rotation, x{translation} translation: {loops} exact loop edges; ATE {:.4} m, end point {:.3} m after",
            ate_rmse(&graph.nodes, truth),
            end_drift(&graph.nodes, truth).0
        );
    }
    Ok(())
}

/// The pose graph of every frame of `estimate` (odometry edges with `s`'s random walk) with an
/// exact loop edge from every 5th frame that revisits the true path to the nearest earlier
/// frame, solved; and the number of loop edges.
fn exact_loops(
    s: &LoopSettings,
    estimate: &[Pose],
    truth: &[Pose],
    travelled: &[f64],
) -> Result<(PoseGraph, usize), Box<dyn std::error::Error>> {
    let n = estimate.len();
    let inverse = |m: nalgebra::Matrix6<f64>| m.try_inverse().ok_or("singular covariance");
    let mut graph = PoseGraph {
        nodes: estimate.to_vec(),
        edges: Vec::new(),
    };
    for i in 1..n {
        graph.edges.push(Edge {
            a: i - 1,
            b: i,
            z: estimate[i - 1].inverse() * estimate[i],
            info: inverse(s.odometry_covariance(travelled[i] - travelled[i - 1]))?,
        });
    }
    let loop_info = inverse(s.loop_covariance())?;
    let mut loops = 0;
    for i in (0..n).step_by(5) {
        let earlier = (0..i)
            .filter(|&j| travelled[i] - travelled[j] >= 100.0)
            .map(|j| {
                (
                    j,
                    (truth[i].translation.vector - truth[j].translation.vector).norm(),
                )
            })
            .filter(|&(_, d)| d < 3.0)
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((j, _)) = earlier {
            graph.edges.push(Edge {
                a: j,
                b: i,
                z: truth[j].inverse() * truth[i],
                info: loop_info,
            });
            loops += 1;
        }
    }
    graph.optimize(10);
    Ok((graph, loops))
}

/// The `--paced` run (see the module docs).
fn paced(flags: &Flags, input: &str) -> Result<(), Box<dyn std::error::Error>> {
    let hz: f64 = flags.parse_or("--hz", 10.0)?;
    let out = PathBuf::from(flags.value("--out").ok_or("--out DIR is required")?);
    let mut source = Input::open(std::path::Path::new(input), None, Default::default())?;
    let settings = LoopSettings::default();
    let mut config = slamesh_core::Config::default();
    settings.configure(&mut config);
    let opts = RunOptions {
        out,
        config,
        preset: "default".into(),
        threads: 2,
        input: input.into(),
        loop_closure: Some(settings),
        ..RunOptions::default()
    };
    let started = Instant::now();
    let mut run = Run::<KittiCapacity>::start(&source, &opts)?;
    for i in 0..source.frames() {
        let due = Duration::from_secs_f64(i as f64 / hz);
        if let Some(wait) = due.checked_sub(started.elapsed()) {
            std::thread::sleep(wait);
        }
        run.step(&mut source, i)?;
    }
    let summary = run.finish(&source)?;
    let report: LoopReport = summary.stage(stage::NAME).unwrap_or_default();
    println!(
        "{} frames at {hz} Hz in {:.1} s; {} closures, {} corrections, {} rebuilds",
        summary.used,
        started.elapsed().as_secs_f64(),
        report.closures.len(),
        report.corrections,
        report.rebuilds
    );
    for c in &report.closures {
        println!(
            "closure found at frame {} (with {}), applied before frame {:?}",
            c.frame, c.with_frame, c.applied_at_frame
        );
    }
    Ok(())
}
