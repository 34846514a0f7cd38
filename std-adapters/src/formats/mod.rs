//! File formats, one module each; a format's reader and writer live together. Formats know
//! nothing of runs or sensors: a source ([`crate::sources`]) or an output
//! ([`crate::outputs`]) uses them. Every error names the file (and the line or record where it
//! applies) and the reason ([`crate::io::FileError`]).
//!
//! | what | module |
//! |---|---|
//! | KITTI `.bin` scans and `calib.txt` | [`kitti`] |
//! | PCD point clouds (with [`lzf`] for `binary_compressed`) | [`pcd`] |
//! | PLY point clouds and meshes, read and written | [`ply`] |
//! | OBJ meshes, written | [`obj`] |
//! | the mesh's spooled records, and the colours of its vertices | [`mesh_records`] |
//! | `sensor_msgs/PointCloud2` messages (ROS 1 and CDR), any field layout | [`pointcloud2`] |
//! | map files: the map saved for later runs, read whole or by tile (the std side) | [`map_file`] |
//! | trajectories, KITTI and TUM | [`trajectory`] |
//! | whether decoded points can be a LiDAR's scan (their median range) | [`sensor_ranges`] |
//! | IMU readings as a CSV in EuRoC's layout | [`imu_csv`] |
//! | KITTI raw's OXTS packets and timestamps | [`oxts`] |
//! | `sensor_msgs/Imu` messages (ROS 1 and CDR) | [`imu_message`] |
//! | the ROS 2 command line (`--ros-args`) and parameter files | [`ros_args`] |
//! | ROS 2 messages as serde types laid out for CDR (odometry, transforms, markers, IMU, ...) | [`ros_messages`] |

pub mod imu_csv;
pub mod imu_message;
pub mod kitti;
pub mod lzf;
pub mod map_file;
pub mod mesh_records;
pub mod obj;
pub mod oxts;
pub mod pcd;
pub mod ply;
pub mod pointcloud2;
pub mod ros_args;
pub mod ros_messages;
pub mod sensor_ranges;
pub mod trajectory;
