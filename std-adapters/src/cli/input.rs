//! Where a command's frames come from (`run`, `mesh`, `localize`, `bench`): the input and how
//! to read it.

use crate::formats::kitti::BinFields;
use crate::io::FileError;
use crate::run::Input;
use crate::sources::packets::PacketOptions;
use crate::sources::sweep_times::{BadSweep, SweepSpec};
use clap::Args;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

/// The input and the flags that say how to read it.
#[derive(Args, Debug)]
pub struct InputArgs {
    /// A folder of scans (.bin, .pcd or .ply, read in natural order), a KITTI sequence folder,
    /// one scan file, a recording (a ROS 1 bag, an MCAP file or a ROS 2 bag folder), a packet
    /// capture of a Velodyne or an Ouster (.pcap or .pcapng, a sweep a frame), or
    /// udp://HOST:PORT to take the sensor's packets live.
    pub input: PathBuf,
    /// The recording's PointCloud2 topic (default: its only one).
    #[arg(long, value_name = "NAME")]
    pub topic: Option<String>,
    /// The float32 fields of each `.bin` point, in order (x, y and z are read): x,y,z,i is
    /// KITTI's, x,y,z,i,ring nuScenes'.
    #[arg(long, value_name = "LIST", default_value = "x,y,z,i", value_parser = BinFields::parse)]
    pub bin_fields: BinFields,
    /// The packets' sensor: vlp16, puck-hires, vlp32c, hdl32, hdl64e-s2, hdl64e-s3 or ouster
    /// (default: told from the packets, or from --metadata).
    #[arg(long, value_name = "MODEL")]
    pub sensor: Option<String>,
    /// An Ouster's metadata JSON, with its beam angles (default for a capture: its name with
    /// .json, when there is one).
    #[arg(long, value_name = "FILE")]
    pub metadata: Option<PathBuf>,
    /// An HDL-64E's calibration YAML (the one Velodyne's ROS driver takes), with --sensor
    /// hdl64e-s2 or hdl64e-s3.
    #[arg(long, value_name = "FILE")]
    pub calibration: Option<PathBuf>,
    /// Where sweeps are cut (degrees of azimuth, clockwise from the sensor's x axis; default:
    /// 0 for a Velodyne, the start of its own frames for an Ouster).
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    pub cut_azimuth: Option<f64>,
    /// A live input (udp://HOST:PORT): end after this many seconds without a packet (default:
    /// run until Ctrl-C).
    #[arg(long, value_name = "S")]
    pub idle_timeout: Option<f64>,
    /// The IMU: `off` ignores the readings an input carries; a CSV in EuRoC's `imu0/data.csv`
    /// layout gives a folder of scans its readings (default: `imu0/data.csv` or `imu.csv` in
    /// the folder or beside it, when there is one). Its place on the LiDAR is the
    /// configuration's `[imu]` section.
    #[arg(long, value_name = "off|FILE")]
    pub imu: Option<String>,
    /// A recording's `sensor_msgs/Imu` topic (default: its only one, when it has one).
    #[arg(long, value_name = "NAME")]
    pub imu_topic: Option<String>,
    /// Time the points of scan files that carry no times (KITTI .bin, PCD or PLY without a
    /// time field) from their azimuths, so that they are deskewed: `kitti` (clockwise from
    /// behind, stamped mid-sweep), `velodyne` and `hesai` (clockwise from the front, stamped at
    /// the start), `ouster` (clockwise from behind, stamped at the start), or
    /// TURN:START_DEG:STAMP_SHARE (cw or ccw; the azimuth the sweep starts at, from x toward y;
    /// where the stamp sits, 0 to 1); `auto` tries each turn and start on the first scans and
    /// keeps the one that registers best, or none; `off` leaves them untimed (the default,
    /// KITTI odometry's scans being deskewed already; a KITTI raw drive's are not: `kitti`).
    #[arg(long, value_name = "SWEEP", value_parser = parse_sweep)]
    pub sweep: Option<SweepArg>,
}

/// `--sweep`'s value.
#[derive(Debug, Clone)]
pub enum SweepArg {
    /// No times from the sweep.
    Off,
    /// Found from the first scans ([`crate::cli::sweep_trial`]).
    Auto,
    /// This sweep.
    Given(SweepSpec),
}

fn parse_sweep(given: &str) -> Result<SweepArg, BadSweep> {
    if given == "auto" {
        return Ok(SweepArg::Auto);
    }
    Ok(SweepSpec::parse(given)?.map_or(SweepArg::Off, SweepArg::Given))
}

impl InputArgs {
    /// Whether the input is live (`udp://HOST:PORT`): it ends on Ctrl-C.
    pub fn is_live(&self) -> bool {
        (self.input.to_str())
            .and_then(crate::sources::live::address)
            .is_some()
    }

    /// Opens the input. A live one ends on Ctrl-C, and the run then writes its outputs.
    pub fn open(&self) -> Result<Input, FileError> {
        let live = self.is_live();
        let stop = (live.then(crate::cli::interrupt::listen).flatten())
            .unwrap_or_else(|| Arc::new(AtomicBool::new(false)));
        let mut input = Input::open_with(
            &self.input,
            self.topic.as_deref(),
            self.bin_fields.clone(),
            &PacketOptions {
                sensor: self.sensor.clone(),
                metadata: self.metadata.clone(),
                calibration: self.calibration.clone(),
                cut_azimuth_deg: self.cut_azimuth,
                idle: self
                    .idle_timeout
                    .filter(|s| s.is_finite() && *s > 0.0)
                    .map(Duration::from_secs_f64),
                stop,
            },
        )?;
        self.attach_imu(&mut input)?;
        match &self.sweep {
            Some(SweepArg::Given(sweep)) => input.time_from_sweep(&self.input, sweep)?,
            None => {
                // Scans a dataset left skewed (KITTI raw's): timed as its sensor's sweeps.
                let sweep = input.default_sweep();
                if let Some(spec) = sweep.and_then(|name| SweepSpec::parse(name).ok().flatten()) {
                    input.time_from_sweep(&self.input, &spec)?;
                }
            }
            _ => {}
        }
        Ok(input)
    }

    /// The IMU's readings as `--imu` and `--imu-topic` say
    /// ([`OpenedInput::attach_imu`](crate::sources::kinds::OpenedInput::attach_imu)).
    fn attach_imu(&self, input: &mut Input) -> Result<(), FileError> {
        input.attach_imu(&self.input, self.imu.as_deref(), self.imu_topic.as_deref())
    }
}
