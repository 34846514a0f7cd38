//! The pipeline: composes the stages for each scan (DESIGN §1.1). Holds no math of its own.
//!
//! Per scan: filter → predict → (bucket → reconstruct → associate → LM) × rounds → bucket →
//! reconstruct → fuse. [`Pipeline::process_scan`] estimates the pose; [`Pipeline::integrate_scan`]
//! meshes a scan at a pose the caller knows. Every buffer is allocated in [`Pipeline::new`] at
//! the capacities of `C`; nothing is allocated afterwards.

use crate::associate::{associate, AssociateStats};
use crate::bounded::BoundedVec;
use crate::bucket::{bucket, BucketStats, CellSpan};
use crate::capacity::{Capacity, KittiCapacity};
use crate::cell::CellKey;
use crate::config::{Config, ConfigError};
use crate::filter::{filter_and_downsample, FilterStats};
use crate::fusion::{integrate, FusionStats};
use crate::lm::{self, LmError, Residual};
use crate::map::MeshMap;
use crate::math::{Point, Pose};
use crate::mesh::{self, Triangle};
use crate::motion::ConstantVelocity;
use crate::reconstruct::{CellLoop, ScanLayer, Serial};
use core::fmt;
use core::marker::PhantomData;

/// How registration of one scan ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RegistrationStatus {
    /// The map was empty: the scan started it at the predicted pose.
    FirstScan,
    /// Every round solved.
    Converged,
    /// A round's geometry left a direction unconstrained: the pose keeps the rounds before
    /// it (the motion prediction if it was the first).
    Degenerate,
    /// A round had too few residuals: as for `Degenerate`.
    TooFewResiduals,
    /// The solver met non-finite numbers: as for `Degenerate`.
    SolverFailed,
    /// The pose was given ([`Pipeline::integrate_scan`]).
    Given,
}

/// Why a scan was not used. The map and motion model are unchanged.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ScanError {
    /// No point survived the filter (all non-finite, out of range, or none given).
    EmptyScan(FilterStats),
    /// The given pose is not finite.
    BadPose,
}

impl fmt::Display for ScanError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ScanError::EmptyScan(s) => write!(
                f,
                "empty scan: none of {} points usable ({} non-finite, {} out of range)",
                s.input, s.non_finite, s.out_of_range
            ),
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
    /// Bucketing of the final reconstruction.
    pub bucket: BucketStats,
    /// Layers in the final reconstruction.
    pub scan_layers: usize,
    /// Layers dropped because the scan's layer buffer was full (summed over rounds).
    pub dropped_layers: usize,
    /// Association of the last round.
    pub associate: AssociateStats,
    /// Registration rounds run.
    pub rounds: usize,
    /// LM iterations over all rounds.
    pub lm_iterations: usize,
    /// Conditioning of the last solved round (see [`lm::conditioning`]).
    pub conditioning: f64,
    /// Map update.
    pub fusion: FusionStats,
}

/// The result of [`Pipeline::process_scan`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ScanOutcome {
    /// The estimated sensor pose in the world (the first scan's frame).
    pub t_world_sensor: Pose,
    /// How registration ended.
    pub status: RegistrationStatus,
    /// Per-stage counts.
    pub stats: ScanStats,
}

/// LiDAR odometry and meshing with capacities `C`.
#[derive(Debug)]
pub struct Pipeline<C: Capacity = KittiCapacity> {
    config: Config,
    map: MeshMap,
    motion: ConstantVelocity,
    frame: u32,
    points: BoundedVec<Point>,
    work: BoundedVec<(CellKey, Point)>,
    cells: BoundedVec<CellSpan>,
    scan: BoundedVec<ScanLayer>,
    residuals: BoundedVec<Residual>,
    _capacity: PhantomData<C>,
}

impl<C: Capacity> Pipeline<C> {
    /// A pipeline with an empty map, all buffers allocated now.
    pub fn new(config: Config) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(Self {
            map: MeshMap::with_capacity(C::MAP_CELLS, C::MAP_LAYERS, config.lattice()),
            config,
            motion: ConstantVelocity::new(),
            frame: 0,
            points: BoundedVec::with_capacity(C::POINTS),
            work: BoundedVec::with_capacity(C::POINTS),
            cells: BoundedVec::with_capacity(C::SCAN_CELLS),
            scan: BoundedVec::with_capacity(C::SCAN_LAYERS),
            residuals: BoundedVec::with_capacity(C::SCAN_LAYERS),
            _capacity: PhantomData,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &Config {
        &self.config
    }

    /// The map.
    pub fn map(&self) -> &MeshMap {
        &self.map
    }

    /// The map, mutably (for eviction).
    pub fn map_mut(&mut self) -> &mut MeshMap {
        &mut self.map
    }

    /// Number of scans given so far.
    pub fn frames(&self) -> u32 {
        self.frame
    }

    /// The newest pose, if any scan was accepted.
    pub fn pose(&self) -> Option<Pose> {
        self.motion.last()
    }

    /// The map's shown triangles (`mesh.variance_show`), without allocation.
    pub fn triangles(&self) -> impl Iterator<Item = Triangle> + '_ {
        mesh::triangles(&self.map, self.config.mesh.variance_show)
    }

    /// Estimates the pose of a scan (sensor-frame points) and fuses it into the map.
    pub fn process_scan(&mut self, points_sensor: &[Point]) -> Result<ScanOutcome, ScanError> {
        self.process_scan_with(points_sensor, &Serial)
    }

    /// [`process_scan`](Self::process_scan) with a given cell loop (e.g. a parallel one).
    pub fn process_scan_with(&mut self, points_sensor: &[Point], cells: &impl CellLoop) -> Result<ScanOutcome, ScanError> {
        let mut stats = self.begin(points_sensor)?;
        let mut pose = self.motion.predict();
        let mut status = RegistrationStatus::FirstScan;
        if !self.map.is_empty() {
            let r = self.config.register;
            let (rounds, reach) = if self.motion.velocity_known() {
                (r.iterations, r.cross_cell_overlap)
            } else {
                (r.initial_iterations, r.initial_cross_cell_overlap)
            };
            status = RegistrationStatus::Converged;
            for round in 0..rounds {
                let reach = if round + 1 == rounds { 0 } else { reach };
                stats.dropped_layers += self.reconstruct(&pose, cells).1;
                stats.associate = associate(&self.scan, &self.map, reach, r.variance_register, &mut self.residuals);
                stats.rounds += 1;
                match lm::solve(&self.residuals, &r.lm) {
                    Ok(sol) => {
                        pose = sol.correction * pose;
                        stats.lm_iterations += sol.iterations;
                        stats.conditioning = sol.conditioning;
                    }
                    Err(e) => {
                        status = match e {
                            LmError::TooFewResiduals { .. } => RegistrationStatus::TooFewResiduals,
                            LmError::Degenerate { conditioning } => {
                                stats.conditioning = conditioning;
                                RegistrationStatus::Degenerate
                            }
                            LmError::NotFinite => RegistrationStatus::SolverFailed,
                        };
                        break;
                    }
                }
            }
        }
        self.finish(pose, cells, &mut stats);
        Ok(ScanOutcome { t_world_sensor: pose, status, stats })
    }

    /// Meshing only: fuses a scan into the map at a pose the caller knows (ground truth, an
    /// external odometry). Later [`process_scan`](Self::process_scan) calls continue from it.
    pub fn integrate_scan(&mut self, points_sensor: &[Point], t_world_sensor: &Pose) -> Result<ScanOutcome, ScanError> {
        let finite = t_world_sensor.translation.vector.iter().chain(t_world_sensor.rotation.coords.iter()).all(|v| v.is_finite());
        if !finite {
            self.frame = self.frame.saturating_add(1);
            return Err(ScanError::BadPose);
        }
        self.integrate_scan_with(points_sensor, t_world_sensor, &Serial)
    }

    /// [`integrate_scan`](Self::integrate_scan) with a given cell loop.
    pub fn integrate_scan_with(
        &mut self,
        points_sensor: &[Point],
        t_world_sensor: &Pose,
        cells: &impl CellLoop,
    ) -> Result<ScanOutcome, ScanError> {
        let mut stats = self.begin(points_sensor)?;
        self.finish(*t_world_sensor, cells, &mut stats);
        Ok(ScanOutcome { t_world_sensor: *t_world_sensor, status: RegistrationStatus::Given, stats })
    }

    /// Counts the frame and filters the scan into `points`.
    fn begin(&mut self, points_sensor: &[Point]) -> Result<ScanStats, ScanError> {
        let frame = self.frame;
        self.frame = self.frame.saturating_add(1);
        let filter = filter_and_downsample(
            points_sensor,
            &self.config.filter,
            self.config.voxel_leaf_m(),
            &mut self.work,
            &mut self.points,
        );
        if filter.kept == 0 {
            return Err(ScanError::EmptyScan(filter));
        }
        Ok(ScanStats { frame, filter, ..ScanStats::default() })
    }

    /// Buckets the scan at `pose` and reconstructs its cells into `scan`.
    fn reconstruct(&mut self, pose: &Pose, cells: &impl CellLoop) -> (BucketStats, usize) {
        let g = &self.config.grid;
        let b = bucket(&self.points, pose, g.cell_size_m, g.min_points, &mut self.work, &mut self.cells);
        self.scan.clear();
        let dropped = cells.run(&self.cells, &self.work, &self.map, &self.config, &mut self.scan);
        (b, dropped)
    }

    /// Final reconstruction at `pose`, map update, motion update.
    fn finish(&mut self, pose: Pose, cells: &impl CellLoop, stats: &mut ScanStats) {
        let (b, dropped) = self.reconstruct(&pose, cells);
        stats.bucket = b;
        stats.dropped_layers += dropped;
        stats.scan_layers = self.scan.len();
        stats.fusion = integrate(&mut self.map, &self.scan, &self.config.map, stats.frame);
        self.motion.push(pose);
    }
}
