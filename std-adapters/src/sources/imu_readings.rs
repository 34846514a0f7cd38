//! An IMU's readings from a file of their own ([`crate::formats::imu_csv`]), handed to a
//! folder of scans frame by frame: frame `i` brings the readings up to a frame period past
//! its stamp (its sweep, when the stamp is the sweep's start; a little early when it is the
//! end), the ones before with the frames before.
//!
//! Frames are asked for in order; the readings are handed in the file's order (the run's
//! track refuses and counts any out of order), each once.

use crate::formats::imu_csv;
use crate::io::error::FileError;
use crate::sources::{ImuReading, Sample};
use std::path::Path;

/// Readings waiting for their frames.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ImuReadings {
    readings: Vec<ImuReading>,
    /// The first reading not handed yet.
    next: usize,
}

impl ImuReadings {
    /// The readings of `path`, its skipped lines named (the first ten).
    pub fn open(path: &Path) -> Result<Self, FileError> {
        let csv = imu_csv::read(path)?;
        name_skipped(path, &csv.skipped);
        Ok(Self::new(csv.readings))
    }

    /// The readings of KITTI raw's `oxts` folder ([`crate::formats::oxts`]), its skipped
    /// packets named (the first ten).
    pub fn from_oxts(dir: &Path) -> Result<Self, FileError> {
        let oxts = crate::formats::oxts::read(dir)?;
        name_skipped(dir, &oxts.skipped);
        Ok(Self::new(oxts.readings))
    }

    /// Readings in time order.
    pub fn new(readings: Vec<ImuReading>) -> Self {
        Self { readings, next: 0 }
    }

    /// The first and last stamps (seconds).
    pub fn span(&self) -> Option<(f64, f64)> {
        Some((self.readings.first()?.stamp, self.readings.last()?.stamp))
    }

    /// The readings not handed yet up to the first one stamped after `until`.
    pub fn until(&mut self, until: f64) -> Vec<Sample> {
        let rest = &self.readings[self.next..];
        let n = rest
            .iter()
            .position(|r| r.stamp > until)
            .unwrap_or(rest.len());
        self.next += n;
        rest[..n].iter().copied().map(Sample::Imu).collect()
    }

    /// For frame `i` of `stamps`: the readings up to a frame period past its stamp (the
    /// period to the next frame, or from the one before, or 0.1 s).
    pub fn for_frame(&mut self, stamps: &[f64], i: usize) -> Vec<Sample> {
        let Some(&t) = stamps.get(i) else {
            return Vec::new();
        };
        let before = i.checked_sub(1).and_then(|j| stamps.get(j)).copied();
        let period = frame_period(t, before, stamps.get(i + 1).copied());
        self.until(t + first_frame_reach(i == 0, period))
    }
}

/// Names the first ten of the `skipped` lines or packets of `path`, then counts them.
fn name_skipped(path: &Path, skipped: &[String]) {
    for s in skipped.iter().take(10) {
        log::warn!("{}: {s}: skipped", path.display());
    }
    if skipped.len() > 10 {
        log::warn!("{}: {} skipped in all", path.display(), skipped.len());
    }
}

/// How far past its stamp a frame takes the readings (`period`: its [`frame_period`]): the
/// `first` frame at least [`FIRST_FRAME_S`], so that an IMU that starts with the first scan
/// still says where up is when the map starts.
pub fn first_frame_reach(first: bool, period: f64) -> f64 {
    match first {
        true => period.max(FIRST_FRAME_S),
        false => period,
    }
}

/// See [`first_frame_reach`]: twice the time gravity's mean needs
/// ([`slamesh_core::gravity::MIN_SECONDS`]).
pub const FIRST_FRAME_S: f64 = 2.0 * slamesh_core::gravity::MIN_SECONDS;

/// The period of the frame stamped `stamp` (seconds): to the next frame's stamp when it is
/// known, else from the one before, else 0.1 s (10 Hz). A frame takes the IMU's readings up to
/// a period past its stamp, wherever they come from (a folder's file, a recording's topic, the
/// ROS 2 node's `imu`).
pub fn frame_period(stamp: f64, before: Option<f64>, next: Option<f64>) -> f64 {
    let valid = |p: f64| (p > 0.0 && p < 1.0).then_some(p);
    next.and_then(|n| valid(n - stamp))
        .or_else(|| before.and_then(|b| valid(stamp - b)))
        .unwrap_or(0.1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_frame_takes_the_readings_through_its_sweep_once() {
        let r = |t: f64| ImuReading {
            stamp: t,
            gyro: [0.0; 3],
            accel: [0.0; 3],
        };
        let mut imu = ImuReadings::new((0..50).map(|k| r(k as f64 * 0.01)).collect());
        let stamps = [0.0, 0.1, 0.2];
        let counts: Vec<usize> = (0..3).map(|i| imu.for_frame(&stamps, i).len()).collect();
        // Up to 0.4 s (the first frame reaches FIRST_FRAME_S past its stamp: 0.00 to 0.40 is
        // 41 readings), then 0.3 s: none left for the second, ten for the third.
        assert_eq!(counts, [41, 0, 0]);
        assert_eq!(imu.until(10.0).len(), 9);
        assert_eq!(first_frame_reach(true, 0.1), FIRST_FRAME_S);
        assert_eq!(first_frame_reach(false, 0.1), 0.1);
        assert_eq!(imu.span(), Some((0.0, 0.49)));
    }
}
