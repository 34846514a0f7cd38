//! The live view and its recording for the Foxglove app (`slamesh run --view`, `--record`):
//! the scan, the trajectory, the sensor pose and the mesh map, with the Foxglove SDK's
//! well-known schemas, so the app shows them with no set-up.
//!
//! | topic | schema | what |
//! |---|---|---|
//! | `/scan` | `foxglove.PointCloud` | the scan as registered (filtered, down-sampled, deskewed), in the world frame |
//! | `/tf` | `foxglove.FrameTransform` | `world` → `sensor`: the estimated pose |
//! | `/trajectory` | `foxglove.PosesInFrame` | every pose so far (at most [`MAX_POSES`], thinned evenly), every [`TRAJECTORY_EVERY`] frames and at the end |
//! | `/mesh` | `foxglove.SceneUpdate` | one entity per map layer the frame changed (id `x,y,z,axis`), its shown triangles; an entity replaces the one of the same id |
//! | `/loop_closures` | `foxglove.Log` | each loop closed (loop closure is on by default): the frames, the score and the correction; the whole corrected trajectory and map are sent with it |
//! | `/map` | `foxglove.Grid` | with [`ViewOptions::grid`] (`run --navmap`): the occupancy grid a planner reads (docs/design.md §1.18), every [`GRID_EVERY`] frames and at the end: the window around the sensor made again on a thread of its own ([`crate::navmap::background`]), up the map's z; fields `red`, `green`, `blue`, `alpha` (unknown clear, free pale, occupied dark) and `occupancy` (`int8`: Nav2's -1, 0, 100) |
//!
//! The view is one of a run's sinks ([`crate::run::sink`]): the SLAM loop only copies the
//! frame's points, pose and changed layers into a [`MapUpdate`] and offers it to a bounded
//! queue ([`QUEUE`] frames, [`WhenFull::DropNewest`]); when the queue is full the update is
//! dropped and counted, so the loop never waits for the view. A thread of its own turns updates
//! into messages and hands them to the SDK: its WebSocket server keeps a bounded backlog per
//! client and drops the oldest messages of a client that does not read; its MCAP writer writes
//! `slam.mcap.tmp` and renames it to `slam.mcap` when the run ends. The server only publishes:
//! it advertises no capability (no client publishing, parameters or services), and a client's
//! messages cannot change or stop the run.

use crate::io::error::FileError;
use crate::navmap::background::{Background, Seen};
use crate::navmap::live::{LiveGrid, FREE, OCCUPIED};
use crate::navmap::tiled_mesh::TiledMesh;
use crate::navmap::NavMapOptions;
use crate::run::sink::{FrameEvent, MapUpdate, Queued, Sink, SinkFault, WhenFull};
use crate::run::Summary;
use foxglove::messages::packed_element_field::NumericType;
use foxglove::messages::{
    Color, FrameTransform, Grid, Log, PackedElementField, Point3, PointCloud, Pose as FgPose,
    PosesInFrame, Quaternion, SceneEntity, SceneUpdate, Timestamp, TriangleListPrimitive, Vector2,
    Vector3,
};
use foxglove::{Channel, Context, McapWriterHandle, WebSocketServer, WebSocketServerHandle};
use slamesh_core::cell::{Axis, CellKey};
use slamesh_core::config::Config;
use slamesh_core::layer::{Layer, Shown};
use slamesh_core::{Capacity, Pipeline, Pose};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Frames the queue between the SLAM loop and the view's thread holds.
pub const QUEUE: usize = 4;
/// The trajectory is sent every this many frames.
pub const TRAJECTORY_EVERY: usize = 10;
/// Most poses a trajectory message holds.
pub const MAX_POSES: usize = 4096;
/// Messages a WebSocket client's backlog holds before its oldest are dropped.
pub const CLIENT_BACKLOG: usize = 256;
/// Frames between two grids on `/map`.
pub const GRID_EVERY: usize = 10;
/// The window the grid is made again in around the sensor (m), and the inner square kept (m).
pub const GRID_WINDOW_M: (f64, f64) = (30.0, 20.0);
/// The address `--view` serves on when none is given: this machine only.
pub const DEFAULT_ADDRESS: &str = "127.0.0.1:8765";

/// What to show and record.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ViewOptions {
    /// Serve the live view on this `host:port`.
    pub serve: Option<String>,
    /// Write `slam.mcap` into the output folder.
    pub record: bool,
    /// Show the occupancy grid on `/map`, made as these say (the run's `--navmap`; up the
    /// map's z); `None`: no grid, which costs nothing.
    pub grid: Option<NavMapOptions>,
}

impl ViewOptions {
    /// True when there is something to do.
    pub fn is_on(&self) -> bool {
        self.serve.is_some() || self.record
    }
}

/// What the view did, for the closing lines.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ViewStats {
    /// Updates shown or recorded.
    pub sent: usize,
    /// Updates dropped because the view's thread was behind.
    pub dropped: usize,
}

/// The running view: the publisher on its thread behind a bounded queue, and the recording
/// to rename when the run ends.
pub struct View {
    queue: Option<Queued>,
    /// The address the server listens on, if serving (the port is the real one when `:0`
    /// was asked for).
    pub address: Option<String>,
    record: Option<(PathBuf, PathBuf)>,
}

impl View {
    /// Starts the server and the recording that `opts` asks for (the recording in `out`);
    /// `None` when it asks for neither.
    pub fn start(
        opts: &ViewOptions,
        out: &Path,
        config: &Config,
    ) -> Result<Option<Self>, FileError> {
        if !opts.is_on() {
            return Ok(None);
        }
        let ctx = Context::new();
        let mut address = None;
        let server = match &opts.serve {
            Some(addr) => {
                let (host, port) = split_address(addr)
                    .ok_or_else(|| FileError::at(Path::new(addr), "--view: expected HOST:PORT"))?;
                let handle = WebSocketServer::new()
                    .name("slamesh")
                    .context(&ctx)
                    .bind(host, port)
                    .message_backlog_size(CLIENT_BACKLOG)
                    .capabilities([])
                    .start_blocking()
                    .map_err(|e| FileError::at(Path::new(addr), format!("cannot serve: {e}")))?;
                address = Some(format!("{host}:{}", handle.port()));
                Some(handle)
            }
            None => None,
        };
        let record = opts
            .record
            .then(|| (out.join("slam.mcap.tmp"), out.join("slam.mcap")));
        let writer = match &record {
            Some((tmp, _)) => {
                let _ = std::fs::remove_file(tmp);
                Some(
                    ctx.mcap_writer()
                        .create_new_buffered_file(tmp)
                        .map_err(|e| FileError::at(tmp, format!("cannot create: {e}")))?,
                )
            }
            None => None,
        };
        let publisher = Publisher::new(ctx, config, opts.grid.clone(), writer, server);
        let queue = Queued::new(publisher, QUEUE, WhenFull::DropNewest)
            .map_err(|e| FileError::at(out, format!("cannot start the view: {e}")))?;
        Ok(Some(View {
            queue: Some(queue),
            address,
            record,
        }))
    }

    /// The view `opts` asks for (the recording in `out`), started, its address said on the
    /// terminal.
    pub fn for_run(
        opts: &ViewOptions,
        out: &Path,
        config: &Config,
    ) -> Result<Option<Self>, FileError> {
        let view = Self::start(opts, out, config)?;
        if let Some(a) = view.as_ref().and_then(|v| v.address.as_ref()) {
            log::info!(
                "view: serving ws://{a} (Foxglove app: Open connection, Foxglove WebSocket)"
            );
        }
        Ok(view)
    }

    /// Offers the last frame of `pipeline` to the view; never waits (a full queue drops it).
    pub fn frame<C: Capacity>(&mut self, pipeline: &Pipeline<C>, frame: usize, stamp_s: f64) {
        let Some(update) = MapUpdate::of(pipeline, frame, stamp_s) else {
            return;
        };
        self.offer(update);
    }

    fn offer(&mut self, update: MapUpdate) {
        if let Some(q) = &mut self.queue {
            let event = FrameEvent {
                record: crate::run::FrameRecord::skipped(update.frame, String::new()),
                pose: Some(update.pose),
                map: Some(update),
                samples: Vec::new(),
                information: None,
            };
            // A publisher that stopped says why when the view finishes.
            let _ = q.frame(Arc::new(event));
        }
    }

    /// Sends what is queued, closes the recording (renamed to `slam.mcap`) and the server.
    /// A publisher that failed says why: the recording's file named when there is one.
    pub fn finish(mut self) -> Result<ViewStats, SinkFault> {
        let Some(queue) = self.queue.take() else {
            return Ok(ViewStats::default());
        };
        let (stats, result) = queue.end();
        if let Err(e) = result {
            return Err(match &self.record {
                Some((_, path)) => SinkFault::File(FileError::at(path, e.to_string())),
                None => e,
            });
        }
        if let Some((tmp, path)) = &self.record {
            std::fs::rename(tmp, path)
                .map_err(|e| FileError::at(path, format!("cannot write: {e}")))?;
        }
        Ok(ViewStats {
            sent: stats.delivered,
            dropped: stats.dropped,
        })
    }
}

/// The view as one of a run's sinks: it shows each used frame's map update (a frame that
/// failed has none).
impl Sink for View {
    fn name(&self) -> String {
        "view".into()
    }
    fn wants_map(&self) -> bool {
        true
    }
    fn frame(&mut self, event: Arc<FrameEvent>) -> Result<(), SinkFault> {
        if event.map.is_some() {
            if let Some(q) = &mut self.queue {
                return q.frame(event);
            }
        }
        Ok(())
    }
    fn finish(&mut self, _: Option<&Summary>) -> Result<Option<String>, SinkFault> {
        let view = View {
            queue: self.queue.take(),
            address: self.address.take(),
            record: self.record.take(),
        };
        let stats = view.finish()?;
        Ok(Some(format!(
            "{} frames shown or recorded, {} dropped (the view was behind)",
            stats.sent, stats.dropped
        )))
    }
}

/// `host:port` split; `None` when it is not that.
fn split_address(addr: &str) -> Option<(&str, u16)> {
    let (host, port) = addr.rsplit_once(':')?;
    Some((host.trim_matches(['[', ']']), port.parse().ok()?))
}

/// Turns each update into messages on its context's channels (on the queue's thread); at the
/// end, the trajectory once more, then closes the recording and stops the server.
struct Publisher {
    /// The context the channels, the server and the writer log through: held while they do.
    _ctx: Arc<Context>,
    scan: Channel<PointCloud>,
    tf: Channel<FrameTransform>,
    trajectory: Channel<PosesInFrame>,
    mesh: Channel<SceneUpdate>,
    closures: Channel<Log>,
    /// The mesh by tile, and the grid made from it (it holds `/map`'s channel), when asked.
    grid: Option<(TiledMesh, Background<(Timestamp, u64)>)>,
    lattice: slamesh_core::lattice::LatticeTable,
    shown: Shown,
    poses: Vec<FgPose>,
    last: Option<(Timestamp, u64)>,
    sent: usize,
    writer: Option<McapWriterHandle<std::io::BufWriter<std::fs::File>>>,
    server: Option<WebSocketServerHandle>,
}

impl Publisher {
    fn new(
        ctx: Arc<Context>,
        config: &Config,
        grid: Option<NavMapOptions>,
        writer: Option<McapWriterHandle<std::io::BufWriter<std::fs::File>>>,
        server: Option<WebSocketServerHandle>,
    ) -> Self {
        let grid = grid.map(|how| {
            let map = ctx.channel_builder("/map").build::<Grid>();
            let out = move |g: &LiveGrid, (time, nanos): (Timestamp, u64)| {
                grid_message(g, time)
                    .map(|m| map.log_with_time(&m, nanos))
                    .is_some()
            };
            let how = NavMapOptions { up: None, ..how };
            let tiles = TiledMesh::new(config.lattice().table(), Shown::new(&config.mesh));
            let every = Background::new(
                "slamesh-view-map",
                GRID_EVERY,
                how,
                GRID_WINDOW_M,
                Box::new(out),
            );
            (tiles, every)
        });
        Publisher {
            grid,
            scan: ctx.channel_builder("/scan").build::<PointCloud>(),
            tf: ctx.channel_builder("/tf").build::<FrameTransform>(),
            trajectory: ctx.channel_builder("/trajectory").build::<PosesInFrame>(),
            mesh: ctx.channel_builder("/mesh").build::<SceneUpdate>(),
            closures: ctx.channel_builder("/loop_closures").build::<Log>(),
            lattice: config.lattice().table(),
            shown: Shown::new(&config.mesh),
            poses: Vec::new(),
            last: None,
            sent: 0,
            writer,
            server,
            _ctx: ctx,
        }
    }

    /// One frame's update, `kept` its pose at its stamp (the path's).
    fn publish(&mut self, u: &MapUpdate, kept: Option<&Pose>) {
        let nanos = (u.stamp_s.max(0.0) * 1e9) as u64;
        let time = timestamp(u.stamp_s);
        self.scan.log_with_time(&point_cloud(u, time), nanos);
        self.tf.log_with_time(
            &FrameTransform {
                timestamp: Some(time),
                parent_frame_id: "world".into(),
                child_frame_id: "sensor".into(),
                translation: Some(vector(&u.pose)),
                rotation: Some(quaternion(&u.pose)),
            },
            nanos,
        );
        self.poses.push(fg_pose(&u.pose));
        if let Some((path, notes)) = &u.closed {
            self.poses = path.iter().map(fg_pose).collect();
            for note in notes {
                let log = Log {
                    timestamp: Some(time),
                    level: foxglove::messages::log::Level::Info as i32,
                    message: note.clone(),
                    name: "slamesh".into(),
                    ..Log::default()
                };
                self.closures.log_with_time(&log, nanos);
            }
        }
        if self.sent.is_multiple_of(TRAJECTORY_EVERY) || u.closed.is_some() {
            let poses = poses_in_frame(&self.poses, time);
            self.trajectory.log_with_time(&poses, nanos);
        }
        let entities = u
            .layers
            .iter()
            .map(|(key, axis, layer)| entity(key, *axis, layer, &self.lattice, self.shown, time))
            .collect();
        self.mesh.log_with_time(
            &SceneUpdate {
                deletions: Vec::new(),
                entities,
            },
            nanos,
        );
        if let Some((tiles, grid)) = &mut self.grid {
            if let Some((path, _)) = &u.closed {
                // The update holds every layer: the mesh anew, the ground's path corrected.
                tiles.clear();
                grid.correct(path);
            }
            tiles.update(&u.layers);
            let seen = Seen {
                kept: kept.unwrap_or(&u.pose),
                pose: &u.pose,
                points: &u.own_points,
            };
            grid.scan(tiles, Some(seen), (time, nanos));
        }
        self.last = Some((time, nanos));
        self.sent += 1;
    }
}

impl Sink for Publisher {
    fn name(&self) -> String {
        "view".into()
    }
    fn wants_map(&self) -> bool {
        true
    }
    fn frame(&mut self, event: Arc<FrameEvent>) -> Result<(), SinkFault> {
        if let Some(u) = &event.map {
            self.publish(u, event.pose.as_ref());
        }
        Ok(())
    }
    fn finish(&mut self, _: Option<&Summary>) -> Result<Option<String>, SinkFault> {
        if let Some((time, nanos)) = self.last {
            let poses = poses_in_frame(&self.poses, time);
            self.trajectory.log_with_time(&poses, nanos);
            if let Some((tiles, grid)) = &mut self.grid {
                grid.finish(tiles, (time, nanos));
            }
        }
        if let Some(w) = self.writer.take() {
            w.close().map_err(|e| e.to_string())?;
        }
        if let Some(s) = self.server.take() {
            // Not waiting for the clients: one that does not read would hold the run.
            s.stop().detach_all();
        }
        Ok(None)
    }
}

fn timestamp(s: f64) -> Timestamp {
    let s = s.max(0.0);
    let sec = s.floor();
    Timestamp::new(sec.min(u32::MAX as f64) as u32, ((s - sec) * 1e9) as u32)
}

fn vector(p: &Pose) -> Vector3 {
    let t = p.translation.vector;
    Vector3 {
        x: t.x,
        y: t.y,
        z: t.z,
    }
}

fn quaternion(p: &Pose) -> Quaternion {
    let q = p.rotation;
    Quaternion {
        x: q.i,
        y: q.j,
        z: q.k,
        w: q.w,
    }
}

fn fg_pose(p: &Pose) -> FgPose {
    FgPose {
        position: Some(vector(p)),
        orientation: Some(quaternion(p)),
    }
}

/// The trajectory so far, thinned evenly to at most [`MAX_POSES`] (the last pose kept).
fn poses_in_frame(poses: &[FgPose], time: Timestamp) -> PosesInFrame {
    let stride = poses.len().div_ceil(MAX_POSES).max(1);
    let mut kept: Vec<FgPose> = poses.iter().step_by(stride).copied().collect();
    if let Some(last) = poses
        .last()
        .filter(|_| !(poses.len() - 1).is_multiple_of(stride))
    {
        kept.push(*last);
    }
    PosesInFrame {
        timestamp: Some(time),
        frame_id: "world".into(),
        poses: kept,
    }
}

/// The scan in the world frame: float32 x, y, z.
fn point_cloud(u: &MapUpdate, time: Timestamp) -> PointCloud {
    let mut data = Vec::with_capacity(u.points.len() * 12);
    for p in &u.points {
        let w = u.pose * nalgebra::Point3::new(p[0] as f64, p[1] as f64, p[2] as f64);
        for c in [w.x, w.y, w.z] {
            data.extend_from_slice(&(c as f32).to_le_bytes());
        }
    }
    let field = |name: &str, offset: u32| PackedElementField {
        name: name.into(),
        offset,
        r#type: NumericType::Float32 as i32,
    };
    PointCloud {
        timestamp: Some(time),
        frame_id: "world".into(),
        pose: None,
        point_stride: 12,
        fields: vec![field("x", 0), field("y", 4), field("z", 8)],
        data: data.into(),
    }
}

/// `grid` as a `foxglove.Grid` in `world` at `time`: five bytes a cell, colours for the 3D
/// panel's RGBA mode and the Nav2 value; `None` before any update.
fn grid_message(grid: &LiveGrid, time: Timestamp) -> Option<Grid> {
    let cells = grid.cells()?;
    let field = |name: &str, offset: u32, kind: NumericType| PackedElementField {
        name: name.into(),
        offset,
        r#type: kind as i32,
    };
    let fields = ["red", "green", "blue", "alpha"]
        .iter()
        .zip(0..)
        .map(|(name, k)| field(name, k, NumericType::Uint8))
        .chain([field("occupancy", 4, NumericType::Int8)])
        .collect();
    let data: Vec<u8> = cells
        .data
        .iter()
        .flat_map(|&v| {
            let [r, g, b, a] = match v {
                FREE => [210, 225, 210, 110],
                OCCUPIED => [25, 25, 25, 255],
                _ => [0, 0, 0, 0],
            };
            [r, g, b, a, v as u8]
        })
        .collect();
    let res = grid.resolution();
    Some(Grid {
        timestamp: Some(time),
        frame_id: "world".into(),
        pose: Some(fg_pose(&grid.corner_pose(&cells))),
        column_count: cells.width as u32,
        cell_size: Some(Vector2 { x: res, y: res }),
        row_stride: 5 * cells.width as u32,
        cell_stride: 5,
        fields,
        data: data.into(),
    })
}

/// One map layer as a scene entity: its 36 vertices and its shown triangles.
fn entity(
    key: &CellKey,
    axis: Axis,
    layer: &Layer,
    lattice: &slamesh_core::lattice::LatticeTable,
    shown: Shown,
    time: Timestamp,
) -> SceneEntity {
    let points = (0..slamesh_core::lattice::VERTICES)
        .map(|j| {
            let v = layer.vertex(lattice, key, axis, j);
            Point3 {
                x: v.x,
                y: v.y,
                z: v.z,
            }
        })
        .collect();
    let indices = layer
        .triangles(lattice, shown)
        .flat_map(|t| t.map(|j| j as u32))
        .collect();
    SceneEntity {
        timestamp: Some(time),
        frame_id: "world".into(),
        id: format!("{},{},{},{:?}", key.x, key.y, key.z, axis),
        triangles: vec![TriangleListPrimitive {
            pose: None,
            points,
            color: Some(Color {
                r: 0.55,
                g: 0.7,
                b: 0.85,
                a: 1.0,
            }),
            colors: Vec::new(),
            indices,
        }],
        ..Default::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn addresses_split_into_host_and_port() {
        assert_eq!(split_address("127.0.0.1:8765"), Some(("127.0.0.1", 8765)));
        assert_eq!(split_address("[::1]:9000"), Some(("::1", 9000)));
        assert_eq!(split_address("0.0.0.0:0"), Some(("0.0.0.0", 0)));
        assert_eq!(split_address("localhost"), None);
        assert_eq!(split_address("host:http"), None);
    }

    #[test]
    fn the_trajectory_is_thinned_evenly_and_keeps_its_last_pose() {
        let pose = |i: usize| FgPose {
            position: Some(Vector3 {
                x: i as f64,
                y: 0.0,
                z: 0.0,
            }),
            orientation: None,
        };
        let x = |p: &PosesInFrame| -> Vec<f64> {
            p.poses.iter().map(|q| q.position.unwrap().x).collect()
        };
        let few: Vec<FgPose> = (0..5).map(pose).collect();
        assert_eq!(
            x(&poses_in_frame(&few, timestamp(1.0))),
            [0.0, 1.0, 2.0, 3.0, 4.0]
        );
        let many: Vec<FgPose> = (0..3 * MAX_POSES + 2).map(pose).collect();
        let thinned = x(&poses_in_frame(&many, timestamp(1.0)));
        assert!(thinned.len() <= MAX_POSES + 1, "{}", thinned.len());
        assert_eq!(thinned[1] - thinned[0], 4.0);
        assert_eq!(*thinned.last().unwrap(), (3 * MAX_POSES + 1) as f64);
    }
}
