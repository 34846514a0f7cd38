//! What processing one scan reports: how its registration ended ([`RegistrationStatus`]), why
//! a scan was refused ([`ScanError`]), and its per-stage counts ([`ScanStats`],
//! [`ScanOutcome`]).

use crate::associate::AssociateStats;
use crate::bucket::BucketStats;
use crate::filter::FilterStats;
use crate::fusion::FusionStats;
use crate::math::Pose;
use core::fmt;

/// How registration of one scan ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RegistrationStatus {
    /// The map was empty: the scan started it at the predicted pose.
    FirstScan,
    /// Every round solved.
    Converged,
    /// The geometry left some direction unconstrained (a tunnel, a plane): the pose was
    /// corrected only in the directions the scan constrains and keeps the motion prediction
    /// in the others ([`ScanStats::degenerate_directions`] says how many). If it constrained
    /// none, the pose keeps the rounds before (the motion prediction if it was the first).
    Degenerate,
    /// A round had too few residuals: as for `Degenerate`.
    TooFewResiduals,
    /// The solver met non-finite numbers: as for `Degenerate`.
    SolverFailed,
    /// Registration from its first start (the motion prediction, or the turn the scans'
    /// azimuth profiles found) did not converge; it did from another guess (docs/design.md
    /// §1.11). The pose is that guess's.
    Recovered,
    /// Registration converged from no guess: the pose is the best attempt's by
    /// [`Verdict::score`](crate::recovery::Verdict::score), and may be wrong. With recovery
    /// off, the prediction's attempt that did not converge.
    NotConverged,
    /// The pose was given ([`Pipeline::integrate_scan`](super::Pipeline::integrate_scan)).
    Given,
    /// The pose was found in a known map without a prediction
    /// ([`Known::Somewhere`](super::Known::Somewhere)).
    Relocalized,
    /// A search for the pose in a known map found no convincing one: the map and the motion
    /// model are unchanged, and the pose given is the best attempt's, not to be trusted.
    NotLocalized,
}

impl RegistrationStatus {
    /// Every status, in the order of declaration (the order reports list them in).
    pub const ALL: [RegistrationStatus; 10] = [
        RegistrationStatus::FirstScan,
        RegistrationStatus::Converged,
        RegistrationStatus::Degenerate,
        RegistrationStatus::TooFewResiduals,
        RegistrationStatus::SolverFailed,
        RegistrationStatus::Recovered,
        RegistrationStatus::NotConverged,
        RegistrationStatus::Given,
        RegistrationStatus::Relocalized,
        RegistrationStatus::NotLocalized,
    ];

    /// The status's name, as reports and messages write it (the variant's name).
    pub const fn name(self) -> &'static str {
        match self {
            RegistrationStatus::FirstScan => "FirstScan",
            RegistrationStatus::Converged => "Converged",
            RegistrationStatus::Degenerate => "Degenerate",
            RegistrationStatus::TooFewResiduals => "TooFewResiduals",
            RegistrationStatus::SolverFailed => "SolverFailed",
            RegistrationStatus::Recovered => "Recovered",
            RegistrationStatus::NotConverged => "NotConverged",
            RegistrationStatus::Given => "Given",
            RegistrationStatus::Relocalized => "Relocalized",
            RegistrationStatus::NotLocalized => "NotLocalized",
        }
    }

    /// The status named `name` ([`name`](Self::name)'s inverse).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }

    /// Registered normally: the first scan, converged, meshed at a given pose, or found in a
    /// known map. Any other status is worth a look (and fails a strict run).
    pub const fn is_normal(self) -> bool {
        matches!(
            self,
            RegistrationStatus::FirstScan
                | RegistrationStatus::Converged
                | RegistrationStatus::Given
                | RegistrationStatus::Relocalized
        )
    }

    /// Registered, normally or not: the normal statuses and [`Recovered`](Self::Recovered)
    /// (named and counted, but not a failure).
    pub const fn is_registered(self) -> bool {
        self.is_normal() || matches!(self, RegistrationStatus::Recovered)
    }
}

impl fmt::Display for RegistrationStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Why a scan was not used. The map and motion model are unchanged.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ScanError {
    /// No point survived the filter (all non-finite, out of range, or none given).
    EmptyScan {
        /// What the filter did.
        stats: FilterStats,
        /// The range limits it applied, `filter.range_min_m` and `filter.range_max_m` (m).
        range_m: [f64; 2],
    },
    /// The given pose is not finite.
    BadPose,
}

impl fmt::Display for ScanError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ScanError::EmptyScan { stats: s, range_m } => {
                write!(f, "empty scan: none of {} points usable", s.input)?;
                let far = s.out_of_range - s.too_near;
                let mut parts = 0;
                let mut part = |f: &mut fmt::Formatter<'_>, n: usize, what: fmt::Arguments| {
                    if n == 0 {
                        return Ok(());
                    }
                    parts += 1;
                    write!(f, "{}{n} {what}", if parts == 1 { " (" } else { ", " })
                };
                part(f, s.non_finite, format_args!("not finite"))?;
                part(
                    f,
                    s.too_near,
                    format_args!(
                        "closer than filter.range_min_m = {} m: lower it for a sensor this close",
                        range_m[0]
                    ),
                )?;
                part(
                    f,
                    far,
                    format_args!(
                        "farther than filter.range_max_m = {} m: raise it for a scene this large",
                        range_m[1]
                    ),
                )?;
                if parts > 0 {
                    write!(f, ")")?;
                }
                Ok(())
            }
            ScanError::BadPose => write!(f, "the given pose is not finite"),
        }
    }
}

impl core::error::Error for ScanError {}

/// What happened to one scan, stage by stage.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ScanStats {
    /// Index of the scan (counts every call, accepted or not).
    pub frame: u32,
    /// Range filter and down-sampling.
    pub filter: FilterStats,
    /// Bucketing of the reconstruction fused into the map.
    pub bucket: BucketStats,
    /// Layers fused into the map.
    pub scan_layers: usize,
    /// Layers dropped because the scan's layer buffer was full (summed over rounds).
    pub dropped_layers: usize,
    /// Association of the last round.
    pub associate: AssociateStats,
    /// Registration rounds run.
    pub rounds: usize,
    /// LM iterations over all rounds.
    pub lm_iterations: usize,
    /// Conditioning of the last solved round: the mean squared normal component along its
    /// weakest direction (see [`crate::lm`]).
    pub conditioning: f64,
    /// Directions the last solved round left to the motion prediction (0 to 6).
    pub degenerate_directions: usize,
    /// How well the last solved round pinned the pose down (zeros when none was solved).
    pub information: crate::lm::PoseInformation,
    /// How far the scan lies from the map at the pose found: the root mean square of the last
    /// solved round's residuals (metres, Huber-weighted; 0 when none was solved). Of two ways
    /// to prepare the same scans, the one whose scans lie closer registers better.
    pub residual_rms_m: f64,
    /// Guesses registered from after the prediction's registration did not converge
    /// (docs/design.md §1.11); 0 on a frame that converged.
    pub recovery_attempts: usize,
    /// Map update.
    pub fusion: FusionStats,
    /// Set when this scan started the map again ([`MapRestart`]).
    pub map_restart: Option<MapRestart>,
}

/// The map was started again from a scan (status `FirstScan`): the scan it had been started
/// from kept far fewer points, and this one could not register against what it gave
/// ([`BASE_POINTS_RATIO`](super::BASE_POINTS_RATIO)). What the earlier scans put in the map
/// is gone; their poses stand as they were, unchecked.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MapRestart {
    /// The frame the map had been started from.
    pub base_frame: u32,
    /// Its points after the filter.
    pub base_points: usize,
}

/// What [`Pipeline::step`](super::Pipeline::step) did with a scan it used.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanOutcome {
    /// The estimated sensor pose in the world (the first scan's frame).
    pub t_world_sensor: Pose,
    /// How registration ended.
    pub status: RegistrationStatus,
    /// Per-stage counts.
    pub stats: ScanStats,
}

#[cfg(test)]
mod tests {
    use super::RegistrationStatus;

    #[test]
    fn every_status_is_listed_once_and_named_as_its_variant() {
        for (i, s) in RegistrationStatus::ALL.into_iter().enumerate() {
            assert_eq!(s as usize, i, "ALL is in the order of declaration");
            assert_eq!(alloc::format!("{s:?}"), s.name());
            assert_eq!(RegistrationStatus::from_name(s.name()), Some(s));
        }
        assert_eq!(RegistrationStatus::from_name("Skipped"), None);
        assert!(RegistrationStatus::Recovered.is_registered());
        assert!(!RegistrationStatus::Recovered.is_normal());
        assert!(!RegistrationStatus::NotConverged.is_registered());
    }
}
