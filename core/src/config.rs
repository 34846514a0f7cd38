//! The one [`Config`], made of one struct per stage, with presets and validation.
//!
//! Defaults are the KITTI values of the original SLAMesh (docs/design.md §1.7) unless a field says
//! otherwise. [`Config::validate`] names the first bad field; the pipeline refuses an invalid
//! configuration at construction.

use crate::lattice::{Lattice, N};
use core::fmt;

/// The largest cross-cell reach of association ([`Config::validate`] refuses more; association
/// sizes its candidate list for it).
pub const MAX_REACH: u32 = 8;

/// Range filter and down-sampling (docs/design.md §1.1 step 1).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FilterConfig {
    /// Points closer to the sensor than this are dropped (metres). Default 1.2.
    pub range_min_m: f64,
    /// Points farther than this are dropped (metres). Default 100.
    pub range_max_m: f64,
    /// KITTI's vertical-angle calibration error: each point is rotated up by this angle about
    /// the horizontal axis perpendicular to its azimuth (docs/design.md §1.8). Default 0 (off);
    /// [`Config::kitti`] sets 0.22.
    pub vertical_correction_deg: f64,
}

/// The world grid of cells and their lattice (docs/design.md §1, §1.3).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GridConfig {
    /// Cell edge (metres). Default 1.6. The voxel down-sampling leaf is `cell_size_m / 6`.
    pub cell_size_m: f64,
    /// Points a cell needs to be reconstructed. Default 11 (5 for meshing).
    pub min_points: usize,
    /// Lattice on the cell faces (`true`, gap-free meshes) or at interval centres (`false`).
    /// Default `false` (`true` for meshing).
    pub full_cover: bool,
}

/// Gaussian-process reconstruction (docs/design.md §1.3).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GpConfig {
    /// κ of the exponential kernel `exp(-κ |u - v|)`, per metre. Default 1.2.
    pub kappa_per_m: f64,
    /// Measurement noise standard deviation σ_n (metres). Default 0.02.
    pub sensor_noise_m: f64,
}

/// Levenberg-Marquardt on SE(3) (docs/design.md §1.4).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LmConfig {
    /// Iterations per solve. Default 10.
    pub max_iterations: usize,
    /// Stop when the update's norm falls below this. Default 1e-5.
    pub tolerance: f64,
    /// Huber loss threshold (metres). Default 0.1.
    pub huber_delta_m: f64,
    /// A direction is degenerate (left to the motion model) when the mean squared normal
    /// component along it is below this (see [`crate::lm`]). Default 0.012: below what
    /// well-constrained outdoor scans carry in their weakest direction and above what a
    /// tunnel or a plane does (the trade-off is measured in docs/journal.md, Robustness).
    pub degenerate_ratio: f64,
    /// Fewer combined residuals than this is [`TooFewResiduals`](crate::lm::LmError). Default 10.
    pub min_residuals: usize,
}

/// Scan-to-map registration (docs/design.md §1.1 step 5, §1.4, §1.8).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RegisterConfig {
    /// Registration rounds per scan (re-bucket and re-reconstruct after each). Default 2.
    pub iterations: usize,
    /// Cross-cell search reach `L` during all but the last round. Default 1 (2 for meshing).
    pub cross_cell_overlap: u32,
    /// Rounds used while the motion is still unknown (the second scan). Default 6.
    pub initial_iterations: usize,
    /// Cross-cell reach while the motion is still unknown. Default 2.
    pub initial_cross_cell_overlap: u32,
    /// Vertices with a variance at or above this are not used for registration. Default 0.6.
    pub variance_register: f64,
    /// Rounds with a cross-cell reach (the coarse ones, all but the last) reconstruct only
    /// every other cell, a 3D checkerboard: they only have to bring the pose within the last
    /// round's reach, and on KITTI and the simulated town half the cells did that as well as
    /// all of them (README), at half the GP cost. The last round and the map update use every
    /// cell. Default `true`.
    pub coarse_half_cells: bool,
    /// The solver.
    pub lm: LmConfig,
    /// Recovery when a registration did not converge.
    pub recovery: RecoveryConfig,
}

/// Recovery from motion the prediction got wrong (docs/design.md §1.11, [`crate::recovery`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RecoveryConfig {
    /// Try other initial guesses when a registration did not converge. Default `true`.
    pub enabled: bool,
    /// Yaw between guesses (degrees; 0: only the last pose). Default 15.
    pub yaw_step_deg: f64,
    /// Largest yaw tried either way (degrees). Default 180.
    pub yaw_max_deg: f64,
    /// Registration rounds from each guess (all but the last with the initial reach). Default 6.
    pub rounds: usize,
    /// A last round that ran LM to its limit with fewer of the scan's layers matched than this
    /// share did not converge; one that stopped before the limit with at least this share
    /// surely did. Default 0.85.
    pub confirm_share: f64,
    /// When no guess surely converged, the best one that converged and settled with at least
    /// this share matched is kept as recovered (a turn into unseen space leaves fewer layers
    /// with a match); below it the frame is `NotConverged`. Default 0.6.
    pub accept_share: f64,
    /// A last round that moved the sensor by more than this (metres) has not settled.
    /// Default 0.5, chosen when the measure was LM's correction about the world's origin (the
    /// simulated town's last rounds moved that by up to 0.32 m and still ended right), which
    /// overstates the sensor's motion away from the origin.
    pub settle_m: f64,
    /// As `settle_m`, in degrees. Default 1.0: KITTI's last rounds turn it by at most 0.07°,
    /// the town's by 0.22°; hand-held steps that ended wrong had turned by 2° to 5°.
    pub settle_deg: f64,
    /// Rounds that refine a recovered pose, or a converged one after a turn of more than
    /// `polish_turn_deg` (at no cross-cell reach, with `polish_huber_delta_m`); 0: none.
    /// Default 2.
    pub polish_rounds: usize,
    /// A frame that converged from a prediction turning more than this from the last pose
    /// (degrees) is polished too. Default 5: cars at 10 Hz turn less (kitti-mini's reference
    /// poses by at most 2.7° a frame), the simulated hand-held rig and drone at 2 Hz by 8° to
    /// 48°.
    pub polish_turn_deg: f64,
    /// LM's Huber threshold in the polishing rounds (metres): tighter than the search's, for a
    /// pose already close. Default 0.05.
    pub polish_huber_delta_m: f64,
    /// The turn since the last scan found from the two scans' azimuth profiles
    /// ([`crate::azimuth`]) is looked for within this many degrees either way; 0: the profiles
    /// are not used. Default 90: the carried rigs turn by up to 48° a scan (with their tilt),
    /// and a hall's profile looks alike turned half round.
    pub profile_turn_max_deg: f64,
    /// When the profiles' turn and the constant-velocity prediction's differ by more than this
    /// (degrees), registration starts from the profiles' turn (docs/design.md §1.11).
    /// Default 5: on kitti-mini the profiles are off by at most 1.5° and the prediction by
    /// less; on the simulated hand-held rig the prediction is off by 23° (median) and the
    /// profiles by 1°.
    pub profile_disagree_deg: f64,
    /// Registration rounds from the profiles' start (all but the last with the initial
    /// reach), which is then polished. Default 3: with 2, the drones took more rounds in all
    /// (docs/journal.md).
    pub profile_rounds: usize,
}

/// Map update (docs/design.md §1.5).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MapConfig {
    /// Vertices are fused when both variances are below this; otherwise the one with the
    /// smaller variance is kept. Default 0.5.
    pub variance_update: f64,
    /// Add a layer that a known cell lacks (the original never does). Default `true`.
    pub add_missing_layers: bool,
    /// Reconstruct the scan again at its final pose before fusing it (docs/design.md §1.1 step 6).
    /// `false` fuses the last registration round's reconstruction instead, moved to the final
    /// pose to first order ([`Layer::moved`](crate::layer::Layer::moved)): that saves a
    /// bucketing and the costliest of the scan's reconstructions at a small cost in accuracy
    /// (both measured in docs/journal.md, Speed). Default `true`.
    pub reconstruct_at_final_pose: bool,
    /// A cell not seen for more than this many frames is *stale*: registration leaves it out,
    /// and a scan that sees it again replaces its layers instead of fusing into them. A
    /// place revisited after a long drift is then mapped afresh rather than as a second,
    /// offset copy fused into the first, and the odometry does not snap onto the old copy
    /// before a loop closure has corrected it (docs/design.md §1.14). 0 (the default): never.
    pub stale_after_frames: u32,
}

/// Mesh export (docs/design.md §1.6).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MeshConfig {
    /// Triangles whose mean vertex variance is at or above this are hidden. Default 1.0
    /// (0.3 for meshing).
    pub variance_show: f64,
    /// Triangles steeper than this against their layer's axis (degrees) are hidden: every
    /// surface orientation is within 54.7° (arccos 1/√3) of some axis, and the layer choice
    /// gives a cell the layers along its surfaces, so a steeper triangle is a layer wrapping
    /// over an edge that another layer holds (a car roof's layer running down its side). 90
    /// shows them all. Default 55.
    pub max_slope_deg: f64,
}

/// Everything the pipeline can be told, grouped by stage.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Config {
    /// Range filter.
    pub filter: FilterConfig,
    /// Cells and lattice.
    pub grid: GridConfig,
    /// GP reconstruction.
    pub gp: GpConfig,
    /// Registration.
    pub register: RegisterConfig,
    /// Map update.
    pub map: MapConfig,
    /// Mesh export.
    pub mesh: MeshConfig,
}

impl Default for Config {
    /// The original's KITTI values (docs/design.md §1.7), without the KITTI calibration correction.
    fn default() -> Self {
        Self {
            filter: FilterConfig {
                range_min_m: 1.2,
                range_max_m: 100.0,
                vertical_correction_deg: 0.0,
            },
            grid: GridConfig {
                cell_size_m: 1.6,
                min_points: 11,
                full_cover: false,
            },
            gp: GpConfig {
                kappa_per_m: 1.2,
                sensor_noise_m: 0.02,
            },
            register: RegisterConfig {
                iterations: 2,
                cross_cell_overlap: 1,
                initial_iterations: 6,
                initial_cross_cell_overlap: 2,
                variance_register: 0.6,
                coarse_half_cells: true,
                lm: LmConfig {
                    max_iterations: 10,
                    tolerance: 1e-5,
                    huber_delta_m: 0.1,
                    degenerate_ratio: 0.012,
                    min_residuals: 10,
                },
                recovery: RecoveryConfig {
                    enabled: true,
                    yaw_step_deg: 15.0,
                    yaw_max_deg: 180.0,
                    rounds: 6,
                    confirm_share: 0.85,
                    accept_share: 0.6,
                    settle_m: 0.5,
                    settle_deg: 1.0,
                    polish_rounds: 2,
                    polish_turn_deg: 5.0,
                    polish_huber_delta_m: 0.05,
                    profile_turn_max_deg: 90.0,
                    profile_disagree_deg: 5.0,
                    profile_rounds: 3,
                },
            },
            map: MapConfig {
                variance_update: 0.5,
                add_missing_layers: true,
                reconstruct_at_final_pose: true,
                stale_after_frames: 0,
            },
            mesh: MeshConfig {
                variance_show: 1.0,
                max_slope_deg: 55.0,
            },
        }
    }
}

impl Config {
    /// Odometry on KITTI HDL-64E scans: the defaults plus the 0.22° vertical-angle correction.
    pub fn kitti() -> Self {
        let mut c = Self::default();
        c.filter.vertical_correction_deg = 0.22;
        c
    }

    /// Meshing: lattice on the cell faces (no gaps), lower point threshold, wider cross-cell
    /// reach, only confident triangles shown (docs/design.md §1.7).
    pub fn meshing() -> Self {
        let mut c = Self::default();
        c.grid.min_points = 5;
        c.grid.full_cover = true;
        c.register.cross_cell_overlap = 2;
        c.mesh.variance_show = 0.3;
        c
    }

    /// The lattice this configuration places vertices on.
    pub fn lattice(&self) -> Lattice {
        Lattice {
            cell_size: self.grid.cell_size_m,
            full_cover: self.grid.full_cover,
        }
    }

    /// The voxel down-sampling leaf: one lattice spacing, `cell_size / 6`.
    pub fn voxel_leaf_m(&self) -> f64 {
        self.grid.cell_size_m / N as f64
    }

    /// Checks every field; the error names the first bad one.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let f = &self.filter;
        check(
            f.range_min_m.is_finite() && f.range_min_m >= 0.0,
            "filter.range_min_m",
            "must be finite and at least 0",
        )?;
        positive("filter.range_max_m", f.range_max_m)?;
        check(
            f.range_max_m > f.range_min_m,
            "filter.range_max_m",
            "must exceed filter.range_min_m",
        )?;
        check(
            f.vertical_correction_deg.is_finite() && libm::fabs(f.vertical_correction_deg) <= 5.0,
            "filter.vertical_correction_deg",
            "must be within ±5 degrees",
        )?;
        let g = &self.grid;
        positive("grid.cell_size_m", g.cell_size_m)?;
        check(
            !(g.cell_size_m < 0.05 || g.cell_size_m > 100.0),
            "grid.cell_size_m",
            "must be between 0.05 and 100 metres",
        )?;
        check(g.min_points >= 3, "grid.min_points", "must be at least 3")?;
        positive("gp.kappa_per_m", self.gp.kappa_per_m)?;
        positive("gp.sensor_noise_m", self.gp.sensor_noise_m)?;
        self.register.validate()?;
        positive("map.variance_update", self.map.variance_update)?;
        positive("mesh.variance_show", self.mesh.variance_show)?;
        check(
            self.mesh.max_slope_deg > 0.0 && self.mesh.max_slope_deg <= 90.0,
            "mesh.max_slope_deg",
            "must be above 0 and at most 90 degrees",
        )
    }
}

impl RegisterConfig {
    /// [`Config::validate`]'s checks of `register` and its sections, in order.
    fn validate(&self) -> Result<(), ConfigError> {
        let one_to_50 = "must be 1 to 50";
        check(
            (1..=50).contains(&self.iterations),
            "register.iterations",
            one_to_50,
        )?;
        check(
            (1..=50).contains(&self.initial_iterations),
            "register.initial_iterations",
            one_to_50,
        )?;
        check(
            self.cross_cell_overlap <= MAX_REACH,
            "register.cross_cell_overlap",
            "must be 0 to 8",
        )?;
        check(
            self.initial_cross_cell_overlap <= MAX_REACH,
            "register.initial_cross_cell_overlap",
            "must be 0 to 8",
        )?;
        positive("register.variance_register", self.variance_register)?;
        let lm = &self.lm;
        check(
            (1..=100).contains(&lm.max_iterations),
            "register.lm.max_iterations",
            "must be 1 to 100",
        )?;
        positive("register.lm.tolerance", lm.tolerance)?;
        positive("register.lm.huber_delta_m", lm.huber_delta_m)?;
        check(
            lm.degenerate_ratio.is_finite() && (0.0..1.0).contains(&lm.degenerate_ratio),
            "register.lm.degenerate_ratio",
            "must be in [0, 1)",
        )?;
        check(
            lm.min_residuals >= 6,
            "register.lm.min_residuals",
            "must be at least 6 (six unknowns)",
        )?;
        self.recovery.validate()
    }
}

impl RecoveryConfig {
    /// [`Config::validate`]'s checks of `register.recovery`, in order.
    fn validate(&self) -> Result<(), ConfigError> {
        let degrees = "must be 0 to 180 degrees";
        let half_turn = |v: f64| v.is_finite() && (0.0..=180.0).contains(&v);
        let at_least_0 = "must be finite and at least 0";
        check(
            (1..=50).contains(&self.rounds),
            "register.recovery.rounds",
            "must be 1 to 50",
        )?;
        check(
            half_turn(self.yaw_step_deg),
            "register.recovery.yaw_step_deg",
            degrees,
        )?;
        check(
            half_turn(self.yaw_max_deg),
            "register.recovery.yaw_max_deg",
            degrees,
        )?;
        check(
            self.confirm_share.is_finite() && (0.0..=1.0).contains(&self.confirm_share),
            "register.recovery.confirm_share",
            "must be in [0, 1]",
        )?;
        check(
            self.accept_share.is_finite()
                && (0.0..=self.confirm_share).contains(&self.accept_share),
            "register.recovery.accept_share",
            "must be in [0, register.recovery.confirm_share]",
        )?;
        positive("register.recovery.settle_m", self.settle_m)?;
        positive("register.recovery.settle_deg", self.settle_deg)?;
        positive(
            "register.recovery.polish_huber_delta_m",
            self.polish_huber_delta_m,
        )?;
        check(
            self.polish_turn_deg.is_finite() && self.polish_turn_deg >= 0.0,
            "register.recovery.polish_turn_deg",
            at_least_0,
        )?;
        check(
            half_turn(self.profile_turn_max_deg),
            "register.recovery.profile_turn_max_deg",
            degrees,
        )?;
        check(
            (1..=50).contains(&self.profile_rounds),
            "register.recovery.profile_rounds",
            "must be 1 to 50",
        )?;
        check(
            self.profile_disagree_deg.is_finite() && self.profile_disagree_deg >= 0.0,
            "register.recovery.profile_disagree_deg",
            at_least_0,
        )
    }
}

/// `Ok` when `ok`, else `field` refused for `reason`.
fn check(ok: bool, field: &'static str, reason: &'static str) -> Result<(), ConfigError> {
    match ok {
        true => Ok(()),
        false => Err(ConfigError { field, reason }),
    }
}

/// `field` refused unless `v` is finite and above 0.
fn positive(field: &'static str, v: f64) -> Result<(), ConfigError> {
    check(
        v.is_finite() && v > 0.0,
        field,
        "must be a finite number above 0",
    )
}

/// A configuration field and why its value is refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ConfigError {
    /// The dotted field name, as in a config file (`register.iterations`).
    pub field: &'static str,
    /// What the value must be.
    pub reason: &'static str,
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "invalid configuration: {} {}", self.field, self.reason)
    }
}

impl core::error::Error for ConfigError {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_are_valid() {
        Config::default().validate().unwrap();
        Config::kitti().validate().unwrap();
        Config::meshing().validate().unwrap();
    }

    #[test]
    fn bad_fields_are_named() {
        let mut c = Config::default();
        c.filter.range_max_m = 1.0;
        assert_eq!(c.validate().unwrap_err().field, "filter.range_max_m");
        let mut c = Config::default();
        c.gp.sensor_noise_m = f64::NAN;
        assert_eq!(c.validate().unwrap_err().field, "gp.sensor_noise_m");
        let mut c = Config::default();
        c.register.iterations = 0;
        assert_eq!(c.validate().unwrap_err().field, "register.iterations");
    }
}
