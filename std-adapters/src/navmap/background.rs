//! A [`LiveGrid`] kept current on a thread of its own while a run goes on (the ROS 2 node's
//! `map`, the live view's `/map`): every `every` scans the window around the sensor is rebuilt
//! from the triangles of a [`TiledMesh`] near it (copied, so the run never waits for the
//! grid), and the grid is handed to the caller's `out` from that thread as soon as it is made;
//! an update due while the last is still being made is skipped (counted); at the end, once
//! more.
//!
//! It owns the grid, the path the ground is grown from (the sensor's positions, corrected
//! after a loop closure), the floor the scans' points saw ([`Hits`], counted as each scan comes, on
//! the caller's thread: the last [`FLOOR_CHUNKS`] stretches of the path, so that the live
//! grid finds a kerb the mesh rounded as the run's files do, in bounded memory) and the update
//! times (the last [`TIMES`], for a median and a 95th percentile). Each update carries a tag
//! of the caller's (a message header, a time stamp) to `out` with the grid.

use crate::io::error::FileError;
use crate::navmap::grid::Triangles;
use crate::navmap::hits::{hand, Hits, ScanFloor};
use crate::navmap::live::LiveGrid;
use crate::navmap::tiled_mesh::TiledMesh;
use crate::navmap::NavMapOptions;
use nalgebra::Vector3;
use slamesh_core::executor::Serial;
use slamesh_core::{Point, Pose};
use std::collections::HashMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, SyncSender, TrySendError};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Instant;

/// Update times kept.
pub const TIMES: usize = 1000;

/// Stretches of the path ([`CHUNK_M`](crate::navmap::hits::CHUNK_M) each) whose scans' floor
/// is kept: at least the last two whole ones, whose scans saw the ground up to
/// [`RANGE_M`](crate::navmap::hits::RANGE_M) around the last 60 m of the path, which holds the
/// window around the sensor; the memory is that of three stretches, however long the run.
pub const FLOOR_CHUNKS: usize = 3;

/// A used scan as the grid takes it.
#[derive(Debug, Clone, Copy)]
pub struct Seen<'a> {
    /// Its pose as the path keeps it (the sensor's at the scan's stamp: what a loop closure
    /// corrects).
    pub kept: &'a Pose,
    /// The pose its points were registered at (sensor to the engine's world).
    pub pose: &'a Pose,
    /// Its own points (sensor frame).
    pub points: &'a [Point],
}

/// What takes a grid once it is made, with its update's tag: true when it went out.
pub type Out<T> = Box<dyn FnMut(&LiveGrid, T) -> bool + Send>;

/// The grid, its thread, and what its updates cost.
pub struct Background<T: Send + 'static> {
    grid: Arc<Mutex<LiveGrid>>,
    /// The rebuilt window's side (m).
    window_m: f64,
    /// Scans between updates, and scans since the last.
    every: usize,
    since: usize,
    /// The sensor's positions so far (the engine's world), the ground's seeds.
    path: Vec<Vector3<f64>>,
    /// The floor the scans' points saw, by the index in `path` of the scan that counted it.
    floors: Hits,
    /// Since the last loop closure: the corrected pose of each scan a chunk of `floors` began
    /// at (a chunk begun since has not moved).
    moved: HashMap<usize, Pose>,
    /// Update times (ms).
    times: Arc<Mutex<Vec<f64>>>,
    /// Where a grid goes once made, and how many went.
    out: Arc<Mutex<Out<T>>>,
    sent: Arc<AtomicU64>,
    /// The worker's queue (one update at most) and thread.
    jobs: Option<SyncSender<Job<T>>>,
    worker: Option<JoinHandle<()>>,
    /// Updates not made because the last one was still being made.
    skipped: u64,
}

/// An update for the worker: the window's triangles and the scans' floor there (copied), the
/// path near it, where, and the caller's tag.
struct Job<T> {
    triangles: Vec<([Point; 3], f32)>,
    floors: Vec<ScanFloor>,
    path: Vec<Vector3<f64>>,
    at: Vector3<f64>,
    tag: T,
}

impl<T: Send + 'static> Background<T> {
    /// A grid made as `how` says from windows of `window_m` metres keeping their inner
    /// `keep_m`, updated every `every` scans on a thread named `name`, each grid handed to
    /// `out`. With no thread to be had, the grid is made at the end only (said in the log).
    pub fn new(
        name: &str,
        every: usize,
        how: NavMapOptions,
        (window_m, keep_m): (f64, f64),
        out: Out<T>,
    ) -> Self {
        let floors = Hits::new(how.resolution_m, &how.up().0);
        let mut b = Background {
            grid: Arc::new(Mutex::new(LiveGrid::new(how, window_m, keep_m))),
            window_m,
            every: every.max(1),
            since: 0,
            path: Vec::new(),
            floors,
            moved: HashMap::new(),
            times: Arc::default(),
            out: Arc::new(Mutex::new(out)),
            sent: Arc::default(),
            jobs: None,
            worker: None,
            skipped: 0,
        };
        let (tx, rx) = sync_channel::<Job<T>>(1);
        let work = b.work();
        let spawned = std::thread::Builder::new()
            .name(name.into())
            .spawn(move || {
                for job in rx {
                    work(job);
                }
            });
        match spawned {
            Ok(worker) => (b.jobs, b.worker) = (Some(tx), Some(worker)),
            Err(e) => {
                log::warn!("{name}: no thread for the grid ({e}): it is made at the end only")
            }
        }
        b
    }

    /// What the worker does with a job: the update, timed, and the grid handed out.
    fn work(&self) -> impl Fn(Job<T>) + Send + 'static {
        let (grid, times) = (self.grid.clone(), self.times.clone());
        let (out, sent) = (self.out.clone(), self.sent.clone());
        move |job: Job<T>| {
            let t = Instant::now();
            let Ok(mut g) = grid.lock() else { return };
            let mut soup = Soup(job.triangles);
            let floors = hand(&job.floors);
            if let Err(e) = g.update(&mut soup, &floors, &job.path, &job.at) {
                log::warn!("grid: {e}");
                return;
            }
            if let Ok(mut times) = times.lock() {
                if times.len() == TIMES {
                    times.remove(0);
                }
                times.push(t.elapsed().as_secs_f64() * 1e3);
            }
            if let Ok(mut out) = out.lock() {
                if out(&g, job.tag) {
                    sent.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
    }

    /// The path corrected (after a loop closure): the sensor's poses, one for each scan used,
    /// oldest first. The scans' floor moves with it; when the count differs from the scans
    /// used, it is forgotten (the next scans count it again).
    pub fn correct(&mut self, corrected: &[Pose]) {
        if corrected.len() != self.path.len() {
            self.floors.keep_last(0);
        }
        self.path = corrected.iter().map(|p| p.translation.vector).collect();
        self.moved = (self.floors.chunk_frames())
            .filter_map(|f| Some((f, *corrected.get(f)?)))
            .collect();
    }

    /// After a scan (`None`: a scan not used): its points' floor counted, and when due the
    /// window around the last position goes to the worker with the triangles of `mesh` and
    /// the scans' floor near it (an update still being made skips this one, counted).
    pub fn scan(&mut self, mesh: &TiledMesh, seen: Option<Seen>, tag: T) {
        if let Some(s) = seen {
            (self.floors).add(self.path.len(), s.kept, s.pose, s.points, &Serial);
            self.floors.keep_last(FLOOR_CHUNKS);
            self.path.push(s.kept.translation.vector);
        }
        let Some(at) = self.path.last().copied() else {
            return;
        };
        self.since += 1;
        if self.since < self.every {
            return;
        }
        self.since = 0;
        let Some(jobs) = &self.jobs else { return };
        match jobs.try_send(self.job(mesh, at, tag)) {
            Ok(()) => {}
            Err(TrySendError::Full(_)) => self.skipped += 1,
            Err(TrySendError::Disconnected(_)) => self.jobs = None,
        }
    }

    fn job(&self, mesh: &TiledMesh, at: Vector3<f64>, tag: T) -> Job<T> {
        let mut triangles = Vec::new();
        // Wide enough for the window turned by a tilted up.
        let half = self.window_m / 2.0 + 5.0;
        mesh.each_triangle_near([at.x, at.y], half, &mut |t, v| triangles.push((t, v)));
        let near = |p: &Vector3<f64>| (p.x - at.x).abs() <= half && (p.y - at.y).abs() <= half;
        let path = self.path.iter().filter(|p| near(p)).copied().collect();
        let mut floors = Vec::new();
        let now = |frame: usize| self.moved.get(&frame).copied();
        (self.floors).each_floor(&now, &mut |f| {
            if near(&f.at) {
                floors.push(f)
            }
        });
        Job {
            triangles,
            floors,
            path,
            at,
            tag,
        }
    }

    /// The end: the worker finishes, and the window around the last position is made once
    /// more and handed out (nothing when no scan was used).
    pub fn finish(&mut self, mesh: &TiledMesh, tag: T) {
        self.jobs = None;
        if let Some(w) = self.worker.take() {
            let _ = w.join();
        }
        if let Some(at) = self.path.last().copied() {
            (self.work())(self.job(mesh, at, tag));
        }
    }

    /// Grids handed out.
    pub fn sent(&self) -> u64 {
        self.sent.load(Ordering::Relaxed)
    }

    /// Updates made (of the last [`TIMES`]), their median and 95th percentile (ms), updates
    /// skipped (the last still being made), and the bytes of the cells and the scans' floor.
    pub fn costs(&self) -> (usize, f64, f64, u64, usize) {
        let mut t = self.times.lock().map(|t| t.clone()).unwrap_or_default();
        t.sort_by(f64::total_cmp);
        let at = |q: f64| {
            t.get(((t.len() as f64 - 1.0) * q).round() as usize)
                .copied()
        };
        let bytes = self.grid.lock().map_or(0, |g| g.bytes()) + self.floors.bytes();
        (
            t.len(),
            at(0.5).unwrap_or(0.0),
            at(0.95).unwrap_or(0.0),
            self.skipped,
            bytes,
        )
    }
}

/// Triangles copied out of the tiles, with their mean variances.
struct Soup(Vec<([Point; 3], f32)>);

impl Triangles for Soup {
    fn each_triangle(&mut self, each: &mut dyn FnMut([Point; 3], f32)) -> Result<(), FileError> {
        self.0.iter().for_each(|(t, v)| each(*t, *v));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};
    use slamesh_core::config::Config;
    use slamesh_core::layer::Shown;

    #[test]
    fn the_scans_floor_moves_with_a_corrected_path_and_is_dropped_when_it_does_not_match() {
        let config = Config::default();
        let mesh = TiledMesh::new(config.lattice().table(), Shown::new(&config.mesh));
        let how = NavMapOptions::default();
        let mut b =
            Background::<()>::new("test-map", 1000, how, (30.0, 20.0), Box::new(|_, ()| true));
        let pose = Pose::identity();
        // Two points in one 2 cm bin: a floor at (1.05, 2.05, -0.51).
        let points = [[1.05, 2.05, -0.51], [1.06, 2.04, -0.51]];
        let seen = Seen {
            kept: &pose,
            pose: &pose,
            points: &points,
        };
        b.scan(&mesh, Some(seen), ());
        let floors = |b: &Background<()>| b.job(&mesh, Vector3::zeros(), ()).floors;
        let near = |f: &[ScanFloor], want: [f64; 3]| {
            f.len() == 1 && f[0].twice && (f[0].at - Vector3::from(want)).norm() < 1e-6
        };
        assert!(near(&floors(&b), [1.05, 2.05, -0.51]), "{:?}", floors(&b));
        // The loop closed: the scan was 1 m further along x.
        let shifted =
            Pose::from_parts(Translation3::new(1.0, 0.0, 0.0), UnitQuaternion::identity());
        b.correct(&[shifted]);
        assert!(near(&floors(&b), [2.05, 2.05, -0.51]), "{:?}", floors(&b));
        // A corrected path of another length than the scans counted: the floor is dropped.
        b.correct(&[shifted, shifted]);
        assert!(floors(&b).is_empty());
    }
}
