//! The node's way out: a [`Sink`] of the run that publishes each frame as ROS 2 messages.
//!
//! | topic | type | what |
//! |---|---|---|
//! | `odom` | `nav_msgs/Odometry` | every registered scan: `base_link` in `odom`, stamped with the scan's stamp (to the nanosecond), its covariance from the registration, its velocity from the last two poses with theirs (the two registrations' covariances over the time between them squared, in `base_link`; zeros when either is unknown) |
//! | `/tf` | `tf2_msgs/TFMessage` | `odom -> base_link` and `map -> odom` with every pose |
//! | `/tf_static` | `tf2_msgs/TFMessage` | `base_link ->` the scans' frame, once, when the `lidar_in_base` parameter gives it (the node sends it: [`crate::ros2::node::Advertised`]) |
//! | `path` | `nav_msgs/Path` | the trajectory in `map` (corrected after a loop closure) |
//! | `mesh` | `visualization_msgs/MarkerArray` | the tiles a frame changed ([`crate::ros2::mesh_tiles`]) |
//! | `map` | `nav_msgs/OccupancyGrid` | every `map_every` scans and at the end: the grid around the robot made again ([`crate::ros2::occupancy`]) |
//! | `/diagnostics` | `diagnostic_msgs/DiagnosticArray` | at most once a second: frames used and not, scans dropped and refused, latency |
//!
//! Frames: the engine estimates the LiDAR's pose in its world (the first scan's LiDAR frame,
//! or a saved map's frame). `map` is that world seen from the robot: with `E` the LiDAR's pose
//! on the robot (`lidar_in_base`), `base_link` in `map` is `E · T · E⁻¹`, so that the robot
//! starts at the identity. `odom` is continuous: it starts at the identity on the first scan
//! and follows the registered motion; a jump of the pose (a relocalization, a loop closure)
//! goes into `map -> odom`, and `odom` goes on as it was moving.

use crate::loop_closure::graph::local_covariance;
use crate::navmap::background::Seen;
use crate::ros2::listen::Counts;
use crate::ros2::mesh_tiles::{MeshTiles, FRAME_POINTS};
use crate::ros2::messages::{
    Covariance, DiagnosticArray, DiagnosticStatus, Header, KeyValue, MarkerArray, Odometry,
    PathMsg, PoseMsg, PoseStamped, PoseWithCovariance, TfMessage, Time, TransformStamped, Twist,
    TwistWithCovariance, Vector3,
};
use crate::ros2::occupancy::LiveMap;
use crate::ros2::path::BoundedPath;
use crate::ros2::settings::Frames;
use crate::run::memory;
use crate::run::sink::{FrameEvent, MapUpdate, Sink, SinkFault};
use crate::run::Summary;
use nalgebra::Matrix6;
use ros2_client::Publisher;
use ros2_client::WriteError;
use slamesh_core::Pose;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The node's publishers (those turned off are `None`).
pub struct Publishers {
    /// `odom`.
    pub odom: Publisher<Odometry>,
    /// `/tf`.
    pub tf: Option<Publisher<TfMessage>>,
    /// `path`.
    pub path: Publisher<PathMsg>,
    /// `mesh`.
    pub mesh: Option<Publisher<MarkerArray>>,
    /// `/diagnostics`.
    pub diagnostics: Publisher<DiagnosticArray>,
    /// `/tf_static`: the LiDAR on the robot, when a parameter gave it (sent once; kept for
    /// late subscribers).
    pub tf_static: Option<Publisher<TfMessage>>,
}

/// How often `/diagnostics` is published, at most.
const DIAGNOSTICS_EVERY: Duration = Duration::from_secs(1);
/// Latencies kept for the median and the 95th percentile.
const LATENCIES: usize = 100;

/// `odom` kept continuous; jumps go to `map -> odom`.
#[derive(Debug, Clone, Copy)]
struct OdomFrame {
    map_odom: Pose,
    odom_base: Pose,
    /// The last motion in `odom` (to carry it over a jump).
    step: Pose,
}

impl OdomFrame {
    /// The robot at `map_base`; `jumped` when the pose may have jumped.
    fn next(last: Option<Self>, map_base: Pose, jumped: bool) -> Self {
        let Some(l) = last else {
            return OdomFrame {
                map_odom: map_base,
                odom_base: Pose::identity(),
                step: Pose::identity(),
            };
        };
        if jumped {
            let odom_base = l.odom_base * l.step;
            return OdomFrame {
                map_odom: map_base * odom_base.inverse(),
                odom_base,
                step: l.step,
            };
        }
        let odom_base = l.map_odom.inverse() * map_base;
        OdomFrame {
            map_odom: l.map_odom,
            odom_base,
            step: l.odom_base.inverse() * odom_base,
        }
    }
}

/// A message the node could not publish: on which topic, and the transport's reason.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PublishError {
    /// The topic, as the node names it in messages (`odom`, `/tf`, `path`, `mesh`,
    /// `/diagnostics`).
    pub topic: &'static str,
    /// What RustDDS said.
    pub reason: String,
}

impl PublishError {
    /// The error of a publish on `topic` (the message itself is left out).
    fn on<D>(topic: &'static str) -> impl Fn(WriteError<D>) -> PublishError {
        move |e| PublishError {
            topic,
            reason: e.to_string(),
        }
    }
}

impl std::fmt::Display for PublishError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "ROS 2: cannot publish on {}: {}",
            self.topic, self.reason
        )
    }
}

impl std::error::Error for PublishError {}

/// A topic the node could not publish on stops its sink (the run goes on).
impl From<PublishError> for SinkFault {
    fn from(e: PublishError) -> Self {
        SinkFault::Failed(e.to_string())
    }
}

impl From<PublishError> for String {
    fn from(e: PublishError) -> String {
        e.to_string()
    }
}

/// The sink that publishes (see the module docs).
pub struct Ros2Sink {
    publishers: Publishers,
    frames: Frames,
    lidar_in_base: Pose,
    counts: Arc<Mutex<Counts>>,
    node: String,
    odom: Option<OdomFrame>,
    last: Option<(f64, Pose)>,
    /// The last pose's covariance in the robot's frame, (ω, ρ) order, when it was registered.
    last_local: Option<Matrix6<f64>>,
    path: BoundedPath,
    tiles: Option<MeshTiles>,
    /// The grid on `map` (it holds `map`'s publisher).
    map: Option<LiveMap>,
    latencies: Vec<f64>,
    used: u64,
    not_used: u64,
    published: u64,
    /// Mesh messages published, their markers and their triangles.
    markers: (u64, u64, u64),
    /// Messages not sent because a reader had not acknowledged the writer's window
    /// ([`crate::ros2::node::UNACKED`]): the mesh's (their tiles wait again) and the path's
    /// (the next one holds it all).
    not_acknowledged: u64,
    last_diagnostics: Option<Instant>,
    /// Whether `mesh` is published now (the parameter `publish_mesh`, settable while
    /// running).
    pub publish_mesh: Arc<std::sync::atomic::AtomicBool>,
}

impl Ros2Sink {
    /// Publishes on `publishers` in `frames`, the LiDAR at `lidar_in_base` on the robot;
    /// `tiles` for `mesh` and `map`, `map`'s grid; `counts` are the inputs' (for
    /// `diagnostics`), `node` the node's name.
    pub fn new(
        publishers: Publishers,
        frames: Frames,
        lidar_in_base: Pose,
        (tiles, map): (Option<MeshTiles>, Option<LiveMap>),
        counts: Arc<Mutex<Counts>>,
        node: String,
    ) -> Self {
        let path = BoundedPath::new(frames.map.clone());
        Ros2Sink {
            publishers,
            frames,
            lidar_in_base,
            counts,
            node,
            odom: None,
            last: None,
            last_local: None,
            path,
            tiles,
            map,
            latencies: Vec::new(),
            used: 0,
            not_used: 0,
            published: 0,
            markers: (0, 0, 0),
            not_acknowledged: 0,
            last_diagnostics: None,
            publish_mesh: Arc::new(std::sync::atomic::AtomicBool::new(true)),
        }
    }

    fn header(&self, stamp: Time, frame: &str) -> Header {
        Header {
            stamp,
            frame_id: frame.to_string(),
        }
    }

    /// The robot in `map` from the LiDAR's pose in the engine's world.
    fn base_of(&self, lidar: &Pose) -> Pose {
        self.lidar_in_base * lidar * self.lidar_in_base.inverse()
    }

    fn publish_pose(&mut self, e: &FrameEvent, lidar: &Pose) -> Result<(), PublishError> {
        // The scan's own stamp, to the nanosecond, for exact-time synchronisers.
        let stamp = e.record.stamp_ns.map_or_else(
            || Time::from_seconds(e.record.stamp),
            |ns| match crate::mutants::on("stamp-f64") {
                true => Time::from_seconds(ns as f64 * 1e-9),
                false => Time::from_nanoseconds(ns),
            },
        );
        let map_base = self.base_of(lidar);
        let jumped = e.record.notes.jumped;
        let odom = OdomFrame::next(self.odom, map_base, jumped);
        self.odom = Some(odom);
        // The registration's information is about the LiDAR's pose in the world; the robot's
        // pose there is `T · E⁻¹`.
        let base_in_world = lidar * self.lidar_in_base.inverse();
        let local = e
            .information
            .as_ref()
            .map(|info| local_covariance(info, &base_in_world));
        let covariance = local.map_or(Covariance::default(), |c| {
            ros_covariance(&c, &odom.odom_base)
        });
        let last_local = std::mem::replace(&mut self.last_local, local);
        let (twist, dt) = self.velocity(e.record.stamp, &odom.odom_base);
        // The velocity is the step between two registered poses over `dt`: its covariance the
        // sum of theirs (taken as independent) over `dt²`, in `base_link`.
        let twist_covariance = match (local, last_local, dt) {
            (Some(now), Some(before), Some(dt)) => {
                ros_covariance(&((now + before) / (dt * dt)), &Pose::identity())
            }
            _ => Covariance::default(),
        };
        let odometry = Odometry {
            header: self.header(stamp, &self.frames.odom),
            child_frame_id: self.frames.base.clone(),
            pose: PoseWithCovariance {
                pose: PoseMsg::from(&odom.odom_base),
                covariance,
            },
            twist: TwistWithCovariance {
                twist,
                covariance: twist_covariance,
            },
        };
        self.publishers
            .odom
            .publish(odometry)
            .map_err(PublishError::on("odom"))?;
        if let Some(tf) = &self.publishers.tf {
            let transforms = vec![
                TransformStamped {
                    header: self.header(stamp, &self.frames.map),
                    child_frame_id: self.frames.odom.clone(),
                    transform: PoseMsg::from(&odom.map_odom),
                },
                TransformStamped {
                    header: self.header(stamp, &self.frames.odom),
                    child_frame_id: self.frames.base.clone(),
                    transform: PoseMsg::from(&odom.odom_base),
                },
            ];
            tf.publish(TfMessage { transforms })
                .map_err(PublishError::on("/tf"))?;
        }
        let pose = PoseStamped {
            header: self.header(stamp, &self.frames.map),
            pose: PoseMsg::from(&map_base),
        };
        self.path.push(pose);
        if let Some(m) = &e.map {
            if let Some((corrected, _)) = &m.closed {
                self.correct_path(corrected);
            }
        }
        self.publish_path()
    }

    /// The path as it stands; held back when a reader has not acknowledged the writer's
    /// window (the next one holds it all).
    fn publish_path(&mut self) -> Result<(), PublishError> {
        match self.publishers.path.publish(self.path.msg().clone()) {
            Err(WriteError::WouldBlock { .. }) => {
                self.behind("path");
                Ok(())
            }
            r => r.map_err(PublishError::on("path")),
        }
    }

    /// A message on `topic` not sent: a reader has not acknowledged the writer's window of
    /// messages (said once, counted).
    fn behind(&mut self, topic: &str) {
        if self.not_acknowledged == 0 {
            log::warn!(
                "ROS 2: {topic}: a reader has not acknowledged the last {} messages: what \
                 would go beyond them is not sent while that lasts (the mesh's tiles wait again, \
                 the next path holds it all; said once, counted)",
                crate::ros2::node::UNACKED
            );
        }
        self.not_acknowledged += 1;
    }

    /// The velocity in the robot's frame from its last two poses in `odom`, and the time
    /// between them (`None`, and no velocity, for the first or a repeated stamp).
    fn velocity(&mut self, stamp: f64, odom_base: &Pose) -> (Twist, Option<f64>) {
        let last = self.last.replace((stamp, *odom_base));
        let Some((t0, p0)) = last else {
            return (Twist::default(), None);
        };
        let dt = stamp - t0;
        if dt.is_nan() || dt <= 1e-6 {
            return (Twist::default(), None);
        }
        let d = p0.inverse() * odom_base;
        let v = d.translation.vector / dt;
        let w = d.rotation.scaled_axis() / dt;
        let twist = Twist {
            linear: Vector3 {
                x: v.x,
                y: v.y,
                z: v.z,
            },
            angular: Vector3 {
                x: w.x,
                y: w.y,
                z: w.z,
            },
        };
        (twist, Some(dt))
    }

    /// The path after a loop closure: `corrected` holds every used frame's LiDAR pose.
    fn correct_path(&mut self, corrected: &[Pose]) {
        if let Some(m) = &mut self.map {
            m.correct(corrected);
        }
        let lidar = self.lidar_in_base;
        (self.path).correct(corrected, |c| PoseMsg::from(&(lidar * c * lidar.inverse())));
    }

    /// The tiles the frame changed wait their turn; the next ones within a frame's budget go
    /// out (all of them when `all`, at the end).
    fn publish_mesh(&mut self, update: Option<&MapUpdate>, all: bool) -> Result<(), PublishError> {
        let Some(tiles) = &mut self.tiles else {
            return Ok(());
        };
        if let Some(u) = update {
            if u.closed.is_some() {
                tiles.clear();
            }
            tiles.update(&u.layers);
        }
        let Some(publisher) = &self.publishers.mesh else {
            return Ok(());
        };
        // Off while running (`ros2 param set … publish_mesh false`): the tiles keep changing
        // and go out once it is on again.
        if !self.publish_mesh.load(std::sync::atomic::Ordering::Relaxed) {
            return Ok(());
        }
        // The mesh is in the engine's world; `map` is that world seen from the robot.
        let header = Header {
            stamp: update.map_or(self.path.msg().header.stamp, |u| {
                Time::from_seconds(u.stamp_s)
            }),
            frame_id: self.frames.map.clone(),
        };
        let budget = if all { usize::MAX } else { FRAME_POINTS };
        let placed = PoseMsg::from(&self.lidar_in_base);
        let mut messages = tiles.next_messages(budget, &header).into_iter();
        while let Some((mut message, keys)) = messages.next() {
            let markers = message.markers.len() as u64;
            let mut triangles = 0;
            for m in &mut message.markers {
                m.pose = placed;
                triangles += m.points.len() as u64 / 3;
            }
            match publisher.publish(message) {
                Ok(()) => {
                    self.markers.0 += 1;
                    self.markers.1 += markers;
                    self.markers.2 += triangles;
                }
                Err(WriteError::WouldBlock { .. }) => {
                    // This message's tiles and the frame's others wait again.
                    tiles.again(&keys);
                    for (_, rest) in messages {
                        tiles.again(&rest);
                    }
                    self.behind("mesh");
                    return Ok(());
                }
                Err(e) => return Err(PublishError::on("mesh")(e)),
            }
        }
        Ok(())
    }

    /// After a scan (`seen`, when it was used; `now`: at the end): the grid made again around
    /// the robot when due (it goes out from the map's own thread).
    fn publish_map(&mut self, seen: Option<Seen>, now: bool) {
        let (Some(map), Some(tiles)) = (&mut self.map, &self.tiles) else {
            return;
        };
        let header = Header {
            stamp: self.path.msg().header.stamp,
            frame_id: self.frames.map.clone(),
        };
        if now {
            map.finish(tiles, header);
        } else {
            map.scan(tiles, seen, header);
        }
    }

    fn publish_diagnostics(&mut self, stamp: f64, force: bool) -> Result<(), PublishError> {
        let due = self
            .last_diagnostics
            .is_none_or(|t| t.elapsed() >= DIAGNOSTICS_EVERY);
        if !(due || force) {
            return Ok(());
        }
        self.last_diagnostics = Some(Instant::now());
        let counts = self.counts.lock().map(|c| c.clone()).unwrap_or_default();
        let stamp = counts.clock_s.unwrap_or(stamp);
        let (median, p95) = percentiles(&self.latencies);
        let level = if counts.dropped + counts.refused + self.not_used > 0 {
            1
        } else {
            0
        };
        // The process's resident memory now and at its peak, as the kernel counts it.
        let mb = |b: Option<u64>| b.map_or(String::new(), |b| format!("{:.1}", b as f64 / 1e6));
        let kv = |k: &str, v: String| KeyValue {
            key: k.into(),
            value: v,
        };
        let status = DiagnosticStatus {
            level,
            name: format!("{}: pipeline", self.node),
            message: format!(
                "{} frames used, {} not; {} scans dropped (behind), {} refused",
                self.used, self.not_used, counts.dropped, counts.refused
            ),
            hardware_id: String::new(),
            values: vec![
                kv("frames_used", self.used.to_string()),
                kv("frames_not_used", self.not_used.to_string()),
                kv("scans_received", counts.received.to_string()),
                kv("scans_dropped", counts.dropped.to_string()),
                kv("messages_refused", counts.refused.to_string()),
                kv("last_refused", counts.last_refused.unwrap_or_default()),
                kv("latency_median_ms", format!("{median:.1}")),
                kv("latency_p95_ms", format!("{p95:.1}")),
                kv("initial_poses", counts.initial_poses.to_string()),
                kv("imu_readings", counts.imu_readings.to_string()),
                kv("imu_dropped", counts.imu_dropped.to_string()),
                kv("imu_late", counts.imu_late.to_string()),
                kv("save_requests", counts.save_requests.to_string()),
                kv(
                    "messages_not_acknowledged",
                    self.not_acknowledged.to_string(),
                ),
                kv("resident_mb", mb(memory::rss_bytes())),
                kv("peak_resident_mb", mb(memory::peak_rss_bytes())),
            ],
        };
        let array = DiagnosticArray {
            header: Header {
                stamp: Time::from_seconds(stamp),
                frame_id: String::new(),
            },
            status: vec![status],
        };
        self.publishers
            .diagnostics
            .publish(array)
            .map_err(PublishError::on("/diagnostics"))
    }
}

/// Median and 95th percentile (0 when there are none).
fn percentiles(v: &[f64]) -> (f64, f64) {
    if v.is_empty() {
        return (0.0, 0.0);
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let at = |q: f64| s[((s.len() - 1) as f64 * q).round() as usize];
    (at(0.5), at(0.95))
}

/// A covariance of `pose · exp(ε)`, `ε = (ω, ρ)` in the robot's frame, as ROS writes a pose's:
/// `(x, y, z, rotation about x, y, z)`, along the axes of the frame `pose` is in.
fn ros_covariance(local: &Matrix6<f64>, pose: &Pose) -> Covariance {
    let r = pose.rotation.to_rotation_matrix().into_inner();
    let mut b = Matrix6::zeros();
    // Rows of ROS's order from columns of (ω, ρ): x, y, z from ρ; rotations from ω.
    b.fixed_view_mut::<3, 3>(0, 3).copy_from(&r);
    b.fixed_view_mut::<3, 3>(3, 0).copy_from(&r);
    Covariance::from(&(b * local * b.transpose()))
}

impl Sink for Ros2Sink {
    fn name(&self) -> String {
        "ROS 2".into()
    }

    fn wants_map(&self) -> bool {
        self.tiles.is_some()
    }

    fn frame(&mut self, event: Arc<FrameEvent>) -> Result<(), SinkFault> {
        let e = &*event;
        if let Some(lidar) = e.pose {
            self.used += 1;
            self.publish_pose(e, &lidar)?;
            self.publish_mesh(e.map.as_ref(), false)?;
            // The map update's pose is the one its points were registered at.
            let seen = Seen {
                kept: &lidar,
                pose: e.map.as_ref().map_or(&lidar, |u| &u.pose),
                points: e.map.as_ref().map_or(&[][..], |u| &u.own_points[..]),
            };
            self.publish_map(Some(seen), false);
            self.published += 1;
        } else {
            self.not_used += 1;
        }
        if let Some(ms) = e.record.latency_ms {
            if self.latencies.len() == LATENCIES {
                self.latencies.remove(0);
            }
            self.latencies.push(ms);
        }
        Ok(self.publish_diagnostics(e.record.stamp, false)?)
    }

    fn finish(&mut self, summary: Option<&Summary>) -> Result<Option<String>, SinkFault> {
        let stamp = self.path.msg().header.stamp.seconds();
        self.publish_mesh(None, true)?;
        self.publish_map(None, true);
        self.publish_diagnostics(stamp, true)?;
        let _ = summary;
        let grids = self.map.as_ref().map_or(String::new(), |m| {
            let (n, median, p95, skipped, bytes) = m.costs();
            format!(
                ", the occupancy grid {} times ({n} updates, median {median:.1} ms, 95th \
                 percentile {p95:.1} ms, {skipped} skipped; {:.1} MB of cells)",
                m.sent(),
                bytes as f64 / 1e6
            )
        });
        let behind = match self.not_acknowledged {
            0 => String::new(),
            n => format!(", {n} messages held back (a reader did not acknowledge)"),
        };
        Ok(Some(format!(
            "published {} poses ({} frames not used), the mesh in {} messages ({} markers, {} \
             triangles){behind}{grids}",
            self.published, self.not_used, self.markers.0, self.markers.1, self.markers.2
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_failed_publish_names_its_topic_and_reason_not_its_message() {
        let big = vec![0u8; 1 << 20];
        let e = PublishError::on("mesh")(WriteError::WouldBlock { data: big });
        assert_eq!(e.topic, "mesh");
        let said = String::from(e);
        assert!(
            said.starts_with("ROS 2: cannot publish on mesh: "),
            "{said}"
        );
        assert!(
            said.len() < 200,
            "the message is left out: {} bytes",
            said.len()
        );
    }

    fn pose(x: f64, yaw: f64) -> Pose {
        Pose::from_parts(
            nalgebra::Translation3::new(x, 0.0, 0.0),
            nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
        )
    }

    #[test]
    fn odom_is_continuous_and_jumps_go_to_map_odom() {
        let a = OdomFrame::next(None, pose(5.0, 0.0), false);
        assert_eq!(a.odom_base, Pose::identity());
        let b = OdomFrame::next(Some(a), pose(6.0, 0.0), false);
        assert!((b.odom_base.translation.vector.x - 1.0).abs() < 1e-12);
        // A jump: odom goes on by the last step, map -> odom takes the rest.
        let c = OdomFrame::next(Some(b), pose(20.0, 0.5), true);
        assert!((c.odom_base.translation.vector.x - 2.0).abs() < 1e-12);
        let map_base = c.map_odom * c.odom_base;
        assert!((map_base.translation.vector.x - 20.0).abs() < 1e-9);
        assert!((map_base.rotation.angle() - 0.5).abs() < 1e-9);
    }

    #[test]
    fn covariance_moves_to_ros_order_and_axes() {
        let mut local = Matrix6::zeros();
        // Rotation about the robot's z (ω_z) and translation along its x (ρ_x).
        local[(2, 2)] = 4.0;
        local[(3, 3)] = 9.0;
        let c = ros_covariance(&local, &pose(0.0, std::f64::consts::FRAC_PI_2));
        // The robot's x is the frame's y; its z stays z.
        assert!((c.0[7] - 9.0).abs() < 1e-9, "{:?}", c.0);
        assert!((c.0[35] - 4.0).abs() < 1e-9);
        assert!(c.0[0].abs() < 1e-9);
    }

    #[test]
    fn percentiles_of_latencies() {
        assert_eq!(percentiles(&[]), (0.0, 0.0));
        let v: Vec<f64> = (1..=100).map(f64::from).collect();
        let (m, p) = percentiles(&v);
        assert!((m - 51.0).abs() < 1.0 && (p - 95.0).abs() < 1.0);
    }
}
