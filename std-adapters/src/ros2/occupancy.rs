//! `map`: the occupancy grid a planner reads (`nav_msgs/OccupancyGrid`, as Nav2's `map_server`
//! publishes it: reliable, transient local, the last one kept), kept current while the node
//! runs ([`crate::navmap::live`]): every `map_every` scans the window around the robot is
//! rebuilt from the mesh there (the mesh's tiles near it,
//! [`TiledMesh::each_triangle_near`](crate::navmap::tiled_mesh::TiledMesh::each_triangle_near),
//! copied) on a thread of its own, so a scan's poses never wait for it, and the whole grid
//! goes out from there as soon as it is made; an update due while the last is still being
//! made is skipped (counted); at the end, once more.
//!
//! Frames: the grid is made in the engine's world with up the robot's (`lidar_in_base`'s
//! rotation turned back: a level robot's map has z up) and placed in `map` by the message's
//! origin pose, as the mesh's markers are placed. The grid, its thread and its update times
//! are [`crate::navmap::background`]'s; this module turns each grid into the message.

use crate::navmap::background::{Background, Seen};
use crate::navmap::live::LiveGrid;
use crate::navmap::NavMapOptions;
use crate::ros2::mesh_tiles::MeshTiles;
use crate::ros2::messages::{Header, MapMetaData, OccupancyGrid, PoseMsg};
use nalgebra::Vector3;
use slamesh_core::Pose;

/// The window rebuilt around the robot (m), and the inner square kept (m).
pub const WINDOW_M: f64 = 30.0;
/// See [`WINDOW_M`].
pub const KEEP_M: f64 = 20.0;

/// The grid on `map`.
pub struct LiveMap {
    grid: Background<Header>,
}

/// What takes a grid once it is made: true when it went out.
pub type Out = Box<dyn FnMut(OccupancyGrid) -> bool + Send>;

impl LiveMap {
    /// A grid updated every `every` scans, for a robot carrying its LiDAR at `lidar_in_base`
    /// (`grid`: the robot and the cell size; up is the robot's z axis), each grid handed to
    /// `out`; the updates run on a thread of their own.
    pub fn new(every: usize, lidar_in_base: Pose, grid: NavMapOptions, mut out: Out) -> Self {
        let up = lidar_in_base.rotation.inverse() * Vector3::z();
        let how = NavMapOptions {
            up: Some((up, "the robot's z axis".into())),
            ..grid
        };
        let to_message = move |g: &LiveGrid, header: Header| {
            message(g, lidar_in_base, header).is_some_and(&mut out)
        };
        LiveMap {
            grid: Background::new(
                "slamesh-map",
                every,
                how,
                (WINDOW_M, KEEP_M),
                Box::new(to_message),
            ),
        }
    }

    /// The path corrected (after a loop closure): the LiDAR's poses, oldest first.
    pub fn correct(&mut self, corrected: &[Pose]) {
        self.grid.correct(corrected);
    }

    /// After a scan (the LiDAR's, in the engine's world; `None`: a scan not used): its
    /// points' floor counted, and when due the window around the last position goes to the
    /// worker with the triangles of `tiles` near it (an update still being made skips this
    /// one, counted).
    pub fn scan(&mut self, tiles: &MeshTiles, seen: Option<Seen>, header: Header) {
        self.grid.scan(tiles.mesh(), seen, header);
    }

    /// The end: the worker finishes, and the window around the last position is made once
    /// more and handed out (nothing when no scan was used).
    pub fn finish(&mut self, tiles: &MeshTiles, header: Header) {
        self.grid.finish(tiles.mesh(), header);
    }

    /// Grids handed out.
    pub fn sent(&self) -> u64 {
        self.grid.sent()
    }

    /// Updates made (of the last [`TIMES`](crate::navmap::background::TIMES)), their median
    /// and 95th percentile (ms), updates skipped (the last still being made), and the cells'
    /// bytes.
    pub fn costs(&self) -> (usize, f64, f64, u64, usize) {
        self.grid.costs()
    }
}

/// `grid` as a message at `header`'s stamp and frame (`map`), placed on the robot by
/// `lidar_in_base`; `None` before any update.
fn message(grid: &LiveGrid, lidar_in_base: Pose, header: Header) -> Option<OccupancyGrid> {
    let cells = grid.cells()?;
    let res = grid.resolution();
    // The grid's corner in the engine's world, then in `map`.
    let in_world = grid.corner_pose(&cells);
    Some(OccupancyGrid {
        info: MapMetaData {
            map_load_time: header.stamp,
            resolution: res as f32,
            width: cells.width as u32,
            height: cells.height as u32,
            origin: PoseMsg::from(&(lidar_in_base * in_world)),
        },
        header,
        data: cells.data,
    })
}
