//! `--sweep auto`: which way a folder's sensor turns and where its sweep starts, found from the
//! first scans. Each candidate (no times at all, or either turn from each of four starts)
//! runs the first [`TRIAL_FRAMES`] frames as the run will, and the one whose scans lie
//! closest to the map they build wins: the median of the converged frames' residuals
//! ([`FrameRecord::residual_rms_m`]). A sweep turning the wrong way, or cut in the wrong place,
//! bends each scan where the right one straightens it; scans that came deskewed already (KITTI
//! odometry's) are bent by any. Where the scans cannot tell (too few frames, none converged),
//! they keep no times.
//!
//! Where the stamp sits in the sweep cannot be told from the points: the candidates take the
//! sweep's start, as most drivers stamp (`--sweep TURN:START_DEG:STAMP_SHARE` says otherwise).

use crate::cli::error::CliError;
use crate::io::FileError;
use crate::run::capacity;
use crate::run::report::Spread;
use crate::run::{run, FrameRecord, FrameSource, Input, RunOptions};
use crate::sources::sweep_times::SweepSpec;
use slamesh_core::Point;
use std::path::Path;

/// Frames each candidate runs.
pub const TRIAL_FRAMES: usize = 24;

/// The frames a candidate's score is read from start here: the motion model has two poses,
/// so that the scans are deskewed.
const FIRST_SCORED: usize = 2;

/// A candidate wins over no times only if its median residual is at least this much smaller:
/// a sweep's times are not taken on a difference within the noise.
const MARGIN: f64 = 0.02;

/// The first frames of a source.
struct FirstFrames<'a> {
    source: &'a mut Input,
    frames: usize,
}

impl FrameSource for FirstFrames<'_> {
    fn frames(&self) -> usize {
        self.source.frames().min(self.frames)
    }
    fn label(&self, i: usize) -> String {
        self.source.label(i)
    }
    fn stamp(&self, i: usize) -> f64 {
        self.source.stamp(i)
    }
    fn read(&mut self, i: usize) -> Result<Vec<Point>, FileError> {
        self.source.read(i)
    }
    fn read_timed(&mut self, i: usize) -> Result<(Vec<Point>, Option<Vec<f32>>), FileError> {
        self.source.read_timed(i)
    }
    fn samples(&mut self, i: usize) -> Vec<crate::run::Sample> {
        self.source.samples(i)
    }
}

/// What the trial found: the sweep chosen (`None`: no times) and every candidate's score.
#[derive(Debug, Clone)]
pub struct Trial {
    /// The sweep chosen.
    pub chosen: Option<SweepSpec>,
    /// Each candidate's name and median residual (m; `None`: no frame converged).
    pub scores: Vec<(String, Option<f64>)>,
}

impl Trial {
    /// The trial in words, for the log and the report.
    pub fn describe(&self) -> String {
        let scores: Vec<String> = (self.scores.iter())
            .map(|(name, s)| match s {
                Some(s) => format!("{name} {:.1} mm", s * 1e3),
                None => format!("{name} -"),
            })
            .collect();
        format!(
            "--sweep auto chose {} over the first {TRIAL_FRAMES} frames (median residual: {})",
            self.chosen.as_ref().map_or("off", |s| s.name.as_str()),
            scores.join(", ")
        )
    }
}

/// The candidates: no times, then each turn from each of four starts, stamped at the start.
fn candidates() -> Vec<Option<SweepSpec>> {
    let mut out = vec![None];
    for turn in ["ccw", "cw"] {
        for start in [0, 90, 180, 270] {
            out.push(
                SweepSpec::parse(&format!("{turn}:{start}:0"))
                    .ok()
                    .flatten(),
            );
        }
    }
    out
}

/// Runs the candidates over the first frames of what `open` opens, each into a folder of its
/// own under `scratch` (removed after), with `opts` less its outputs.
pub fn choose(
    open: impl Fn() -> Result<Input, FileError>,
    input: &Path,
    opts: &RunOptions,
    scratch: &Path,
) -> Result<Trial, CliError> {
    let trial_opts = RunOptions {
        out: scratch.to_path_buf(),
        mesh_formats: Vec::new(),
        picture: false,
        loop_closure: None,
        navmap: None,
        save_map: None,
        checkpoint_every: None,
        resume: false,
        ..opts.clone()
    };
    let mut scores = Vec::new();
    for spec in candidates() {
        let mut source = open()?;
        if let Some(spec) = &spec {
            source.time_from_sweep(input, spec)?;
        }
        let mut first = FirstFrames {
            source: &mut source,
            frames: TRIAL_FRAMES,
        };
        let class = capacity::choose(&mut first, &trial_opts).id;
        let mut residuals = Vec::new();
        let keep = |r: &FrameRecord| {
            if r.frame >= FIRST_SCORED && r.status == "Converged" {
                residuals.push(r.residual_rms_m);
            }
        };
        crate::with_capacity!(class, C => run::<C>(&mut first, &trial_opts, keep))?;
        // Each candidate's pipeline freed before the next takes its own.
        crate::run::memory::release_freed();
        let name = spec.as_ref().map_or("off".to_string(), |s| s.name.clone());
        let median = (!residuals.is_empty()).then(|| Spread::of(residuals).median);
        scores.push((spec, name, median));
    }
    let _ = std::fs::remove_dir_all(scratch);
    Ok(pick(scores))
}

/// The candidate with the smallest median, if it beats no times by [`MARGIN`].
fn pick(scores: Vec<(Option<SweepSpec>, String, Option<f64>)>) -> Trial {
    let off = scores.first().and_then(|s| s.2);
    let best = (scores.iter())
        .filter_map(|(spec, _, s)| Some((spec, (*s)?)))
        .min_by(|a, b| a.1.total_cmp(&b.1));
    let chosen = match (best, off) {
        (Some((spec, s)), Some(off)) if s < off * (1.0 - MARGIN) => spec.clone(),
        _ => None,
    };
    Trial {
        chosen,
        scores: scores.into_iter().map(|(_, n, s)| (n, s)).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(s: &str) -> Option<SweepSpec> {
        SweepSpec::parse(s).unwrap()
    }

    #[test]
    fn the_closest_candidate_wins_only_by_a_margin_over_no_times() {
        let scores = |a: f64, b: f64| {
            vec![
                (None, "off".to_string(), Some(a)),
                (spec("ccw:0:0"), "ccw:0:0".into(), Some(b)),
                (spec("cw:0:0"), "cw:0:0".into(), None),
            ]
        };
        let t = pick(scores(0.030, 0.024));
        assert_eq!(t.chosen.map(|s| s.name), Some("ccw:0:0".into()));
        assert_eq!(pick(scores(0.030, 0.0299)).chosen, None);
        assert_eq!(pick(scores(0.020, 0.024)).chosen, None);
        let t = pick(scores(0.030, 0.024));
        assert!(t
            .describe()
            .contains("off 30.0 mm, ccw:0:0 24.0 mm, cw:0:0 -"));
        assert_eq!(candidates().len(), 9);
    }
}
