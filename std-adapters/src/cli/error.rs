//! [`CliError`]: why a subcommand failed, with the error of the layer that failed kept whole.

use crate::io::FileError;
use crate::merge::MergeError;
use crate::run::RunError;
use std::fmt;

/// Why a subcommand failed.
#[derive(Debug)]
pub enum CliError {
    /// A file could not be read or written (it names the file, line and reason).
    File(FileError),
    /// A run could not start or finish.
    Run(RunError),
    /// Two maps were not merged.
    Merge(MergeError),
    /// A flag's value is out of its range.
    BadFlag {
        /// The flag, e.g. `--memory-cap`.
        flag: &'static str,
        /// What is wrong with its value.
        reason: String,
    },
    /// `eval` was given no complete mode.
    NoEvalMode,
    /// Fewer reference poses than scans.
    TooFewPoses {
        /// The sequence.
        sequence: String,
        /// Reference poses found.
        poses: usize,
        /// Scans found.
        scans: usize,
    },
    /// The run ended without a single usable frame.
    NoFrameUsed,
    /// Ctrl-C (or SIGTERM) ended the run before its input did: what it had is written.
    Interrupted {
        /// The first frame not run.
        before: usize,
        /// The input's frames.
        of: usize,
    },
    /// With `--strict`: frames were not registered normally.
    NotRegistered {
        /// How many.
        frames: usize,
    },
}

impl fmt::Display for CliError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CliError::File(e) => write!(f, "{e}"),
            CliError::Run(e) => write!(f, "{e}"),
            CliError::Merge(e) => write!(f, "{e}"),
            CliError::BadFlag { flag, reason } => write!(f, "{flag}: {reason}"),
            CliError::NoEvalMode => write!(
                f,
                "eval: give --estimate and --reference, --mesh and --cloud, or --build-reference"
            ),
            CliError::TooFewPoses {
                sequence,
                poses,
                scans,
            } => write!(f, "{sequence}: {poses} reference poses for {scans} scans"),
            CliError::NoFrameUsed => write!(f, "no frame could be used"),
            CliError::Interrupted { before, of } => write!(
                f,
                "interrupted before frame {before} of {of}: the outputs hold the frames before it"
            ),
            CliError::NotRegistered { frames } => write!(
                f,
                "--strict: {frames} frame(s) not registered normally (listed above)"
            ),
        }
    }
}

impl std::error::Error for CliError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            CliError::File(e) => Some(e),
            CliError::Run(e) => Some(e),
            CliError::Merge(e) => Some(e),
            _ => None,
        }
    }
}

impl From<FileError> for CliError {
    fn from(e: FileError) -> Self {
        CliError::File(e)
    }
}

impl From<RunError> for CliError {
    fn from(e: RunError) -> Self {
        CliError::Run(e)
    }
}

impl From<MergeError> for CliError {
    fn from(e: MergeError) -> Self {
        CliError::Merge(e)
    }
}
