//! KITTI odometry files: Velodyne `.bin` scans and `calib.txt` (its `poses.txt` is a KITTI
//! trajectory: [`crate::io::trajectory`]).
//!
//! Every error names the file and, where it applies, the line and the reason.

use crate::io::error::FileError;
use crate::io::trajectory::{parse_numbers, pose_from_row};
use slamesh_core::{Point, Pose};
use std::path::{Path, PathBuf};

fn err(path: &Path, line: Option<usize>, reason: impl Into<String>) -> FileError {
    FileError::new(path, line, reason)
}

/// Reads a Velodyne scan: little-endian `f32` x, y, z, reflectance per point.
pub fn read_bin(path: &Path) -> Result<Vec<Point>, FileError> {
    let bytes = std::fs::read(path).map_err(|e| err(path, None, e.to_string()))?;
    parse_bin(path, &bytes)
}

/// Parses the bytes of a Velodyne scan read from `path` (named in errors).
pub fn parse_bin(path: &Path, bytes: &[u8]) -> Result<Vec<Point>, FileError> {
    if bytes.is_empty() {
        return Err(err(path, None, "empty file"));
    }
    if !bytes.len().is_multiple_of(16) {
        return Err(err(
            path,
            None,
            format!(
                "truncated: {} bytes is not a whole number of 16-byte points",
                bytes.len()
            ),
        ));
    }
    let f = |b: &[u8]| f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    Ok(bytes
        .chunks_exact(16)
        .map(|c| [f(&c[0..4]), f(&c[4..8]), f(&c[8..12])])
        .collect())
}

/// Reads `Tr` (LiDAR to camera) from a KITTI `calib.txt`.
pub fn read_calib_tr(path: &Path) -> Result<Pose, FileError> {
    let text = std::fs::read_to_string(path).map_err(|e| err(path, None, e.to_string()))?;
    for (i, line) in text.lines().enumerate() {
        if let Some(rest) = line.strip_prefix("Tr:") {
            let v = parse_numbers(path, i + 1, rest)?;
            if v.len() != 12 {
                return Err(err(
                    path,
                    Some(i + 1),
                    format!("Tr: expected 12 numbers, found {}", v.len()),
                ));
            }
            return pose_from_row(&v)
                .ok_or_else(|| err(path, Some(i + 1), "Tr is not a finite transform"));
        }
    }
    Err(err(path, None, "no line starting with Tr:"))
}

/// Camera-frame reference poses `P_i` to LiDAR poses in the first LiDAR frame:
/// `inv(Tr) · P_i · Tr`.
pub fn lidar_poses(camera_poses: &[Pose], tr: &Pose) -> Vec<Pose> {
    let tr_inv = tr.inverse();
    camera_poses.iter().map(|p| tr_inv * p * tr).collect()
}

/// The reference LiDAR poses of a KITTI sequence folder: its `poses.txt` (camera frame)
/// turned into the LiDAR frame with its `calib.txt`.
pub fn reference_lidar_poses(sequence: &Path) -> Result<Vec<Pose>, FileError> {
    let camera = crate::io::trajectory::read_kitti(&sequence.join("poses.txt"))?;
    Ok(lidar_poses(
        &camera,
        &read_calib_tr(&sequence.join("calib.txt"))?,
    ))
}

/// The sequence folder of a KITTI scan folder: the folder itself, or its parent when the
/// folder is a `velodyne/` folder.
pub fn sequence_folder(scans: &Path) -> PathBuf {
    match scans.file_name() {
        Some(n) if n == "velodyne" => scans.parent().unwrap_or(scans).to_path_buf(),
        _ => scans.to_path_buf(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn truncated_and_empty_bins_are_errors_naming_the_file() {
        let dir = crate::test_support::scratch_dir("kitti");
        let p = dir.join("000000.bin");
        std::fs::write(&p, [0u8; 20]).unwrap();
        let e = read_bin(&p).unwrap_err();
        assert!(e.to_string().contains("000000.bin") && e.reason.contains("truncated"));
        std::fs::write(&p, []).unwrap();
        assert!(read_bin(&p).unwrap_err().reason.contains("empty"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
