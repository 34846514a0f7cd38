//! Readers and writers, one module per format; a format's reader and writer live together.
//! Every error names the file (and the line or record where it applies) and the reason
//! ([`FileError`]); every output is written to a temporary name and renamed ([`atomic`]).
//!
//! | what | module |
//! |---|---|
//! | errors naming the file, line and reason | [`error`] |
//! | write-then-rename | [`atomic`] |
//! | scan inputs: folders of scans in natural order, or one file | [`scans`] |
//! | KITTI `.bin` scans and `calib.txt` | [`kitti`] |
//! | PCD point clouds (with [`lzf`] for `binary_compressed`) | [`pcd`] |
//! | PLY point clouds and meshes, read and written | [`ply`] |
//! | OBJ meshes, written | [`obj`] |
//! | `sensor_msgs/PointCloud2` messages (ROS 1 and CDR), any field layout | [`pointcloud2`] |
//! | robot recordings: ROS 1 bags, MCAP, ROS 2 bag folders (feature `recordings`) | `recording` |
//! | the run's mesh on its way to disk | [`mesh_spool`] (its records in [`mesh_records`]) |
//! | map files: the map saved for later runs, read whole or by tile | [`map_file`] |
//! | one indexed mesh from map layers, shared vertices merged, with normals | [`mesh_weld`] |
//! | packet captures (pcap, pcapng) to UDP datagrams | [`capture`] |
//! | Velodyne data packets | [`velodyne`] |
//! | Ouster lidar packets and the sensor's metadata JSON | [`ouster`] |
//! | packets to sweeps, whichever the sensor | [`packets`] (turns cut in [`sweep`]) |
//! | a capture replayed as frames; packets taken live from a socket | [`replay`], [`live`] |
//! | trajectories, KITTI and TUM | [`trajectory`] |
//! | TOML configuration files | [`config_file`] |
//! | a picture of the mesh from above (PNG) | [`topview`] |

pub mod atomic;
pub mod capture;
pub mod config_file;
pub mod error;
pub mod kitti;
pub mod live;
pub mod lzf;
pub mod map_file;
pub mod mesh_records;
pub mod mesh_spool;
pub mod mesh_weld;
pub mod obj;
pub mod ouster;
pub mod packets;
pub mod pcd;
pub mod ply;
pub mod pointcloud2;
#[cfg(feature = "recordings")]
pub mod recording;
pub mod replay;
pub mod scans;
pub mod sweep;
pub mod topview;
pub mod trajectory;
pub mod velodyne;

pub use error::FileError;
