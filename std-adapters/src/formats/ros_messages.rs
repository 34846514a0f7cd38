//! ROS 2 messages as serde types laid out for CDR: each struct lists its message's fields in
//! the order of its `.msg` file (Jazzy and later), so that a CDR serializer writes, and a CDR
//! deserializer reads, the message as ROS 2 does; [`Typed::TYPE`] names it (`package/Name`,
//! which DDS spells `package::msg::dds_::Name_`). The ROS 2 node sends and takes these
//! (`crate::ros2`, feature `ros2`); the decoding of those it takes is fuzzed
//! (`fuzz/fuzz_targets/ros_messages.rs`).
//!
//! `sensor_msgs/PointCloud2` is not here: it is read from its bytes as they come, by
//! [`crate::formats::pointcloud2`].

use nalgebra::Matrix6;
use serde::de::{self, SeqAccess, Visitor};
use serde::ser::SerializeTuple;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use slamesh_core::Pose;
use std::fmt;

/// A message type: its package and name.
pub trait Typed {
    /// `(package, name)`, as in `nav_msgs/Odometry`.
    const TYPE: (&'static str, &'static str);
}

macro_rules! typed {
    ($t:ty, $package:literal, $name:literal) => {
        impl Typed for $t {
            const TYPE: (&'static str, &'static str) = ($package, $name);
        }
    };
}

/// `builtin_interfaces/Time`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Time {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds within the second.
    pub nanosec: u32,
}

impl Time {
    /// `seconds` (non-negative; a negative or non-finite one is zero).
    pub fn from_seconds(seconds: f64) -> Self {
        if !seconds.is_finite() || seconds <= 0.0 {
            return Time::default();
        }
        let sec = seconds.floor().min(i32::MAX as f64);
        let nanosec = ((seconds - sec) * 1e9).round().min(999_999_999.0) as u32;
        Time {
            sec: sec as i32,
            nanosec,
        }
    }

    /// In seconds.
    pub fn seconds(&self) -> f64 {
        self.sec as f64 + self.nanosec as f64 * 1e-9
    }

    /// `ns` nanoseconds since the epoch, exactly (seconds out of `i32`'s range are clamped).
    pub fn from_nanoseconds(ns: i64) -> Self {
        let (sec, nanosec) = (ns.div_euclid(1_000_000_000), ns.rem_euclid(1_000_000_000));
        Time {
            sec: sec.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32,
            nanosec: nanosec as u32,
        }
    }

    /// In nanoseconds, exactly.
    pub fn nanoseconds(&self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }
}

/// `std_msgs/Header`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Header {
    /// When.
    pub stamp: Time,
    /// In which frame.
    pub frame_id: String,
}

/// `geometry_msgs/Point` (and `Vector3`: the same three doubles).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// `geometry_msgs/Quaternion`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

/// `geometry_msgs/Pose` (and `Transform`: a translation and a rotation, in the same order).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseMsg {
    /// Position (translation).
    pub position: Vector3,
    /// Orientation (rotation).
    pub orientation: Quaternion,
}

impl From<&Pose> for PoseMsg {
    fn from(p: &Pose) -> Self {
        let t = p.translation.vector;
        let q = p.rotation;
        PoseMsg {
            position: Vector3 {
                x: t.x,
                y: t.y,
                z: t.z,
            },
            orientation: Quaternion {
                x: q.i,
                y: q.j,
                z: q.k,
                w: q.w,
            },
        }
    }
}

impl PoseMsg {
    /// As a pose; `None` when a number is not finite or the quaternion is zero.
    pub fn to_pose(&self) -> Option<Pose> {
        let (p, o) = (self.position, self.orientation);
        let all = [p.x, p.y, p.z, o.x, o.y, o.z, o.w];
        if !all.iter().all(|v| v.is_finite()) {
            return None;
        }
        let q = nalgebra::Quaternion::new(o.w, o.x, o.y, o.z);
        if q.norm() < 1e-9 {
            return None;
        }
        Some(Pose::from_parts(
            nalgebra::Translation3::new(p.x, p.y, p.z),
            nalgebra::UnitQuaternion::from_quaternion(q),
        ))
    }
}

/// A 6 x 6 covariance, row by row (`float64[36]`: a fixed array, no length in CDR).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Covariance(pub [f64; 36]);

impl Default for Covariance {
    fn default() -> Self {
        Covariance([0.0; 36])
    }
}

impl From<&Matrix6<f64>> for Covariance {
    fn from(m: &Matrix6<f64>) -> Self {
        Covariance(std::array::from_fn(|k| m[(k / 6, k % 6)]))
    }
}

impl Serialize for Covariance {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut t = s.serialize_tuple(36)?;
        for v in &self.0 {
            t.serialize_element(v)?;
        }
        t.end()
    }
}

impl<'de> Deserialize<'de> for Covariance {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Values;
        impl<'de> Visitor<'de> for Values {
            type Value = Covariance;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("36 doubles")
            }
            fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Covariance, A::Error> {
                let mut c = [0.0; 36];
                for (k, v) in c.iter_mut().enumerate() {
                    *v = seq
                        .next_element()?
                        .ok_or_else(|| de::Error::invalid_length(k, &self))?;
                }
                Ok(Covariance(c))
            }
        }
        d.deserialize_tuple(36, Values)
    }
}

/// `geometry_msgs/PoseWithCovariance`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovariance {
    /// The pose.
    pub pose: PoseMsg,
    /// Its covariance: x, y, z, then rotations about x, y, z.
    pub covariance: Covariance,
}

/// `geometry_msgs/Twist`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Twist {
    /// Linear velocity (m/s).
    pub linear: Vector3,
    /// Angular velocity (rad/s).
    pub angular: Vector3,
}

/// `geometry_msgs/TwistWithCovariance`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct TwistWithCovariance {
    /// The twist.
    pub twist: Twist,
    /// Its covariance.
    pub covariance: Covariance,
}

/// `nav_msgs/Odometry`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Odometry {
    /// Stamp and parent frame (`odom`).
    pub header: Header,
    /// The moving frame (`base_link`).
    pub child_frame_id: String,
    /// Its pose in the parent frame.
    pub pose: PoseWithCovariance,
    /// Its velocity, in the child frame.
    pub twist: TwistWithCovariance,
}
typed!(Odometry, "nav_msgs", "Odometry");

/// `geometry_msgs/TransformStamped`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TransformStamped {
    /// Stamp and parent frame.
    pub header: Header,
    /// The child frame.
    pub child_frame_id: String,
    /// The child in the parent (translation, rotation).
    pub transform: PoseMsg,
}

/// `tf2_msgs/TFMessage`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TfMessage {
    /// The transforms.
    pub transforms: Vec<TransformStamped>,
}
typed!(TfMessage, "tf2_msgs", "TFMessage");

/// `geometry_msgs/PoseStamped`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseStamped {
    /// Stamp and frame.
    pub header: Header,
    /// The pose.
    pub pose: PoseMsg,
}

/// `nav_msgs/Path`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PathMsg {
    /// Stamp and frame.
    pub header: Header,
    /// The poses, oldest first.
    pub poses: Vec<PoseStamped>,
}
typed!(PathMsg, "nav_msgs", "Path");

/// `nav_msgs/MapMetaData`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MapMetaData {
    /// When the map was made.
    pub map_load_time: Time,
    /// Cell size (m).
    pub resolution: f32,
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// The pose of cell (0, 0)'s lower-left corner.
    pub origin: PoseMsg,
}

/// `nav_msgs/OccupancyGrid`: cells row by row from the origin, -1 unknown, 0 to 100.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct OccupancyGrid {
    /// Stamp and frame.
    pub header: Header,
    /// Size and place.
    pub info: MapMetaData,
    /// The cells.
    pub data: Vec<i8>,
}
typed!(OccupancyGrid, "nav_msgs", "OccupancyGrid");

/// `geometry_msgs/PoseWithCovarianceStamped` (RViz's "2D Pose Estimate" on `initialpose`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovarianceStamped {
    /// Stamp and frame.
    pub header: Header,
    /// The pose.
    pub pose: PoseWithCovariance,
}
typed!(
    PoseWithCovarianceStamped,
    "geometry_msgs",
    "PoseWithCovarianceStamped"
);

/// `diagnostic_msgs/KeyValue`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct KeyValue {
    /// The name.
    pub key: String,
    /// The value, as text.
    pub value: String,
}

/// `diagnostic_msgs/DiagnosticStatus`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct DiagnosticStatus {
    /// 0 OK, 1 WARN, 2 ERROR, 3 STALE.
    pub level: u8,
    /// What it is about.
    pub name: String,
    /// A sentence.
    pub message: String,
    /// The hardware, if any.
    pub hardware_id: String,
    /// The counts.
    pub values: Vec<KeyValue>,
}

/// `diagnostic_msgs/DiagnosticArray`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct DiagnosticArray {
    /// Stamp.
    pub header: Header,
    /// One status a component.
    pub status: Vec<DiagnosticStatus>,
}
typed!(DiagnosticArray, "diagnostic_msgs", "DiagnosticArray");

/// `std_msgs/ColorRGBA`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Colour {
    /// Red, 0 to 1.
    pub r: f32,
    /// Green.
    pub g: f32,
    /// Blue.
    pub b: f32,
    /// Opacity.
    pub a: f32,
}

/// `builtin_interfaces/Duration`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct DurationMsg {
    /// Seconds.
    pub sec: i32,
    /// Nanoseconds.
    pub nanosec: u32,
}

/// `sensor_msgs/CompressedImage` (a marker's texture; always empty here).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CompressedImage {
    /// Stamp and frame.
    pub header: Header,
    /// `png` or `jpeg`.
    pub format: String,
    /// The image.
    pub data: Vec<u8>,
}

/// `visualization_msgs/UVCoordinate`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct UvCoordinate {
    /// u.
    pub u: f32,
    /// v.
    pub v: f32,
}

/// `visualization_msgs/MeshFile` (a marker's mesh file; always empty here).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MeshFile {
    /// Its name.
    pub filename: String,
    /// Its bytes.
    pub data: Vec<u8>,
}

/// `visualization_msgs/Marker`, as Jazzy and later define it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Marker {
    /// Stamp and frame.
    pub header: Header,
    /// Namespace: with `id`, what a later marker replaces.
    pub ns: String,
    /// Id within the namespace.
    pub id: i32,
    /// [`Marker::TRIANGLE_LIST`], ...
    #[serde(rename = "type")]
    pub kind: i32,
    /// [`Marker::ADD`] or [`Marker::DELETE`].
    pub action: i32,
    /// Where the points are placed.
    pub pose: PoseMsg,
    /// Scale (1 for a triangle list).
    pub scale: Vector3,
    /// The colour of the whole marker.
    pub color: Colour,
    /// How long RViz shows it (zero: until replaced).
    pub lifetime: DurationMsg,
    /// Whether it follows its frame.
    pub frame_locked: bool,
    /// The points (three a triangle).
    pub points: Vec<Vector3>,
    /// A colour a point (empty: `color`).
    pub colors: Vec<Colour>,
    /// Unused.
    pub texture_resource: String,
    /// Unused.
    pub texture: CompressedImage,
    /// Unused.
    pub uv_coordinates: Vec<UvCoordinate>,
    /// Unused.
    pub text: String,
    /// Unused.
    pub mesh_resource: String,
    /// Unused.
    pub mesh_file: MeshFile,
    /// Unused.
    pub mesh_use_embedded_materials: bool,
}

impl Marker {
    /// `type`: a list of triangles, three points each.
    pub const TRIANGLE_LIST: i32 = 11;
    /// `action`: add or replace.
    pub const ADD: i32 = 0;
    /// `action`: remove.
    pub const DELETE: i32 = 2;
}

/// `visualization_msgs/MarkerArray`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MarkerArray {
    /// The markers.
    pub markers: Vec<Marker>,
}
typed!(MarkerArray, "visualization_msgs", "MarkerArray");

/// `sensor_msgs/Imu`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Imu {
    /// Stamp and the IMU's frame.
    pub header: Header,
    /// Orientation, if the IMU estimates it.
    pub orientation: Quaternion,
    /// Its covariance (row by row; -1 first: none).
    pub orientation_covariance: [f64; 9],
    /// Angular velocity (rad/s).
    pub angular_velocity: Vector3,
    /// Its covariance.
    pub angular_velocity_covariance: [f64; 9],
    /// Specific force (m/s², gravity included).
    pub linear_acceleration: Vector3,
    /// Its covariance.
    pub linear_acceleration_covariance: [f64; 9],
}
typed!(Imu, "sensor_msgs", "Imu");

/// `rosgraph_msgs/Clock` (`/clock`, when `use_sim_time` is set).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Clock {
    /// The simulated time.
    pub clock: Time,
}
typed!(Clock, "rosgraph_msgs", "Clock");

/// `std_srvs/Trigger`'s request: an empty message, which ROS 2 gives one placeholder byte.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct TriggerRequest {
    /// The placeholder ROS 2 adds to an empty message.
    pub structure_needs_at_least_one_member: u8,
}

/// `std_srvs/Trigger`'s response.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct TriggerResponse {
    /// Whether it worked.
    pub success: bool,
    /// What happened.
    pub message: String,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// CDR, little-endian, as ros2-client writes it (no 4-byte header).
    fn cdr<T: Serialize>(v: &T) -> Vec<u8> {
        cdr_encoding::to_vec::<T, byteorder::LittleEndian>(v).unwrap()
    }

    #[test]
    fn time_splits_seconds() {
        let t = Time::from_seconds(12.25);
        assert_eq!((t.sec, t.nanosec), (12, 250_000_000));
        assert_eq!(Time::from_seconds(f64::NAN), Time::default());
        assert_eq!(Time::from_seconds(-3.0), Time::default());
        // Nanoseconds both ways, exactly, where f64 seconds are off.
        let ns = 1_733_560_000_123_456_789;
        let t = Time::from_nanoseconds(ns);
        assert_eq!((t.sec, t.nanosec), (1_733_560_000, 123_456_789));
        assert_eq!(t.nanoseconds(), ns);
        assert_ne!(Time::from_seconds(t.seconds()), t);
        let before = Time::from_nanoseconds(-1_999_999_995);
        assert_eq!((before.sec, before.nanosec), (-2, 5));
        assert_eq!(Time::from_nanoseconds(i64::MAX).sec, i32::MAX);
    }

    #[test]
    fn covariance_is_36_doubles_without_a_length() {
        let mut c = Covariance::default();
        c.0[35] = 2.0;
        let bytes = cdr(&c);
        assert_eq!(bytes.len(), 36 * 8);
        assert_eq!(&bytes[35 * 8..], &2.0f64.to_le_bytes());
        let back: Covariance =
            cdr_encoding::from_bytes::<Covariance, byteorder::LittleEndian>(&bytes)
                .unwrap()
                .0;
        assert_eq!(back, c);
    }

    #[test]
    fn odometry_lays_out_as_its_msg_file() {
        let o = Odometry {
            header: Header {
                stamp: Time { sec: 1, nanosec: 2 },
                frame_id: "odom".into(),
            },
            child_frame_id: "base_link".into(),
            ..Odometry::default()
        };
        let b = cdr(&o);
        // stamp (8), "odom" (4 + 5, padded to 20), "base_link" (4 + 10 → 34, padded to 40),
        // pose (7 doubles), its covariance (36), twist (6), its covariance (36).
        assert_eq!(b.len(), 40 + (7 + 36 + 6 + 36) * 8);
        assert_eq!(&b[8..12], &5u32.to_le_bytes());
        assert_eq!(&b[12..17], b"odom\0");
        // The quaternion's w is the pose's seventh double.
        assert_eq!(&b[40 + 6 * 8..40 + 7 * 8], &1.0f64.to_le_bytes());
    }

    #[test]
    fn a_pose_goes_and_comes_back() {
        let p = Pose::from_parts(
            nalgebra::Translation3::new(1.0, -2.0, 0.5),
            nalgebra::UnitQuaternion::from_euler_angles(0.1, -0.2, 1.0),
        );
        let back = PoseMsg::from(&p).to_pose().unwrap();
        assert!((back.translation.vector - p.translation.vector).norm() < 1e-12);
        assert!(back.rotation.angle_to(&p.rotation) < 1e-12);
        let mut bad = PoseMsg::from(&p);
        bad.orientation = Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 0.0,
        };
        assert!(bad.to_pose().is_none());
    }
}
