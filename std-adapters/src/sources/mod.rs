//! One way in: where frames come from. A [`FrameSource`] yields scans in order (each with its
//! stamp, and its points' times when the sensor gives them) and, between them, the other
//! timed samples it carries ([`Sample`]: an IMU's readings); [`Input`] opens whichever a path
//! or address names, asking each kind of input ([`kinds::Kinds`]) in turn. Sources read
//! their files through [`crate::formats`].
//!
//! | what | module |
//! |---|---|
//! | the source interface, and the input a path or address names | [`input`] |
//! | the kinds of input, each told apart and opened by its own; the list asked in order | [`kinds`] |
//! | scan files as an input: their frames, their IMU file, their sweep's times | [`folder`] |
//! | folders of scans in natural order, or one file | [`scans`] |
//! | KITTI raw's drive folders: scans, their stamps, the OXTS unit | [`kitti_raw`] |
//! | points' times from their azimuths, for scans that carry none | [`sweep_times`] |
//! | robot recordings: ROS 1 bags, MCAP, ROS 2 bag folders (feature `recordings`) | `recording` |
//! | packet captures (pcap, pcapng) to UDP datagrams | [`capture`] |
//! | Velodyne data packets | [`velodyne`] |
//! | Ouster lidar packets and the sensor's metadata JSON | [`ouster`] |
//! | packets to sweeps, whichever the sensor | [`packets`] (turns cut in [`sweep`]) |
//! | a capture replayed as frames; packets taken live from a socket | [`replay`], [`live`] |
//! | a live source's frames, handed over through a bounded queue | [`feed`] |
//! | an IMU's readings from a file, handed to a folder's frames | [`imu_readings`] |

pub mod capture;
pub mod feed;
pub mod folder;
pub mod imu_readings;
pub mod input;
pub mod kinds;
pub mod kitti_raw;
pub mod live;
pub mod ouster;
pub mod packets;
#[cfg(feature = "recordings")]
pub mod recording;
pub mod replay;
pub mod scans;
pub mod sweep;
pub mod sweep_times;
pub mod velodyne;

pub use input::{FrameSource, ImuReading, Input, OtherSample, Request, Sample, Waited};
