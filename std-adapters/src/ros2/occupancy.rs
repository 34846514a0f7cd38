//! `map`: the occupancy grid a planner reads (`nav_msgs/OccupancyGrid`, as Nav2's `map_server`
//! publishes it: reliable, transient local, the last one kept), kept current while the node
//! runs ([`crate::navmap::live`]): every `map_every` scans the window around the robot is
//! rebuilt from the mesh there (the mesh's tiles near it, [`MeshTiles::each_triangle_near`],
//! copied) on a thread of its own, so a scan's poses never wait for it, and the whole grid
//! goes out from there as soon as it is made; an update due while the last is still being
//! made is skipped (counted); at the end, once more.
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
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Instant;

/// The window rebuilt around the robot (m), and the inner square kept (m).
pub const WINDOW_M: f64 = 30.0;
/// See [`WINDOW_M`].
pub const KEEP_M: f64 = 20.0;
/// Update times kept.
pub const TIMES: usize = 1000;

/// The grid on `map`.
pub struct LiveMap {
    grid: Arc<Mutex<LiveGrid>>,
    /// Scans between updates, and scans since the last.
    every: usize,
    since: usize,
    /// The LiDAR on the robot.
    lidar_in_base: Pose,
    /// The LiDAR's positions so far (the engine's world), the ground's seeds.
    path: Vec<Vector3<f64>>,
    /// Update times (ms).
    times: Arc<Mutex<Vec<f64>>>,
    /// Where a grid goes once made (the publisher), and how many went.
    out: Arc<Mutex<Out>>,
    sent: Arc<AtomicU64>,
    /// The worker's queue (one update at most) and thread.
    jobs: Option<SyncSender<Job>>,
    worker: Option<JoinHandle<()>>,
    /// Updates not made because the last one was still being made.
    skipped: u64,
}

/// What takes a grid once it is made: true when it went out.
pub type Out = Box<dyn FnMut(OccupancyGrid) -> bool + Send>;

/// An update for the worker: the window's triangles (copied), the path, where, and the
/// message's header.
struct Job {
    triangles: Vec<[Point; 3]>,
    path: Vec<Vector3<f64>>,
    at: Vector3<f64>,
    header: Header,
}

impl LiveMap {
    /// A grid updated every `every` scans, for a robot carrying its LiDAR at `lidar_in_base`,
    /// each grid handed to `out`; the updates run on a thread of their own.
    pub fn new(every: usize, lidar_in_base: Pose, out: Out) -> Self {
        let up = lidar_in_base.rotation.inverse() * Vector3::z();
        let how = NavMapOptions {
            up: Some((up, "the robot's z axis".into())),
            ..NavMapOptions::default()
        };
        let mut map = LiveMap {
            grid: Arc::new(Mutex::new(LiveGrid::new(how, WINDOW_M, KEEP_M))),
            every: every.max(1),
            since: 0,
            lidar_in_base,
            path: Vec::new(),
            times: Arc::default(),
            out: Arc::new(Mutex::new(out)),
            sent: Arc::default(),
            jobs: None,
            worker: None,
            skipped: 0,
        };
        let (tx, rx) = sync_channel::<Job>(1);
        let work = map.work();
        let spawned = std::thread::Builder::new()
            .name("slamesh-map".into())
            .spawn(move || {
                for job in rx {
                    work(job);
                }
            });
        match spawned {
            Ok(worker) => (map.jobs, map.worker) = (Some(tx), Some(worker)),
            Err(e) => log::warn!("map: no thread for the grid ({e}): it is made at the end only"),
        }
        map
    }

    /// What the worker does with a job: the update, timed, and the grid handed out.
    fn work(&self) -> impl Fn(Job) + Send + 'static {
        let (grid, times) = (self.grid.clone(), self.times.clone());
        let (out, sent) = (self.out.clone(), self.sent.clone());
        let lidar_in_base = self.lidar_in_base;
        move |job: Job| {
            let t = Instant::now();
            let Ok(mut g) = grid.lock() else { return };
            let mut soup = Soup(job.triangles);
            if let Err(e) = g.update(&mut soup, &job.path, &job.at) {
                log::warn!("map: {e}");
                return;
            }
            let message = message(&g, lidar_in_base, job.header);
            drop(g);
            if let Ok(mut times) = times.lock() {
                if times.len() == TIMES {
                    times.remove(0);
                }
                times.push(t.elapsed().as_secs_f64() * 1e3);
            }
            if let (Some(m), Ok(mut out)) = (message, out.lock()) {
                if out(m) {
                    sent.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
    }

    /// The path corrected (after a loop closure): the LiDAR's poses, oldest first.
    pub fn correct(&mut self, corrected: &[Pose]) {
        self.path = corrected.iter().map(|p| p.translation.vector).collect();
    }

    /// After a scan at `at` (the LiDAR's position, the engine's world; `None`: a scan not
    /// used): when due, the window around the last position goes to the worker with the
    /// triangles of `tiles` near it (an update still being made skips this one, counted).
    pub fn scan(&mut self, tiles: &MeshTiles, at: Option<Vector3<f64>>, header: Header) {
        self.path.extend(at);
        let Some(at) = self.path.last().copied() else {
            return;
        };
        self.since += 1;
        if self.since < self.every {
            return;
        }
        self.since = 0;
        let Some(jobs) = &self.jobs else { return };
        match jobs.try_send(self.job(tiles, at, header)) {
            Ok(()) => {}
            Err(TrySendError::Full(_)) => self.skipped += 1,
            Err(TrySendError::Disconnected(_)) => self.jobs = None,
        }
    }

    fn job(&self, tiles: &MeshTiles, at: Vector3<f64>, header: Header) -> Job {
        let mut triangles = Vec::new();
        // Wide enough for the window turned by a tilted up.
        let half = WINDOW_M / 2.0 + 5.0;
        tiles.each_triangle_near([at.x, at.y], half, &mut |t| triangles.push(t));
        let near = |p: &Vector3<f64>| (p.x - at.x).abs() <= half && (p.y - at.y).abs() <= half;
        let path = self.path.iter().filter(|p| near(p)).copied().collect();
        Job {
            triangles,
            path,
            at,
            header,
        }
    }

    /// The end: the worker finishes, and the window around the last position is made once
    /// more and handed out (nothing when no scan was used).
    pub fn finish(&mut self, tiles: &MeshTiles, header: Header) {
        self.jobs = None;
        if let Some(w) = self.worker.take() {
            let _ = w.join();
        }
        if let Some(at) = self.path.last().copied() {
            (self.work())(self.job(tiles, at, header));
        }
    }

    /// Grids handed out.
    pub fn sent(&self) -> u64 {
        self.sent.load(Ordering::Relaxed)
    }

    /// Updates made (of the last [`TIMES`]), their median and 95th percentile (ms), updates
    /// skipped (the last still being made), and the cells' bytes.
    pub fn costs(&self) -> (usize, f64, f64, u64, usize) {
        let mut t = self.times.lock().map(|t| t.clone()).unwrap_or_default();
        t.sort_by(f64::total_cmp);
        let at = |q: f64| {
            t.get(((t.len() as f64 - 1.0) * q).round() as usize)
                .copied()
        };
        let bytes = self.grid.lock().map_or(0, |g| g.bytes());
        (
            t.len(),
            at(0.5).unwrap_or(0.0),
            at(0.95).unwrap_or(0.0),
            self.skipped,
            bytes,
        )
    }
}

/// `grid` as a message at `header`'s stamp and frame (`map`), placed on the robot by
/// `lidar_in_base`; `None` before any update.
fn message(grid: &LiveGrid, lidar_in_base: Pose, header: Header) -> Option<OccupancyGrid> {
    let cells = grid.cells()?;
    let res = grid.resolution();
    // The lower-left corner of cell (0, 0), level frame, to the engine's world, to `map`.
    let corner = Vector3::new(
        cells.origin.0 as f64 * res,
        cells.origin.1 as f64 * res,
        0.0,
    );
    let level_inv = grid.level().inverse();
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
            origin: PoseMsg::from(&(lidar_in_base * in_world)),
        },
        header,
        data: cells.data,
    })
}

/// Triangles copied out of the tiles.
struct Soup(Vec<[Point; 3]>);

impl Triangles for Soup {
    fn each_triangle(&mut self, each: &mut dyn FnMut([Point; 3])) -> Result<(), FileError> {
        self.0.iter().for_each(|t| each(*t));
        Ok(())
    }
}
