//! `map`: the occupancy grid a planner reads (`nav_msgs/OccupancyGrid`, as Nav2's `map_server`
//! publishes it: reliable, transient local, the last one kept), kept current while the node
//! runs ([`crate::navmap::live`]): every `map_every` scans the window around the robot is
//! rebuilt from the mesh there (the mesh's tiles near it, [`MeshTiles::each_triangle_near`])
//! and the whole grid goes out; at the end, once more.
//!
//! Frames: the grid is made in the engine's world with up the robot's (`lidar_in_base`'s
//! rotation turned back: a level robot's map has z up) and placed in `map` by the message's
//! origin pose, as the mesh's markers are placed. It owns the grid and the update times
//! (the last [`TIMES`], for the finish line's median and 95th percentile).

use crate::io::error::FileError;
use crate::navmap::grid::Triangles;
use crate::navmap::live::LiveGrid;
use crate::navmap::NavMapOptions;
use crate::ros2::mesh_tiles::MeshTiles;
use crate::ros2::messages::{Header, MapMetaData, OccupancyGrid, PoseMsg};
use nalgebra::{Translation3, UnitQuaternion, Vector3};
use slamesh_core::{Point, Pose};
use std::time::Instant;

/// The window rebuilt around the robot (m), and the inner square kept (m).
pub const WINDOW_M: f64 = 40.0;
/// See [`WINDOW_M`].
pub const KEEP_M: f64 = 30.0;
/// Update times kept.
pub const TIMES: usize = 1000;

/// The grid on `map`.
pub struct LiveMap {
    grid: LiveGrid,
    /// Scans between updates, and scans since the last.
    every: usize,
    since: usize,
    /// The LiDAR on the robot.
    lidar_in_base: Pose,
    /// The LiDAR's positions so far (the engine's world), the ground's seeds.
    path: Vec<Vector3<f64>>,
    /// Update times (ms).
    times: Vec<f64>,
}

impl LiveMap {
    /// A grid updated every `every` scans, for a robot carrying its LiDAR at `lidar_in_base`.
    pub fn new(every: usize, lidar_in_base: Pose) -> Self {
        let up = lidar_in_base.rotation.inverse() * Vector3::z();
        let how = NavMapOptions {
            up: Some((up, "the robot's z axis".into())),
            ..NavMapOptions::default()
        };
        LiveMap {
            grid: LiveGrid::new(how, WINDOW_M, KEEP_M),
            every: every.max(1),
            since: 0,
            lidar_in_base,
            path: Vec::new(),
            times: Vec::new(),
        }
    }

    /// The path corrected (after a loop closure): the LiDAR's poses, oldest first.
    pub fn correct(&mut self, corrected: &[Pose]) {
        self.path = corrected.iter().map(|p| p.translation.vector).collect();
    }

    /// After a scan at `at` (the LiDAR's position, the engine's world; `None`: a scan not
    /// used): when due (or when `now`), the window around the last position rebuilt from
    /// `tiles`, the ground grown from the path; true when it was.
    pub fn scan(
        &mut self,
        tiles: &MeshTiles,
        at: Option<Vector3<f64>>,
        now: bool,
    ) -> Result<bool, FileError> {
        self.path.extend(at);
        let Some(at) = self.path.last().copied() else {
            return Ok(false);
        };
        self.since += 1;
        if self.since < self.every && !now {
            return Ok(false);
        }
        self.since = 0;
        let t = Instant::now();
        let mut near = Near {
            tiles,
            centre: [at.x, at.y],
            // Wide enough for the window turned by a tilted up.
            half: WINDOW_M / 2.0 + 5.0,
        };
        self.grid.update(&mut near, &self.path, &at)?;
        if self.times.len() == TIMES {
            self.times.remove(0);
        }
        self.times.push(t.elapsed().as_secs_f64() * 1e3);
        Ok(true)
    }

    /// The grid as a message at `header`'s stamp and frame (`map`); `None` before any update.
    pub fn message(&self, header: Header) -> Option<OccupancyGrid> {
        let cells = self.grid.cells()?;
        let res = self.grid.resolution();
        // The lower-left corner of cell (0, 0), level frame, to the engine's world, to `map`.
        let corner = Vector3::new(
            cells.origin.0 as f64 * res,
            cells.origin.1 as f64 * res,
            0.0,
        );
        let level_inv = self.grid.level().inverse();
        let in_world = Pose::from_parts(
            Translation3::from(level_inv * corner),
            UnitQuaternion::from_rotation_matrix(&level_inv),
        );
        Some(OccupancyGrid {
            info: MapMetaData {
                map_load_time: header.stamp,
                resolution: res as f32,
                width: cells.width as u32,
                height: cells.height as u32,
                origin: PoseMsg::from(&(self.lidar_in_base * in_world)),
            },
            header,
            data: cells.data,
        })
    }

    /// Updates so far (of the last [`TIMES`]), their median and 95th percentile (ms), and the
    /// grid's bytes.
    pub fn costs(&self) -> (usize, f64, f64, usize) {
        let mut t = self.times.clone();
        t.sort_by(f64::total_cmp);
        let at = |q: f64| {
            t.get(((t.len() as f64 - 1.0) * q).round() as usize)
                .copied()
        };
        (
            t.len(),
            at(0.5).unwrap_or(0.0),
            at(0.95).unwrap_or(0.0),
            self.grid.bytes(),
        )
    }
}

/// The mesh's tiles near a point, as triangles.
struct Near<'a> {
    tiles: &'a MeshTiles,
    centre: [f64; 2],
    half: f64,
}

impl Triangles for Near<'_> {
    fn each_triangle(&mut self, each: &mut dyn FnMut([Point; 3])) -> Result<(), FileError> {
        self.tiles.each_triangle_near(self.centre, self.half, each);
        Ok(())
    }
}
