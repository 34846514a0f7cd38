//! Scan files as an input kind ([`FolderKind`]): a folder of scans, a KITTI sequence or raw
//! drive folder, or one scan file ([`ScanFolder`] lists them), read frame by frame; with an
//! IMU's readings from a file beside it or named (`--imu`), or KITTI raw's OXTS, and times
//! for scans that carry none from their sweep (`--sweep`).
//!
//! The last kind the command asks: a path no other kind knows is read as scan files, and
//! refused with the reason when it holds none.

use crate::formats::imu_csv;
use crate::io::error::FileError;
use crate::sources::imu_readings::ImuReadings;
use crate::sources::kinds::{InputKind, OpenOptions, Opened, OpenedInput, NOT_A_RECORDING};
use crate::sources::scans::{read_scan_as, ScanFolder, Stamps};
use crate::sources::sweep_times::{period_of, SweepSpec, SweepTimer};
use crate::sources::{FrameSource, Sample};
use slamesh_core::Point;
use std::path::{Path, PathBuf};

/// Scan files: what every path no other kind knows is read as.
pub struct FolderKind;

impl InputKind for FolderKind {
    fn name(&self) -> &'static str {
        "scan files"
    }

    fn open(&self, path: &Path, how: &OpenOptions) -> Option<Result<Opened, FileError>> {
        Some(open_folder(path, how))
    }
}

fn open_folder(path: &Path, how: &OpenOptions) -> Result<Opened, FileError> {
    how.refuse_packet_options(path)?;
    if how.topic.is_some() {
        return Err(FileError::at(
            path,
            "--topic is for recordings (ROS 1 bags, MCAP, ROS 2 bag folders), and this is not one",
        ));
    }
    let mut folder = ScanFolder::open(path)?;
    folder.bin_fields = how.bin_fields.clone();
    Ok(Box::new(folder))
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

impl OpenedInput for ScanFolder {
    fn describe(&self) -> String {
        let times = match self.stamps_from {
            Stamps::TimesTxt => "from times.txt",
            Stamps::FileNames => "from the file names",
            Stamps::Assumed10Hz => "assumed 10 Hz: no times.txt, and the file names are not times",
            Stamps::KittiRaw => "from KITTI raw's velodyne_points/timestamps.txt",
        };
        let sweep = self.sweep.as_ref().map_or(String::new(), |s| {
            format!(
                ", points without times timed from a {} sweep of {:.3} s",
                s.counts().sweep,
                s.counts().period_s
            )
        });
        format!("{} scan files (times {times}){sweep}", self.len())
    }

    /// The readings of a CSV file (`imu`, or one beside the folder, [`imu_csv::beside`]), or
    /// KITTI raw's OXTS, saying when their times miss the scans'.
    fn attach_imu(
        &mut self,
        at: &Path,
        imu: Option<&str>,
        imu_topic: Option<&str>,
    ) -> Result<(), FileError> {
        if imu_topic.is_some() {
            return Err(FileError::at(at, NOT_A_RECORDING));
        }
        let path = match imu {
            Some("off") => return Ok(()),
            Some(file) => Some(PathBuf::from(file)),
            None => imu_csv::beside(at),
        };
        let oxts = (self.raw.as_ref())
            .and_then(|r| r.oxts())
            .filter(|_| path.is_none());
        let (imu, path) = match (path, oxts) {
            (Some(path), _) => (ImuReadings::open(&path)?, path),
            (None, Some(oxts)) => (ImuReadings::from_oxts(&oxts)?, oxts),
            (None, None) => return Ok(()),
        };
        if let (Some((a, b)), Some(first), Some(last)) =
            (imu.span(), self.stamps.first(), self.stamps.last())
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
        self.imu = Some(imu);
        Ok(())
    }

    /// Its period the scans' own.
    fn time_from_sweep(&mut self, _at: &Path, sweep: &SweepSpec) -> Result<(), FileError> {
        self.sweep = Some(Box::new(SweepTimer::new(sweep, period_of(&self.stamps))));
        Ok(())
    }

    /// KITTI raw's scans were not deskewed by the dataset's makers: timed as its HDL-64E's.
    fn default_sweep(&self) -> Option<&'static str> {
        self.raw.as_ref().map(|_| "kitti")
    }

    fn note_sweep_trial(&mut self, trial: String) {
        self.sweep_trial = Some(trial);
    }
}
