//! How loop closure is run (docs/design.md §1.14): keyframes, the reach of the search for a
//! revisit, when a closure is accepted, the pose graph's weights and when the map is rebuilt.

use nalgebra::{Matrix6, Vector6};

/// Loop-closure settings. [`Default`] is what the command uses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LoopSettings {
    /// A new keyframe after this much travel (m) ...
    pub keyframe_m: f64,
    /// ... or this much turn (degrees) since the last one.
    pub keyframe_deg: f64,
    /// A keyframe is checked for a revisit at most once per this much travel (m).
    pub check_every_m: f64,
    /// Frames less than this far behind along the path (m) are never a revisit.
    pub min_travel_m: f64,
    /// The odometry's drift allowed for: a frame `d` metres of path behind may be a revisit
    /// when within `reach_m + reach_per_m · d` of the current pose.
    pub reach_m: f64,
    /// See `reach_m` (metres of drift a metre of path).
    pub reach_per_m: f64,
    /// The pose found may turn from the odometry's by at most `turn_deg + turn_per_m · d`.
    pub turn_deg: f64,
    /// See `turn_deg` (degrees a metre of path).
    pub turn_per_m: f64,
    /// The local map is made of the earlier frames within the reach plus this (m) ...
    pub submap_margin_m: f64,
    /// ... at most this many of them, evenly spaced.
    pub submap_frames: usize,
    /// Two checked revisits agree when their corrections differ by less than this (m) ...
    pub agree_m: f64,
    /// ... and this (degrees). A closure is accepted only when one agrees with the one
    /// before it.
    pub agree_deg: f64,
    /// The odometry's standard deviation a square-root metre of travel: translation (m) ...
    pub odometry_sigma_m: f64,
    /// ... and rotation (degrees).
    pub odometry_sigma_deg: f64,
    /// A loop edge's standard deviation: translation (m) ...
    pub loop_sigma_m: f64,
    /// ... and rotation (degrees).
    pub loop_sigma_deg: f64,
    /// The map is rebuilt when a frame's corrected pose moves more than this (m) ...
    pub rebuild_m: f64,
    /// ... or turns more than this (degrees) from where the map has it.
    pub rebuild_deg: f64,
    /// What the run's `map.stale_after_frames` is set to when loop closure is on and the
    /// configuration leaves it at 0: a revisit before its closure is mapped afresh, and the
    /// odometry does not snap onto the drifted first copy.
    pub stale_after_frames: u32,
    /// The most disk the scans kept for rebuilds may take (MB): about 85 KB a 64-beam street
    /// frame, so 2 000 MB hold some 23 000 frames (40 minutes at 10 Hz). Loop closure stops
    /// there, saying so, and the run goes on without it.
    pub spool_budget_mb: f64,
}

impl LoopSettings {
    /// Sets what a run with loop closure needs of its configuration: `map.stale_after_frames`
    /// to [`LoopSettings::stale_after_frames`] unless the configuration sets it already.
    pub fn configure(&self, config: &mut slamesh_core::Config) {
        if config.map.stale_after_frames == 0 {
            config.map.stale_after_frames = self.stale_after_frames;
        }
    }

    /// The odometry's drift over `metres` of travel (twist order `(ω, ρ)`): a random walk of
    /// `odometry_sigma_m` and `odometry_sigma_deg` a square-root metre, the floor under an
    /// odometry edge's own covariance.
    pub fn odometry_covariance(&self, metres: f64) -> Matrix6<f64> {
        let d = metres.max(0.1).sqrt();
        covariance(self.odometry_sigma_m * d, self.odometry_sigma_deg * d)
    }

    /// What a loop edge's covariance adds to its registration's.
    pub fn loop_covariance(&self) -> Matrix6<f64> {
        covariance(self.loop_sigma_m, self.loop_sigma_deg)
    }
}

/// Diagonal covariance for standard deviations `m` (translation) and `deg` (rotation).
fn covariance(m: f64, deg: f64) -> Matrix6<f64> {
    let (r, t) = (deg.to_radians().powi(2), m * m);
    Matrix6::from_diagonal(&Vector6::new(r, r, r, t, t, t))
}

impl Default for LoopSettings {
    fn default() -> Self {
        Self {
            keyframe_m: 2.0,
            keyframe_deg: 15.0,
            check_every_m: 4.0,
            min_travel_m: 50.0,
            reach_m: 3.0,
            reach_per_m: 0.02,
            turn_deg: 3.0,
            turn_per_m: 0.005,
            submap_margin_m: 20.0,
            submap_frames: 30,
            agree_m: 0.3,
            agree_deg: 0.5,
            odometry_sigma_m: 0.005,
            odometry_sigma_deg: 0.01,
            loop_sigma_m: 0.02,
            loop_sigma_deg: 0.01,
            rebuild_m: 0.05,
            rebuild_deg: 0.1,
            stale_after_frames: 300,
            spool_budget_mb: 2_000.0,
        }
    }
}
