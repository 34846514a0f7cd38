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
//! | `/loop_closures` | `foxglove.Log` | each loop closed (`--loop-closure on`): the frames, the score and the correction; the whole corrected trajectory and map are sent with it |
//!
//! The SLAM loop only copies the frame's points, pose and changed layers into an [`Update`]
//! and offers it to a bounded queue ([`QUEUE`] frames); when the queue is full the update is
//! dropped and counted, so the loop never waits for the view. A thread of its own turns updates
//! into messages and hands them to the SDK: its WebSocket server keeps a bounded backlog per
//! client and drops the oldest messages of a client that does not read; its MCAP writer writes
//! `slam.mcap.tmp` and renames it to `slam.mcap` when the run ends. The server only publishes:
//! it advertises no capability (no client publishing, parameters or services), and a client's
//! messages cannot change or stop the run.

use crate::io::error::FileError;
use foxglove::messages::{
    Color, FrameTransform, Log, PackedElementField, Point3, PointCloud, Pose as FgPose,
    PosesInFrame, Quaternion, SceneEntity, SceneUpdate, Timestamp, TriangleListPrimitive, Vector3,
};
use foxglove::{Context, WebSocketServer};
use slamesh_core::cell::{Axis, CellKey};
use slamesh_core::config::Config;
use slamesh_core::layer::{Layer, Shown};
use slamesh_core::{Capacity, Pipeline, Point, Pose};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TrySendError};
use std::thread::JoinHandle;

/// Frames the queue between the SLAM loop and the view's thread holds.
pub const QUEUE: usize = 4;
/// The trajectory is sent every this many frames.
pub const TRAJECTORY_EVERY: usize = 10;
/// Most poses a trajectory message holds.
pub const MAX_POSES: usize = 4096;
/// Messages a WebSocket client's backlog holds before its oldest are dropped.
pub const CLIENT_BACKLOG: usize = 256;
/// The address `--view` serves on when none is given: this machine only.
pub const DEFAULT_ADDRESS: &str = "127.0.0.1:8765";

/// What to show and record.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ViewOptions {
    /// Serve the live view on this `host:port`.
    pub serve: Option<String>,
    /// Write `slam.mcap` into the output folder.
    pub record: bool,
}

impl ViewOptions {
    /// True when there is something to do.
    pub fn is_on(&self) -> bool {
        self.serve.is_some() || self.record
    }
}

/// One frame for the view: copied out of the pipeline by the SLAM loop.
#[derive(Debug, Clone)]
pub struct Update {
    /// Frame index.
    pub frame: usize,
    /// The frame's time (seconds).
    pub stamp_s: f64,
    /// The estimated sensor pose.
    pub pose: Pose,
    /// The scan's points as registered, sensor frame.
    pub points: Vec<Point>,
    /// The map layers the frame changed, as they are after it (every layer after a loop
    /// closure).
    pub layers: Vec<(CellKey, Axis, Layer)>,
    /// After a loop closure: the whole corrected trajectory and what was closed.
    pub closed: Option<(Vec<Pose>, Vec<String>)>,
}

impl Update {
    /// The last frame `pipeline` took (frame `frame`, at `stamp_s`); `None` before the first.
    pub fn of<C: Capacity>(pipeline: &Pipeline<C>, frame: usize, stamp_s: f64) -> Option<Self> {
        let pose = pipeline.pose()?;
        let map = pipeline.map();
        let layers = pipeline
            .last_scan()
            .iter()
            .filter_map(|s| map.layer(&s.key, s.axis).map(|l| (s.key, s.axis, *l)))
            .collect();
        Some(Update {
            frame,
            stamp_s,
            pose,
            points: pipeline.last_points().to_vec(),
            layers,
            closed: None,
        })
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

/// The running view: the queue's sending end and the thread behind it.
pub struct View {
    tx: Option<SyncSender<Update>>,
    thread: Option<JoinHandle<Result<usize, String>>>,
    /// The address the server listens on, if serving (the port is the real one when `:0`
    /// was asked for).
    pub address: Option<String>,
    dropped: usize,
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
        let (tx, rx) = sync_channel(QUEUE);
        let config = *config;
        let thread = std::thread::Builder::new()
            .name("slamesh-view".into())
            .spawn(move || {
                let sent = publish(&ctx, rx, &config);
                if let Some(w) = writer {
                    w.close().map_err(|e| e.to_string())?;
                }
                if let Some(s) = server {
                    // Not waiting for the clients: one that does not read would hold the run.
                    s.stop().detach_all();
                }
                Ok(sent)
            })
            .map_err(|e| FileError::at(out, format!("cannot start the view: {e}")))?;
        Ok(Some(View {
            tx: Some(tx),
            thread: Some(thread),
            address,
            dropped: 0,
            record,
        }))
    }

    /// The view `opts` asks for, started, its address said on the terminal.
    pub fn for_run(opts: &crate::run::RunOptions) -> Result<Option<Self>, FileError> {
        let view = Self::start(&opts.view, &opts.out, &opts.config)?;
        if let Some(a) = view.as_ref().and_then(|v| v.address.as_ref()) {
            log::info!(
                "view: serving ws://{a} (Foxglove app: Open connection, Foxglove WebSocket)"
            );
        }
        Ok(view)
    }

    /// Finishes `view` if there is one ([`View::finish`]) and says what it did.
    pub fn close(view: Option<Self>) -> Result<(), FileError> {
        if let Some(v) = view {
            let stats = v.finish()?;
            log::info!(
                "view: {} frames shown or recorded, {} dropped (the view was behind)",
                stats.sent,
                stats.dropped
            );
        }
        Ok(())
    }

    /// Offers the last frame of `pipeline` to the view; never waits (a full queue drops it).
    pub fn frame<C: Capacity>(&mut self, pipeline: &Pipeline<C>, frame: usize, stamp_s: f64) {
        let (Some(tx), Some(update)) = (&self.tx, Update::of(pipeline, frame, stamp_s)) else {
            return;
        };
        match tx.try_send(update) {
            Ok(()) => {}
            Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => self.dropped += 1,
        }
    }

    /// Offers the frame `record` describes, as [`View::frame`], or as [`View::loop_closed`]
    /// (with the trajectory `path` gives) when loop closures came with it; nothing for a frame
    /// that failed.
    pub fn show<C: Capacity>(
        &mut self,
        pipeline: &Pipeline<C>,
        record: &crate::run::FrameRecord,
        path: impl FnOnce() -> Vec<Pose>,
    ) {
        if record.error.is_some() {
            return;
        }
        if record.loop_closures.is_empty() {
            self.frame(pipeline, record.frame, record.stamp);
        } else {
            self.loop_closed(
                pipeline,
                record.frame,
                record.stamp,
                path(),
                &record.loop_closures,
            );
        }
    }

    /// Offers the last frame of `pipeline` after a loop closure: with the whole map, the whole
    /// corrected `path` and the closures' descriptions. Never waits.
    pub fn loop_closed<C: Capacity>(
        &mut self,
        pipeline: &Pipeline<C>,
        frame: usize,
        stamp_s: f64,
        path: Vec<Pose>,
        closures: &[crate::loop_closure::Closure],
    ) {
        let (Some(tx), Some(mut update)) = (&self.tx, Update::of(pipeline, frame, stamp_s)) else {
            return;
        };
        update.layers = pipeline
            .map()
            .layers()
            .map(|l| (l.key, l.axis, *l.layer))
            .collect();
        update.closed = Some((path, closures.iter().map(|c| c.describe()).collect()));
        if tx.try_send(update).is_err() {
            self.dropped += 1;
        }
    }

    /// Sends what is queued, closes the recording (renamed to `slam.mcap`) and the server.
    pub fn finish(mut self) -> Result<ViewStats, FileError> {
        self.tx = None;
        let sent = match self.thread.take().map(JoinHandle::join) {
            Some(Ok(Ok(sent))) => sent,
            Some(Ok(Err(e))) => return Err(self.file_error(e)),
            Some(Err(_)) => return Err(self.file_error("the view's thread panicked".into())),
            None => 0,
        };
        if let Some((tmp, path)) = &self.record {
            std::fs::rename(tmp, path)
                .map_err(|e| FileError::at(path, format!("cannot write: {e}")))?;
        }
        Ok(ViewStats {
            sent,
            dropped: self.dropped,
        })
    }

    fn file_error(&self, reason: String) -> FileError {
        match &self.record {
            Some((_, path)) => FileError::at(path, reason),
            None => FileError::at(Path::new("--view"), reason),
        }
    }
}

/// `host:port` split; `None` when it is not that.
fn split_address(addr: &str) -> Option<(&str, u16)> {
    let (host, port) = addr.rsplit_once(':')?;
    Some((host.trim_matches(['[', ']']), port.parse().ok()?))
}

/// Turns every update from `rx` into messages on `ctx`'s channels until the SLAM loop closes
/// the queue; returns how many it published.
fn publish(ctx: &std::sync::Arc<Context>, rx: Receiver<Update>, config: &Config) -> usize {
    let scan = ctx.channel_builder("/scan").build::<PointCloud>();
    let tf = ctx.channel_builder("/tf").build::<FrameTransform>();
    let trajectory = ctx.channel_builder("/trajectory").build::<PosesInFrame>();
    let mesh = ctx.channel_builder("/mesh").build::<SceneUpdate>();
    let closures = ctx.channel_builder("/loop_closures").build::<Log>();
    let lattice = config.lattice().table();
    let shown = Shown::new(&config.mesh);
    let mut poses: Vec<FgPose> = Vec::new();
    let mut last = None;
    let mut sent = 0;
    for u in rx {
        let nanos = (u.stamp_s.max(0.0) * 1e9) as u64;
        let time = timestamp(u.stamp_s);
        scan.log_with_time(&point_cloud(&u, time), nanos);
        tf.log_with_time(
            &FrameTransform {
                timestamp: Some(time),
                parent_frame_id: "world".into(),
                child_frame_id: "sensor".into(),
                translation: Some(vector(&u.pose)),
                rotation: Some(quaternion(&u.pose)),
            },
            nanos,
        );
        poses.push(fg_pose(&u.pose));
        if let Some((path, notes)) = &u.closed {
            poses = path.iter().map(fg_pose).collect();
            for note in notes {
                let log = Log {
                    timestamp: Some(time),
                    level: foxglove::messages::log::Level::Info as i32,
                    message: note.clone(),
                    name: "slamesh".into(),
                    ..Log::default()
                };
                closures.log_with_time(&log, nanos);
            }
        }
        if sent % TRAJECTORY_EVERY == 0 || u.closed.is_some() {
            trajectory.log_with_time(&poses_in_frame(&poses, time), nanos);
        }
        let entities = u
            .layers
            .iter()
            .map(|(key, axis, layer)| entity(key, *axis, layer, &lattice, shown, time))
            .collect();
        mesh.log_with_time(
            &SceneUpdate {
                deletions: Vec::new(),
                entities,
            },
            nanos,
        );
        last = Some((time, nanos));
        sent += 1;
    }
    if let Some((time, nanos)) = last {
        trajectory.log_with_time(&poses_in_frame(&poses, time), nanos);
    }
    sent
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
fn point_cloud(u: &Update, time: Timestamp) -> PointCloud {
    let mut data = Vec::with_capacity(u.points.len() * 12);
    for p in &u.points {
        let w = u.pose * nalgebra::Point3::new(p[0] as f64, p[1] as f64, p[2] as f64);
        for c in [w.x, w.y, w.z] {
            data.extend_from_slice(&(c as f32).to_le_bytes());
        }
    }
    // foxglove.PackedElementField's FLOAT32.
    const FLOAT32: i32 = 7;
    let field = |name: &str, offset: u32| PackedElementField {
        name: name.into(),
        offset,
        r#type: FLOAT32,
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
