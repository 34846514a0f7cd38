//! Where a run's frames come from: [`FrameSource`], and its implementation for a folder of
//! scans (and, with the `sim` feature, for a simulated drive).

use crate::io::error::FileError;
use crate::io::scans::{read_scan, ScanFolder};
use slamesh_core::Point;

/// Frames to run over.
pub trait FrameSource {
    /// Number of frames.
    fn frames(&self) -> usize;
    /// What to call frame `i` in messages (its file).
    fn label(&self, i: usize) -> String;
    /// Timestamp of frame `i` (seconds).
    fn stamp(&self, i: usize) -> f64;
    /// The points of frame `i`, in the sensor frame.
    fn read(&mut self, i: usize) -> Result<Vec<Point>, FileError>;
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
        read_scan(&self.paths[i])
    }
}

/// A simulated drive: its noisy scans, made on demand, 10 frames a second.
#[cfg(feature = "sim")]
impl FrameSource for slamesh_sim::Drive {
    fn frames(&self) -> usize {
        self.poses.len()
    }
    fn label(&self, i: usize) -> String {
        format!("simulated frame {i}")
    }
    fn stamp(&self, i: usize) -> f64 {
        i as f64 * 0.1
    }
    fn read(&mut self, i: usize) -> Result<Vec<Point>, FileError> {
        Ok(self.scan(i))
    }
}
