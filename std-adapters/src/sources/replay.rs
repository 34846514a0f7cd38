//! A packet capture replayed as frames: the sensor's packets in a `.pcap` or `.pcapng` file,
//! decoded ([`crate::sources::velodyne`], [`crate::sources::ouster`]) and cut into sweeps
//! ([`crate::sources::sweep`]), one frame a sweep, each point with its firing time.
//!
//! Opening reads the whole capture once, streaming, to find its sweeps and their stamps (so
//! that a run knows its frames); frames are then read in order by decoding again from where
//! the last one ended, with one sweep in memory at a time. The sensor is told from the packets
//! (size, block flags, product byte) or named (`--sensor`); an Ouster's by its metadata
//! (`--metadata`, or the capture's name with `.json`). A capture of another sensor, or of
//! none, is refused with what was found. Packets that are not the sensor's data (its position
//! packets, other traffic) are skipped; damaged ones are counted and skipped. An Ouster's IMU
//! packets are kept from the index pass and handed to the frames by time.

use crate::io::error::FileError;
use crate::sources::capture::{Capture, CaptureStats};
use crate::sources::imu_readings::ImuReadings;
use crate::sources::packets::{self, PacketOptions, Sensor, SensorHint, SensorStream, StreamStats};
use crate::sources::sweep::Sweep;
use serde::Serialize;
use slamesh_core::Point;
use std::path::{Path, PathBuf};

/// What a replay counted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct ReplayStats {
    /// The capture's own counts.
    pub capture: CaptureStats,
    /// The sensor's packets.
    pub stream: StreamStats,
}

/// The decoding state: where in the capture, and the sweep being filled.
struct Cursor {
    capture: Capture,
    stream: SensorStream,
    /// The next sweep it will complete.
    next: usize,
    /// The capture's end was read.
    ended: bool,
    stats: ReplayStats,
}

/// A capture as frames.
pub struct Replay {
    path: PathBuf,
    sensor: Sensor,
    /// The destination port of the sensor's data packets (the first data packet's).
    port: u16,
    options: PacketOptions,
    /// Each sweep's stamp and gaps.
    sweeps: Vec<(f64, u32)>,
    /// The sweeps' stamps, for handing out the IMU's readings.
    stamps: Vec<f64>,
    /// An Ouster's IMU readings (its IMU packets), handed to the frames by time.
    imu: ImuReadings,
    stats: ReplayStats,
    cursor: Option<Cursor>,
}

impl std::fmt::Debug for Replay {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Replay")
            .field("path", &self.path)
            .field("sensor", &self.sensor.name())
            .field("sweeps", &self.sweeps.len())
            .finish()
    }
}

impl Replay {
    /// Opens a capture: finds its sensor and its sweeps.
    pub fn open(path: &Path, options: &PacketOptions) -> Result<Self, FileError> {
        let hint = SensorHint::new(options, Some(path))?;
        let (sensor, port) = find_sensor(path, &hint)?;
        let mut replay = Self {
            path: path.to_path_buf(),
            sensor,
            port,
            options: options.clone(),
            sweeps: Vec::new(),
            stamps: Vec::new(),
            imu: ImuReadings::default(),
            stats: ReplayStats::default(),
            cursor: None,
        };
        // The index pass, which keeps the IMU's readings (a few bytes a millisecond).
        let mut cursor = replay.start(true)?;
        let mut imu = Vec::new();
        while let Some(s) = replay.advance(&mut cursor)? {
            replay.sweeps.push((s.stamp().unwrap_or(0.0), s.gaps));
            imu.append(&mut cursor.stream.take_imu());
        }
        imu.append(&mut cursor.stream.take_imu());
        replay.stamps = replay.sweeps.iter().map(|s| s.0).collect();
        replay.imu = ImuReadings::new(imu);
        replay.stats = cursor.stats;
        if replay.sweeps.is_empty() {
            return Err(FileError::at(
                path,
                format!(
                    "{} {} data packets, but not one whole turn of the sensor",
                    replay.stats.stream.packets,
                    replay.sensor.name()
                ),
            ));
        }
        Ok(replay)
    }

    /// The sensor's name.
    pub fn sensor(&self) -> String {
        self.sensor.name()
    }

    /// What the whole capture held (from the index pass).
    pub fn stats(&self) -> ReplayStats {
        self.stats
    }

    /// Number of sweeps.
    pub fn len(&self) -> usize {
        self.sweeps.len()
    }

    /// Whether there is no sweep (never, once opened).
    pub fn is_empty(&self) -> bool {
        self.sweeps.is_empty()
    }

    /// A cursor at the capture's start; `imu`: keeping the IMU's readings (the index pass).
    fn start(&self, imu: bool) -> Result<Cursor, FileError> {
        let stream = SensorStream::new(&self.sensor, self.port, self.options.cut_azimuth_deg);
        Ok(Cursor {
            capture: Capture::open(&self.path)?,
            stream: if imu { stream } else { stream.without_imu() },
            next: 0,
            ended: false,
            stats: ReplayStats::default(),
        })
    }

    /// Decodes until the cursor completes a sweep; `None` at the end.
    fn advance(&self, c: &mut Cursor) -> Result<Option<Sweep>, FileError> {
        loop {
            if c.ended {
                return Ok(None);
            }
            let Some(d) = c.capture.next_datagram()? else {
                c.ended = true;
                // The last turn, if it ended at the cut.
                let last = c.stream.finish();
                c.stats = ReplayStats {
                    capture: c.capture.stats(),
                    stream: c.stream.stats(),
                };
                c.next += usize::from(last.is_some());
                return Ok(last);
            };
            if let Some(s) = c.stream.datagram(d.udp.dst_port, d.udp.payload, d.time_s) {
                c.next += 1;
                return Ok(Some(s));
            }
        }
    }

    /// Sweep `i`, decoded again from the capture.
    fn sweep(&mut self, i: usize) -> Result<Sweep, FileError> {
        let mut cursor = match self.cursor.take() {
            Some(c) if c.next <= i => c,
            _ => self.start(false)?,
        };
        loop {
            let at = cursor.next;
            match self.advance(&mut cursor)? {
                Some(s) if at == i => {
                    self.cursor = Some(cursor);
                    return Ok(s);
                }
                Some(_) => {}
                None => {
                    return Err(FileError::at(
                        &self.path,
                        format!("sweep {i} is not there on a second reading: the file changed"),
                    ))
                }
            }
        }
    }

    /// Frame `i`'s label.
    pub fn label(&self, i: usize) -> String {
        format!("{} sweep {i}", self.path.display())
    }

    /// Frame `i`'s stamp: the middle of its firings' times ([`Sweep::stamp`]).
    pub fn stamp(&self, i: usize) -> f64 {
        self.sweeps.get(i).map_or(0.0, |s| s.0)
    }

    /// The IMU's readings for frame `i` (frames asked in order): those up to a frame period
    /// past its stamp not handed before ([`ImuReadings::for_frame`]); none without an IMU.
    pub fn samples(&mut self, i: usize) -> Vec<crate::sources::Sample> {
        self.imu.for_frame(&self.stamps, i)
    }

    /// Frame `i`'s points and their times relative to its stamp.
    pub fn read_timed(&mut self, i: usize) -> Result<(Vec<Point>, Option<Vec<f32>>), FileError> {
        let s = self.sweep(i)?;
        let times = s.relative_times();
        Ok((s.points, Some(times)))
    }
}

/// The sensor of a capture: the first data packet's (of the sensor the hint names, when it
/// does), and the port it went to.
fn find_sensor(path: &Path, hint: &SensorHint) -> Result<(Sensor, u16), FileError> {
    let mut cap = Capture::open(path)?;
    let mut sizes: Vec<(usize, u64)> = Vec::new();
    while let Some(d) = cap.next_datagram()? {
        let payload = d.udp.payload;
        if let Some(sensor) =
            packets::identify(payload, hint).map_err(|e| FileError::at(path, e))?
        {
            return Ok((sensor, d.udp.dst_port));
        }
        match sizes.iter().position(|(n, _)| *n == payload.len()) {
            Some(k) => sizes[k].1 += 1,
            None if sizes.len() < 5 => sizes.push((payload.len(), 1)),
            None => {}
        }
    }
    let seen = if sizes.is_empty() {
        "no UDP datagrams at all".to_string()
    } else {
        let list: Vec<String> = sizes
            .iter()
            .map(|(n, c)| format!("{c} of {n} bytes"))
            .collect();
        format!("UDP datagrams: {}", list.join(", "))
    };
    let wanted = match (hint.ouster_packet_bytes(), hint.hdl64()) {
        (Some(n), _) => format!("no lidar packets of the Ouster's metadata ({n} bytes)"),
        (None, Some(name)) => format!("no {name} data packets"),
        (None, None) => format!(
            "no Velodyne data packets ({} bytes)",
            crate::sources::velodyne::DATA_PACKET_BYTES
        ),
    };
    Err(FileError::at(
        path,
        format!("{wanted} in the capture; {seen}"),
    ))
}

/// A sensor's packets in a `.pcap` or `.pcapng` file (told by its first bytes), a sweep a
/// frame.
pub struct CaptureKind;

impl crate::sources::kinds::InputKind for CaptureKind {
    fn name(&self) -> &'static str {
        "a packet capture"
    }

    fn open(
        &self,
        path: &Path,
        how: &crate::sources::kinds::OpenOptions,
    ) -> Option<Result<crate::sources::kinds::Opened, FileError>> {
        if !crate::sources::capture::is_capture(path) {
            return None;
        }
        Some(Replay::open(path, &how.packets).map(|r| Box::new(r) as _))
    }
}

impl crate::sources::FrameSource for Replay {
    fn frames(&self) -> usize {
        self.len()
    }
    fn label(&self, i: usize) -> String {
        Replay::label(self, i)
    }
    fn stamp(&self, i: usize) -> f64 {
        Replay::stamp(self, i)
    }
    fn read(&mut self, i: usize) -> Result<Vec<Point>, FileError> {
        Replay::read_timed(self, i).map(|(p, _)| p)
    }
    fn read_timed(&mut self, i: usize) -> Result<(Vec<Point>, Option<Vec<f32>>), FileError> {
        Replay::read_timed(self, i)
    }
    fn samples(&mut self, i: usize) -> Vec<crate::sources::Sample> {
        Replay::samples(self, i)
    }
    fn input_report(&self) -> Option<serde_json::Value> {
        serde_json::to_value(self.stats()).ok()
    }
}

impl crate::sources::kinds::OpenedInput for Replay {
    fn describe(&self) -> String {
        let s = self.stats();
        format!(
            "{} sweeps of a {} ({} packets, {} missing, {} damaged)",
            self.len(),
            self.sensor(),
            s.stream.packets,
            s.stream.gaps,
            s.stream.bad_packets
        )
    }
}
