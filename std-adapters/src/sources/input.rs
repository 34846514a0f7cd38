//! Where a run's frames come from: [`FrameSource`], its implementation for a simulated drive
//! (the `sim` feature), and [`Input`], the command's input: whichever kind of input a path or
//! address names, opened by its kind ([`crate::sources::kinds`]).

use crate::formats::kitti::BinFields;
use crate::io::error::FileError;
use crate::sources::kinds::{Kinds, OpenOptions, Opened, OpenedInput};
use crate::sources::packets::PacketOptions;
use slamesh_core::Point;
use std::path::Path;

/// A timed measurement a source carries beside its scans, on the scans' clock: the one way
/// in for what is not a scan. The run hands them to its sinks with their frame; the IMU's
/// stage takes the readings, and every other stage and sink passes over what it does not
/// know.
#[derive(Debug, Clone)]
pub enum Sample {
    /// One reading of an inertial measurement unit, in its own frame.
    Imu(ImuReading),
    /// Any other measurement (a camera's image, a wheel's count), shared: a sink that knows
    /// it takes it, and nothing else pays more than a pointer for it.
    Other(OtherSample),
}

impl Sample {
    /// Its time (seconds, the scans' clock).
    pub fn stamp(&self) -> f64 {
        match self {
            Sample::Imu(r) => r.stamp,
            Sample::Other(o) => o.stamp,
        }
    }

    /// The IMU reading it is, if it is one.
    pub fn imu(&self) -> Option<&ImuReading> {
        match self {
            Sample::Imu(r) => Some(r),
            Sample::Other(_) => None,
        }
    }

    /// [`imu`](Self::imu), to change.
    pub fn imu_mut(&mut self) -> Option<&mut ImuReading> {
        match self {
            Sample::Imu(r) => Some(r),
            Sample::Other(_) => None,
        }
    }
}

/// A measurement that is neither a scan nor an IMU reading: its time, what it is, and its
/// data for whichever sink knows its type ([`data`](Self::data)).
#[derive(Clone)]
pub struct OtherSample {
    /// Its time (seconds, the scans' clock).
    pub stamp: f64,
    /// What it is, for messages and for a sink to pick its own ("image", "wheel").
    pub kind: &'static str,
    /// The measurement itself.
    pub value: std::sync::Arc<dyn std::any::Any + Send + Sync>,
}

impl OtherSample {
    /// The measurement as a `T`, when it is one.
    pub fn data<T: std::any::Any>(&self) -> Option<&T> {
        self.value.downcast_ref::<T>()
    }
}

impl std::fmt::Debug for OtherSample {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "OtherSample {{ stamp: {}, kind: {:?} }}",
            self.stamp, self.kind
        )
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
/// What the command reads: whichever kind of input a path or address names (scan files, a
/// robot recording, a packet capture, a live sensor: [`Kinds::standard`], or the caller's
/// own kinds with [`open_among`](Self::open_among)).
pub struct Input(Opened);

impl Input {
    /// Opens `path` as the command does ([`Kinds::standard`]): a recording if its content says
    /// so (reading `topic`, or the only PointCloud2 topic), otherwise scan files (`.bin` ones
    /// as `bin_fields`). `topic` given for scan files is an error.
    pub fn open(
        path: &Path,
        topic: Option<&str>,
        bin_fields: BinFields,
    ) -> Result<Self, FileError> {
        Self::open_with(path, topic, bin_fields, &PacketOptions::default())
    }

    /// [`open`](Self::open), a packet capture (told by its first bytes) or a live address
    /// read with `packets`.
    pub fn open_with(
        path: &Path,
        topic: Option<&str>,
        bin_fields: BinFields,
        packets: &PacketOptions,
    ) -> Result<Self, FileError> {
        let how = OpenOptions {
            topic: topic.map(str::to_string),
            bin_fields,
            packets: packets.clone(),
        };
        Self::open_among(&Kinds::standard(), path, &how)
    }

    /// `path` opened by the first of `kinds` that knows it.
    pub fn open_among(kinds: &Kinds, path: &Path, how: &OpenOptions) -> Result<Self, FileError> {
        kinds.open(path, how).map(Input)
    }

    /// The source opened, as its own type when it is `T` (a live input's address, say).
    pub fn downcast_ref<T: OpenedInput>(&self) -> Option<&T> {
        (&*self.0 as &dyn std::any::Any).downcast_ref::<T>()
    }
}

impl std::ops::Deref for Input {
    type Target = dyn OpenedInput;
    fn deref(&self) -> &Self::Target {
        &*self.0
    }
}

impl std::ops::DerefMut for Input {
    fn deref_mut(&mut self) -> &mut Self::Target {
        &mut *self.0
    }
}

impl FrameSource for Input {
    fn frames(&self) -> usize {
        self.0.frames()
    }
    fn label(&self, i: usize) -> String {
        self.0.label(i)
    }
    fn stamp(&self, i: usize) -> f64 {
        self.0.stamp(i)
    }
    fn stamp_ns(&self, i: usize) -> Option<i64> {
        self.0.stamp_ns(i)
    }
    fn read(&mut self, i: usize) -> Result<Vec<Point>, FileError> {
        self.0.read(i)
    }
    fn read_timed(&mut self, i: usize) -> Result<(Vec<Point>, Option<Vec<f32>>), FileError> {
        self.0.read_timed(i)
    }
    fn dropped_by_reader(&self) -> usize {
        self.0.dropped_by_reader()
    }
    fn has(&mut self, i: usize) -> bool {
        self.0.has(i)
    }
    fn would_wait(&mut self, i: usize) -> bool {
        self.0.would_wait(i)
    }
    fn arrival(&self, i: usize) -> Option<std::time::Instant> {
        self.0.arrival(i)
    }
    fn input_report(&self) -> Option<serde_json::Value> {
        self.0.input_report()
    }
    fn samples(&mut self, i: usize) -> Vec<Sample> {
        self.0.samples(i)
    }
    fn wait(&mut self, i: usize) -> Waited {
        self.0.wait(i)
    }
    fn requests(&mut self) -> Vec<Request> {
        self.0.requests()
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
