//! Hard motion: a hand-held scanner and a drone carried through the simulated town, 2 scans a
//! second with turns of up to 45 degrees and tilts of up to 15 degrees between scans, seen by
//! a 32-beam sensor. Runs the pipeline with a preset and prints, per drive, how each step's
//! relative pose compares with the truth, the share of steps within 5 cm and 0.5 degree, the
//! ATE and the statuses: what the code does today on motion the constant-velocity guess gets
//! wrong.
//!
//! `--signals` also prints, for the steps tracked (within 5 cm and 0.5 degree) and those lost,
//! the range of each candidate signal for telling them apart: the share of the scan's layers
//! that found a match in the map in the last round, the share of the fused layers that were
//! new to the map, the LM iterations and the conditioning. The town's car drive (10 Hz) is
//! added as a drive that tracks.
//!
//! `--drive NAME` runs that drive alone (`hand-held`, `drone` or `car`: the town's car drive,
//! without `--signals` too). `--scalar f32` reconstructs in single precision
//! (`Pipeline<_, f32>`, the firmware's) instead of `f64`. Each drive also prints the median
//! milliseconds a frame.
//!
//! `cargo run --release --example hard_motion -- [--frames N] [--preset NAME | --config FILE] [--seed S] [--drive NAME] [--scalar f32] [--steps] [--signals]`

#[path = "common/flags.rs"]
mod flags;

use flags::Flags;
use slamesh::eval::odometry::{ate_rmse, consecutive_errors};
use slamesh::parallel::Workers;
use slamesh::run::config_file;
use slamesh_core::pipeline::{Known, Scan, Stepped};
use slamesh_core::{Lidar32Capacity, NoProbe, Pipeline, Point, Pose, ScanError, ScanOutcome};
use slamesh_sim::town::Carried;
use slamesh_sim::Drive;
use std::collections::BTreeMap;
use std::time::Instant;

/// A pipeline in either scalar.
enum Tracker {
    Double(Box<Pipeline<Lidar32Capacity>>),
    Single(Box<Pipeline<Lidar32Capacity, f32>>),
}

impl Tracker {
    fn process(&mut self, scan: &[Point], workers: &Workers) -> Result<ScanOutcome, ScanError> {
        let stepped = match self {
            Tracker::Double(p) => p.step(Scan::Raw(scan), Known::Nothing, workers, &mut NoProbe),
            Tracker::Single(p) => p.step(Scan::Raw(scan), Known::Nothing, workers, &mut NoProbe),
        };
        stepped.map(Stepped::into_outcome)
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let flags = Flags::from_env();
    let frames: usize = flags.parse_or("--frames", 60)?;
    let seed: u64 = flags.parse_or("--seed", 1)?;
    let preset = flags.value("--preset").unwrap_or("default");
    let steps = flags.has("--steps");
    let signals = flags.has("--signals");
    let only = flags.value("--drive");
    let single = match flags.value("--scalar").unwrap_or("f64") {
        "f64" => false,
        "f32" => true,
        other => return Err(format!("--scalar {other}: f32 or f64").into()),
    };
    // Per step: tracked or not, and the signals.
    let mut seen: Vec<(bool, [f64; 4])> = Vec::new();
    let config = match flags.value("--config") {
        Some(path) => config_file::read(std::path::Path::new(path))?.config,
        None => config_file::preset(preset).ok_or("unknown preset")?,
    };
    let workers = Workers::new(0)?;
    let drives = [
        ("hand-held", Some(Carried::HANDHELD)),
        ("drone", Some(Carried::DRONE)),
        ("car", None),
    ];
    for (name, how) in drives {
        if only.map_or(how.is_none() && !signals, |d| d != name) {
            continue;
        }
        let drive = match how {
            Some(how) => Drive::carried(frames, how, seed),
            None => Drive::town(frames, seed),
        };
        let truth: Vec<Pose> = drive
            .poses
            .iter()
            .map(|p| drive.poses[0].inverse() * p)
            .collect();
        let mut pipeline = if single {
            Tracker::Single(Box::new(Pipeline::new(config)?))
        } else {
            Tracker::Double(Box::new(Pipeline::new(config)?))
        };
        let Tracked {
            mut ms,
            estimate,
            statuses,
            step_signals,
            frame_status,
        } = track(&mut pipeline, &drive, frames, &workers);
        let good = judge_steps(
            name,
            &truth,
            &estimate,
            &step_signals,
            &frame_status,
            steps,
            &mut seen,
        );
        let c = consecutive_errors(&estimate, &truth);
        ms.sort_by(f64::total_cmp);
        println!(
            "{name} ({preset}, {}, {frames} scans at {} Hz): {good} of {} steps within 5 cm and 0.5 deg; \
             mean step error {:.2} cm, worst {:.2} cm, {:.3} deg; ATE {:.3} m; median {:.1} ms a frame; {statuses:?}",
            if single { "f32" } else { "f64" },
            if how.is_some() { 2 } else { 10 },
            frames - 1,
            c.mean_translation_m * 100.0,
            c.max_translation_m * 100.0,
            c.mean_rotation_deg,
            ate_rmse(&estimate, &truth),
            ms[ms.len() / 2]
        );
    }
    if signals {
        print_signals(&seen);
    }
    Ok(())
}

/// What tracking one drive gave, frame by frame.
struct Tracked {
    /// Each frame's time (ms).
    ms: Vec<f64>,
    /// Each frame's pose (the last one again for a rejected frame).
    estimate: Vec<Pose>,
    /// Frames by outcome.
    statuses: BTreeMap<String, usize>,
    /// Each frame's signals: matched share of layers, new share of fused layers, LM
    /// iterations, conditioning.
    step_signals: Vec<[f64; 4]>,
    /// Each frame's outcome in words.
    frame_status: Vec<String>,
}

/// Runs `pipeline` over the first `frames` scans of `drive`.
fn track(pipeline: &mut Tracker, drive: &Drive, frames: usize, workers: &Workers) -> Tracked {
    let mut ms = Vec::with_capacity(frames);
    let mut estimate = Vec::with_capacity(frames);
    let mut statuses: BTreeMap<String, usize> = BTreeMap::new();
    let mut step_signals = vec![[f64::NAN; 4]; frames];
    let mut frame_status = Vec::with_capacity(frames);
    for (i, signals_i) in step_signals.iter_mut().enumerate() {
        let scan = drive.scan(i);
        let start = Instant::now();
        let result = pipeline.process(&scan, workers);
        ms.push(start.elapsed().as_secs_f64() * 1e3);
        let status = match result {
            Ok(o) => {
                estimate.push(o.t_world_sensor);
                let st = &o.stats;
                let layers = st.scan_layers.max(1) as f64;
                let fused = (st.fusion.fused + st.fusion.added).max(1) as f64;
                *signals_i = [
                    st.associate.residuals as f64 / layers,
                    st.fusion.added as f64 / fused,
                    st.lm_iterations as f64,
                    st.conditioning,
                ];
                format!("{:?}", o.status)
                    + &match st.recovery_attempts {
                        0 => String::new(),
                        n => format!(" after {n} guesses"),
                    }
                    + &format!(" ({} rounds)", st.rounds)
            }
            Err(e) => {
                estimate.push(*estimate.last().unwrap_or(&Pose::identity()));
                format!("rejected ({e})")
            }
        };
        let kind = status
            .split([' ', '('])
            .next()
            .unwrap_or_default()
            .to_string();
        *statuses.entry(kind).or_default() += 1;
        frame_status.push(status);
    }
    Tracked {
        ms,
        estimate,
        statuses,
        step_signals,
        frame_status,
    }
}

/// Each signal's spread over the tracked and the lost steps.
fn print_signals(seen: &[(bool, [f64; 4])]) {
    let names = [
        "matched share of layers",
        "new share of fused layers",
        "LM iterations",
        "conditioning",
    ];
    for (k, name) in names.iter().enumerate() {
        for tracked in [true, false] {
            let mut v: Vec<f64> = seen
                .iter()
                .filter(|(g, s)| *g == tracked && s[k].is_finite())
                .map(|(_, s)| s[k])
                .collect();
            v.sort_by(f64::total_cmp);
            if v.is_empty() {
                continue;
            }
            let q = |f: f64| v[((v.len() - 1) as f64 * f).round() as usize];
            println!(
                "{name}, {} steps ({}): min {:.3}, 5 % {:.3}, median {:.3}, 95 % {:.3}, max {:.3}",
                if tracked { "tracked" } else { "lost" },
                v.len(),
                q(0.0),
                q(0.05),
                q(0.5),
                q(0.95),
                q(1.0)
            );
        }
    }
}

/// Counts the steps within 5 cm and 0.5 degree of the truth, keeping each step's signals in
/// `seen`; with `steps`, prints each step.
fn judge_steps(
    name: &str,
    truth: &[Pose],
    estimate: &[Pose],
    step_signals: &[[f64; 4]],
    frame_status: &[String],
    steps: bool,
    seen: &mut Vec<(bool, [f64; 4])>,
) -> usize {
    let mut good = 0;
    for i in 1..estimate.len() {
        let step = |p: &[Pose]| p[i - 1].inverse() * p[i];
        let e = step(truth).inverse() * step(estimate);
        let (t, r) = (e.translation.vector.norm(), e.rotation.angle().to_degrees());
        let turn = step(truth).rotation.angle().to_degrees();
        if t <= 0.05 && r <= 0.5 {
            good += 1;
        }
        seen.push((t <= 0.05 && r <= 0.5, step_signals[i]));
        if steps {
            let v = e.translation.vector * 100.0;
            println!(
                "{name} step {i}: turn {turn:.1} deg; error {:.2} cm ({:.2}, {:.2}, {:.2} in the sensor frame), {r:.3} deg; {}",
                t * 100.0,
                v.x,
                v.y,
                v.z,
                frame_status[i]
            );
        }
    }
    good
}
