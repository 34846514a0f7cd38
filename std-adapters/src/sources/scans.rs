//! Scan inputs: a folder of point-cloud files (KITTI `.bin`, `.pcd`, `.ply`) read one frame at
//! a time in natural file order (`2.pcd` before `10.pcd`), or a single such file.
//!
//! A KITTI sequence folder may be given instead of its `velodyne/` folder. The frames'
//! timestamps come from, in order: a `times.txt` (KITTI: one number a line); file names that
//! are all numbers, increasing (seconds, or nanoseconds when over 1e15, as in
//! `1700000000.123456.pcd` or `1700000000123456789.bin`); otherwise 10 Hz is assumed
//! ([`Stamps`] says which).

use crate::formats::kitti;
use crate::formats::pcd;
use crate::formats::ply;
use crate::io::error::FileError;
use slamesh_core::Point;
use std::cmp::Ordering;
use std::path::{Path, PathBuf};

/// The extensions read as scans.
pub const EXTENSIONS: [&str; 3] = ["bin", "pcd", "ply"];

/// Where a folder's timestamps came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stamps {
    /// The sequence's `times.txt`.
    TimesTxt,
    /// The file names.
    FileNames,
    /// Neither: frames 0.1 s apart.
    Assumed10Hz,
    /// A KITTI raw drive's `velodyne_points/timestamps.txt`.
    KittiRaw,
}

/// The scan files of an input.
#[derive(Debug, Clone, PartialEq)]
pub struct ScanFolder {
    /// The scan files in natural order.
    pub paths: Vec<PathBuf>,
    /// One timestamp per file (seconds).
    pub stamps: Vec<f64>,
    /// Where they came from.
    pub stamps_from: Stamps,
    /// The record layout of `.bin` files.
    pub bin_fields: kitti::BinFields,
    /// An IMU's readings for the frames (`--imu FILE`, or a file beside the folder).
    pub imu: Option<crate::sources::imu_readings::ImuReadings>,
    /// Times for scans that carry none, from their sweep (`--sweep`).
    pub sweep: Option<Box<crate::sources::sweep_times::SweepTimer>>,
    /// How the sweep was chosen, when the scans chose it (`--sweep auto`), in words.
    pub sweep_trial: Option<String>,
    /// The KITTI raw drive the scans are from, if they are.
    pub raw: Option<crate::sources::kitti_raw::RawDrive>,
}

impl ScanFolder {
    /// Lists the scans of `input` (a folder, a KITTI sequence folder, or one file).
    pub fn open(input: &Path) -> Result<Self, FileError> {
        if input.is_file() {
            let (stamps, stamps_from) =
                file_name_stamps(std::slice::from_ref(&input.to_path_buf()))
                    .map_or((vec![0.0], Stamps::Assumed10Hz), |s| (s, Stamps::FileNames));
            return Ok(ScanFolder {
                paths: vec![input.to_path_buf()],
                stamps,
                stamps_from,
                bin_fields: kitti::BinFields::default(),
                imu: None,
                sweep: None,
                sweep_trial: None,
                raw: None,
            });
        }
        if !input.exists() {
            return Err(FileError::at(input, "no such file or folder"));
        }
        let raw = crate::sources::kitti_raw::RawDrive::detect(input);
        let velodyne = input.join("velodyne");
        let dir = match &raw {
            Some(raw) => raw.scans(),
            None if velodyne.is_dir() => velodyne,
            None => input.to_path_buf(),
        };
        let entries = std::fs::read_dir(&dir).map_err(|e| FileError::at(&dir, e.to_string()))?;
        let mut paths: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.is_file() && is_scan(p))
            .collect();
        paths.sort_by(|a, b| natural_cmp(&a.to_string_lossy(), &b.to_string_lossy()));
        if paths.is_empty() {
            return Err(FileError::at(
                &dir,
                "no scans in this folder (looked for .bin, .pcd and .ply files)",
            ));
        }
        let raw_stamps = match &raw {
            Some(raw) => raw.stamps(paths.len())?,
            None => None,
        };
        let (stamps, stamps_from) = if let Some(t) = raw_stamps {
            (t, Stamps::KittiRaw)
        } else if let Some(t) =
            read_times(&kitti::sequence_folder(&dir).join("times.txt"), paths.len())
        {
            (t, Stamps::TimesTxt)
        } else if let Some(t) = file_name_stamps(&paths) {
            (t, Stamps::FileNames)
        } else {
            let t = (0..paths.len()).map(|i| i as f64 * 0.1).collect();
            (t, Stamps::Assumed10Hz)
        };
        Ok(ScanFolder {
            paths,
            stamps,
            stamps_from,
            bin_fields: kitti::BinFields::default(),
            imu: None,
            sweep: None,
            sweep_trial: None,
            raw,
        })
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.paths.len()
    }

    /// True if there are no frames (never, for an opened folder).
    pub fn is_empty(&self) -> bool {
        self.paths.is_empty()
    }
}

/// True if `path` has one of the [`EXTENSIONS`] (any case).
pub fn is_scan(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

/// Reads one scan by its extension (`.bin` files as KITTI's `x,y,z,i`).
pub fn read_scan(path: &Path) -> Result<Vec<Point>, FileError> {
    read_scan_as(path, &kitti::BinFields::default())
}

/// Reads one scan by its extension, `.bin` files as `bin_fields`.
pub fn read_scan_as(path: &Path, bin_fields: &kitti::BinFields) -> Result<Vec<Point>, FileError> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase());
    match ext.as_deref() {
        Some("bin") => kitti::read_bin_as(path, bin_fields),
        Some("pcd") => pcd::read_pcd(path),
        Some("ply") => ply::read_ply_points(path),
        _ => Err(FileError::at(path, "not a scan file (.bin, .pcd or .ply)")),
    }
}

/// `times.txt` with one number a line, if it exists, parses, and covers `frames`.
fn read_times(path: &Path, frames: usize) -> Option<Vec<f64>> {
    let text = std::fs::read_to_string(path).ok()?;
    let t: Vec<f64> = text
        .split_whitespace()
        .map(|w| w.parse().ok())
        .collect::<Option<_>>()?;
    (t.len() >= frames).then(|| t[..frames].to_vec())
}

/// Timestamps from file names that are all numbers and increase: seconds, or nanoseconds
/// when over 1e15.
fn file_name_stamps(paths: &[PathBuf]) -> Option<Vec<f64>> {
    let t: Vec<f64> = paths
        .iter()
        .map(|p| {
            let v: f64 = p.file_stem()?.to_str()?.parse().ok()?;
            (v.is_finite() && v > 0.0).then_some(if v > 1e15 { v * 1e-9 } else { v })
        })
        .collect::<Option<_>>()?;
    // Frame numbers (0, 1, 2, ... as KITTI names them) are not times.
    let numbered = t.iter().enumerate().all(|(i, &v)| v == i as f64);
    let increasing = t.windows(2).all(|w| w[1] > w[0]);
    (increasing && !numbered && t[0] > 1e6).then_some(t)
}

/// Natural order: runs of digits compare as numbers, everything else as text.
pub fn natural_cmp(a: &str, b: &str) -> Ordering {
    let (mut a, mut b) = (a.as_bytes(), b.as_bytes());
    loop {
        match (a.first(), b.first()) {
            (None, None) => return Ordering::Equal,
            (None, _) => return Ordering::Less,
            (_, None) => return Ordering::Greater,
            (Some(x), Some(y)) if x.is_ascii_digit() && y.is_ascii_digit() => {
                let da = a.iter().take_while(|c| c.is_ascii_digit()).count();
                let db = b.iter().take_while(|c| c.is_ascii_digit()).count();
                let strip = |d: &[u8]| {
                    let z = d.iter().take_while(|&&c| c == b'0').count();
                    d[z..].to_vec()
                };
                let (na, nb) = (strip(&a[..da]), strip(&b[..db]));
                let ord = na.len().cmp(&nb.len()).then_with(|| na.cmp(&nb));
                if ord != Ordering::Equal {
                    return ord;
                }
                (a, b) = (&a[da..], &b[db..]);
            }
            (Some(x), Some(y)) => {
                if x != y {
                    return x.cmp(y);
                }
                (a, b) = (&a[1..], &b[1..]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn natural_order_sorts_numbers_by_value() {
        let mut v = vec![
            "scan10.pcd",
            "scan2.pcd",
            "scan1.pcd",
            "scan02b.pcd",
            "a.pcd",
        ];
        v.sort_by(|a, b| natural_cmp(a, b));
        assert_eq!(
            v,
            [
                "a.pcd",
                "scan1.pcd",
                "scan2.pcd",
                "scan02b.pcd",
                "scan10.pcd"
            ]
        );
        assert_eq!(natural_cmp("000009.bin", "000010.bin"), Ordering::Less);
    }

    #[test]
    fn stamps_come_from_times_txt_or_file_names_or_are_assumed() {
        let dir = crate::test_support::scratch_dir("stamps");
        for name in ["1700000000.100000.pcd", "1700000000.200000.pcd"] {
            std::fs::write(dir.join(name), "").unwrap();
        }
        let f = ScanFolder::open(&dir).unwrap();
        assert_eq!(f.stamps_from, Stamps::FileNames);
        assert_eq!(f.stamps, vec![1_700_000_000.1, 1_700_000_000.2]);
        std::fs::write(dir.join("times.txt"), "5\n6\n").unwrap();
        let f = ScanFolder::open(&dir).unwrap();
        assert_eq!(
            (f.stamps_from, f.stamps),
            (Stamps::TimesTxt, vec![5.0, 6.0])
        );
        let dir = crate::test_support::scratch_dir("stamps-ns");
        for name in ["1700000000100000000.bin", "1700000000250000000.bin"] {
            std::fs::write(dir.join(name), "").unwrap();
        }
        let f = ScanFolder::open(&dir).unwrap();
        assert_eq!(f.stamps_from, Stamps::FileNames);
        assert!((f.stamps[1] - 1_700_000_000.25).abs() < 1e-6);
        let dir = crate::test_support::scratch_dir("stamps-none");
        for name in ["000000.bin", "000001.bin"] {
            std::fs::write(dir.join(name), "").unwrap();
        }
        let f = ScanFolder::open(&dir).unwrap();
        assert_eq!(
            (f.stamps_from, f.stamps),
            (Stamps::Assumed10Hz, vec![0.0, 0.1])
        );
    }

    #[test]
    fn a_folder_without_scans_is_an_error_naming_it() {
        let dir = crate::test_support::scratch_dir("noscans");
        std::fs::write(dir.join("notes.txt"), "hi").unwrap();
        let e = ScanFolder::open(&dir).unwrap_err();
        let folder = dir.file_name().unwrap().to_str().unwrap();
        assert!(e.reason.contains("no scans") && e.to_string().contains(folder));
    }
}
