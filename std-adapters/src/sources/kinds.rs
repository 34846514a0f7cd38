//! The kinds of input a path or address can name, each told apart and opened by its own
//! [`InputKind`], beside the source it opens; [`Kinds`] is the list the command asks in order.
//! A new kind is one type that implements [`InputKind`] (its detection included) and one
//! that implements [`OpenedInput`], added to a [`Kinds`] with [`Kinds::with`]: nothing here,
//! in [`crate::sources::input`] or in the run changes.
//!
//! Owns: the order kinds are asked in and what every kind is opened with ([`OpenOptions`]).
//! Guarantees: the first kind that knows the path opens it; a path no kind knows is opened
//! by the last (scan files: a folder, or one file), which says why it cannot be read.

use crate::formats::kitti::BinFields;
use crate::io::error::FileError;
use crate::sources::packets::PacketOptions;
use crate::sources::sweep_times::SweepSpec;
use crate::sources::FrameSource;
use std::path::Path;

/// What an input is opened with: the command's options that say how to read it. A kind
/// refuses those that are not its own (`--topic` for scan files, `--sensor` for a recording).
#[derive(Debug, Clone, Default)]
pub struct OpenOptions {
    /// A recording's point cloud topic (`--topic`); by default its only one.
    pub topic: Option<String>,
    /// The fields of a folder's `.bin` scans (`--bin-fields`).
    pub bin_fields: BinFields,
    /// How packets are read: a capture's or a live input's sensor, metadata, calibration.
    pub packets: PacketOptions,
}

impl OpenOptions {
    /// Refused: packet options given for an input that is not a capture or a live one.
    pub fn refuse_packet_options(&self, path: &Path) -> Result<(), FileError> {
        let p = &self.packets;
        match p.sensor.is_some() || p.metadata.is_some() || p.calibration.is_some() {
            true => Err(FileError::at(
                path,
                "--sensor, --metadata and --calibration are for packet captures (.pcap, \
                 .pcapng) and live inputs (udp://), and this is neither",
            )),
            false => Ok(()),
        }
    }
}

/// One kind of input: how to tell it from a path (or address), and how to open it.
pub trait InputKind: Send + Sync {
    /// What it is, for messages ("scan files", "a recording").
    fn name(&self) -> &'static str;
    /// `path` opened when it is of this kind (told cheaply: its name, its first bytes);
    /// `None` when it is not, and the next kind is asked.
    fn open(&self, path: &Path, how: &OpenOptions) -> Option<Result<Opened, FileError>>;
}

/// An opened input, of whichever kind.
pub type Opened = Box<dyn OpenedInput>;

/// What the command asks of an opened input beside its frames. Each has a default for a kind
/// it does not concern: a sweep's times and a folder's IMU file are refused, naming why.
pub trait OpenedInput: FrameSource + Send + std::any::Any {
    /// What was opened, for the log: "12 frames of topic /points", "12 scan files (...)".
    fn describe(&self) -> String;
    /// Whether it is live (it ends on Ctrl-C, with no known number of frames).
    fn is_live(&self) -> bool {
        false
    }
    /// Attaches the IMU's readings as `--imu` (`imu`: `off`, a file, or `None` for what comes
    /// with the input) and `--imu-topic` say; `at` is the path the input was opened from. By
    /// default the readings come with the input, and a file or topic is refused.
    fn attach_imu(
        &mut self,
        at: &Path,
        imu: Option<&str>,
        imu_topic: Option<&str>,
    ) -> Result<(), FileError> {
        readings_come_with_it(at, imu, imu_topic)
    }
    /// Times the scans that carry none from `sweep` (`--sweep`). By default refused: the
    /// input's scans come with their times, or its sensor is known.
    fn time_from_sweep(&mut self, at: &Path, _sweep: &SweepSpec) -> Result<(), FileError> {
        Err(FileError::at(at, NOT_A_FOLDER))
    }
    /// The sweep (a [`SweepSpec`] name) its scans are timed by when `--sweep` says nothing:
    /// scans a dataset's makers left skewed (KITTI raw's, `"kitti"`). By default none.
    fn default_sweep(&self) -> Option<&'static str> {
        None
    }
    /// Keeps what `--sweep auto` found (in words) for the report; by default not kept.
    fn note_sweep_trial(&mut self, _trial: String) {}
}

/// [`OpenedInput::attach_imu`] for an input whose IMU readings come with it: `--imu FILE` and
/// `--imu-topic` refused, naming why.
pub fn readings_come_with_it(
    at: &Path,
    imu: Option<&str>,
    imu_topic: Option<&str>,
) -> Result<(), FileError> {
    if imu_topic.is_some() {
        return Err(FileError::at(at, NOT_A_RECORDING));
    }
    match imu.filter(|v| *v != "off") {
        Some(_) => Err(FileError::at(
            at,
            "--imu FILE is for a folder of scans; a recording's or a live input's IMU \
             readings come with it",
        )),
        None => Ok(()),
    }
}

/// Why `--imu-topic` is refused for an input that is not a recording.
pub const NOT_A_RECORDING: &str = "--imu-topic is for recordings";

/// Why `--sweep` is refused for an input that is not a folder of scan files.
pub const NOT_A_FOLDER: &str =
    "--sweep is for folders of scan files (.bin, .pcd, .ply), and this is not one";

/// The kinds of input, asked in order.
pub struct Kinds(Vec<Box<dyn InputKind>>);

impl Kinds {
    /// The command's: a live address (`udp://`), a packet capture, a recording (with the
    /// feature `recordings`), then scan files.
    pub fn standard() -> Self {
        let mut kinds: Vec<Box<dyn InputKind>> = vec![
            Box::new(crate::sources::live::LiveKind),
            Box::new(crate::sources::replay::CaptureKind),
        ];
        #[cfg(feature = "recordings")]
        kinds.push(Box::new(crate::sources::recording::RecordingKind));
        kinds.push(Box::new(crate::sources::folder::FolderKind));
        Kinds(kinds)
    }

    /// These kinds with `kind` asked first (before the scan files every other path falls to).
    pub fn with(mut self, kind: impl InputKind + 'static) -> Self {
        self.0.insert(0, Box::new(kind));
        self
    }

    /// The kinds' names, in the order they are asked.
    pub fn names(&self) -> Vec<&'static str> {
        self.0.iter().map(|k| k.name()).collect()
    }

    /// `path` opened by the first kind that knows it.
    pub fn open(&self, path: &Path, how: &OpenOptions) -> Result<Opened, FileError> {
        self.0
            .iter()
            .find_map(|k| k.open(path, how))
            .unwrap_or_else(|| {
                Err(FileError::at(
                    path,
                    format!(
                        "no input kind reads it (asked: {})",
                        self.names().join(", ")
                    ),
                ))
            })
    }
}
