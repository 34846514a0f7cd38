//! The pipeline: composes the stages for each scan (docs/design.md §1.1). Holds no math of its own.
//!
//! Per scan: filter → predict → (bucket → reconstruct → associate → LM) × rounds (from other
//! guesses as well when that did not converge: `pipeline/register.rs`) → bucket → reconstruct → fuse; or, without `MapConfig::reconstruct_at_final_pose`, the last round's
//! reconstruction moved to the final pose → fuse. One entry point, [`Pipeline::step`]
//! (`pipeline/step.rs`), takes a scan and what is known of its pose: nothing (estimate it), the
//! pose (mesh there) or a search over a known map. Every buffer is allocated in
//! [`Pipeline::new`] at the capacities of `C`; nothing is allocated afterwards.

use crate::azimuth::AzimuthProfile;
use crate::bounded::BoundedVec;
use crate::bucket::{bucket, BucketStats, CellSpan, Placement};
use crate::capacity::{Capacity, KittiCapacity};
use crate::cell::CellKey;
use crate::config::Config;
#[cfg(any(feature = "alloc", test))]
use crate::config::ConfigError;
use crate::executor::Executor;
use crate::filter::{filter_and_downsample, FilterStats, Filtered};
use crate::fusion::{face, integrate};
use crate::layer::ScanLayer;
use crate::lm::Residual;
use crate::map::MeshMap;
use crate::math::{Point, Pose};
use crate::mesh::{self, Triangle};
use crate::motion::ConstantVelocity;
use crate::real::Real;
use crate::reconstruct::{reconstruct_cells, Purpose, ReconstructStats};
use crate::sort::KeySorter;
use crate::stage::{Probe, Stage};
use core::marker::PhantomData;

mod clear;
mod outcome;
mod register;
mod relocalize;
mod step;

pub use outcome::{MapRestart, RegistrationStatus, ScanError, ScanOutcome, ScanStats};
pub use relocalize::Relocalized;
pub use step::{Known, Scan, Stepped};

/// LiDAR odometry and meshing with capacities `C`, reconstructing in the scalar `R` (`f64`, or
/// `f32` for an FPU with single precision only: [`crate::real`]). Cloning (feature `alloc`)
/// copies the map and every buffer into memory from the global allocator, like
/// [`Pipeline::new`].
#[derive(Debug)]
#[cfg_attr(feature = "alloc", derive(Clone))]
pub struct Pipeline<C: Capacity = KittiCapacity, R: Real = f64> {
    config: Config,
    map: MeshMap,
    motion: ConstantVelocity,
    frame: u32,
    points: BoundedVec<Point>,
    work: BoundedVec<(CellKey, Point)>,
    sorter: KeySorter,
    cells: BoundedVec<CellSpan>,
    scan: BoundedVec<ScanLayer>,
    residuals: BoundedVec<Residual>,
    /// Whether scans are fused into the map (off: localization in a fixed map).
    map_updates: bool,
    /// The last frame's number and its scan's azimuth profile ([`crate::azimuth`]).
    last_profile: Option<(u32, AzimuthProfile)>,
    /// The scan the map was started from, while no registration against the map has
    /// converged since ([`MapBase`]).
    base: Option<MapBase>,
    /// The capacity and the reconstruction's scalar ([`Real`]) are types only: the pipeline
    /// holds none of them (and is `Send` whatever they are).
    _types: PhantomData<fn() -> (C, R)>,
}

impl<C: Capacity, R: Real> Pipeline<C, R> {
    /// A pipeline with an empty map, all buffers allocated now (feature `alloc`; see
    /// [`in_storage`](Self::in_storage) for none).
    #[cfg(any(feature = "alloc", test))]
    pub fn new(config: Config) -> Result<Self, ConfigError> {
        Self::with_map_layers(config, C::MAP_LAYERS)
    }

    /// A pipeline whose map holds at most `layers` layers and as many cells (each at most
    /// the capacity's), all buffers allocated now: for a run that keeps its map small (a
    /// sliding window under a memory cap), the map's table and pool are allocated for what it
    /// will hold, and cost [`Capacity::memory_bytes_with_map_layers`] at most. A new layer or
    /// cell past the limit is refused and counted, as past the capacity.
    #[cfg(any(feature = "alloc", test))]
    pub fn with_map_layers(config: Config, layers: usize) -> Result<Self, ConfigError> {
        Self::with_limits(config, crate::ScanLimits::of::<C>(), layers)
    }

    /// [`with_map_layers`](Self::with_map_layers) with scan buffers of `limits` (each at
    /// most the capacity's): for a pipeline that only fuses and searches scans already
    /// filtered (a loop-closure thread under a memory cap), whose buffers cost
    /// [`ScanLimits::bytes`](crate::ScanLimits::bytes) instead of [`Capacity::scan_bytes`].
    #[cfg(any(feature = "alloc", test))]
    pub fn with_limits(
        config: Config,
        limits: crate::ScanLimits,
        layers: usize,
    ) -> Result<Self, ConfigError> {
        config.validate()?;
        let limits = limits.within::<C>();
        let (cells, layers) = (layers.min(C::MAP_CELLS), layers.min(C::MAP_LAYERS));
        Ok(Self::assemble(
            config,
            MeshMap::with_capacity(cells, layers, config.lattice()),
            (
                BoundedVec::with_capacity(limits.points),
                BoundedVec::with_capacity(limits.points),
            ),
            KeySorter::with_capacity(limits.sort_entries::<C>()),
            BoundedVec::with_capacity(limits.cells),
            BoundedVec::with_capacity(limits.layers),
            BoundedVec::with_capacity(limits.layers),
        ))
    }

    /// A pipeline from its map and buffers.
    pub(crate) fn assemble(
        config: Config,
        map: MeshMap,
        (points, work): (BoundedVec<Point>, BoundedVec<(CellKey, Point)>),
        sorter: KeySorter,
        cells: BoundedVec<CellSpan>,
        scan: BoundedVec<ScanLayer>,
        residuals: BoundedVec<Residual>,
    ) -> Self {
        Self {
            map,
            config,
            motion: ConstantVelocity::new(),
            frame: 0,
            last_profile: None,
            base: None,
            points,
            work,
            sorter,
            cells,
            scan,
            residuals,
            map_updates: true,
            _types: PhantomData,
        }
    }

    /// The layers fused from the last accepted scan, at its final pose: the cells it
    /// updated in the map (e.g. to refresh a mesh view incrementally).
    pub fn last_scan(&self) -> &[ScanLayer] {
        &self.scan
    }

    /// The last scan's points as filtered and down-sampled, in the sensor frame (what it was
    /// registered and fused with).
    pub fn last_points(&self) -> &[Point] {
        &self.points
    }

    /// The configuration.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// The map.
    pub fn map(&self) -> &MeshMap {
        &self.map
    }

    /// The map alone: the scan buffers are given back (freed, or their caller storage left
    /// unused), for a program that has registered its last scan and goes on to write the map.
    pub fn into_map(self) -> MeshMap {
        self.map
    }

    /// The map, mutably (for eviction).
    pub fn map_mut(&mut self) -> &mut MeshMap {
        &mut self.map
    }

    /// Number of scans given so far.
    pub fn frames(&self) -> u32 {
        self.frame
    }

    /// The motion model (its history is what a checkpoint saves besides the map).
    pub fn motion(&self) -> &ConstantVelocity {
        &self.motion
    }

    /// Continues from saved progress: `frames` scans given so far and the motion model's
    /// history. With the map restored through [`map_mut`](Self::map_mut), the next scan is
    /// processed exactly as it would have been without the interruption.
    pub fn restore_progress(&mut self, frames: u32, motion: ConstantVelocity) {
        self.frame = frames;
        self.motion = motion;
        self.last_profile = None;
        self.base = None;
    }

    /// Whether scans are fused into the map (the default), or only registered against it:
    /// localization in a fixed map, which also skips the map update's reconstruction.
    pub fn set_map_updates(&mut self, on: bool) {
        self.map_updates = on;
    }

    /// See [`set_map_updates`](Self::set_map_updates).
    pub fn map_updates(&self) -> bool {
        self.map_updates
    }

    /// The newest pose, if any scan was accepted.
    pub fn pose(&self) -> Option<Pose> {
        self.motion.last()
    }

    /// The map's shown triangles (`mesh.variance_show`, `mesh.max_slope_deg`), without allocation.
    pub fn triangles(&self) -> impl Iterator<Item = Triangle> + '_ {
        mesh::triangles(&self.map, &self.config.mesh)
    }

    /// Registration of the filtered scan from `prior` (or the motion model's prediction), then
    /// the map update.
    fn estimate(
        &mut self,
        prior: Option<Pose>,
        mut stats: ScanStats,
        exec: &impl Executor,
        probe: &mut impl Probe,
    ) -> ScanOutcome {
        let mut pose = prior.unwrap_or_else(|| self.motion.predict());
        let mut status = RegistrationStatus::FirstScan;
        // The last round's reconstruction when it is also the map update's (see
        // `MapConfig::reconstruct_at_final_pose`): its bucketing and the pose it was made at.
        let mut for_update: Option<(BucketStats, Pose)> = None;
        // Kept up to date with a prior too, for the frames that come without one.
        let profile_yaw = self
            .turn_by_profile(stats.frame)
            .filter(|_| prior.is_none());
        if !self.map.is_empty() {
            let best = self.register_scan(pose, profile_yaw, exec, probe, &mut stats);
            stats.associate = best.associate;
            stats.conditioning = best.conditioning;
            stats.degenerate_directions = best.degenerate_directions;
            stats.information = best.information;
            stats.residual_rms_m = best.residual_rms_m;
            (pose, status, for_update) = (best.pose, best.status, best.for_update);
        }
        if let Some(base) = self.base_to_drop(status, &stats) {
            // The map rests on a scan too small to register against: it starts again here,
            // where that scan was (or at the prior), with no motion history.
            self.map.clear();
            self.motion = ConstantVelocity::new();
            pose = prior.unwrap_or(base.pose);
            (status, for_update) = (RegistrationStatus::FirstScan, None);
            stats = ScanStats {
                frame: stats.frame,
                filter: stats.filter,
                map_restart: Some(MapRestart {
                    base_frame: base.frame,
                    base_points: base.points,
                }),
                ..ScanStats::default()
            };
        }
        match status {
            _ if !self.map_updates => self.base = None,
            RegistrationStatus::FirstScan => {
                self.base = Some(MapBase {
                    frame: stats.frame,
                    points: stats.filter.kept,
                    pose,
                })
            }
            RegistrationStatus::Converged | RegistrationStatus::Recovered => self.base = None,
            _ => {}
        }
        match for_update {
            _ if !self.map_updates => {
                stats.scan_layers = self.scan.len();
                self.motion.push(pose);
            }
            Some((b, made_at)) => self.move_and_fuse(made_at, pose, b, exec, probe, &mut stats),
            None => self.finish(pose, exec, probe, &mut stats),
        }
        self.outcome(pose, status, stats)
    }

    /// The map's base, when a registration that ended with `status` shows that the map must
    /// start again: it did not converge, no registration has converged since the map was
    /// started, and the scan the map was started from kept under
    /// 1 / [`BASE_POINTS_RATIO`] of this scan's points (a scan far smaller than its
    /// neighbours: a driver's partial first sweep, say). Left as it is, the registration's
    /// pose would be an unchecked prediction, the map would be made from it, and every later
    /// scan would follow that map: a whole trajectory turned by a guess.
    fn base_to_drop(&self, status: RegistrationStatus, stats: &ScanStats) -> Option<MapBase> {
        let failed = !matches!(
            status,
            RegistrationStatus::FirstScan
                | RegistrationStatus::Converged
                | RegistrationStatus::Recovered
        );
        self.base.filter(|b| {
            failed
                && self.map_updates
                && b.points.saturating_mul(BASE_POINTS_RATIO) < stats.filter.kept
        })
    }

    /// A given pose that is not finite counts the frame and refuses it.
    fn check_given(&mut self, t_world_sensor: &Pose) -> Result<(), ScanError> {
        if pose_is_finite(t_world_sensor) {
            return Ok(());
        }
        self.frame = self.frame.saturating_add(1);
        Err(ScanError::BadPose)
    }

    /// The map update at a given pose.
    fn integrate(
        &mut self,
        t_world_sensor: &Pose,
        mut stats: ScanStats,
        exec: &impl Executor,
        probe: &mut impl Probe,
    ) -> ScanOutcome {
        self.turn_by_profile(stats.frame);
        self.finish(*t_world_sensor, exec, probe, &mut stats);
        self.outcome(*t_world_sensor, RegistrationStatus::Given, stats)
    }

    /// The outcome, logged (feature `defmt`).
    fn outcome(&self, pose: Pose, status: RegistrationStatus, stats: ScanStats) -> ScanOutcome {
        let outcome = ScanOutcome {
            t_world_sensor: pose,
            status,
            stats,
        };
        #[cfg(feature = "defmt")]
        log::scan_done(&outcome);
        outcome
    }

    /// Counts the frame and filters the scan into `points`.
    fn begin(
        &mut self,
        points_sensor: &[Point],
        exec: &impl Executor,
        probe: &mut impl Probe,
    ) -> Result<ScanStats, ScanError> {
        probe.enter(Stage::Filter);
        let filter = filter_and_downsample(
            points_sensor,
            &self.config.filter,
            self.config.voxel_leaf_m(),
            &mut self.work,
            &mut self.sorter,
            &mut self.points,
            exec,
        );
        probe.enter(Stage::Done);
        self.accept(filter)
    }

    /// Counts the frame and copies the filtered scan into `points` (points past their
    /// capacity are dropped, and counted as over capacity).
    fn begin_filtered(&mut self, filtered: Filtered<'_>) -> Result<ScanStats, ScanError> {
        let mut filter = filtered.stats;
        self.points.clear();
        for p in filtered.points {
            if self.points.push(*p).is_err() {
                filter.over_capacity += 1;
            }
        }
        filter.kept = self.points.len();
        self.accept(filter)
    }

    /// Counts the frame; refuses it when no point survived the filter.
    fn accept(&mut self, filter: FilterStats) -> Result<ScanStats, ScanError> {
        let frame = self.frame;
        self.frame = self.frame.saturating_add(1);
        if filter.kept == 0 {
            let error = ScanError::EmptyScan {
                stats: filter,
                range_m: [
                    self.config.filter.range_min_m,
                    self.config.filter.range_max_m,
                ],
            };
            #[cfg(feature = "defmt")]
            log::scan_rejected(frame, &error);
            return Err(error);
        }
        Ok(ScanStats {
            frame,
            filter,
            ..ScanStats::default()
        })
    }

    /// Keeps the filtered scan's azimuth profile for the next frame, and returns the turn about
    /// the sensor's vertical since the last frame that the two profiles find, if the last
    /// frame was the one before `frame` and `register.recovery.profile_turn_max_deg` is set.
    fn turn_by_profile(&mut self, frame: u32) -> Option<f64> {
        let max_deg = self.config.register.recovery.profile_turn_max_deg;
        if max_deg <= 0.0 {
            return None;
        }
        let now = AzimuthProfile::of(&self.points);
        let earlier = self
            .last_profile
            .replace((frame, now))
            .filter(|(f, _)| f.checked_add(1) == Some(frame))?;
        now.turn_from(&earlier.1, max_deg.to_radians())
            .map(|t| t.yaw)
    }

    /// Buckets the scan at `pose` and reconstructs its cells into `scan`.
    fn reconstruct(
        &mut self,
        pose: &Pose,
        exec: &impl Executor,
        purpose: Purpose,
        probe: &mut impl Probe,
    ) -> (BucketStats, ReconstructStats) {
        probe.enter(Stage::Bucket);
        let g = &self.config.grid;
        let b = bucket(
            &self.points,
            &Placement::<R>::new(pose, g.cell_size_m),
            g.min_points,
            &mut self.work,
            &mut self.sorter,
            &mut self.cells,
            exec,
        );
        self.scan.clear();
        probe.enter(Stage::Reconstruct);
        let made = reconstruct_cells::<R>(
            &self.cells,
            &self.work,
            &self.map,
            &self.config,
            purpose,
            &mut self.scan,
            exec,
        );
        (b, made)
    }

    /// Final reconstruction at `pose`, map update, motion update.
    fn finish(
        &mut self,
        pose: Pose,
        exec: &impl Executor,
        probe: &mut impl Probe,
        stats: &mut ScanStats,
    ) {
        let (b, made) = self.reconstruct(&pose, exec, Purpose::Update, probe);
        stats.dropped_layers += made.dropped;
        probe.enter(Stage::Update);
        self.fuse(pose, b, exec, stats);
        probe.enter(Stage::Done);
    }

    /// Moves `scan`, reconstructed at `made_at`, to the final `pose` (to first order:
    /// [`Layer::moved`](crate::layer::Layer::moved)); map update, motion update.
    fn move_and_fuse(
        &mut self,
        made_at: Pose,
        pose: Pose,
        bucketed: BucketStats,
        exec: &impl Executor,
        probe: &mut impl Probe,
        stats: &mut ScanStats,
    ) {
        probe.enter(Stage::Update);
        let motion = pose * made_at.inverse();
        let lattice = self.config.lattice().table();
        exec.update_each(&mut self.scan, |s| {
            s.layer = s.layer.moved(&lattice, &s.key, s.axis, &motion);
        });
        self.fuse(pose, bucketed, exec, stats);
        probe.enter(Stage::Done);
    }

    /// The frame before which a map cell last seen is stale for the frame being processed
    /// (0: none is; see [`MapConfig::stale_after_frames`](crate::config::MapConfig)).
    fn stale_before(&self) -> u32 {
        crate::fusion::stale_before(self.frame.saturating_sub(1), &self.config.map)
    }

    /// Fuses `scan` (at `pose`, bucketed as `bucketed`) into the map, its layers' facings
    /// decided on `exec`; motion update.
    fn fuse(
        &mut self,
        pose: Pose,
        bucketed: BucketStats,
        exec: &impl Executor,
        stats: &mut ScanStats,
    ) {
        stats.bucket = bucketed;
        stats.scan_layers = self.scan.len();
        let lattice = self.config.lattice().table();
        let max_var = self.config.map.variance_update as f32;
        let viewpoint = pose.translation.vector;
        face(&mut self.scan, &lattice, &viewpoint, max_var, exec);
        stats.fusion = integrate(&mut self.map, &self.scan, &self.config.map, stats.frame);
        self.motion.push(pose);
    }
}

/// A map whose first scan kept fewer than 1 / this of a later scan's points starts again from
/// that later scan when it cannot register against it, while no registration against the map
/// has converged ([`MapRestart`]).
pub const BASE_POINTS_RATIO: usize = 4;

/// The scan a map was started from: its frame, its points after the filter and its pose.
#[derive(Debug, Clone, Copy)]
struct MapBase {
    frame: u32,
    points: usize,
    pose: Pose,
}

/// True when every number of `pose` is finite.
fn pose_is_finite(pose: &Pose) -> bool {
    pose.translation
        .vector
        .iter()
        .chain(pose.rotation.coords.iter())
        .all(|v| v.is_finite())
}

/// defmt: the pipeline's types and the one place the core logs.
#[cfg(feature = "defmt")]
mod log {
    use super::{Pipeline, ScanOutcome};
    use crate::capacity::Capacity;
    use crate::log::formats::PoseFmt;
    use crate::real::Real;
    use defmt::{write, Format, Formatter};

    impl Format for ScanOutcome {
        fn format(&self, f: Formatter) {
            write!(
                f,
                "ScanOutcome {{ {}, {}, {} }}",
                PoseFmt(&self.t_world_sensor),
                self.status,
                self.stats
            )
        }
    }

    impl<C: Capacity, R: Real> Format for Pipeline<C, R> {
        fn format(&self, f: Formatter) {
            write!(
                f,
                "Pipeline {{ frames: {}, map: {} }}",
                self.frames(),
                self.map()
            )
        }
    }

    /// Logs the end of one scan (defmt `debug`, or `warn` when registration fell back).
    #[cfg(feature = "defmt")]
    pub(super) fn scan_done(outcome: &super::ScanOutcome) {
        use super::RegistrationStatus as S;
        match outcome.status {
            S::FirstScan | S::Converged | S::Given | S::Relocalized => {
                defmt::debug!("scan {}: {}", outcome.stats.frame, outcome)
            }
            _ => defmt::warn!(
                "scan {}: kept the motion prediction: {}",
                outcome.stats.frame,
                outcome
            ),
        }
    }

    /// Logs a rejected scan.
    #[cfg(feature = "defmt")]
    pub(super) fn scan_rejected(frame: u32, error: &super::ScanError) {
        defmt::warn!("scan {} rejected: {}", frame, error);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::executor::Serial;
    use crate::stage::NoProbe;
    use crate::storage::Storage;
    use alloc::vec::Vec;

    /// Deliberately small capacities, to hit every limit.
    #[derive(Debug)]
    struct Tiny;
    impl Capacity for Tiny {
        const POINTS: usize = 600;
        const SCAN_CELLS: usize = 6;
        const SCAN_LAYERS: usize = 8;
        const MAP_CELLS: usize = 4;
        const MAP_LAYERS: usize = 6;
    }

    /// A dense horizontal patch of `side x side` metres at height `z`, starting at `x0`.
    fn patch(x0: f32, side: f32, z: f32, step: f32) -> Vec<Point> {
        let n = (side / step) as usize;
        (0..n * n)
            .map(|i| [x0 + step * (i / n) as f32, 2.0 + step * (i % n) as f32, z])
            .collect()
    }

    #[test]
    fn empty_and_all_non_finite_scans_are_errors_that_leave_the_map_alone() {
        let mut p = Pipeline::<Tiny>::new(Config::default()).unwrap();
        assert!(matches!(
            p.process_scan(&[]),
            Err(ScanError::EmptyScan { .. })
        ));
        let bad = [
            [f32::NAN, 0.0, 0.0],
            [f32::INFINITY, 1.0, 2.0],
            [0.0, f32::NEG_INFINITY, 0.0],
            [1e30, 1e30, 1e30],
        ];
        let Err(e @ ScanError::EmptyScan { stats: s, .. }) = p.process_scan(&bad) else {
            panic!("expected EmptyScan")
        };
        assert_eq!((s.non_finite, s.out_of_range, s.too_near), (3, 1, 0));
        assert_eq!(
            alloc::string::ToString::to_string(&e),
            "empty scan: none of 4 points usable (3 not finite, 1 farther than \
             filter.range_max_m = 100 m: raise it for a scene this large)"
        );
        // Every point too close: the message names the limit and the parameter.
        let near = [[0.3f32, 0.2, 0.0]; 5];
        let Err(e) = p.process_scan(&near) else {
            panic!("expected EmptyScan")
        };
        assert_eq!(
            alloc::string::ToString::to_string(&e),
            "empty scan: none of 5 points usable (5 closer than filter.range_min_m = 1.2 m: \
             lower it for a sensor this close)"
        );
        assert!(p.map().is_empty() && p.pose().is_none());
        assert_eq!(p.frames(), 3);
    }

    #[test]
    fn nan_points_among_good_ones_are_dropped_and_counted() {
        let mut p = Pipeline::<Tiny>::new(Config::default()).unwrap();
        let mut scan = patch(3.2, 1.5, -1.0, 0.1);
        scan.truncate(200);
        scan.extend([[f32::NAN; 3]; 7]);
        let out = p.process_scan(&scan).unwrap();
        assert_eq!(out.stats.filter.non_finite, 7);
        assert_eq!(out.status, RegistrationStatus::FirstScan);
        assert!(p.map().layer_count() > 0);
    }

    #[test]
    fn all_points_in_one_cell_give_too_few_residuals_and_keep_the_prediction() {
        let mut p = Pipeline::<Tiny>::new(Config::default()).unwrap();
        let scan: Vec<Point> = patch(3.3, 1.2, -1.0, 0.1);
        p.process_scan(&scan).unwrap();
        let out = p.process_scan(&scan).unwrap();
        assert_eq!(out.status, RegistrationStatus::TooFewResiduals);
        // A map started by a scan as large as this one stays.
        assert_eq!(out.stats.map_restart, None);
        assert_eq!(out.t_world_sensor, Pose::identity());
        assert!(out
            .t_world_sensor
            .translation
            .vector
            .iter()
            .all(|v| v.is_finite()));
    }

    #[test]
    fn a_map_started_by_a_scan_far_smaller_than_the_next_starts_again_from_it() {
        let config = Config::default();
        let mut p = Pipeline::<Tiny>::new(config).unwrap();
        // A patch of floor in one cell, then one over four cells around it: too few residuals
        // against either map.
        let (small, big) = (patch(3.3, 1.2, -1.0, 0.1), patch(3.3, 3.1, -1.0, 0.2));
        let first = p.process_scan(&small).unwrap();
        assert_eq!(first.status, RegistrationStatus::FirstScan);
        assert!(p.map().layer_count() > 0);
        let out = p.process_scan(&big).unwrap();
        assert!(first.stats.filter.kept * BASE_POINTS_RATIO < out.stats.filter.kept);
        assert_eq!(out.status, RegistrationStatus::FirstScan);
        let restart = MapRestart {
            base_frame: 0,
            base_points: first.stats.filter.kept,
        };
        assert_eq!(out.stats.map_restart, Some(restart));
        assert_eq!(out.t_world_sensor, Pose::identity());
        // The map is the large scan's alone, as if it had come first.
        let mut fresh = Pipeline::<Tiny>::new(config).unwrap();
        let alone = fresh.process_scan(&big).unwrap();
        assert_eq!(out.stats.fusion, alone.stats.fusion);
        let layers = |p: &Pipeline<Tiny>| {
            let mut v: Vec<_> = p
                .map()
                .layers()
                .map(|l| (l.key, l.axis, *l.layer))
                .collect();
            v.sort_by_key(|(k, a, _)| (*k, a.index()));
            v
        };
        assert_eq!(layers(&p), layers(&fresh));
        // Now the map rests on a scan of its size: a failure keeps the prediction.
        let again = p.process_scan(&big).unwrap();
        assert_eq!(again.status, RegistrationStatus::TooFewResiduals);
        assert_eq!(again.stats.map_restart, None);
        // Off when the map is fixed (localization): nothing is dropped.
        let mut fixed = Pipeline::<Tiny>::new(config).unwrap();
        fixed.process_scan(&small).unwrap();
        fixed.set_map_updates(false);
        let kept = fixed.process_scan(&big).unwrap();
        assert_eq!(kept.status, RegistrationStatus::TooFewResiduals);
        assert!(fixed.map().layer_count() > 0);
    }

    #[test]
    fn more_points_cells_and_layers_than_capacity_are_dropped_by_rule() {
        let mut p = Pipeline::<Tiny>::new(Config::default()).unwrap();
        // 40 x 40 points over 4 m x 4 m: 1600 points (> 600), then many cells.
        let scan = patch(2.0, 4.0, -1.0, 0.1);
        let out = p.process_scan(&scan).unwrap();
        assert_eq!(out.stats.filter.over_capacity, 1600 - 600);
        let spread: Vec<Point> = (0..600)
            .map(|i| {
                [
                    2.0 + (i % 30) as f32 * 1.7,
                    2.0 + (i / 30) as f32 * 1.7,
                    -1.0,
                ]
            })
            .collect();
        // Every point in a cell of its own: all cells sparse.
        let out = p.process_scan(&spread).unwrap();
        assert_eq!(out.stats.bucket.cells, 0);
        assert!(out.stats.bucket.sparse_cells > 0);
        // Ten dense cells against a list of six: four dropped, in key order.
        let mut many = Vec::new();
        for c in 0..10 {
            many.extend(
                patch(2.0 + 1.6 * c as f32, 1.5, -1.0, 0.3)
                    .into_iter()
                    .take(30),
            );
        }
        let mut p = Pipeline::<Tiny>::new(Config::default()).unwrap();
        let out = p.process_scan(&many).unwrap();
        assert_eq!(out.stats.bucket.dropped_cells, 10 - Tiny::SCAN_CELLS);
        // The map holds four cells: the others are refused, not inserted.
        assert_eq!(p.map().cell_count(), Tiny::MAP_CELLS);
        assert!(out.stats.fusion.refused > 0);
    }

    /// `Tiny`'s buffers in leaked memory, the map's table `short` buckets short.
    fn tiny_storage(short: usize) -> Storage {
        let mut s = Storage::leak::<Tiny>();
        let table = core::mem::take(&mut s.map.table);
        s.map.table = &mut table[short..];
        s
    }

    #[test]
    fn a_pipeline_in_caller_storage_works_as_one_from_the_allocator() {
        let mut lent = Pipeline::<Tiny>::in_storage(Config::default(), tiny_storage(0)).unwrap();
        let mut own = Pipeline::<Tiny>::new(Config::default()).unwrap();
        for (i, z) in [-1.0, -1.02, -1.04].into_iter().enumerate() {
            let mut scan = patch(3.2, 1.5, z, 0.1);
            scan.extend(patch(1.0 + 0.05 * i as f32, 1.5, -1.3, 0.1));
            let (a, b) = (lent.process_scan(&scan), own.process_scan(&scan));
            assert_eq!(
                a.map(|o| (o.status, o.t_world_sensor)),
                b.map(|o| (o.status, o.t_world_sensor))
            );
        }
        assert_eq!(lent.map().layer_count(), own.map().layer_count());
        assert!(lent.map().layer_count() > 0);
        let e = Pipeline::<Tiny>::in_storage(Config::default(), tiny_storage(1)).unwrap_err();
        assert_eq!(e.field, "storage.map.table");
    }

    #[test]
    fn a_scan_filtered_apart_gives_what_the_pipeline_filtering_it_gives() {
        let mut apart = Pipeline::<Tiny>::new(Config::default()).unwrap();
        let mut own = Pipeline::<Tiny>::new(Config::default()).unwrap();
        let mut filter = crate::filter::ScanFilter::new::<Tiny>();
        let config = Config::default();
        for (i, z) in [-1.0, -1.02, -1.04, f32::NAN].into_iter().enumerate() {
            // Over the capacity of 600 points; last, a scan whose first patch is not finite.
            let mut scan = patch(3.2, 2.5, z, 0.1);
            scan.extend(patch(1.0 + 0.05 * i as f32, 1.5, -1.3, 0.1));
            let a = apart
                .step(
                    Scan::Filtered(filter.filter(&scan, &config, &Serial)),
                    Known::Nothing,
                    &Serial,
                    &mut NoProbe,
                )
                .map(Stepped::into_outcome);
            let b = own.process_scan(&scan);
            assert_eq!(a, b);
            assert_eq!(apart.last_points(), own.last_points());
        }
        assert!(apart.map().layer_count() > 0);
        let given = Pose::translation(0.1, 0.0, 0.0);
        let scan = patch(3.2, 1.5, -1.0, 0.1);
        let a = apart
            .step(
                Scan::Filtered(filter.filter(&scan, &config, &Serial)),
                Known::Pose(given),
                &Serial,
                &mut NoProbe,
            )
            .map(Stepped::into_outcome);
        assert_eq!(a, own.integrate_scan(&scan, &given));
        assert_eq!(apart.map().layer_count(), own.map().layer_count());
    }

    #[test]
    fn a_non_finite_given_pose_is_refused() {
        let mut p = Pipeline::<Tiny>::new(Config::meshing()).unwrap();
        let mut pose = Pose::identity();
        pose.translation.vector.x = f64::NAN;
        assert_eq!(
            p.integrate_scan(&patch(3.0, 1.0, -1.0, 0.1), &pose),
            Err(ScanError::BadPose)
        );
        let out = p
            .integrate_scan(
                &patch(3.0, 1.0, -1.0, 0.1),
                &Pose::translation(100.0, 0.0, 0.0),
            )
            .unwrap();
        assert_eq!(out.status, RegistrationStatus::Given);
        assert_eq!(p.pose(), Some(Pose::translation(100.0, 0.0, 0.0)));
    }

    #[test]
    fn an_invalid_config_is_refused() {
        let mut c = Config::default();
        c.grid.cell_size_m = -1.0;
        assert_eq!(
            Pipeline::<Tiny>::new(c).unwrap_err().field,
            "grid.cell_size_m"
        );
    }
}
