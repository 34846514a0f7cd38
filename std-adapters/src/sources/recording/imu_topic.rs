//! A recording's `sensor_msgs/Imu` topic, read beside its clouds: chosen by name
//! (`--imu-topic`) or as the recording's only one ([`choose_imu_topic`]), streamed a message
//! at a time (never the whole topic in memory), each message decoded by
//! [`crate::formats::imu_message`] and handed to the frame whose sweep it falls in
//! ([`crate::sources::imu_readings`]'s rule: up to a frame period past the frame's stamp).
//!
//! A malformed message is skipped with the recording, topic, index and reason (the first ten
//! named, all counted); the frames go on.

use crate::formats::imu_message;
use crate::sources::imu_readings::{first_frame_reach, frame_period};
use crate::sources::recording::RecordingError::{self, TopicChoice};
use crate::sources::recording::{Container, Encoding, Messages, Topic};
use crate::sources::Sample;

/// True for `sensor_msgs/Imu` in either ROS's spelling.
pub fn is_imu(t: &Topic) -> bool {
    matches!(
        t.type_name.as_str(),
        "sensor_msgs/Imu" | "sensor_msgs/msg/Imu"
    )
}

/// The IMU topic to read: `wanted` if given (it must hold `sensor_msgs/Imu`), otherwise the
/// only one; `Ok(None)` when there is none, an error naming them when there are several.
pub fn choose_imu_topic(
    topics: &[Topic],
    wanted: Option<&str>,
) -> Result<Option<Topic>, RecordingError> {
    let imus: Vec<&Topic> = topics.iter().filter(|t| is_imu(t)).collect();
    if let Some(w) = wanted {
        return match topics.iter().find(|t| t.name == w) {
            Some(t) if is_imu(t) => Ok(Some(t.clone())),
            Some(t) => Err(TopicChoice(format!(
                "--imu-topic {w} holds {}, not sensor_msgs/Imu",
                t.type_name
            ))),
            None => Err(TopicChoice(format!("no topic {w} for --imu-topic"))),
        };
    }
    match imus[..] {
        [] => Ok(None),
        [one] => Ok(Some(one.clone())),
        _ => Err(TopicChoice(format!(
            "several sensor_msgs/Imu topics, choose one with --imu-topic (or --imu off): {}",
            imus.iter()
                .map(|t| t.name.as_str())
                .collect::<Vec<_>>()
                .join(", ")
        ))),
    }
}

/// The IMU topic's messages, read as the frames need them.
pub struct ImuTopic {
    /// The topic.
    pub topic: Topic,
    stream: Messages,
    /// A reading read but later than the frames asked for so far.
    held: Option<Sample>,
    /// Messages read, and those skipped as malformed.
    pub read: usize,
    /// Malformed messages skipped.
    pub skipped: usize,
    /// The last frame's stamp, for the period.
    last_stamp: Option<f64>,
}

impl ImuTopic {
    /// Starts reading `topic` of `container`.
    pub fn open(container: &Container, topic: Topic) -> Result<Self, crate::io::FileError> {
        Ok(Self {
            stream: container.messages(&topic.name)?,
            topic,
            held: None,
            read: 0,
            skipped: 0,
            last_stamp: None,
        })
    }

    /// The readings up to a frame period past `stamp`, the stamp of the next frame (frames in
    /// order); `label` names the recording in messages.
    pub fn for_frame(&mut self, stamp: f64, label: &str) -> Vec<Sample> {
        let before = self.last_stamp.replace(stamp);
        let until = stamp + first_frame_reach(before.is_none(), frame_period(stamp, before, None));
        let mut out = Vec::new();
        loop {
            let s = match self.held.take() {
                Some(s) => s,
                None => match self.next(label) {
                    Some(s) => s,
                    None => return out,
                },
            };
            if s.stamp() > until {
                self.held = Some(s);
                return out;
            }
            out.push(s);
        }
    }

    /// The next well-formed reading, if any.
    fn next(&mut self, label: &str) -> Option<Sample> {
        loop {
            let m = self.stream.next()?;
            let index = self.read;
            self.read += 1;
            let decoded = m.map_err(|e| e.to_string()).and_then(|m| {
                match m.encoding {
                    Encoding::Ros1 => imu_message::parse_ros1(m.bytes()),
                    Encoding::Cdr => imu_message::parse_cdr(m.bytes()),
                }
                .map_err(|e| e.to_string())
            });
            match decoded {
                Ok(m) => return Some(Sample::Imu(m.reading)),
                Err(e) => {
                    self.skipped += 1;
                    if self.skipped <= 10 {
                        log::warn!(
                            "{label}: topic {}, message {index}: skipped: {e}",
                            self.topic.name
                        );
                    }
                }
            }
        }
    }
}

impl std::fmt::Debug for ImuTopic {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ImuTopic")
            .field("topic", &self.topic)
            .field("read", &self.read)
            .field("skipped", &self.skipped)
            .finish()
    }
}
