//! Maps a planner reads, made from the mesh: a 2D occupancy grid as Nav2's `map_server` loads
//! it (`map.yaml` + `map.pgm`) and a 2.5D elevation grid (ESRI ASCII grids of the ground's
//! height and spread), for a robot profile.
//!
//! | what | module |
//! |---|---|
//! | the robot: radius, slope, step, height; profiles and its file | [`robot`] |
//! | the grid: cells in tiles, floor, obstacles, occupancy, elevation | [`grid`] |
//! | how sure the map is of a triangle, and how sure what stands must be | [`unsure`] |
//! | the ground: grown from the path; the height each cell is judged against | [`ground`] |
//! | the floor as the scans' points saw it, in chunks of the path | [`hits`] |
//! | that floor kept beside a saved map, for `slamesh navmap` | [`floor_file`] |
//! | what stands where the mesh has no surface: the scans' floor raised over the ground | [`raised`] |
//! | what the path saw: lines of sight over the grid | [`sight`] |
//! | traversability on a mesh of the ground: slope, step, roughness, border, cost | [`layers`] |
//! | the navigation map in a run: the scans' floor kept, the files made at its end | [`stage`] |
//! | the files: Nav2's YAML and PGM, the elevation grids, `navmesh.ply`, `navmap.json` | [`files`] |
//! | the grid kept current during a run, window by window | [`live`] |
//! | the map's shown triangles by tile, kept current from each frame's layers | [`tiled_mesh`] |
//! | the live grid updated on a thread of its own from those triangles | [`background`] |
//!
//! Up is the map's z axis (the first scan taken as level) unless the caller gives another
//! direction; a run whose IMU levelled the map (docs/design.md §1.19) says gravity gave it.
//! The files say which.

pub mod background;
pub mod files;
pub mod floor_file;
pub mod grid;
pub mod ground;
pub mod hits;
pub mod layers;
pub mod live;
pub mod raised;
pub mod robot;
pub mod sight;
pub mod stage;
pub mod tiled_mesh;
pub mod unsure;

pub use grid::{Grid, Occupancy, Triangles};
pub use robot::Robot;

use crate::io::error::FileError;
use nalgebra::Vector3;
use std::path::Path;

/// Builds the navigation map of the triangles `mesh` hands over, with the floor the scans'
/// points saw (`floors` calls its argument with each, map frame: [`hits::Hits::each_floor`];
/// none from a saved map), the ground grown from `path` (sensor positions in the map frame),
/// and writes its files into `dir` ([`files::write`]); the summary is `None` when the mesh
/// held nothing to map. The grid comes back for the layers on the mesh's own vertices
/// ([`layers::OnMesh`]).
pub fn make(
    mesh: &mut dyn Triangles,
    floors: &hits::Floors,
    path: &[Vector3<f64>],
    how: &NavMapOptions,
    dir: &Path,
) -> Result<(Option<files::NavMapSummary>, Grid), FileError> {
    let t = std::time::Instant::now();
    let (res, up) = (how.resolution_m, how.up().0);
    let grid = Grid::build_with_floors(mesh, floors, how.robot, res, up, path, &[])?;
    let summary = files::write(dir, &grid, how)?;
    match &summary {
        Some(s) => log::info!(
            "navigation map: {} ({:.1} s)",
            s.describe(),
            t.elapsed().as_secs_f64()
        ),
        None => log::warn!("navigation map: the mesh holds no ground or obstacle; none written"),
    }
    Ok((summary, grid))
}

/// How a navigation map is made.
#[derive(Debug, Clone, PartialEq)]
pub struct NavMapOptions {
    /// The robot it is for.
    pub robot: Robot,
    /// Cell size (m): 0.05 to 0.1 suits Nav2.
    pub resolution_m: f64,
    /// Up in the map frame, and where it came from; `None`: the map's z axis.
    pub up: Option<(Vector3<f64>, String)>,
}

impl Default for NavMapOptions {
    fn default() -> Self {
        NavMapOptions {
            robot: Robot::WHEELED,
            resolution_m: 0.1,
            up: None,
        }
    }
}

impl NavMapOptions {
    /// Up (map frame) and what says so.
    pub fn up(&self) -> (Vector3<f64>, String) {
        self.up.clone().unwrap_or_else(|| {
            (
                Vector3::z(),
                "the map's z axis (the first scan taken as level)".to_string(),
            )
        })
    }
}
