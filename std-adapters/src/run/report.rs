//! What a run reports: a record per frame, the summary, the per-stage spreads, the frames'
//! health and what each outcome cost. The files they are written to are sinks of
//! [`crate::run::files`].

use crate::io::error::FileError;
use crate::outputs::mesh_spool::MeshSpool;
use crate::outputs::topview::map::{self, MapPicture};
use crate::parallel::Workers;
use crate::run::status::FrameStatus;
use crate::run::timing::StageMs;
use crate::stage::Notes;
use serde::{Deserialize, Serialize};
use slamesh_core::layer::Shown;
use slamesh_core::{Capacity, Config, Pipeline, Pose, RegistrationStatus, ScanStats};
use std::collections::BTreeMap;
use std::path::Path;

/// What happened to one frame (a line of `report.json`).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FrameRecord {
    /// Frame index.
    pub frame: usize,
    /// Its file.
    pub file: String,
    /// The registration status (`FirstScan`, `Converged`, `Degenerate`, ...), or `Skipped`.
    pub status: FrameStatus,
    /// Why it was skipped.
    pub error: Option<String>,
    /// Why it was not registered normally (statuses `Degenerate`, `TooFewResiduals`,
    /// `SolverFailed`, `Recovered`, `NotConverged`), naming the parameter involved; or why a
    /// `FirstScan` after the first started the map again
    /// ([`MapRestart`](slamesh_core::MapRestart)).
    pub reason: Option<String>,
    /// Milliseconds per stage.
    pub ms: StageMs,
    /// Points read.
    pub points: usize,
    /// Points the reader dropped before: a recording's NaN and no-return (all-zero) points.
    #[serde(default)]
    pub points_dropped_by_reader: usize,
    /// Points after filtering and down-sampling.
    pub points_kept: usize,
    /// Cells of the scan reconstructed.
    pub scan_cells: usize,
    /// Layers of the scan.
    pub scan_layers: usize,
    /// Cells in the map after the frame.
    pub map_cells: usize,
    /// Layers in the map after the frame.
    pub map_layers: usize,
    /// Triangles of the cells this frame updated.
    pub triangles_updated: usize,
    /// Cells evicted after this frame.
    pub evicted_cells: usize,
    /// Conditioning of the registration: the mean squared normal component along its
    /// weakest direction (0 to 1/3; small is weak).
    pub conditioning: f64,
    /// How far the scan lay from the map at its pose: the root mean square of the last
    /// solve's residuals (m; [`ScanStats::residual_rms_m`](slamesh_core::ScanStats)).
    #[serde(default)]
    pub residual_rms_m: f64,
    /// Directions registration left to the motion model (see the `Degenerate` status).
    pub degenerate_directions: usize,
    /// Registration rounds run (each a reconstruction, an association and a solve), recovery's
    /// and polishing's included.
    #[serde(default)]
    pub rounds: usize,
    /// Guesses registered from after the prediction's registration did not converge
    /// (docs/design.md §1.11); 0 on a frame that converged.
    #[serde(default)]
    pub recovery_attempts: usize,
    /// Resident memory after the frame (MB).
    pub rss_mb: Option<f64>,
    /// Points moved by deskewing (0: the scan had no point times, or was not deskewed).
    #[serde(default)]
    pub deskewed_points: usize,
    /// The frame's time (seconds): a recording's header stamp, a folder's `times.txt` or file
    /// name, or the assumed 10 Hz.
    #[serde(default)]
    pub stamp: f64,
    /// The frame's stamp exactly, in nanoseconds, when the source had it
    /// ([`FrameSource::stamp_ns`](crate::sources::FrameSource::stamp_ns)): what the ROS 2
    /// node's replies carry. Not in `report.json` (`stamp` is).
    #[serde(skip)]
    pub stamp_ns: Option<i64>,
    /// A live input: milliseconds from the frame's last packet to its pose.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub latency_ms: Option<f64>,
    /// Samples that are not scans (an IMU's readings) the source gave with this frame.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub samples: usize,
    /// What the run's stages noted for the frame, each under its key
    /// ([`crate::stage::RunStage::used`], [`fused`](crate::stage::RunStage::fused),
    /// [`correct`](crate::stage::RunStage::between); each stage's module says what it notes),
    /// and why a stage doubts it (`doubts`).
    #[serde(flatten)]
    pub notes: Notes,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

impl FrameRecord {
    /// The record of frame `frame` from `file` before anything is known of it: skipped, until
    /// the pipeline says otherwise.
    pub fn skipped(frame: usize, file: String) -> Self {
        FrameRecord {
            frame,
            file,
            status: FrameStatus::Skipped,
            error: None,
            reason: None,
            ms: StageMs::default(),
            points: 0,
            points_dropped_by_reader: 0,
            points_kept: 0,
            scan_cells: 0,
            scan_layers: 0,
            map_cells: 0,
            map_layers: 0,
            triangles_updated: 0,
            evicted_cells: 0,
            conditioning: 0.0,
            residual_rms_m: 0.0,
            degenerate_directions: 0,
            rounds: 0,
            recovery_attempts: 0,
            rss_mb: None,
            deskewed_points: 0,
            stamp: 0.0,
            stamp_ns: None,
            latency_ms: None,
            samples: 0,
            notes: Notes::default(),
        }
    }

    /// Takes the counts of the pipeline's `stats` for the frame.
    pub fn take_stats(&mut self, stats: &ScanStats) {
        self.points_kept = stats.filter.kept;
        self.scan_cells = stats.bucket.cells;
        self.scan_layers = stats.scan_layers;
        self.conditioning = stats.conditioning;
        self.residual_rms_m = stats.residual_rms_m;
        self.degenerate_directions = stats.degenerate_directions;
        self.rounds = stats.rounds;
        self.recovery_attempts = stats.recovery_attempts;
    }
}

/// Median and 95th percentile of one stage (ms).
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct Spread {
    /// Median.
    pub median: f64,
    /// 95th percentile.
    pub p95: f64,
}

/// The end of a run (the `summary` of `report.json`).
#[derive(Debug, Clone, Default, Serialize)]
pub struct Summary {
    /// Frames in the input.
    pub frames: usize,
    /// Frames used.
    pub used: usize,
    /// Frames skipped, with their reasons.
    pub skipped: Vec<String>,
    /// Wall time of the frame loop (seconds).
    pub seconds: f64,
    /// Used frames per second of wall time.
    pub hz: f64,
    /// Reconstruction threads.
    pub threads: usize,
    /// The capacity class ([`slamesh_core::Capacity::NAME`]).
    pub capacity: String,
    /// Median and 95th percentile per stage over used frames (ms).
    pub stage_ms: Vec<(String, Spread)>,
    /// What each registration outcome's frames cost ([`cost_by_outcome`]).
    pub cost_by_outcome: Vec<OutcomeCost>,
    /// The mesh written.
    pub mesh_vertices: u64,
    /// The mesh written.
    pub mesh_triangles: u64,
    /// Map cells at the end.
    pub map_cells: usize,
    /// Map layers at the end.
    pub map_layers: usize,
    /// Cells evicted during the run.
    pub evicted_cells: usize,
    /// Layer budget under the memory cap, if one was set.
    pub max_layers: Option<usize>,
    /// The memory cap's shares and the peak the kernel counted, if a cap was set.
    pub memory_budget: Option<crate::run::budget::MemoryBudget>,
    /// Peak resident memory of the process (MB).
    pub peak_rss_mb: Option<f64>,
    /// Frames by status, and those not registered normally.
    pub health: Health,
    /// What the input's reader counted (a capture's or a live stream's packets, gaps, dropped
    /// sweeps).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub input: Option<serde_json::Value>,
    /// The run's stages' parts, each under its name ([`crate::stage::RunStage::summary`];
    /// each stage's module says what its part holds).
    #[serde(flatten)]
    pub stages: BTreeMap<String, serde_json::Value>,
    /// The first frame not run when the run was stopped before its input ended (Ctrl-C,
    /// [`crate::run::RunOptions::stop`]): the outputs hold the frames before it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub interrupted: Option<usize>,
    /// The files this run wrote into the output folder (the stages' with the run's own);
    /// `report.json` last.
    pub files: Vec<String>,
    /// The estimated (or given) pose of each used frame, frame index first.
    #[serde(skip)]
    pub poses: Vec<(usize, Pose)>,
    /// Each used frame's stamp (seconds), in the order of [`poses`](Self::poses).
    #[serde(skip)]
    pub stamps: Vec<f64>,
}

impl Summary {
    /// The part of the summary the stage named `name` gave ([`Summary::stages`]), read as a
    /// `T` (the IMU's [`crate::inertial::ImuSummary`], say); `None` when it gave none.
    pub fn stage<T: serde::de::DeserializeOwned>(&self, name: &str) -> Option<T> {
        serde_json::from_value(self.stages.get(name)?.clone()).ok()
    }
}

/// How the run's frames went.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Health {
    /// Frames by status (`Converged`, `Degenerate`, ..., `Skipped`), the statuses seen, in
    /// the order of [`RegistrationStatus`]'s variants then `Skipped`.
    pub counts: Vec<(String, usize)>,
    /// Each frame not registered normally, in frame order.
    pub not_registered: Vec<NotRegistered>,
    /// Each frame a stage doubts, in frame order, with the stage's status and reason: a frame
    /// the IMU's readings did not cover, run on the motion model (`ImuGap`, the uncovered
    /// time).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub doubted: Vec<NotRegistered>,
}

/// A frame not registered normally.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NotRegistered {
    /// Frame index.
    pub frame: usize,
    /// Its file.
    pub file: String,
    /// Its status (`Skipped` when it could not be read or used).
    pub status: String,
    /// Why, with the parameter involved where there is one.
    pub reason: String,
}

impl Health {
    /// The health of the frames whose records `records` gives, in frame order (taken one at a
    /// time: none is kept but those not registered normally).
    pub fn of<R: std::borrow::Borrow<FrameRecord>>(
        records: impl IntoIterator<Item = Result<R, FileError>>,
    ) -> Result<Self, FileError> {
        let mut counts = [0usize; FrameStatus::ALL.len()];
        let mut not_registered = Vec::new();
        let mut doubted = Vec::new();
        for r in records {
            let r = r?;
            let r = r.borrow();
            for (status, why) in &r.notes.doubts {
                doubted.push(NotRegistered {
                    frame: r.frame,
                    file: r.file.clone(),
                    status: status.clone(),
                    reason: why.clone(),
                });
            }
            if let Some(k) = FrameStatus::ALL.iter().position(|s| *s == r.status) {
                counts[k] += 1;
            }
            if !r.status.is_registered() {
                not_registered.push(NotRegistered {
                    frame: r.frame,
                    file: r.file.clone(),
                    status: r.status.to_string(),
                    reason: r
                        .error
                        .clone()
                        .or_else(|| r.reason.clone())
                        .unwrap_or_default(),
                });
            }
        }
        let counts = (FrameStatus::ALL.iter())
            .zip(counts)
            .filter(|(_, n)| *n > 0)
            .map(|(s, n)| (s.to_string(), n))
            .collect();
        Ok(Health {
            counts,
            not_registered,
            doubted,
        })
    }

    /// The health and [`cost_by_outcome`] of the frame records spooled in `frames` (one JSON
    /// object a line), in one pass that reads a line at a time.
    pub fn of_spool(frames: &Path) -> Result<(Self, Vec<OutcomeCost>), FileError> {
        let file = std::fs::File::open(frames)
            .map_err(|e| FileError::at(frames, format!("cannot read: {e}")))?;
        let lines = std::io::BufRead::lines(std::io::BufReader::new(file));
        let mut costs = Vec::new();
        let health = Self::of(lines.enumerate().map(|(i, line)| {
            let bad = |reason: String| FileError::new(frames, Some(i + 1), reason);
            let line = line.map_err(|e| bad(format!("cannot read: {e}")))?;
            let r = serde_json::from_str::<FrameRecord>(&line)
                .map_err(|e| bad(format!("bad record: {e}")))?;
            costs.push(Cost::of(&r));
            Ok(r)
        }))?;
        Ok((health, group_costs(costs)))
    }

    /// `8 Converged, 1 FirstScan, 1 TooFewResiduals`.
    pub fn counts_line(&self) -> String {
        let parts: Vec<String> = self
            .counts
            .iter()
            .map(|(s, n)| format!("{n} {s}"))
            .collect();
        parts.join(", ")
    }
}

/// Why a scan that was registered with `status` was not registered normally, naming the
/// parameter involved; `None` for a normal status.
pub fn registration_reason(
    status: RegistrationStatus,
    stats: &ScanStats,
    config: &Config,
) -> Option<String> {
    let lm = &config.register.lm;
    match status {
        RegistrationStatus::FirstScan => stats.map_restart.map(|r| {
            format!(
                "the map starts again here: frame {} had started it with {} points after the \
                 filter, under 1/{} of this scan's {}, and this scan could not register \
                 against what it gave; the map keeps none of it, and the poses before this \
                 frame are assumed, not measured",
                r.base_frame,
                r.base_points,
                slamesh_core::pipeline::BASE_POINTS_RATIO,
                stats.filter.kept
            )
        }),
        RegistrationStatus::Converged
        | RegistrationStatus::Given
        | RegistrationStatus::Relocalized => None,
        RegistrationStatus::NotLocalized => Some(
            "no pose in the map explained the scan convincingly (see the relocalization's \
             scores); the frame has no pose and the next one searches again"
                .into(),
        ),
        RegistrationStatus::Degenerate if stats.degenerate_directions >= 6 => Some(format!(
            "no direction constrained (weakest {:.4}); the pose is the motion prediction",
            stats.conditioning
        )),
        RegistrationStatus::Degenerate => Some(format!(
            "{} of 6 directions unconstrained (weakest {:.4}, below register.lm.degenerate_ratio \
             = {}) kept the motion prediction",
            stats.degenerate_directions, stats.conditioning, lm.degenerate_ratio
        )),
        RegistrationStatus::TooFewResiduals => Some(format!(
            "{} surface matches with the map, fewer than register.lm.min_residuals = {}; the \
             pose is the motion prediction",
            stats.associate.residuals, lm.min_residuals
        )),
        RegistrationStatus::SolverFailed => {
            Some("the solver's correction was not finite; the pose is the motion prediction".into())
        }
        RegistrationStatus::Recovered => Some(format!(
            "registration from its first start (the motion prediction, or the turn the scans' \
             azimuth profiles found) did not converge; it did from guess {} of register.recovery \
             (1: where the first start ended, with more rounds; next the prediction, if the first \
             start was the profiles'; later: the last pose turned in yaw), {} surface matches",
            stats.recovery_attempts, stats.associate.residuals
        )),
        RegistrationStatus::NotConverged => Some(format!(
            "registration converged neither from its first start nor from {} guesses of \
             register.recovery (none settled with register.recovery.accept_share = {} of its \
             layers matched); the pose is the best attempt's ({} surface matches for {} layers) \
             and may be wrong",
            stats.recovery_attempts,
            config.register.recovery.accept_share,
            stats.associate.residuals,
            stats.scan_layers,
        )),
    }
}

/// Median and 95th percentile of each stage over `ms`, in [`StageMs::NAMES`] order.
pub fn spreads(ms: &[StageMs]) -> Vec<(String, Spread)> {
    (0..StageMs::NAMES.len())
        .map(|k| {
            let v: Vec<f64> = ms.iter().map(|m| m.values()[k]).collect();
            (StageMs::NAMES[k].to_string(), Spread::of(v))
        })
        .collect()
}

impl Spread {
    /// The median and 95th percentile of `v` (the nearest rank; 0 for none).
    pub fn of(mut v: Vec<f64>) -> Self {
        v.sort_by(f64::total_cmp);
        let at = |q: f64| {
            v.get(((v.len() as f64 - 1.0) * q).round() as usize)
                .copied()
                .unwrap_or(0.0)
        };
        Spread {
            median: at(0.5),
            p95: at(0.95),
        }
    }
}

/// What the frames of one registration outcome (`Converged`, `Recovered`, ...) cost: a hard
/// motion's price in time.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OutcomeCost {
    /// The status.
    pub status: String,
    /// Its frames.
    pub frames: usize,
    /// Their whole time per frame (milliseconds): median and 95th percentile.
    pub median_ms: f64,
    /// See [`median_ms`](Self::median_ms).
    pub p95_ms: f64,
    /// Registration rounds a frame, on average (each a reconstruction, an association and a
    /// solve).
    pub rounds: f64,
    /// Recovery's guesses a frame, on average.
    pub recovery_attempts: f64,
}

/// What one frame cost: its status, whole time (ms), registration rounds and recovery's
/// guesses.
struct Cost {
    status: FrameStatus,
    ms: f64,
    rounds: usize,
    guesses: usize,
}

impl Cost {
    fn of(r: &FrameRecord) -> Self {
        Cost {
            status: r.status,
            ms: r.ms.total,
            rounds: r.rounds,
            guesses: r.recovery_attempts,
        }
    }
}

/// Each outcome's cost from its frames' records (whole time, rounds, recovery's guesses), the
/// commonest first; skipped frames are left out.
pub fn cost_by_outcome<'a>(frames: impl IntoIterator<Item = &'a FrameRecord>) -> Vec<OutcomeCost> {
    group_costs(frames.into_iter().map(Cost::of))
}

fn group_costs(costs: impl IntoIterator<Item = Cost>) -> Vec<OutcomeCost> {
    let mut by: Vec<(FrameStatus, Vec<Cost>)> = Vec::new();
    for c in costs {
        if c.status == FrameStatus::Skipped {
            continue;
        }
        match by.iter_mut().find(|(s, _)| *s == c.status) {
            Some((_, v)) => v.push(c),
            None => by.push((c.status, vec![c])),
        }
    }
    let mut out: Vec<OutcomeCost> = by
        .into_iter()
        .map(|(status, v)| {
            let frames = v.len();
            let mean =
                |f: fn(&Cost) -> usize| v.iter().map(|c| f(c) as f64).sum::<f64>() / frames as f64;
            let s = Spread::of(v.iter().map(|c| c.ms).collect());
            OutcomeCost {
                status: status.to_string(),
                frames,
                median_ms: s.median,
                p95_ms: s.p95,
                rounds: mean(|c| c.rounds),
                recovery_attempts: mean(|c| c.guesses),
            }
        })
        .collect();
    out.sort_by(|a, b| b.frames.cmp(&a.frames).then(a.status.cmp(&b.status)));
    out
}

/// Metres of map around the path that the picture shows.
pub(crate) const PICTURE_MARGIN_M: f64 = 40.0;
/// Pixels on the picture's long side.
pub(crate) const PICTURE_PIXELS: usize = 1000;

/// Writes `file`, a PNG of the spooled mesh from above with `path`
/// ([`crate::outputs::topview::map`]: a roof over the path cut away, start and end marked, a scale
/// bar, a colour scale and a legend): heights coloured from 3 m below the first sensor pose to
/// the mesh's top (2 to 20 m), covering the path and [`PICTURE_MARGIN_M`] around it,
/// [`PICTURE_PIXELS`] on its long side (7 bytes a pixel while it is drawn: 7 MB). The mesh
/// is read from the spool twice. Nothing is written for an empty path.
pub(crate) fn write_topview(
    spool: &mut MeshSpool,
    path: &[Pose],
    file: &Path,
) -> Result<(), FileError> {
    if path.is_empty() {
        return Ok(());
    }
    let how = MapPicture {
        pixels: PICTURE_PIXELS,
        margin_m: PICTURE_MARGIN_M,
        z_lo: -3.0,
        z_top: spool.z_range().1.clamp(2.0, 20.0),
    };
    let (mut view, _) = map::draw(|f| spool.for_each_triangle(|t, _| f(t)), path, None, how)?;
    view.write_png(file)
}

/// Triangles of the map layers the last scan updated (the mesh a viewer would refresh).
pub(crate) fn updated_triangles<C: Capacity>(pipeline: &Pipeline<C>, workers: &Workers) -> usize {
    let shown = Shown::new(&pipeline.config().mesh);
    let lattice = pipeline.map().lattice().table();
    let map = pipeline.map();
    workers.sum(pipeline.last_scan(), |s| {
        map.layer(&s.key, s.axis)
            .map_or(0, |l| l.shown_mask(&lattice, shown).count_ones() as usize)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outcomes_are_counted_and_timed_the_commonest_first() {
        let frames = [
            ("Converged", 10.0, 2, 0),
            ("Recovered", 80.0, 10, 1),
            ("Converged", 12.0, 2, 0),
            ("Skipped", 1.0, 0, 0),
            ("Converged", 11.0, 3, 0),
            ("Recovered", 60.0, 14, 3),
        ]
        .map(|(s, ms, rounds, attempts)| FrameRecord {
            status: FrameStatus::from_name(s).unwrap(),
            ms: StageMs {
                total: ms,
                ..StageMs::default()
            },
            rounds,
            recovery_attempts: attempts,
            ..FrameRecord::skipped(0, String::new())
        });
        let c = cost_by_outcome(&frames);
        assert_eq!(c.len(), 2, "skipped frames are left out");
        assert_eq!((c[0].status.as_str(), c[0].frames), ("Converged", 3));
        assert_eq!((c[0].median_ms, c[0].p95_ms), (11.0, 12.0));
        assert_eq!((c[1].status.as_str(), c[1].frames), ("Recovered", 2));
        assert_eq!(c[1].median_ms, 80.0);
        assert_eq!((c[0].rounds, c[0].recovery_attempts), (7.0 / 3.0, 0.0));
        assert_eq!((c[1].rounds, c[1].recovery_attempts), (12.0, 2.0));
        assert_eq!(
            Spread::of(Vec::new()),
            Spread {
                median: 0.0,
                p95: 0.0
            }
        );
    }
}
