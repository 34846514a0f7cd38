//! The one error type of slamesh's file IO: which file, which line, what is wrong.

use std::fmt;
use std::path::{Path, PathBuf};

/// A file that could not be read or written, with where and why.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FileError {
    /// The file (or folder).
    pub path: PathBuf,
    /// 1-based line, for text files.
    pub line: Option<usize>,
    /// What is wrong.
    pub reason: String,
}

impl FileError {
    /// An error about `path` (at `line`, if given).
    pub fn new(path: &Path, line: Option<usize>, reason: impl Into<String>) -> Self {
        FileError {
            path: path.to_path_buf(),
            line,
            reason: reason.into(),
        }
    }

    /// An error about the whole of `path`.
    pub fn at(path: &Path, reason: impl Into<String>) -> Self {
        Self::new(path, None, reason)
    }
}

impl fmt::Display for FileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(l) => write!(f, "{}:{}: {}", self.path.display(), l, self.reason),
            None => write!(f, "{}: {}", self.path.display(), self.reason),
        }
    }
}

impl std::error::Error for FileError {}
