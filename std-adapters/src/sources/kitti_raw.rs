//! KITTI raw's drive folders as the dataset ships them (`2011_09_26_drive_0001_sync/`): the
//! scans in `velodyne_points/data/*.bin` with their stamps in `velodyne_points/timestamps.txt`
//! (the moment the head faced forward, mid-sweep; `timestamps_start.txt` and
//! `timestamps_end.txt` bound each sweep), and the OXTS unit's packets in `oxts/`
//! ([`crate::formats::oxts`]). A run is given the drive folder, `velodyne_points/` or its
//! `data/`; it reads the scans with their stamps and, unless told otherwise, the OXTS packets
//! as its IMU.
//!
//! Unlike the odometry benchmark's, raw scans are not deskewed by the dataset's makers (its
//! readme says so): a raw drive's points are timed from a `kitti` sweep unless `--sweep`
//! says otherwise ([`crate::sources::sweep_times`]).

use crate::formats::oxts;
use crate::io::error::FileError;
use std::path::{Path, PathBuf};

/// A KITTI raw drive folder.
#[derive(Debug, Clone, PartialEq)]
pub struct RawDrive {
    /// The drive folder (holding `velodyne_points/` and, when it has one, `oxts/`).
    pub drive: PathBuf,
}

impl RawDrive {
    /// The drive `input` names: the drive folder, its `velodyne_points/` or that folder's
    /// `data/`, when `velodyne_points/data/` is a folder.
    pub fn detect(input: &Path) -> Option<Self> {
        let named = |p: &Path, name: &str| p.file_name().is_some_and(|n| n == name);
        let drive = if named(input, "data")
            && input.parent().is_some_and(|p| named(p, "velodyne_points"))
        {
            input.parent()?.parent()?.to_path_buf()
        } else if named(input, "velodyne_points") {
            input.parent()?.to_path_buf()
        } else {
            input.to_path_buf()
        };
        drive
            .join("velodyne_points")
            .join("data")
            .is_dir()
            .then_some(RawDrive { drive })
    }

    /// The scans' folder.
    pub fn scans(&self) -> PathBuf {
        self.drive.join("velodyne_points").join("data")
    }

    /// The scans' stamps (`velodyne_points/timestamps.txt`), when they are there and one a
    /// scan of `frames`; an error names the file and line of a stamp that does not read.
    pub fn stamps(&self, frames: usize) -> Result<Option<Vec<f64>>, FileError> {
        let path = self.drive.join("velodyne_points").join("timestamps.txt");
        if !path.is_file() {
            return Ok(None);
        }
        let stamps = oxts::read_times(&path)?;
        if stamps.len() != frames {
            log::warn!(
                "{}: {} stamps for {frames} scans: not used (10 Hz is assumed)",
                path.display(),
                stamps.len()
            );
            return Ok(None);
        }
        Ok(Some(stamps))
    }

    /// The OXTS folder, when the drive has one with its stamps.
    pub fn oxts(&self) -> Option<PathBuf> {
        let dir = self.drive.join("oxts");
        dir.join("timestamps.txt").is_file().then_some(dir)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_drive_is_found_from_its_folder_its_velodyne_points_or_their_data() {
        let root = std::env::temp_dir().join(format!("slamesh-kitti-raw-{}", std::process::id()));
        let drive = root.join("2011_09_26_drive_0001_sync");
        let data = drive.join("velodyne_points").join("data");
        std::fs::create_dir_all(&data).unwrap();
        for given in [drive.clone(), drive.join("velodyne_points"), data.clone()] {
            let raw = RawDrive::detect(&given).expect("found");
            assert_eq!(raw.drive, drive, "{}", given.display());
            assert_eq!(raw.scans(), data);
        }
        assert_eq!(RawDrive::detect(&root), None);
        assert_eq!(RawDrive::detect(&drive).unwrap().oxts(), None);
        std::fs::create_dir_all(drive.join("oxts")).unwrap();
        std::fs::write(drive.join("oxts").join("timestamps.txt"), "").unwrap();
        assert_eq!(
            RawDrive::detect(&drive).unwrap().oxts(),
            Some(drive.join("oxts"))
        );
        let stamps = drive.join("velodyne_points").join("timestamps.txt");
        std::fs::write(&stamps, "2011-09-26 13:02:25.5\n2011-09-26 13:02:25.6\n").unwrap();
        let raw = RawDrive::detect(&drive).unwrap();
        let s = raw.stamps(2).unwrap().unwrap();
        assert!((s[1] - s[0] - 0.1).abs() < 1e-6);
        assert_eq!(raw.stamps(3).unwrap(), None, "one a scan or none");
        std::fs::write(&stamps, "yesterday\n").unwrap();
        let e = raw.stamps(1).unwrap_err().to_string();
        assert!(e.contains("timestamps.txt") && e.contains("line 1"), "{e}");
        std::fs::remove_dir_all(&root).unwrap();
    }
}
