//! KITTI odometry files: Velodyne `.bin` scans, `poses.txt`, `calib.txt`.
//!
//! Every error names the file and, where it applies, the line and the reason.

use nalgebra::{Matrix3, Matrix4, Rotation3, Translation3, UnitQuaternion};
use slamesh_core::{Point, Pose};
use std::fmt;
use std::path::{Path, PathBuf};

/// A KITTI file that could not be read, with where and why.
#[derive(Debug)]
pub struct ReadError {
    /// The file.
    pub path: PathBuf,
    /// 1-based line, for text files.
    pub line: Option<usize>,
    /// What is wrong.
    pub reason: String,
}

impl fmt::Display for ReadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(l) => write!(f, "{}:{}: {}", self.path.display(), l, self.reason),
            None => write!(f, "{}: {}", self.path.display(), self.reason),
        }
    }
}

impl std::error::Error for ReadError {}

fn err(path: &Path, line: Option<usize>, reason: impl Into<String>) -> ReadError {
    ReadError {
        path: path.to_path_buf(),
        line,
        reason: reason.into(),
    }
}

/// Reads a Velodyne scan: little-endian `f32` x, y, z, reflectance per point.
pub fn read_bin(path: &Path) -> Result<Vec<Point>, ReadError> {
    let bytes = std::fs::read(path).map_err(|e| err(path, None, e.to_string()))?;
    if bytes.is_empty() {
        return Err(err(path, None, "empty file"));
    }
    if bytes.len() % 16 != 0 {
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

/// The `.bin` files of a sequence folder (or of its `velodyne/` folder), in name order.
pub fn scan_paths(dir: &Path) -> Result<Vec<PathBuf>, ReadError> {
    let velodyne = dir.join("velodyne");
    let dir = if velodyne.is_dir() {
        velodyne
    } else {
        dir.to_path_buf()
    };
    let entries = std::fs::read_dir(&dir).map_err(|e| err(&dir, None, e.to_string()))?;
    let mut paths: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "bin"))
        .collect();
    paths.sort();
    if paths.is_empty() {
        return Err(err(&dir, None, "no .bin scans in this folder"));
    }
    Ok(paths)
}

fn pose_from_row(v: &[f64]) -> Option<Pose> {
    let m = Matrix3::new(v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10]);
    let r = Rotation3::from_matrix_eps(&m, 1e-12, 100, Rotation3::identity());
    let t = Translation3::new(v[3], v[7], v[11]);
    let pose = Pose::from_parts(t, UnitQuaternion::from_rotation_matrix(&r));
    pose.translation
        .vector
        .iter()
        .all(|x| x.is_finite())
        .then_some(pose)
}

fn parse_numbers(path: &Path, line_no: usize, text: &str) -> Result<Vec<f64>, ReadError> {
    text.split_whitespace()
        .map(|w| {
            w.parse::<f64>()
                .map_err(|_| err(path, Some(line_no), format!("not a number: {w:?}")))
        })
        .collect()
}

/// Reads a KITTI trajectory: 12 numbers a line, row-major `[R | t]`.
pub fn read_poses(path: &Path) -> Result<Vec<Pose>, ReadError> {
    let text = std::fs::read_to_string(path).map_err(|e| err(path, None, e.to_string()))?;
    let mut poses = Vec::new();
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        let v = parse_numbers(path, i + 1, line)?;
        if v.len() != 12 {
            return Err(err(
                path,
                Some(i + 1),
                format!("expected 12 numbers, found {}", v.len()),
            ));
        }
        poses.push(pose_from_row(&v).ok_or_else(|| err(path, Some(i + 1), "not a finite pose"))?);
    }
    Ok(poses)
}

/// Reads `Tr` (LiDAR to camera) from a KITTI `calib.txt`.
pub fn read_calib_tr(path: &Path) -> Result<Pose, ReadError> {
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

/// A pose as a row-major 3x4 matrix line (KITTI format).
pub fn format_pose(p: &Pose) -> String {
    let m: Matrix4<f64> = p.to_homogeneous();
    let mut s = String::new();
    for r in 0..3 {
        for c in 0..4 {
            if !s.is_empty() {
                s.push(' ');
            }
            s.push_str(&format!("{:.9e}", m[(r, c)]));
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_lines_round_trip() {
        let p = Pose::from_parts(
            Translation3::new(1.0, -2.0, 3.5),
            UnitQuaternion::from_euler_angles(0.1, -0.2, 0.3),
        );
        let v: Vec<f64> = format_pose(&p)
            .split_whitespace()
            .map(|w| w.parse().unwrap())
            .collect();
        let q = pose_from_row(&v).unwrap();
        assert!((q.translation.vector - p.translation.vector).norm() < 1e-9);
        assert!(q.rotation.angle_to(&p.rotation) < 1e-9);
    }

    #[test]
    fn truncated_and_empty_bins_are_errors_naming_the_file() {
        let dir = std::env::temp_dir().join(format!("slamesh-kitti-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("000000.bin");
        std::fs::write(&p, [0u8; 20]).unwrap();
        let e = read_bin(&p).unwrap_err();
        assert!(e.to_string().contains("000000.bin") && e.reason.contains("truncated"));
        std::fs::write(&p, []).unwrap();
        assert!(read_bin(&p).unwrap_err().reason.contains("empty"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
