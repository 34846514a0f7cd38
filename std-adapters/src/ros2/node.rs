//! The node itself: a DDS participant in the domain the environment names (on this machine
//! only when it says so), a ROS 2 node on it, and the endpoints the way in and the way out
//! use ([`crate::ros2::listen`], [`crate::ros2::publish`]).
//!
//! Quality of service, as ROS 2's own profiles are:
//! - `points`: best effort, the last [`POINTS_CACHE`] messages: it takes sensor drivers'
//!   best-effort publishers and reliable ones alike (a reliable reader would not match a
//!   best-effort writer). Its topic is made with resource limits of the same depth: RustDDS
//!   keeps each topic's samples in a cache of its own whether taken or not, 64 deep when the
//!   topic's QoS sets no limits (and it never shrinks): 64 clouds of 2 MB held for nothing. The
//!   listening thread takes each cloud as it comes and decodes it into the node's own queue,
//!   so the cache only has to cover the moments between two of its wake-ups;
//! - `odom`, `path`, `/diagnostics`: reliable, volatile, the last 10; `mesh` the last
//!   [`MESH_HISTORY`] (a frame's tiles go out in several messages); `map`: reliable, transient
//!   local, the last 1 (as Nav2's `map_server`: a planner that starts late gets the map);
//! - `/tf`: reliable, the last 100; `initialpose`, `/clock`: reliable and best effort, the
//!   last 10 and 1; `imu`: best effort, the last 400 (a second at 400 Hz); `~/save_map`: the
//!   services' default.

use crate::navmap::NavMapOptions;
use crate::ros2::clouds::{RawAdapter, RawMessage};
use crate::ros2::listen::{Endpoints, Names, Ros2Source};
use crate::ros2::mesh_tiles::MeshTiles;
use crate::ros2::messages::{
    Clock, DiagnosticArray, Header, Imu, MarkerArray, OccupancyGrid, Odometry, PathMsg, PoseMsg,
    PoseWithCovarianceStamped, TfMessage, Time, TransformStamped, TriggerRequest, TriggerResponse,
    Typed,
};
use crate::ros2::node_error::NodeError;
use crate::ros2::occupancy::LiveMap;
use crate::ros2::parameters::{self, Live};
use crate::ros2::publish::{Publishers, Ros2Sink};
use crate::ros2::settings::NodeSettings;
use crate::sources::FrameSource;
use ros2_client::parameters::ParameterValue;
use ros2_client::qos::{Durability, History, WhenFull};
use ros2_client::{
    Context, MessageTypeName, Name, Node, NodeName, Publisher, QosProfile, ServiceMapping,
    ServiceTypeName, Subscription,
};
use rustdds::policy::ResourceLimits;
use rustdds::{DomainParticipantBuilder, QosPolicies, QosPolicyBuilder, TopicKind};
use serde::de::DeserializeOwned;
use serde::Serialize;
use slamesh_core::layer::Shown;
use slamesh_core::{Config, Pose};
use std::net::{IpAddr, Ipv4Addr};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// A running node: its DDS participant and ROS 2 node (held while the endpoints are used).
pub struct RosNode {
    /// What it was told.
    pub settings: NodeSettings,
    /// What can be set while it runs.
    pub live: Live,
    /// Dropped before the context it lives in (fields drop in order).
    node: Node,
    context: Context,
}

/// Mesh messages a late or slow subscriber can still be sent again: a frame's tiles go out in
/// several messages (a first frame's in dozens), and a reliable writer repairs only what its
/// history still holds.
pub const MESH_HISTORY: usize = 64;

/// Messages of `mesh` and `path` a reliable writer keeps for readers that have not
/// acknowledged them, at most. RustDDS's own bound is 8 192, and a writer with no reader at all
/// keeps that many (it counts none as acknowledged): the mesh's messages of a 150-scan drive,
/// 142 MB, were all still held at its end (heaptrack). Past the bound the node holds a message
/// back rather than wait ([`crate::ros2::publish`]). A frame sends about 12 mesh messages;
/// readers acknowledge within a heartbeat or two.
pub const UNACKED: usize = 128;

/// Grids on `map` its writer keeps unacknowledged, at most (a grid is up to a few MB; one goes
/// out every `map_every` scans, from the map's own thread, which waits its turn).
pub const MAP_UNACKED: usize = 8;

/// Clouds RustDDS's cache of `points` keeps (taken or not; see the module's docs): two
/// clouds that come between two of the listening thread's wake-ups are both kept.
pub const POINTS_CACHE: usize = 2;

/// As Nav2's `map_server` offers `map`: reliable, the last one kept for late subscribers.
fn latched() -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 1 })
}

/// `points`' QoS, for its topic and its reader (see the module's docs): best effort, the last
/// `depth` clouds.
fn points_qos(depth: usize) -> QosProfile {
    QosProfile::subscription_default()
        .reliability_best_effort()
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth })
}

/// `qos` for a topic and its endpoints, with resource limits of `samples`: without limits
/// RustDDS keeps 64 samples in a topic's cache, taken or not, and a reliable writer up to
/// 8 192 that some reader has not acknowledged. With them a reliable writer whose window is
/// full refuses the next sample (`WouldBlock`, at once or after its wait): the small messages
/// (`odom`, `/tf`, `/diagnostics`) keep RustDDS's bound, so that a stuck subscriber never
/// holds the odometry up.
fn limited(qos: &QosProfile, samples: usize) -> QosPolicies {
    let samples = i32::try_from(samples).unwrap_or(i32::MAX);
    let limits = QosPolicyBuilder::new()
        .resource_limits(ResourceLimits {
            max_samples: samples,
            max_instances: 1,
            max_samples_per_instance: samples,
        })
        .build();
    QosPolicies::from(qos).modify_by(&limits)
}

/// As tf2's static listener reads `/tf_static`: reliable, transient local (a robot's static
/// transforms are sent once, before the node may start), the last 100.
fn latched_in() -> QosProfile {
    QosProfile::subscription_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 100 })
}

/// [`reliable`], but a message the writer's window of [`UNACKED`] has no room for is refused
/// at once (`WhenFull::Fail`), not waited for: for topics whose next message makes up for one
/// held back (`mesh`'s tiles wait again, a `path` holds the whole path).
fn reliable_or_held_back(depth: usize) -> QosProfile {
    reliable(depth).reliability_reliable(WhenFull::Fail)
}

fn reliable(depth: usize) -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth })
}

/// [`NodeError::Start`]: `doing` failed with `e`.
fn start(doing: String, e: impl std::fmt::Debug) -> NodeError {
    NodeError::Start {
        doing,
        why: format!("{e:?}"),
    }
}

/// [`NodeError::Topic`]: `doing` on topic `name` failed with `e`.
fn on_topic(name: &str, doing: &'static str, e: impl std::fmt::Debug) -> NodeError {
    NodeError::Topic {
        name: name.to_string(),
        doing,
        why: format!("{e:?}"),
    }
}

/// The node's name as ros2-client takes it.
fn node_name(settings: &NodeSettings) -> Result<NodeName, NodeError> {
    NodeName::new(&settings.namespace, &settings.name).map_err(|e| NodeError::Name {
        name: settings.fqn(),
        kind: "a node name",
        why: format!("{e:?}"),
    })
}

/// `/a/b/c` as ros2-client names it: namespace `/a/b`, base name `c`.
fn name(full: &str) -> Result<Name, NodeError> {
    let (ns, base) = full.rsplit_once('/').unwrap_or(("", full));
    let ns = if ns.is_empty() { "/" } else { ns };
    Name::new(ns, base).map_err(|e| NodeError::Name {
        name: full.to_string(),
        kind: "a ROS 2 name",
        why: format!("{e:?}"),
    })
}

/// The log's lines at info level and above on `/rosout` too, as `name`'s
/// (`rcl_interfaces/Log`, [`crate::io::log_tap`]), until the node is dropped.
fn rosout(node: &ros2_client::Node, name: &str) {
    use ros2_client::log::LogLevel;
    use ros2_client::RosoutRaw;
    let handle = std::sync::Mutex::new(node.logging_handle());
    let name = name.to_string();
    crate::io::log_tap::install(Box::new(move |level, text, file, line| {
        let level = match level {
            log::Level::Error => LogLevel::Error,
            log::Level::Warn => LogLevel::Warn,
            log::Level::Info => LogLevel::Info,
            log::Level::Debug | log::Level::Trace => LogLevel::Debug,
        };
        let now = ros2_client::builtin_interfaces::Time::now();
        if let Ok(h) = handle.lock() {
            h.rosout_raw(now, level, &name, text, file, "", line);
        }
    }));
}

impl Drop for RosNode {
    fn drop(&mut self) {
        crate::io::log_tap::remove();
    }
}

impl RosNode {
    /// Joins the domain and starts the node, its parameters declared with `values` and served
    /// ([`crate::ros2::parameters`]).
    pub fn start(
        settings: NodeSettings,
        values: Vec<(String, ParameterValue)>,
    ) -> Result<Self, NodeError> {
        let mut participant = DomainParticipantBuilder::new(settings.domain_id);
        if settings.localhost_only {
            participant = participant.with_only_networks([IpAddr::V4(Ipv4Addr::LOCALHOST)]);
        }
        let participant = participant
            .build()
            .map_err(|e| start(format!("join DDS domain {}", settings.domain_id), e))?;
        let context = Context::from_domain_participant(participant)
            .map_err(|e| start("start ROS 2".into(), e))?;
        let node_name = node_name(&settings)?;
        let live = Live::new(settings.publish_mesh);
        let mut node = context
            .new_node(node_name, parameters::options(values, &live))
            .map_err(|e| start(format!("start the node {}", settings.fqn()), e))?;
        live.started();
        rosout(&node, &settings.name);
        // The parameter services: ros2-client's spinner, until the node is dropped.
        let spinner = node
            .spinner()
            .map_err(|e| start("serve the parameters".into(), e))?;
        std::thread::Builder::new()
            .name("slamesh-params".into())
            .spawn(move || {
                if let Err(e) = futures::executor::block_on(spinner.spin()) {
                    log::warn!("the parameter services stopped: {e:?}");
                }
            })
            .map_err(|e| start("start the parameters' thread".into(), e))?;
        Ok(RosNode {
            settings,
            live,
            node,
            context,
        })
    }

    /// Topic `full` of `M`s, made as `Node::create_topic` makes it, with resource limits of
    /// `samples` when given ([`limited`]; its writers and readers inherit them).
    fn topic<M: Typed>(
        &mut self,
        full: &str,
        qos: &QosProfile,
        samples: Option<usize>,
    ) -> Result<rustdds::Topic, NodeError> {
        let (package, type_name) = M::TYPE;
        let qos = match samples {
            Some(n) => limited(qos, n),
            None => QosPolicies::from(qos),
        };
        let node_name = node_name(&self.settings)?;
        self.context
            .domain_participant()
            .create_topic(
                name(full)?.to_dds_name("rt", &node_name, ""),
                MessageTypeName::new(package, type_name).dds_msg_type(),
                &qos,
                TopicKind::NoKey,
            )
            .map_err(|e| on_topic(full, "create the topic", e))
    }

    /// A publisher on `full`, its topic limited to `samples` when given ([`limited`]).
    fn publisher<M: Typed + Serialize>(
        &mut self,
        full: &str,
        qos: QosProfile,
        samples: Option<usize>,
    ) -> Result<Publisher<M>, NodeError> {
        let topic = self.topic::<M>(full, &qos, samples)?;
        self.node
            .create_publisher(&topic, Some(qos))
            .map_err(|e| on_topic(full, "publish", e))
    }

    fn subscription<M: Typed + DeserializeOwned + 'static>(
        &mut self,
        full: &str,
        qos: QosProfile,
    ) -> Result<Subscription<M>, NodeError> {
        let topic = self.topic::<M>(full, &qos, None)?;
        self.node
            .create_subscription(&topic, Some(qos))
            .map_err(|e| on_topic(full, "subscribe", e))
    }

    /// The way in: subscriptions and the service, on a thread of their own, until `stop`.
    pub fn listen(&mut self, stop: Arc<AtomicBool>) -> Result<Ros2Source, NodeError> {
        let t = self.settings.topics.clone();
        let qos = points_qos(POINTS_CACHE);
        let topic = self.topic::<RawMessage>(&t.points, &qos, Some(POINTS_CACHE))?;
        let reader_qos = limited(&qos, POINTS_CACHE);
        let subscriber = (self.context.domain_participant())
            .create_subscriber(&reader_qos)
            .map_err(|e| on_topic(&t.points, "subscribe", e))?;
        let points = subscriber
            .create_simple_datareader_no_key::<RawMessage, RawAdapter>(&topic, Some(reader_qos))
            .map_err(|e| on_topic(&t.points, "subscribe", e))?;
        let clock = match self.settings.use_sim_time {
            true => Some(
                self.subscription::<Clock>(
                    &t.clock,
                    QosProfile::subscription_default()
                        .reliability_best_effort()
                        .history(History::KeepLast { depth: 1 }),
                )?,
            ),
            false => None,
        };
        let save_map = self
            .node
            .create_server::<TriggerRequest, TriggerResponse>(
                ServiceMapping::Enhanced,
                &name(&t.save_map)?,
                &ServiceTypeName::new("std_srvs", "Trigger"),
                reliable(10),
                reliable(10),
            )
            .map_err(|e| on_topic(&t.save_map, "offer the service", e))?;
        let endpoints = Endpoints {
            points,
            initialpose: self
                .subscription::<PoseWithCovarianceStamped>(&t.initialpose, reliable(10))?,
            imu: self.subscription::<Imu>(
                &t.imu,
                QosProfile::subscription_default()
                    .reliability_best_effort()
                    .history(History::KeepLast { depth: 400 }),
            )?,
            clock,
            save_map,
            tf_static: self.subscription::<TfMessage>(&t.tf_static, latched_in())?,
        };
        let names = Names {
            points: t.points.clone(),
            initialpose: t.initialpose.clone(),
        };
        // Readings that go unused are not waited for.
        let imu_wait = match self.settings.use_imu {
            true => self.settings.imu_wait,
            false => std::time::Duration::ZERO,
        };
        Ros2Source::start(
            endpoints,
            names,
            (self.settings.queue, imu_wait),
            self.settings.lidar_frame.clone(),
            stop,
        )
    }

    /// The way out, advertised: every output topic, at start (before the first scan decides
    /// the run's scale), so that a subscriber or `ros2 topic list` finds them at once.
    pub fn advertise(&mut self) -> Result<Advertised, NodeError> {
        let s = self.settings.clone();
        let t = &s.topics;
        let publishers = Publishers {
            odom: self.publisher::<Odometry>(&t.odom, reliable(10), None)?,
            tf: match s.publish_tf {
                true => Some(self.publisher::<TfMessage>(&t.tf, reliable(100), None)?),
                false => None,
            },
            path: self.publisher::<PathMsg>(&t.path, reliable_or_held_back(10), Some(UNACKED))?,
            mesh: match s.publish_mesh {
                true => Some(self.publisher::<MarkerArray>(
                    &t.mesh,
                    reliable_or_held_back(MESH_HISTORY),
                    Some(UNACKED),
                )?),
                false => None,
            },
            diagnostics: self.publisher::<DiagnosticArray>(&t.diagnostics, reliable(10), None)?,
            // The LiDAR's place, when the parameter gives it, for the robot's other nodes.
            tf_static: match s.lidar_in_base {
                Some(_) => Some(self.publisher::<TfMessage>(&t.tf_static, latched(), None)?),
                None => None,
            },
        };
        let map = match s.map_every {
            Some(_) => {
                Some(self.publisher::<OccupancyGrid>(&t.map, latched(), Some(MAP_UNACKED))?)
            }
            None => None,
        };
        let mut advertised = Advertised {
            publishers,
            map,
            settings: s,
            live: self.live.clone(),
            static_sent: false,
        };
        // With the scans' frame named, the LiDAR's place goes out at once.
        if let Some(frame) = advertised.settings.lidar_frame.clone() {
            advertised.send_static(&frame);
        }
        Ok(advertised)
    }
}

/// The node's output topics, advertised ([`RosNode::advertise`]), waiting for the run's
/// configuration to become its sink.
pub struct Advertised {
    publishers: Publishers,
    map: Option<Publisher<OccupancyGrid>>,
    settings: NodeSettings,
    live: Live,
    /// Whether the LiDAR's place went out on `/tf_static`.
    static_sent: bool,
}

impl Advertised {
    /// Sends the `lidar_in_base` parameter on `/tf_static` (the robot's frame to `frame`),
    /// when it was given.
    fn send_static(&mut self, frame: &str) {
        let (Some(publisher), Some(pose)) =
            (&self.publishers.tf_static, self.settings.lidar_in_base)
        else {
            return;
        };
        let transform = TransformStamped {
            header: Header {
                stamp: Time::default(),
                frame_id: self.settings.frames.base.clone(),
            },
            child_frame_id: frame.to_string(),
            transform: PoseMsg::from(&pose),
        };
        let message = TfMessage {
            transforms: vec![transform],
        };
        match publisher.publish(message) {
            Ok(()) => self.static_sent = true,
            Err(e) => log::warn!("/tf_static: {e:?}"),
        }
    }

    /// The LiDAR's pose on the robot: the parameter's, else `/tf_static`'s from the robot's
    /// frame to the scans' (waiting for the first scan, which names it), else the identity;
    /// said.
    pub fn lidar_in_base(&self, source: &mut Ros2Source) -> Pose {
        let s = &self.settings;
        if let Some(p) = s.lidar_in_base {
            return p;
        }
        // The first scan (or the stream's end): nothing is published before it anyway.
        source.has(0);
        let frame = s.lidar_frame.clone().or_else(|| source.scans_frame());
        let heard = frame
            .as_deref()
            .and_then(|f| Some((f, source.static_transform(&s.frames.base, f)?)));
        match heard {
            Some((f, p)) => {
                let t = p.translation.vector;
                log::info!(
                    "the LiDAR on the robot from /tf_static: {} -> {f} at ({:.3}, {:.3}, {:.3}) m",
                    s.frames.base,
                    t.x,
                    t.y,
                    t.z
                );
                p
            }
            None => {
                log::info!(
                    "the LiDAR on the robot: the identity (no lidar_in_base parameter, and \
                     /tf_static has said nothing of {} -> {})",
                    s.frames.base,
                    frame.as_deref().unwrap_or("the scans' frame")
                );
                Pose::identity()
            }
        }
    }

    /// The IMU on the LiDAR from `/tf_static` ([`crate::ros2::transforms::imu_on_lidar`]),
    /// once the first scan came (readings before it name their frame), the LiDAR at
    /// `lidar_in_base` on the robot; `None` when the readings named no frame or the transform
    /// was not heard (the configuration's `[imu]` place stands).
    pub fn lidar_from_imu(&self, source: &mut Ros2Source, lidar_in_base: &Pose) -> Option<Pose> {
        source.has(0);
        let imu = source.imu_frame()?;
        let scans = source.scans_frame();
        let base = &self.settings.frames.base;
        let frames = (imu.as_str(), scans.as_deref(), base.as_str());
        let placed =
            crate::ros2::transforms::imu_on_lidar(frames, lidar_in_base, source.transforms())?;
        let t = placed.translation.vector;
        log::info!(
            "the IMU on the LiDAR from /tf_static: {base} -> {imu}, at ({:.3}, {:.3}, {:.3}) m \
             from the LiDAR, turned {:.1} degrees",
            t.x,
            t.y,
            t.z,
            placed.rotation.angle().to_degrees()
        );
        Some(placed)
    }

    /// The publishers as a sink of the run; `config` is the run's (the mesh's lattice and
    /// what it shows); `source` the way in (its counts go into `diagnostics`); `grid` the
    /// `map` topic's; the LiDAR on the robot at `lidar_in_base` ([`Self::lidar_in_base`]),
    /// published on `/tf_static` when a parameter gave it.
    pub fn sink(
        mut self,
        config: &Config,
        source: &Ros2Source,
        grid: NavMapOptions,
        lidar_in_base: Pose,
    ) -> Ros2Sink {
        if !self.static_sent {
            let frame = source.scans_frame().unwrap_or_else(|| "lidar".into());
            self.send_static(&frame);
        }
        let s = self.settings;
        // The grid is made from the mesh's tiles, kept also when the mesh is not published.
        let tiles = (s.publish_mesh || s.map_every.is_some())
            .then(|| MeshTiles::new(config.lattice().table(), Shown::new(&config.mesh)));
        let map = match (s.map_every, self.map) {
            (Some(every), Some(publisher)) => {
                let out = Box::new(move |grid| match publisher.publish(grid) {
                    Ok(()) => true,
                    Err(e) => {
                        log::warn!("map: {e}");
                        false
                    }
                });
                Some(LiveMap::new(every, lidar_in_base, grid, out))
            }
            _ => None,
        };
        let mut sink = Ros2Sink::new(
            self.publishers,
            s.frames.clone(),
            lidar_in_base,
            (tiles, map),
            source.counts(),
            s.fqn(),
        );
        sink.publish_mesh = self.live.publish_mesh;
        sink
    }
}
