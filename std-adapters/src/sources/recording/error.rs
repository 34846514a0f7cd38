//! Why a recording could not be read ([`RecordingError`]): the one error of the container
//! readers (ROS 1 bags, MCAP files, ROS 2 bag folders and their `.db3` files). The
//! recording's source names the file beside it ([`crate::io::FileError`]).

use std::fmt;

/// Why a recording's container could not be read, by kind, with its words.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum RecordingError {
    /// The system could not open, seek in or read the file: its reason.
    Io(String),
    /// The file ends where more was due: where.
    Truncated(String),
    /// The file is not of the container's format: what it is not.
    NotThisFormat(String),
    /// A record, field or message that cannot be what it claims: which, and why.
    Damaged(String),
    /// What this reader does not read (a compression, a message encoding, a `.db3` file in a
    /// build without its feature).
    Unsupported(String),
    /// A ROS 2 bag's database refused a query.
    Database(String),
    /// The topic asked for is not there or not one to read, or there is no one topic to
    /// choose: with the topics the recording has.
    TopicChoice(String),
}

impl fmt::Display for RecordingError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RecordingError::Io(why)
            | RecordingError::Truncated(why)
            | RecordingError::NotThisFormat(why)
            | RecordingError::Damaged(why)
            | RecordingError::Unsupported(why)
            | RecordingError::Database(why)
            | RecordingError::TopicChoice(why) => f.write_str(why),
        }
    }
}

impl std::error::Error for RecordingError {}

impl From<std::io::Error> for RecordingError {
    fn from(e: std::io::Error) -> Self {
        RecordingError::Io(e.to_string())
    }
}

#[cfg(feature = "db3")]
impl From<rusqlite::Error> for RecordingError {
    fn from(e: rusqlite::Error) -> Self {
        RecordingError::Database(e.to_string())
    }
}
