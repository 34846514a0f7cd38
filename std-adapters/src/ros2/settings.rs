//! What the node is told: its name and namespace, the topics' names after remapping, the
//! frames, the DDS domain and discovery range, and the parameters (from `--ros-args` and the
//! environment, [`crate::formats::ros_args`]).
//!
//! | parameter | type | default | what |
//! |---|---|---|---|
//! | `map_frame`, `odom_frame`, `base_frame` | text | `map`, `odom`, `base_link` | the frames of `/tf` and `odom` |
//! | `lidar_in_base` | 6 or 7 doubles | `/tf_static`'s, else identity | the LiDAR's pose on the robot: `[x, y, z, roll, pitch, yaw]` or `[x, y, z, qx, qy, qz, qw]`; given, it is also published on `/tf_static` (`base_frame` to the scans' frame); not given, the transform from `base_frame` to the scans' frame heard on `/tf_static` by the first scan (a `robot_state_publisher`'s) |
//! | `lidar_frame` | text | the first scan's | scans in another frame are refused |
//! | `queue` | integer | 2 | scans waiting for the pipeline, at most; a scan that finds it full is dropped |
//! | `publish_tf`, `publish_mesh`, `publish_map` | bool | true | whether `/tf`, `mesh` and `map` are published |
//! | `map_every` | integer | 10 | scans between two updates of `map` (1 to 1000) |
//! | `use_sim_time` | bool | false | stamp `diagnostics` with `/clock` |
//! | `use_imu` | bool | true | use the readings on `imu` (docs/design.md §1.19; its place on the LiDAR is the configuration's `[imu]`, or else `/tf_static`'s `base_link` -> the readings' frame) |
//! | `imu_wait` | seconds | 0.2 | with `use_imu`, once an IMU has been heard: how long after a scan came it waits for the readings that cover its sweep (0 to 2; 0: never waits) |
//! | `preset`, `config`, `threads`, `out`, `map`, `save_map`, `localize`, `loop_closure`, `navmap`, `dynamic`, `robot`, `navmap_resolution` | | | as the command's flags of the same names (`loop_closure` and `dynamic`: true or false; `loop_closure` on by default where the run can close loops, under a memory cap or window only when true; `robot` and `navmap_resolution` are the `map` topic's too) |
//!
//! Environment: `ROS_DOMAIN_ID` (0 to 232), `ROS_AUTOMATIC_DISCOVERY_RANGE` (`LOCALHOST` or
//! `OFF`: this machine only) and the older `ROS_LOCALHOST_ONLY=1`.

use crate::formats::ros_args::{ParamValue, RosArgs, RosArgsError};
use slamesh_core::Pose;
use std::collections::BTreeMap;

/// The node's name unless `__node` says otherwise.
pub const NODE_NAME: &str = "slamesh";

/// `imu_wait`'s default (seconds): two sweeps at 10 Hz. A driver that stamps a scan at its
/// sweep's start and publishes it at once sends it a sweep before the IMU's last reading over
/// it; this leaves as much again for an IMU whose transport lags the LiDAR's.
pub const IMU_WAIT_S: f64 = 0.2;

/// The longest `imu_wait` taken (seconds).
pub const MAX_IMU_WAIT_S: f64 = 2.0;

/// The highest domain id ROS 2 allows.
pub const MAX_DOMAIN_ID: u16 = 232;

/// Where the node's topics are, resolved (absolute) and remapped.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Topics {
    /// Scans in (`points`).
    pub points: String,
    /// IMU readings in (`imu`).
    pub imu: String,
    /// RViz's pose estimate in (`initialpose`).
    pub initialpose: String,
    /// Simulated time in (`/clock`).
    pub clock: String,
    /// The pose of every scan out (`odom`).
    pub odom: String,
    /// The trajectory out (`path`).
    pub path: String,
    /// The mesh out (`mesh`).
    pub mesh: String,
    /// The occupancy grid out (`map`).
    pub map: String,
    /// The node's health out (`/diagnostics`).
    pub diagnostics: String,
    /// Transforms out (`/tf`).
    pub tf: String,
    /// Static transforms in and out (`/tf_static`).
    pub tf_static: String,
    /// The map-saving service (`~/save_map`).
    pub save_map: String,
}

/// The frames the node names.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frames {
    /// The map's frame (`map`).
    pub map: String,
    /// The odometry frame (`odom`).
    pub odom: String,
    /// The robot (`base_link`).
    pub base: String,
}

/// Everything the node is told.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeSettings {
    /// The node's namespace (`/` when none).
    pub namespace: String,
    /// The node's name.
    pub name: String,
    /// The DDS domain.
    pub domain_id: u16,
    /// Discovery on this machine only.
    pub localhost_only: bool,
    /// The topics.
    pub topics: Topics,
    /// The frames.
    pub frames: Frames,
    /// The LiDAR's pose in the robot's frame, when the parameter gives it.
    pub lidar_in_base: Option<Pose>,
    /// The scans' frame, if named.
    pub lidar_frame: Option<String>,
    /// Scans waiting for the pipeline, at most.
    pub queue: usize,
    /// Publish `/tf`.
    pub publish_tf: bool,
    /// Publish `mesh`.
    pub publish_mesh: bool,
    /// Publish `map`, every this many scans (`None`: not at all).
    pub map_every: Option<usize>,
    /// Follow `/clock`.
    pub use_sim_time: bool,
    /// Use the readings on `imu`.
    pub use_imu: bool,
    /// How long a scan waits for the IMU's readings over its sweep ([`IMU_WAIT_S`]).
    pub imu_wait: std::time::Duration,
    /// The rest of the parameters (`preset`, `threads`, ...), for the command.
    pub params: BTreeMap<String, ParamValue>,
}

/// An environment variable's value, if set.
pub type Env<'a> = &'a dyn Fn(&str) -> Option<String>;

impl NodeSettings {
    /// From the command line's ROS arguments and the environment (`env`, the process's by
    /// [`NodeSettings::from_process`]). Errors name the argument, parameter or variable.
    pub fn new(args: &RosArgs, env: Env) -> Result<Self, SettingsError> {
        let namespace = match args.namespace.as_deref() {
            None | Some("/") => "/".to_string(),
            Some(ns) => format!("/{}", ns.trim_matches('/')),
        };
        let name = args.node.clone().unwrap_or_else(|| NODE_NAME.into());
        check_name(&name)?;
        let fqn = join(&namespace, &name);
        let mut params = args.parameters(&fqn)?;
        let mut take = |k: &str| params.remove(k);
        let text =
            |v: Option<ParamValue>, default: &str| v.map_or(default.to_string(), |v| v.as_text());
        let flag = |k: &str, v: Option<ParamValue>, default: bool| match v {
            None => Ok(default),
            Some(ParamValue::Bool(b)) => Ok(b),
            Some(other) => Err(BadParameter {
                name: k.into(),
                given: Some(other.as_text()),
                must_be: "true or false".into(),
            }),
        };
        let frames = Frames {
            map: text(take("map_frame"), "map"),
            odom: text(take("odom_frame"), "odom"),
            base: text(take("base_frame"), "base_link"),
        };
        let lidar_in_base = match take("lidar_in_base") {
            None => None,
            Some(v) => Some(pose_of(&v)?),
        };
        let queue = count("queue", take("queue"), 2)?;
        let map_every = count("map_every", take("map_every"), 10)?;
        let resolve = |n: &str| resolve(args, &namespace, &name, n);
        let topics = Topics {
            points: resolve("points"),
            imu: resolve("imu"),
            initialpose: resolve("initialpose"),
            clock: resolve("/clock"),
            odom: resolve("odom"),
            path: resolve("path"),
            mesh: resolve("mesh"),
            map: resolve("map"),
            diagnostics: resolve("/diagnostics"),
            tf: resolve("/tf"),
            tf_static: resolve("/tf_static"),
            save_map: resolve("~/save_map"),
        };
        Ok(NodeSettings {
            lidar_frame: take("lidar_frame").map(|v| v.as_text()),
            publish_tf: flag("publish_tf", take("publish_tf"), true)?,
            publish_mesh: flag("publish_mesh", take("publish_mesh"), true)?,
            map_every: flag("publish_map", take("publish_map"), true)?.then_some(map_every),
            use_sim_time: flag("use_sim_time", take("use_sim_time"), false)?,
            use_imu: flag("use_imu", take("use_imu"), true)?,
            imu_wait: seconds("imu_wait", take("imu_wait"), IMU_WAIT_S, MAX_IMU_WAIT_S)?,
            domain_id: domain_id(env)?,
            localhost_only: localhost_only(env),
            namespace,
            name,
            topics,
            frames,
            lidar_in_base,
            queue,
            params,
        })
    }

    /// [`new`](Self::new) with this process's environment.
    pub fn from_process(args: &RosArgs) -> Result<Self, SettingsError> {
        Self::new(args, &|k| std::env::var(k).ok())
    }

    /// The node's fully qualified name (`/ns/name`).
    pub fn fqn(&self) -> String {
        join(&self.namespace, &self.name)
    }
}

/// Why the node's settings could not be made from its arguments and environment.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SettingsError {
    /// The ROS arguments, or a parameter file they name.
    Args(RosArgsError),
    /// The node's name (`__node`): why it is not one.
    NodeName(String),
    /// A parameter out of its range or of the wrong type.
    Parameter(BadParameter),
    /// The `lidar_in_base` parameter: why it is not a pose.
    LidarInBase(String),
    /// An environment variable (`ROS_DOMAIN_ID`): why it is not read.
    Environment(String),
}

impl std::fmt::Display for SettingsError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            SettingsError::Args(e) => e.fmt(f),
            SettingsError::NodeName(why) => write!(f, "__node: {why}"),
            SettingsError::Parameter(p) => p.fmt(f),
            SettingsError::LidarInBase(why) => write!(f, "parameter lidar_in_base: {why}"),
            SettingsError::Environment(why) => f.write_str(why),
        }
    }
}

impl std::error::Error for SettingsError {}

impl From<RosArgsError> for SettingsError {
    fn from(e: RosArgsError) -> Self {
        SettingsError::Args(e)
    }
}

impl From<BadParameter> for SettingsError {
    fn from(p: BadParameter) -> Self {
        SettingsError::Parameter(p)
    }
}

/// A parameter whose value is out of its range or of the wrong type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BadParameter {
    /// The parameter.
    pub name: String,
    /// What was given, when it says something.
    pub given: Option<String>,
    /// What it must be (`1 to 1000`, `0 to 2 seconds`).
    pub must_be: String,
}

impl std::fmt::Display for BadParameter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.given {
            Some(v) => write!(f, "parameter {}: {v} is not {}", self.name, self.must_be),
            None => write!(f, "parameter {}: not {}", self.name, self.must_be),
        }
    }
}

/// A duration parameter from 0 to `max` seconds (a double or an integer), `default` when not
/// given.
fn seconds(
    name: &str,
    v: Option<ParamValue>,
    default: f64,
    max: f64,
) -> Result<std::time::Duration, BadParameter> {
    let s = match v {
        None => default,
        Some(ParamValue::Double(d)) => d,
        Some(ParamValue::Int(n)) => n as f64,
        // Not a number of seconds: refused below.
        Some(_) => f64::NAN,
    };
    if !(0.0..=max).contains(&s) {
        return Err(BadParameter {
            name: name.into(),
            given: None,
            must_be: format!("0 to {max} seconds"),
        });
    }
    Ok(std::time::Duration::from_secs_f64(s))
}

/// An integer parameter from 1 to 1000, `default` when not given.
fn count(name: &str, v: Option<ParamValue>, default: usize) -> Result<usize, BadParameter> {
    match v {
        None => Ok(default),
        Some(ParamValue::Int(n)) if (1..=1000).contains(&n) => Ok(n as usize),
        Some(other) => Err(BadParameter {
            name: name.into(),
            given: Some(other.as_text()),
            must_be: "1 to 1000".into(),
        }),
    }
}

fn join(namespace: &str, name: &str) -> String {
    if namespace == "/" {
        format!("/{name}")
    } else {
        format!("{namespace}/{name}")
    }
}

fn check_name(name: &str) -> Result<(), SettingsError> {
    let ok = !name.is_empty()
        && !name.starts_with(|c: char| c.is_ascii_digit())
        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    if ok {
        Ok(())
    } else {
        Err(SettingsError::NodeName(format!(
            "{name:?} is not a node name (letters, digits and _)"
        )))
    }
}

/// `name` as ROS resolves it for the node `node` in `namespace` (`~/x` is the node's own,
/// `/x` absolute, `x` in the namespace), then renamed if a remap names it (given or resolved).
pub fn resolve(args: &RosArgs, namespace: &str, node: &str, name: &str) -> String {
    let absolute = |n: &str| {
        if let Some(rest) = n.strip_prefix("~/") {
            format!("{}/{rest}", join(namespace, node))
        } else if n.starts_with('/') {
            n.to_string()
        } else {
            join(namespace, n)
        }
    };
    let resolved = absolute(name);
    match args
        .renamed(name)
        .or_else(|| args.renamed(&resolved))
        .or_else(|| name.strip_prefix('/').and_then(|bare| args.renamed(bare)))
    {
        Some(to) => absolute(to),
        None => resolved,
    }
}

/// `[x, y, z, roll, pitch, yaw]` (radians) or `[x, y, z, qx, qy, qz, qw]`.
fn pose_of(v: &ParamValue) -> Result<Pose, SettingsError> {
    let bad = |why: String| SettingsError::LidarInBase(why);
    let ParamValue::Doubles(d) = v else {
        return Err(bad(format!("{} is not a list of numbers", v.as_text())));
    };
    if !d.iter().all(|x| x.is_finite()) {
        return Err(bad("a number is not finite".into()));
    }
    let t = nalgebra::Translation3::new;
    match d[..] {
        [x, y, z, roll, pitch, yaw] => Ok(Pose::from_parts(
            t(x, y, z),
            nalgebra::UnitQuaternion::from_euler_angles(roll, pitch, yaw),
        )),
        [x, y, z, qx, qy, qz, qw] => {
            let q = nalgebra::Quaternion::new(qw, qx, qy, qz);
            if q.norm() < 1e-9 {
                return Err(bad("the quaternion is zero".into()));
            }
            Ok(Pose::from_parts(
                t(x, y, z),
                nalgebra::UnitQuaternion::from_quaternion(q),
            ))
        }
        _ => Err(bad(format!("{} numbers, not 6 or 7", d.len()))),
    }
}

fn domain_id(env: Env) -> Result<u16, SettingsError> {
    match env("ROS_DOMAIN_ID").filter(|s| !s.trim().is_empty()) {
        None => Ok(0),
        Some(s) => s
            .trim()
            .parse::<u16>()
            .ok()
            .filter(|d| *d <= MAX_DOMAIN_ID)
            .ok_or_else(|| {
                SettingsError::Environment(format!(
                    "ROS_DOMAIN_ID={s:?} is not a domain id (0 to {MAX_DOMAIN_ID})"
                ))
            }),
    }
}

fn localhost_only(env: Env) -> bool {
    match env("ROS_AUTOMATIC_DISCOVERY_RANGE").as_deref() {
        Some("LOCALHOST") | Some("OFF") => true,
        Some(_) => false,
        None => env("ROS_LOCALHOST_ONLY").as_deref() == Some("1"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings(line: &str, env: &[(&str, &str)]) -> Result<NodeSettings, SettingsError> {
        let args: Vec<String> = line.split_whitespace().map(String::from).collect();
        let env: Vec<(String, String)> = env
            .iter()
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        NodeSettings::new(&RosArgs::parse(&args)?, &|k| {
            env.iter().find(|(n, _)| n == k).map(|(_, v)| v.clone())
        })
    }

    #[test]
    fn defaults_need_no_arguments() {
        let s = settings("", &[]).unwrap();
        assert_eq!(s.fqn(), "/slamesh");
        assert_eq!(s.topics.points, "/points");
        assert_eq!(s.topics.tf, "/tf");
        assert_eq!(s.topics.save_map, "/slamesh/save_map");
        assert_eq!((s.domain_id, s.localhost_only, s.queue), (0, false, 2));
        assert_eq!(s.frames.base, "base_link");
        assert!(s.publish_tf && s.publish_mesh && !s.use_sim_time);
        assert_eq!((s.topics.map.as_str(), s.map_every), ("/map", Some(10)));
        let off = settings("--ros-args -p publish_map:=false -p map_every:=3", &[]).unwrap();
        assert_eq!(off.map_every, None);
        let every = settings("--ros-args -p map_every:=3", &[]).unwrap();
        assert_eq!(every.map_every, Some(3));
        assert_eq!(s.imu_wait.as_secs_f64(), IMU_WAIT_S);
        for (given, wait) in [("0.5", 0.5), ("0", 0.0), ("1", 1.0)] {
            let s = settings(&format!("--ros-args -p imu_wait:={given}"), &[]).unwrap();
            assert_eq!(s.imu_wait.as_secs_f64(), wait);
        }
        for bad in ["-0.1", "2.5", "soon", "true"] {
            let e = settings(&format!("--ros-args -p imu_wait:={bad}"), &[]).unwrap_err();
            assert!(matches!(&e, SettingsError::Parameter(p) if p.name == "imu_wait"));
            assert_eq!(e.to_string(), "parameter imu_wait: not 0 to 2 seconds");
        }
    }

    #[test]
    fn namespaces_remaps_and_parameters() {
        let s = settings(
            "--ros-args -r __ns:=/robot1 -r points:=/velodyne_points -r __node:=mapper \
             -p odom_frame:=odom1 -p queue:=4 -p lidar_in_base:=[0.5,0,1.0,0,0,0] \
             -p preset:=kitti -r /diagnostics:=/robot1/diag",
            &[("ROS_DOMAIN_ID", "7"), ("ROS_LOCALHOST_ONLY", "1")],
        )
        .unwrap();
        assert_eq!(s.topics.points, "/velodyne_points");
        assert_eq!(s.topics.odom, "/robot1/odom");
        assert_eq!(s.topics.tf, "/tf");
        assert_eq!(s.topics.diagnostics, "/robot1/diag");
        assert_eq!(s.topics.save_map, "/robot1/mapper/save_map");
        assert_eq!(s.frames.odom, "odom1");
        assert_eq!(s.queue, 4);
        assert_eq!(s.lidar_in_base.unwrap().translation.vector.x, 0.5);
        assert_eq!((s.domain_id, s.localhost_only), (7, true));
        assert_eq!(s.params["preset"], ParamValue::Text("kitti".into()));
    }

    #[test]
    fn the_example_parameter_file_is_read_as_documented() {
        let file = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/ros2/params.yaml");
        let s = settings(&format!("--ros-args --params-file {file}"), &[]).unwrap();
        assert_eq!(
            (s.queue, s.publish_tf, s.use_sim_time, s.use_imu),
            (2, true, false, true)
        );
        assert_eq!(s.map_every, Some(10));
        assert_eq!(s.lidar_in_base, None, "the robot's /tf_static unless given");
        assert_eq!(s.frames.map, "map");
        // What is left is the command's (cli/ros2.rs), as the module docs list.
        let left: Vec<&str> = s.params.keys().map(String::as_str).collect();
        assert_eq!(
            left,
            [
                "dynamic",
                "navmap",
                "navmap_resolution",
                "out",
                "preset",
                "robot",
                "threads"
            ]
        );
    }

    #[test]
    fn bad_settings_say_which() {
        for (line, env, what) in [
            ("", [("ROS_DOMAIN_ID", "300")], "ROS_DOMAIN_ID"),
            ("--ros-args -p queue:=0", [("X", "")], "queue"),
            ("--ros-args -p publish_tf:=3", [("X", "")], "publish_tf"),
            ("--ros-args -p map_every:=0", [("X", "")], "map_every"),
            (
                "--ros-args -p lidar_in_base:=[1,2]",
                [("X", "")],
                "lidar_in_base",
            ),
            ("--ros-args -r __node:=9x", [("X", "")], "__node"),
        ] {
            let e = settings(line, &env).unwrap_err().to_string();
            assert!(e.contains(what), "{line}: {e}");
        }
        let s = settings("", &[("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")]).unwrap();
        assert!(s.localhost_only);
    }
}
