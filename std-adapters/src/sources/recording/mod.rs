//! Robot recordings: ROS 1 bags, MCAP files and ROS 2 bag folders, read as a run's frames.
//!
//! [`Recording::open`] tells the container by its content (the first bytes of a file; a folder
//! with a `metadata.yaml`), picks the `sensor_msgs/PointCloud2` topic ([`choose_topic`]), and
//! reads its messages one at a time, never the whole file: memory holds one chunk of the
//! recording and one cloud. Messages of other topics are skipped undecoded. Each cloud is
//! decoded by [`crate::formats::pointcloud2`]; a malformed one is an error naming the recording,
//! the topic, the message's index and the reason, and the run skips that frame.
//!
//! | container | module | compression |
//! |---|---|---|
//! | ROS 1 bag (`#ROSBAG V2.0`) | [`rosbag1`] | none, bz2, lz4 |
//! | MCAP, ROS 2 (`cdr`) or ROS 1 (`ros1`) messages | [`mcap`] | none, zstd, lz4 |
//! | ROS 2 bag folder: `metadata.yaml` and `.db3` (`db3`) or `.mcap` files | [`ros2`] | as its files |
//!
//! A `sensor_msgs/Imu` topic (the only one, or `--imu-topic`'s) is read beside the clouds and
//! its readings handed to the frames ([`imu_topic`]).

#[cfg(feature = "db3")]
pub mod db3;
pub mod error;
pub mod imu_topic;
pub mod mcap;
pub mod ros2;
pub mod rosbag1;

use crate::formats::pointcloud2::{Cloud, DecodedScan};
use crate::io::error::FileError;
pub use error::RecordingError;
use error::RecordingError::{Damaged, TopicChoice};
use std::io::Read;
use std::path::{Path, PathBuf};

/// How a message's bytes are serialised.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    /// ROS 1: little-endian, packed.
    Ros1,
    /// ROS 2: CDR, aligned, with a 4-byte header giving the byte order.
    Cdr,
}

/// One message as the container holds it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RawMessage {
    /// The serialised message, from byte `start` (what comes before is the container's record
    /// header, kept rather than copied away).
    pub data: Vec<u8>,
    /// Where the message starts in `data`.
    pub start: usize,
    /// Its serialisation.
    pub encoding: Encoding,
    /// When it was recorded (nanoseconds since the epoch).
    pub log_time_ns: u64,
}

impl RawMessage {
    /// The serialised message.
    pub fn bytes(&self) -> &[u8] {
        self.data.get(self.start..).unwrap_or(&[])
    }
}

/// A topic of a recording.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Topic {
    /// Its name, `/os_cloud_node/points` say.
    pub name: String,
    /// Its message type, `sensor_msgs/msg/PointCloud2` (ROS 2) or `sensor_msgs/PointCloud2`.
    pub type_name: String,
    /// How many messages it has.
    pub messages: u64,
}

impl Topic {
    /// True for `sensor_msgs/PointCloud2` in either ROS's spelling.
    pub fn is_point_cloud(&self) -> bool {
        matches!(
            self.type_name.as_str(),
            "sensor_msgs/PointCloud2" | "sensor_msgs/msg/PointCloud2"
        )
    }
}

/// The kinds of recording, as told by their content.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Container {
    /// A ROS 1 bag file.
    Ros1Bag(PathBuf),
    /// An MCAP file.
    Mcap(PathBuf),
    /// A ROS 2 bag: its storage files in order (or one `.db3` file given alone).
    Ros2(Vec<PathBuf>),
}

/// The chunk compressions robot recordings use: ROS 1 bags bz2 and lz4, MCAP zstd and lz4
/// (lz4 as frames in both).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Compression {
    /// bzip2.
    Bz2,
    /// The LZ4 frame format.
    Lz4,
    /// Zstandard.
    Zstd,
}

/// Decompresses a chunk that its header says holds `size` bytes (at most
/// [`mcap::MAX_RECORD_BYTES`]): the output is reserved as it arrives beyond 16 MB, so a corrupt
/// size costs no memory, and decompression stops at `size`.
pub fn decompress(kind: Compression, data: &[u8], size: usize) -> Result<Vec<u8>, RecordingError> {
    if size > mcap::MAX_RECORD_BYTES {
        return Err(Damaged(format!(
            "a chunk decompressing to {size} bytes, over the {}-byte limit",
            mcap::MAX_RECORD_BYTES
        )));
    }
    let mut out = Vec::with_capacity(size.min(16 << 20));
    let limit = size as u64;
    let read = match kind {
        Compression::Bz2 => bzip2::read::BzDecoder::new(data)
            .take(limit)
            .read_to_end(&mut out),
        Compression::Lz4 => lz4_flex::frame::FrameDecoder::new(data)
            .take(limit)
            .read_to_end(&mut out),
        Compression::Zstd => {
            zstd::stream::read::Decoder::new(data).and_then(|d| d.take(limit).read_to_end(&mut out))
        }
    };
    read.map_err(|e| Damaged(format!("a {kind:?} chunk does not decompress: {e}")))?;
    if out.len() != size {
        return Err(Damaged(format!(
            "a chunk decompresses to {} bytes, not the {size} its header says",
            out.len()
        )));
    }
    Ok(out)
}

/// True if `path` is a file starting with `magic`.
pub fn has_magic(path: &Path, magic: &[u8]) -> bool {
    let mut head = vec![0u8; magic.len()];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok()
        && head == magic
}

impl Container {
    /// The recording at `path`, or `None` if it is not one (a scan file or folder).
    pub fn detect(path: &Path) -> Option<Result<Container, FileError>> {
        if path.is_dir() {
            if !path.join("metadata.yaml").is_file() {
                return None;
            }
            return Some(
                ros2::files(path)
                    .map(Container::Ros2)
                    .map_err(|e| FileError::at(path, e.to_string())),
            );
        }
        if has_magic(path, mcap::MAGIC) {
            Some(Ok(Container::Mcap(path.to_path_buf())))
        } else if has_magic(path, rosbag1::MAGIC) {
            Some(Ok(Container::Ros1Bag(path.to_path_buf())))
        } else if has_magic(path, ros2::SQLITE_MAGIC) {
            Some(Ok(Container::Ros2(vec![path.to_path_buf()])))
        } else {
            None
        }
    }

    /// Every topic with its type and message count.
    pub fn topics(&self) -> Result<Vec<Topic>, FileError> {
        match self {
            Container::Ros1Bag(p) => {
                rosbag1::topics(p).map_err(|e| FileError::at(p, e.to_string()))
            }
            Container::Mcap(p) => mcap::topics(p).map_err(|e| FileError::at(p, e.to_string())),
            Container::Ros2(files) => {
                let mut all: Vec<Topic> = Vec::new();
                for f in files {
                    for t in ros2::topics(f).map_err(|e| FileError::at(f, e.to_string()))? {
                        match all.iter_mut().find(|a| a.name == t.name) {
                            Some(a) => a.messages += t.messages,
                            None => all.push(t),
                        }
                    }
                }
                Ok(all)
            }
        }
    }

    /// The messages of `topic`, in recorded order.
    pub fn messages(&self, topic: &str) -> Result<Messages, FileError> {
        Ok(match self {
            Container::Ros1Bag(p) => Box::new(
                rosbag1::Messages::new(p, Some(topic))
                    .map_err(|e| FileError::at(p, e.to_string()))?
                    .map(|m| m.map(|(_, m)| m)),
            ),
            Container::Mcap(p) => {
                Box::new(mcap::messages(p, topic).map_err(|e| FileError::at(p, e.to_string()))?)
            }
            Container::Ros2(files) => {
                let topic = topic.to_owned();
                Box::new(files.clone().into_iter().flat_map(move |f| {
                    let it: Messages = if has_magic(&f, ros2::SQLITE_MAGIC) {
                        #[cfg(feature = "db3")]
                        match db3::Db3Messages::new(&f, &topic) {
                            Ok(m) => Box::new(m),
                            Err(e) => Box::new(std::iter::once(Err(e))),
                        }
                        #[cfg(not(feature = "db3"))]
                        Box::new(std::iter::once(Err(RecordingError::Unsupported(
                            "built without the db3 feature".into(),
                        ))))
                    } else {
                        match mcap::messages(&f, &topic) {
                            Ok(m) => Box::new(m),
                            Err(e) => Box::new(std::iter::once(Err(e))),
                        }
                    };
                    it
                }))
            }
        })
    }

    /// The file named in messages: the bag, the MCAP file, or the ROS 2 bag's folder.
    pub fn path(&self) -> PathBuf {
        match self {
            Container::Ros1Bag(p) | Container::Mcap(p) => p.clone(),
            Container::Ros2(files) => {
                let first = &files[0];
                first.parent().map_or(first.clone(), Path::to_path_buf)
            }
        }
    }
}

/// A stream of messages.
pub type Messages = Box<dyn Iterator<Item = Result<RawMessage, RecordingError>> + Send>;

/// The topic to read: `wanted` if given (it must be a PointCloud2 topic), otherwise the only
/// PointCloud2 topic. The errors list the topics a user can choose from.
pub fn choose_topic(topics: &[Topic], wanted: Option<&str>) -> Result<Topic, RecordingError> {
    let list = |ts: &mut dyn Iterator<Item = &Topic>| {
        ts.map(|t| format!("{} ({}, {} messages)", t.name, t.type_name, t.messages))
            .collect::<Vec<_>>()
            .join(", ")
    };
    if let Some(w) = wanted {
        let t = topics.iter().find(|t| t.name == w).ok_or_else(|| {
            TopicChoice(format!(
                "no topic {w}; the recording has {}",
                list(&mut topics.iter())
            ))
        })?;
        if !t.is_point_cloud() {
            return Err(TopicChoice(format!(
                "topic {w} holds {}, not sensor_msgs/PointCloud2",
                t.type_name
            )));
        }
        return Ok(t.clone());
    }
    let clouds: Vec<&Topic> = topics.iter().filter(|t| t.is_point_cloud()).collect();
    match clouds[..] {
        [one] => Ok(one.clone()),
        [] => Err(TopicChoice(format!(
            "no sensor_msgs/PointCloud2 topic; the recording has {}",
            if topics.is_empty() {
                "no topics".into()
            } else {
                list(&mut topics.iter())
            }
        ))),
        _ => Err(TopicChoice(format!(
            "several PointCloud2 topics, choose one with --topic: {}",
            list(&mut clouds.into_iter())
        ))),
    }
}

/// A recording's PointCloud2 topic as a run's frames: one message a frame, read in order.
pub struct Recording {
    container: Container,
    /// The topic read.
    pub topic: Topic,
    stream: Option<Messages>,
    /// Index of the next message `stream` gives.
    next: usize,
    /// Each frame's time (header stamp, else the recorded time), once read.
    stamps: Vec<Option<f64>>,
    /// Points the last decoded cloud dropped (NaN or no return).
    last_dropped: usize,
    /// The IMU topic read beside the clouds ([`Recording::read_imu`]).
    pub imu: Option<imu_topic::ImuTopic>,
}

impl Recording {
    /// Opens the recording `container`, reading `topic` (or the only PointCloud2 topic).
    pub fn open(container: Container, topic: Option<&str>) -> Result<Self, FileError> {
        let topics = container.topics()?;
        let path = container.path();
        let topic =
            choose_topic(&topics, topic).map_err(|e| FileError::at(&path, e.to_string()))?;
        if topic.messages == 0 {
            return Err(FileError::at(
                &path,
                format!("topic {} has no messages", topic.name),
            ));
        }
        Ok(Recording {
            stamps: vec![None; topic.messages as usize],
            container,
            topic,
            stream: None,
            next: 0,
            last_dropped: 0,
            imu: None,
        })
    }

    /// Reads the IMU topic `wanted` (or the only one) beside the clouds; `Ok(false)` when the
    /// recording has none. An error names the topics when the choice is not clear.
    pub fn read_imu(&mut self, wanted: Option<&str>) -> Result<bool, FileError> {
        let topics = self.container.topics()?;
        let path = self.container.path();
        let chosen = imu_topic::choose_imu_topic(&topics, wanted)
            .map_err(|e| FileError::at(&path, e.to_string()))?;
        let Some(topic) = chosen else {
            return Ok(false);
        };
        log::info!(
            "IMU readings from topic {} ({} messages)",
            topic.name,
            topic.messages
        );
        self.imu = Some(imu_topic::ImuTopic::open(&self.container, topic)?);
        Ok(true)
    }

    /// The container read.
    pub fn container(&self) -> &Container {
        &self.container
    }

    fn error(&self, i: usize, reason: impl std::fmt::Display) -> FileError {
        FileError::at(
            &self.container.path(),
            format!("topic {}, message {i}: {reason}", self.topic.name),
        )
    }

    /// Frame `i`'s cloud, decoded, with its times, intensity and ring where the cloud has them.
    pub fn read_decoded(&mut self, i: usize) -> Result<DecodedScan, FileError> {
        self.read_with(i, true)
    }

    /// Frame `i`'s cloud; its intensity and ring only with `extras`.
    fn read_with(&mut self, i: usize, extras: bool) -> Result<DecodedScan, FileError> {
        if self.stream.is_none() || i < self.next {
            self.stream = Some(self.container.messages(&self.topic.name)?);
            self.next = 0;
        }
        let stream = self.stream.as_mut().expect("opened above");
        let msg = loop {
            let at = self.next;
            let Some(m) = stream.next() else {
                return Err(self.error(i, format!("the recording ends after {at} messages")));
            };
            self.next += 1;
            match m {
                Ok(m) if at == i => break m,
                Ok(m) => {
                    if let Some(slot) = self.stamps.get_mut(at) {
                        slot.get_or_insert(m.log_time_ns as f64 * 1e-9);
                    }
                }
                Err(e) if at == i => return Err(self.error(i, e)),
                Err(_) => {}
            }
        };
        let cloud = match msg.encoding {
            Encoding::Ros1 => Cloud::parse_ros1(msg.bytes()),
            Encoding::Cdr => Cloud::parse_cdr(msg.bytes()),
        };
        let stamp = cloud
            .as_ref()
            .map_or(msg.log_time_ns as f64 * 1e-9, |c| c.stamp);
        if let Some(s) = self.stamps.get_mut(i) {
            *s = Some(stamp);
        }
        self.last_dropped = 0;
        let decoded = cloud
            .and_then(|c| c.decode_with(extras))
            .map_err(|e| self.error(i, e))?;
        self.last_dropped = decoded.dropped_non_finite + decoded.dropped_zero;
        Ok(decoded)
    }
}

/// A ROS 1 bag, an MCAP file or a ROS 2 bag folder, told by its content
/// ([`Container::detect`]).
pub struct RecordingKind;

impl crate::sources::kinds::InputKind for RecordingKind {
    fn name(&self) -> &'static str {
        "a recording (ROS 1 bag, MCAP, ROS 2 bag folder)"
    }

    fn open(
        &self,
        path: &Path,
        how: &crate::sources::kinds::OpenOptions,
    ) -> Option<Result<crate::sources::kinds::Opened, FileError>> {
        let container = Container::detect(path)?;
        let open = || {
            how.refuse_packet_options(path)?;
            let rec = Recording::open(container?, how.topic.as_deref())?;
            Ok(Box::new(rec) as _)
        };
        Some(open())
    }
}

impl crate::sources::kinds::OpenedInput for Recording {
    fn describe(&self) -> String {
        let frames = crate::sources::FrameSource::frames(self);
        format!("{frames} frames of topic {}", self.topic.name)
    }

    /// A `sensor_msgs/Imu` topic of the recording: the only one, or `imu_topic`.
    fn attach_imu(
        &mut self,
        at: &Path,
        imu: Option<&str>,
        imu_topic: Option<&str>,
    ) -> Result<(), FileError> {
        match imu {
            Some("off") => Ok(()),
            None => self.read_imu(imu_topic).map(|_| ()),
            Some(_) => crate::sources::kinds::readings_come_with_it(at, imu, imu_topic),
        }
    }
}

impl crate::sources::FrameSource for Recording {
    fn frames(&self) -> usize {
        self.stamps.len()
    }
    fn label(&self, i: usize) -> String {
        format!(
            "{} {} #{i}",
            self.container.path().display(),
            self.topic.name
        )
    }
    fn stamp(&self, i: usize) -> f64 {
        self.stamps
            .get(i)
            .copied()
            .flatten()
            .unwrap_or(i as f64 * 0.1)
    }
    fn read(&mut self, i: usize) -> Result<Vec<slamesh_core::Point>, FileError> {
        self.read_with(i, false).map(|d| d.points)
    }
    fn read_timed(
        &mut self,
        i: usize,
    ) -> Result<(Vec<slamesh_core::Point>, Option<Vec<f32>>), FileError> {
        self.read_with(i, false).map(|d| (d.points, d.times))
    }
    fn dropped_by_reader(&self) -> usize {
        self.last_dropped
    }
    fn samples(&mut self, i: usize) -> Vec<crate::sources::Sample> {
        let stamp = crate::sources::FrameSource::stamp(self, i);
        let label = self.container.path().display().to_string();
        self.imu
            .as_mut()
            .map_or_else(Vec::new, |imu| imu.for_frame(stamp, &label))
    }
}
