//! `slamesh ros2`: the pipeline as a ROS 2 node, with no ROS installation. It speaks DDS, ROS
//! 2's default middleware, through ros2-client on RustDDS (pure Rust), so a stock ROS 2
//! robot's nodes (Fast DDS, Cyclone DDS) talk to it untouched (the choice: docs/design.md
//! §2.2).
//!
//! The node is a run like any other: a live source of frames (the way in) and a sink of the
//! run's events (the way out), so its poses are `slamesh run`'s on the same scans.
//!
//! | what | module |
//! |---|---|
//! | what the node is told: names, remaps, parameters, domain | [`settings`] |
//! | its parameters served to `ros2 param` (list, get, set, describe), the live ones applied | [`parameters`] |
//! | the messages it sends and takes (`formats::ros_messages`, as ros2-client takes them) | [`messages`] |
//! | `points`: PointCloud2 bytes to scans, bad messages refused | [`clouds`] |
//! | the way in: subscriptions and the service on a thread, scans through a bounded queue | [`listen`] |
//! | what the way in counted, for `/diagnostics`, `report.json` and the closing line | [`counts`] |
//! | the way out: odometry, transforms, path, diagnostics | [`publish`] |
//! | the `path` message, bounded however long the run | [`path`] |
//! | the mesh as RViz markers, a tile at a time | [`mesh_tiles`] |
//! | the occupancy grid for Nav2, kept current window by window | [`occupancy`] |
//! | the robot's static transforms heard on `/tf_static` | [`transforms`] |
//! | the DDS participant, the node and its endpoints | [`node`] |
//! | why the node or one of its endpoints could not be made | [`node_error`] |

pub mod clouds;
pub mod counts;
pub mod listen;
pub mod mesh_tiles;
pub mod messages;
pub mod node;
pub mod node_error;
pub mod occupancy;
pub mod parameters;
pub mod path;
pub mod publish;
pub mod settings;
pub mod transforms;

pub use listen::Ros2Source;
pub use node::{Advertised, RosNode};
pub use publish::Ros2Sink;
pub use settings::NodeSettings;
