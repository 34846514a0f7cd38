//! The pipeline's one entry point, [`Pipeline::step`]: a scan (raw or filtered already) and
//! what is known of its pose decide what is done with it.
//!
//! | known | done | status |
//! |---|---|---|
//! | [`Known::Nothing`] | registered against the map from the motion model's prediction, then fused | any but `Given`, `Relocalized`, `NotLocalized` |
//! | [`Known::Near`] | the same from a prior pose (an IMU's) in place of the prediction | as `Nothing` |
//! | [`Known::Pose`] | fused at that pose (meshing at poses from elsewhere) | `Given` |
//! | [`Known::Somewhere`] | searched for among candidates in a known map, fused when found | `Relocalized` or `NotLocalized` |
//!
//! Every caller (the command, Python, the firmware, the tests) goes through it; the two
//! shorthands [`Pipeline::process_scan`] and [`Pipeline::integrate_scan`] are calls of it on
//! one thread with no probe. Like every stage, it allocates nothing and does not panic on its
//! input: a scan it cannot use is refused with a [`ScanError`], the map and motion model
//! unchanged.

use super::{Pipeline, Relocalized, ScanError, ScanOutcome};
use crate::capacity::Capacity;
use crate::executor::{Executor, Serial};
use crate::filter::Filtered;
use crate::math::{Point, Pose};
use crate::real::Real;
use crate::relocalize::{Paging, Search};
use crate::stage::{NoProbe, Probe};

/// A scan as it reaches the pipeline.
#[derive(Debug, Clone, Copy)]
pub enum Scan<'a> {
    /// Sensor-frame points, as read: the pipeline filters and down-samples them.
    Raw(&'a [Point]),
    /// A scan filtered apart already, by a [`ScanFilter`](crate::filter::ScanFilter) (on
    /// another thread, say): the same result as its raw points, to the bit.
    Filtered(Filtered<'a>),
}

/// What is known of a scan's pose, which decides what the pipeline does with it.
pub enum Known<'a> {
    /// Nothing: the pose is estimated by registration against the map.
    Nothing,
    /// A prior for the pose (the IMU's rotation on the motion model's translation:
    /// [`crate::imu`]): estimated as with `Nothing`, from there instead of the motion model's
    /// prediction, and without the azimuth profiles' turn (the prior measured it). The first
    /// scan of a map is fused at it (a map levelled by gravity). A prior that is not finite
    /// refuses the frame ([`ScanError::BadPose`]).
    Near(Pose),
    /// The pose (world from sensor, from ground truth or an external odometry): the scan is
    /// fused there. A pose that is not finite refuses the frame ([`ScanError::BadPose`]).
    Pose(Pose),
    /// The sensor is somewhere in a known map, most likely near one of `candidates`: a search
    /// without a prediction (docs/design.md §1.13). Accepted, the motion model restarts from
    /// the pose found (and the scan is fused unless map updates are off); not accepted, the map
    /// and the motion model are unchanged, and the next scan may try again.
    Somewhere {
        /// Where to look first.
        candidates: &'a [Pose],
        /// How widely and how strictly.
        search: &'a Search,
        /// Makes the map hold what lies around each chunk of candidates and each registration
        /// ([`AllResident`](crate::relocalize::AllResident) when the whole map is resident).
        paging: &'a mut (dyn Paging + Send),
    },
}

/// What a step did with a scan it used.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Stepped {
    /// Estimated or given: the outcome.
    Scan(ScanOutcome),
    /// Searched for ([`Known::Somewhere`]): the outcome and what the search saw.
    Searched(Relocalized),
}

impl Stepped {
    /// The scan's outcome, however it was reached.
    pub fn outcome(&self) -> &ScanOutcome {
        match self {
            Stepped::Scan(o) => o,
            Stepped::Searched(r) => &r.outcome,
        }
    }

    /// [`outcome`](Self::outcome), by value.
    pub fn into_outcome(self) -> ScanOutcome {
        *self.outcome()
    }
}

impl<C: Capacity, R: Real> Pipeline<C, R> {
    /// Runs one scan through the pipeline: filters it (unless [`Scan::Filtered`]), then
    /// estimates, takes or searches for its pose as `known` says, and fuses it into the map.
    /// `exec` spreads the stages' work (results do not depend on it); `probe` is told the
    /// stage boundaries.
    pub fn step(
        &mut self,
        scan: Scan<'_>,
        known: Known<'_>,
        exec: &impl Executor,
        probe: &mut impl Probe,
    ) -> Result<Stepped, ScanError> {
        if let Known::Pose(pose) | Known::Near(pose) = &known {
            self.check_given(pose)?;
        }
        let stats = match scan {
            Scan::Raw(points) => self.begin(points, exec, probe)?,
            Scan::Filtered(filtered) => self.begin_filtered(filtered)?,
        };
        Ok(match known {
            Known::Nothing => Stepped::Scan(self.estimate(None, stats, exec, probe)),
            Known::Near(prior) => Stepped::Scan(self.estimate(Some(prior), stats, exec, probe)),
            Known::Pose(pose) => Stepped::Scan(self.integrate(&pose, stats, exec, probe)),
            Known::Somewhere {
                candidates,
                search,
                paging,
            } => Stepped::Searched(self.relocalize(stats, candidates, search, exec, probe, paging)),
        })
    }

    /// Estimates the pose of a scan (sensor-frame points) and fuses it into the map:
    /// [`step`](Self::step) with nothing known, on one thread.
    pub fn process_scan(&mut self, points_sensor: &[Point]) -> Result<ScanOutcome, ScanError> {
        self.step(
            Scan::Raw(points_sensor),
            Known::Nothing,
            &Serial,
            &mut NoProbe,
        )
        .map(Stepped::into_outcome)
    }

    /// Meshing only: fuses a scan into the map at a pose the caller knows (ground truth, an
    /// external odometry); later scans continue from it. [`step`](Self::step) with the pose
    /// known, on one thread.
    pub fn integrate_scan(
        &mut self,
        points_sensor: &[Point],
        t_world_sensor: &Pose,
    ) -> Result<ScanOutcome, ScanError> {
        let known = Known::Pose(*t_world_sensor);
        self.step(Scan::Raw(points_sensor), known, &Serial, &mut NoProbe)
            .map(Stepped::into_outcome)
    }
}
