//! Where a run's frames come from: [`FrameSource`], its implementation for a folder of scans
//! (and, with the `sim` feature, for a simulated drive), and [`Input`], the command's input:
//! a folder of scans or a robot recording, told apart by content.

use crate::formats::imu_csv;
use crate::formats::kitti::BinFields;
use crate::io::error::FileError;
use crate::sources::imu_readings::ImuReadings;
use crate::sources::live::{Live, LiveOptions};
use crate::sources::packets::PacketOptions;
use crate::sources::replay::Replay;
use crate::sources::scans::{read_scan_as, ScanFolder};
use slamesh_core::Point;
use std::path::{Path, PathBuf};

/// A timed measurement a source carries beside its scans, on the scans' clock: the one way
/// in for what is not a scan (an IMU's readings; the run hands them to its sinks with their
/// frame, and the IMU's motion prior will take them from there).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Sample {
    /// One reading of an inertial measurement unit, in its own frame.
    Imu(ImuReading),
}

impl Sample {
    /// Its time (seconds, the scans' clock).
    pub fn stamp(&self) -> f64 {
        match self {
            Sample::Imu(r) => r.stamp,
        }
    }
}

/// One IMU reading: the core's ([`slamesh_core::imu::ImuSample`]), in the IMU's own axes
/// and on its clock.
pub use slamesh_core::imu::ImuSample as ImuReading;

/// Frames to run over.
pub trait FrameSource {
    /// Number of frames.
    fn frames(&self) -> usize;
    /// What to call frame `i` in messages (its file).
    fn label(&self, i: usize) -> String;
    /// Timestamp of frame `i` (seconds).
    fn stamp(&self, i: usize) -> f64;
    /// Frame `i`'s timestamp exactly, in nanoseconds, when the source has it in whole numbers
    /// (a ROS message's header): what a reply to the frame is stamped with. By default none
    /// (replies use [`stamp`](Self::stamp)).
    fn stamp_ns(&self, _i: usize) -> Option<i64> {
        None
    }
    /// The points of frame `i`, in the sensor frame.
    fn read(&mut self, i: usize) -> Result<Vec<Point>, FileError>;
    /// The points of frame `i` with each one's time relative to the frame's stamp (seconds),
    /// when the source records them; by default, [`read`](Self::read) and no times.
    fn read_timed(&mut self, i: usize) -> Result<(Vec<Point>, Option<Vec<f32>>), FileError> {
        Ok((self.read(i)?, None))
    }
    /// Points the last read dropped before handing them over (a recording's NaN and no-return
    /// points); by default none.
    fn dropped_by_reader(&self) -> usize {
        0
    }
    /// Whether frame `i` exists; a live source waits until it comes or the stream ends. By
    /// default, `i < frames()`.
    fn has(&mut self, i: usize) -> bool {
        i < self.frames()
    }
    /// Whether reading frame `i` now would wait for it to come (a live source's); by default,
    /// never.
    fn would_wait(&mut self, _i: usize) -> bool {
        false
    }
    /// When frame `i`'s data came in, for a live source (the latency to its pose).
    fn arrival(&self, _i: usize) -> Option<std::time::Instant> {
        None
    }
    /// What the reader counted over the whole input, for `report.json` (`summary.input`).
    fn input_report(&self) -> Option<serde_json::Value> {
        None
    }
    /// The samples that are not scans (an IMU's) with stamps after frame `i - 1`'s and up to
    /// frame `i`'s, in time order. The run takes them once a frame, right after reading frame
    /// `i`. By default none: a source of scans only.
    fn samples(&mut self, _i: usize) -> Vec<Sample> {
        Vec::new()
    }
    /// Waits for frame `i` as [`has`](Self::has) does, but also returns when a request comes
    /// ([`Waited::Request`]), so that the run can serve it while no frame comes. By default,
    /// [`has`](Self::has).
    fn wait(&mut self, i: usize) -> Waited {
        if self.has(i) {
            Waited::Frame
        } else {
            Waited::End
        }
    }
    /// What the source's user asked of the run since the last call (a live source's: a pose
    /// to relocalize at, a map to save), served between frames. By default none.
    fn requests(&mut self) -> Vec<Request> {
        Vec::new()
    }
}

/// What [`FrameSource::wait`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Waited {
    /// The frame is there.
    Frame,
    /// A request came first ([`FrameSource::requests`]).
    Request,
    /// The stream has ended.
    End,
}

/// What a live source's user asks of the run.
#[derive(Debug)]
pub enum Request {
    /// Search for the pose near this one (in the map's frame) from the next frame on.
    Relocalize(slamesh_core::Pose),
    /// Save the map now; the answer (what was written, or why not) goes back on the sender.
    SaveMap(std::sync::mpsc::Sender<Result<String, String>>),
}

/// What the command reads: a folder of scans (or one scan file), a robot recording, or a
/// packet capture.
pub enum Input {
    /// Scan files.
    Folder(ScanFolder),
    /// A sensor's packets in a `.pcap` or `.pcapng` file, a sweep a frame (boxed: the
    /// decoder's tables are a few KB).
    Capture(Box<Replay>),
    /// A sensor's packets taken live from a UDP socket (`udp://HOST:PORT`).
    Live(Box<Live>),
    /// A ROS 1 bag, an MCAP file or a ROS 2 bag folder.
    #[cfg(feature = "recordings")]
    Recording(crate::sources::recording::Recording),
}

impl Input {
    /// Opens `path`: a recording if its content says so (reading `topic`, or the only
    /// PointCloud2 topic), otherwise scan files (`.bin` ones as `bin_fields`). `topic` given
    /// for scan files is an error.
    pub fn open(
        path: &std::path::Path,
        topic: Option<&str>,
        bin_fields: BinFields,
    ) -> Result<Self, FileError> {
        Self::open_with(path, topic, bin_fields, &PacketOptions::default())
    }

    /// [`open`](Self::open), a packet capture (told by its first bytes) read with `packets`.
    pub fn open_with(
        path: &std::path::Path,
        topic: Option<&str>,
        bin_fields: BinFields,
        packets: &PacketOptions,
    ) -> Result<Self, FileError> {
        if let Some(addr) = path.to_str().and_then(crate::sources::live::address) {
            let live = LiveOptions {
                packets: packets.clone(),
                ..LiveOptions::default()
            };
            return Ok(Input::Live(Box::new(Live::open(addr, &live)?)));
        }
        if crate::sources::capture::is_capture(path) {
            return Ok(Input::Capture(Box::new(Replay::open(path, packets)?)));
        }
        if packets.sensor.is_some() || packets.metadata.is_some() || packets.calibration.is_some() {
            return Err(FileError::at(
                path,
                "--sensor, --metadata and --calibration are for packet captures (.pcap, \
                 .pcapng) and live inputs (udp://), and this is neither",
            ));
        }
        #[cfg(feature = "recordings")]
        if let Some(container) = crate::sources::recording::Container::detect(path) {
            let rec = crate::sources::recording::Recording::open(container?, topic)?;
            return Ok(Input::Recording(rec));
        }
        if topic.is_some() {
            return Err(FileError::at(
                path,
                "--topic is for recordings (ROS 1 bags, MCAP, ROS 2 bag folders), and this is not one",
            ));
        }
        let mut folder = ScanFolder::open(path)?;
        folder.bin_fields = bin_fields;
        Ok(Input::Folder(folder))
    }

    /// What was opened, for the log: "12 frames of /points" or "12 scan files".
    pub fn describe(&self) -> String {
        match self {
            Input::Folder(f) => format!(
                "{} scan files (times {}){}",
                f.len(),
                match f.stamps_from {
                    crate::sources::scans::Stamps::TimesTxt => "from times.txt",
                    crate::sources::scans::Stamps::FileNames => "from the file names",
                    crate::sources::scans::Stamps::Assumed10Hz =>
                        "assumed 10 Hz: no times.txt, and the file names are not times",
                    crate::sources::scans::Stamps::KittiRaw =>
                        "from KITTI raw's velodyne_points/timestamps.txt",
                },
                f.sweep.as_ref().map_or(String::new(), |s| format!(
                    ", points without times timed from a {} sweep of {:.3} s",
                    s.counts().sweep,
                    s.counts().period_s
                ))
            ),
            #[cfg(feature = "recordings")]
            Input::Recording(r) => format!("{} frames of topic {}", r.frames(), r.topic.name),
            Input::Live(l) => format!("packets on {}", l.local_addr()),
            Input::Capture(c) => {
                let s = c.stats();
                format!(
                    "{} sweeps of a {} ({} packets, {} missing, {} damaged)",
                    c.len(),
                    c.sensor(),
                    s.stream.packets,
                    s.stream.gaps,
                    s.stream.bad_packets
                )
            }
        }
    }
}

impl FrameSource for Input {
    fn frames(&self) -> usize {
        match self {
            Input::Folder(f) => f.frames(),
            Input::Capture(c) => c.len(),
            Input::Live(l) => l.frames(),
            #[cfg(feature = "recordings")]
            Input::Recording(r) => r.frames(),
        }
    }
    fn label(&self, i: usize) -> String {
        match self {
            Input::Folder(f) => f.label(i),
            Input::Capture(c) => c.label(i),
            Input::Live(l) => l.label(i),
            #[cfg(feature = "recordings")]
            Input::Recording(r) => r.label(i),
        }
    }
    fn stamp(&self, i: usize) -> f64 {
        match self {
            Input::Folder(f) => f.stamp(i),
            Input::Capture(c) => c.stamp(i),
            Input::Live(l) => l.stamp(i),
            #[cfg(feature = "recordings")]
            Input::Recording(r) => r.stamp(i),
        }
    }
    fn read(&mut self, i: usize) -> Result<Vec<Point>, FileError> {
        match self {
            Input::Folder(f) => f.read(i),
            Input::Capture(c) => c.read_timed(i).map(|(p, _)| p),
            Input::Live(l) => l.read_timed(i).map(|(p, _)| p),
            #[cfg(feature = "recordings")]
            Input::Recording(r) => r.read(i),
        }
    }
    fn read_timed(&mut self, i: usize) -> Result<(Vec<Point>, Option<Vec<f32>>), FileError> {
        match self {
            Input::Folder(f) => f.read_timed(i),
            Input::Capture(c) => c.read_timed(i),
            Input::Live(l) => l.read_timed(i),
            #[cfg(feature = "recordings")]
            Input::Recording(r) => r.read_timed(i),
        }
    }
    fn dropped_by_reader(&self) -> usize {
        match self {
            Input::Folder(f) => f.dropped_by_reader(),
            Input::Capture(_) | Input::Live(_) => 0,
            #[cfg(feature = "recordings")]
            Input::Recording(r) => r.dropped_by_reader(),
        }
    }
    fn has(&mut self, i: usize) -> bool {
        match self {
            Input::Live(l) => l.has(i),
            other => i < other.frames(),
        }
    }
    fn would_wait(&mut self, i: usize) -> bool {
        match self {
            Input::Live(l) => l.would_wait(i),
            _ => false,
        }
    }
    fn arrival(&self, i: usize) -> Option<std::time::Instant> {
        match self {
            Input::Live(l) => l.arrival(i),
            _ => None,
        }
    }
    fn samples(&mut self, i: usize) -> Vec<Sample> {
        match self {
            Input::Folder(f) => f.samples(i),
            Input::Capture(c) => c.samples(i),
            Input::Live(l) => l.samples(i),
            #[cfg(feature = "recordings")]
            Input::Recording(r) => r.samples(i),
        }
    }
    fn input_report(&self) -> Option<serde_json::Value> {
        match self {
            Input::Live(l) => serde_json::to_value(l.stats()).ok(),
            Input::Capture(c) => serde_json::to_value(c.stats()).ok(),
            Input::Folder(f) => f.input_report(),
            #[cfg(feature = "recordings")]
            Input::Recording(_) => None,
        }
    }
}

/// `points` read from `path`, refused when they cannot be a LiDAR's scan
/// ([`crate::formats::sensor_ranges`]).
fn as_scan(path: &Path, points: Vec<Point>) -> Result<Vec<Point>, FileError> {
    match crate::formats::sensor_ranges::check(&points) {
        Ok(()) => Ok(points),
        Err(e) => Err(FileError::at(path, e.to_string())),
    }
}

impl FrameSource for ScanFolder {
    fn frames(&self) -> usize {
        self.paths.len()
    }
    fn label(&self, i: usize) -> String {
        self.paths[i].display().to_string()
    }
    fn stamp(&self, i: usize) -> f64 {
        self.stamps[i]
    }
    fn read(&mut self, i: usize) -> Result<Vec<Point>, FileError> {
        let points = read_scan_as(&self.paths[i], &self.bin_fields)?;
        as_scan(&self.paths[i], points)
    }
    fn samples(&mut self, i: usize) -> Vec<Sample> {
        let stamps = &self.stamps;
        self.imu
            .as_mut()
            .map_or_else(Vec::new, |imu| imu.for_frame(stamps, i))
    }
    /// PCD and PLY files with a time field give their points' times; `.bin` files none. Scans
    /// without times get them from their sweep when the folder has one (`--sweep`).
    fn read_timed(&mut self, i: usize) -> Result<(Vec<Point>, Option<Vec<f32>>), FileError> {
        let path = &self.paths[i];
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        let (points, times) = match ext.as_deref() {
            Some("pcd") => crate::formats::pcd::read_pcd_timed(path, self.stamps[i])?,
            Some("ply") => crate::formats::ply::read_ply_timed(path, self.stamps[i])?,
            _ => (read_scan_as(path, &self.bin_fields)?, None),
        };
        let points = as_scan(path, points)?;
        let times = match (times, &mut self.sweep) {
            (None, Some(sweep)) => sweep.times(&path.display().to_string(), &points),
            (times, _) => times,
        };
        Ok((points, times))
    }
    fn input_report(&self) -> Option<serde_json::Value> {
        if self.sweep.is_none() && self.sweep_trial.is_none() {
            return None;
        }
        Some(serde_json::json!({
            "sweep_times": self.sweep.as_ref().map(|s| s.counts()),
            "sweep_trial": self.sweep_trial,
        }))
    }
}

/// Why `--sweep` is refused for an input that is not a folder of scan files.
pub const NOT_A_FOLDER: &str =
    "--sweep is for folders of scan files (.bin, .pcd, .ply), and this is not one";

impl Input {
    /// Times the scans of a folder that carry none from `sweep` (`--sweep`), its period the
    /// scans' own; `sweep` for another input, whose scans come with their times or whose sensor
    /// is known, is refused.
    pub fn time_from_sweep(
        &mut self,
        input: &Path,
        sweep: &crate::sources::sweep_times::SweepSpec,
    ) -> Result<(), FileError> {
        use crate::sources::sweep_times::{period_of, SweepTimer};
        match self {
            Input::Folder(f) => {
                f.sweep = Some(Box::new(SweepTimer::new(sweep, period_of(&f.stamps))));
                Ok(())
            }
            _ => Err(FileError::at(input, NOT_A_FOLDER)),
        }
    }

    /// Whether this is a KITTI raw drive's folder ([`crate::sources::kitti_raw`]): its scans
    /// were not deskewed by the dataset's makers.
    pub fn is_kitti_raw(&self) -> bool {
        matches!(self, Input::Folder(f) if f.raw.is_some())
    }

    /// Keeps what `--sweep auto` found (`trial`, in words) for the report; a folder's only.
    pub fn note_sweep_trial(&mut self, trial: String) {
        if let Input::Folder(f) = self {
            f.sweep_trial = Some(trial);
        }
    }

    /// Attaches the IMU's readings as the command's `--imu` (`imu`: `off`, a file, or `None`
    /// for what comes with the input) and `--imu-topic` say: a recording's `sensor_msgs/Imu`
    /// topic (the only one, or `imu_topic`); a folder of scans' CSV (`imu`, or one beside it,
    /// [`imu_csv::beside`]), saying when its times miss the scans'. A capture's or a live
    /// input's come with it. `input` is the path the input was opened from.
    pub fn attach_imu(
        &mut self,
        input: &Path,
        imu: Option<&str>,
        imu_topic: Option<&str>,
    ) -> Result<(), FileError> {
        let asked = imu.filter(|v| *v != "off");
        let off = imu == Some("off");
        #[cfg(feature = "recordings")]
        if let (Input::Recording(r), None) = (&mut *self, asked) {
            if !off {
                r.read_imu(imu_topic)?;
            }
            return Ok(());
        }
        if imu_topic.is_some() {
            return Err(FileError::at(input, "--imu-topic is for recordings"));
        }
        let Input::Folder(folder) = self else {
            return match asked {
                Some(_) => Err(FileError::at(
                    input,
                    "--imu FILE is for a folder of scans; a recording's or a live input's IMU \
                     readings come with it",
                )),
                None => Ok(()),
            };
        };
        let path = match asked {
            _ if off => return Ok(()),
            Some(file) => Some(PathBuf::from(file)),
            None => imu_csv::beside(input),
        };
        let oxts = folder
            .raw
            .as_ref()
            .and_then(|r| r.oxts())
            .filter(|_| path.is_none());
        let (imu, path) = match (path, oxts) {
            (Some(path), _) => (ImuReadings::open(&path)?, path),
            (None, Some(oxts)) => (ImuReadings::from_oxts(&oxts)?, oxts),
            (None, None) => return Ok(()),
        };
        if let (Some((a, b)), Some(first), Some(last)) =
            (imu.span(), folder.stamps.first(), folder.stamps.last())
        {
            log::info!("IMU readings from {}, {a:.3} s to {b:.3} s", path.display());
            if b < *first || a > *last {
                log::warn!(
                    "{}: its readings ({a:.3} to {b:.3} s) miss the scans' times ({first:.3} to \
                     {last:.3} s): set [imu] time_offset_s in the configuration",
                    path.display()
                );
            }
        }
        folder.imu = Some(imu);
        Ok(())
    }
}

/// A simulated drive: its noisy scans, made on demand, a frame every `period_s`; with an
/// IMU, frame `i` brings the readings up to the end of its sweep (a period after its stamp).
#[cfg(feature = "sim")]
impl FrameSource for slamesh_sim::Drive {
    fn frames(&self) -> usize {
        self.poses.len()
    }
    fn label(&self, i: usize) -> String {
        format!("simulated frame {i}")
    }
    fn stamp(&self, i: usize) -> f64 {
        i as f64 * self.period_s
    }
    fn read(&mut self, i: usize) -> Result<Vec<Point>, FileError> {
        Ok(self.scan(i))
    }
    fn samples(&mut self, i: usize) -> Vec<Sample> {
        let end = |i: usize| (i + 1) as f64 * self.period_s;
        let after = i.checked_sub(1).map_or(f64::NEG_INFINITY, end);
        let readings = self.imu_between(after.max(-1.0), end(i));
        readings.into_iter().map(Sample::Imu).collect()
    }
    fn read_timed(&mut self, i: usize) -> Result<(Vec<Point>, Option<Vec<f32>>), FileError> {
        let (points, times) = self.scan_timed(i);
        Ok((points, self.sweep_s.map(|_| times)))
    }
}
