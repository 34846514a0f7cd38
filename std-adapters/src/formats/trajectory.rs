//! Trajectories on disk: KITTI (12 numbers a line, row-major `[R | t]`) and TUM
//! (`timestamp tx ty tz qx qy qz qw`). Reading detects the format from the first pose line.

use crate::io::error::FileError;
use nalgebra::{Quaternion, Translation3, UnitQuaternion};
use slamesh_core::math::pose_from_row;
use slamesh_core::Pose;
use std::io::Write;
use std::path::Path;

/// Trajectory file formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// KITTI odometry: 12 numbers a line.
    Kitti,
    /// TUM RGB-D: timestamp, translation, quaternion (x y z w).
    Tum,
}

/// A read trajectory: poses, with timestamps for TUM files.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    /// The format it was read from.
    pub format: Format,
    /// Timestamps in seconds (TUM only).
    pub stamps: Option<Vec<f64>>,
    /// The poses, one per line.
    pub poses: Vec<Pose>,
}

/// Parses the whitespace-separated numbers of `text` (line `line_no` of `path`).
pub(crate) fn parse_numbers(
    path: &Path,
    line_no: usize,
    text: &str,
) -> Result<Vec<f64>, FileError> {
    text.split_whitespace()
        .map(|w| {
            w.parse::<f64>()
                .map_err(|_| FileError::new(path, Some(line_no), format!("not a number: {w:?}")))
        })
        .collect()
}

/// Why a line's numbers are not a pose.
const NOT_A_POSE: &str = "not a pose: a number is not finite, or the rotation is not one (a \
                          KITTI line's 3 x 3 must be a rotation, a TUM line's quaternion of \
                          finite, non-zero length)";

/// The pose of a TUM line's numbers `t x y z qx qy qz qw` (the quaternion normalised);
/// `None` unless there are eight, all finite, with a quaternion of finite, non-zero length.
pub fn tum_pose(v: &[f64]) -> Option<Pose> {
    let &[_, x, y, z, qx, qy, qz, qw] = v else {
        return None;
    };
    let q = Quaternion::new(qw, qx, qy, qz);
    (v.iter().all(|x| x.is_finite()) && q.norm() > 1e-9 && q.norm().is_finite()).then(|| {
        Pose::from_parts(
            Translation3::new(x, y, z),
            UnitQuaternion::from_quaternion(q),
        )
    })
}

/// Reads a trajectory, KITTI or TUM, by the count of numbers on its first pose line (`#`
/// lines and blank lines are skipped).
pub fn read(path: &Path) -> Result<Trajectory, FileError> {
    let text = std::fs::read_to_string(path).map_err(|e| FileError::at(path, e.to_string()))?;
    parse(path, &text)
}

/// [`read`] on the text of the file at `path` (named in the errors).
pub fn parse(path: &Path, text: &str) -> Result<Trajectory, FileError> {
    let mut format = None;
    let mut stamps = Vec::new();
    let mut poses = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let v = parse_numbers(path, i + 1, line)?;
        let f = *format.get_or_insert(match v.len() {
            12 => Format::Kitti,
            8 => Format::Tum,
            n => {
                return Err(FileError::new(
                    path,
                    Some(i + 1),
                    format!("{n} numbers: neither KITTI (12) nor TUM (8)"),
                ))
            }
        });
        let want = if f == Format::Kitti { 12 } else { 8 };
        if v.len() != want {
            return Err(FileError::new(
                path,
                Some(i + 1),
                format!(
                    "expected {want} numbers like the first line, found {}",
                    v.len()
                ),
            ));
        }
        let pose = match f {
            Format::Kitti => pose_from_row(&v),
            Format::Tum => tum_pose(&v),
        };
        poses.push(pose.ok_or_else(|| FileError::new(path, Some(i + 1), NOT_A_POSE))?);
        if f == Format::Tum {
            stamps.push(v[0]);
        }
    }
    let format = format.ok_or_else(|| FileError::at(path, "no poses in this file"))?;
    Ok(Trajectory {
        format,
        stamps: (format == Format::Tum).then_some(stamps),
        poses,
    })
}

impl Trajectory {
    /// Half the median spacing of the stamps (seconds): how far a frame's time may be from a
    /// pose's for them to match. 0.05 s (half of 10 Hz) without two stamps.
    pub fn tolerance_s(&self) -> f64 {
        let Some(s) = &self.stamps else { return 0.05 };
        let mut d: Vec<f64> = s.windows(2).map(|w| (w[1] - w[0]).abs()).collect();
        if d.is_empty() {
            return 0.05;
        }
        d.sort_by(f64::total_cmp);
        d[d.len() / 2] / 2.0
    }

    /// The pose of frame `i` recorded at `stamp`: with TUM stamps, the pose whose stamp is
    /// nearest, if within [`Self::tolerance_s`]; without, line `i`.
    pub fn pose_at(&self, i: usize, stamp: f64) -> Option<Pose> {
        let Some(s) = &self.stamps else {
            return self.poses.get(i).copied();
        };
        let tol = self.tolerance_s();
        let k = nearest(s, stamp)?;
        ((s[k] - stamp).abs() <= tol).then(|| self.poses[k])
    }

    /// Pairs of (line in `self`, line in `other`) for the same instant: by nearest stamp when
    /// both have stamps (within `self`'s tolerance, each of `other`'s lines used once), by
    /// line order otherwise. Lines of `self` left unpaired are listed second.
    pub fn pair_with(&self, other: &Trajectory) -> (Vec<(usize, usize)>, Vec<usize>) {
        match (&self.stamps, &other.stamps) {
            (Some(a), Some(b)) => {
                let tol = self.tolerance_s().max(other.tolerance_s());
                let mut pairs = Vec::new();
                let mut missing = Vec::new();
                let mut last = None;
                for (i, &t) in a.iter().enumerate() {
                    match nearest(b, t).filter(|&k| (b[k] - t).abs() <= tol && Some(k) != last) {
                        Some(k) => {
                            pairs.push((i, k));
                            last = Some(k);
                        }
                        None => missing.push(i),
                    }
                }
                (pairs, missing)
            }
            _ => {
                let n = self.poses.len().min(other.poses.len());
                (
                    (0..n).map(|i| (i, i)).collect(),
                    (n..self.poses.len()).collect(),
                )
            }
        }
    }
}

/// The index of the stamp nearest `t` in `s` (sorted ascending, as recorded), if any.
fn nearest(s: &[f64], t: f64) -> Option<usize> {
    let k = s.partition_point(|&x| x < t);
    [k.checked_sub(1), (k < s.len()).then_some(k)]
        .into_iter()
        .flatten()
        .min_by(|&a, &b| (s[a] - t).abs().total_cmp(&(s[b] - t).abs()))
}

/// Reads a KITTI trajectory (an error if the file is TUM).
pub fn read_kitti(path: &Path) -> Result<Vec<Pose>, FileError> {
    let t = read(path)?;
    if t.format != Format::Kitti {
        return Err(FileError::at(
            path,
            "expected a KITTI trajectory (12 numbers a line)",
        ));
    }
    Ok(t.poses)
}

/// Writes one KITTI line: the row-major 3x4 `[R | t]`.
pub fn write_kitti_line(w: &mut impl Write, p: &Pose) -> std::io::Result<()> {
    let m = p.to_homogeneous();
    for r in 0..3 {
        for c in 0..4 {
            let sep = if r == 2 && c == 3 { "\n" } else { " " };
            write!(w, "{:.9e}{sep}", m[(r, c)])?;
        }
    }
    Ok(())
}

/// Writes one TUM line: `timestamp tx ty tz qx qy qz qw`.
pub fn write_tum_line(w: &mut impl Write, stamp: f64, p: &Pose) -> std::io::Result<()> {
    let t = p.translation.vector;
    let q = p.rotation.coords; // x, y, z, w
    writeln!(
        w,
        "{stamp:.6} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9} {:.9}",
        t.x, t.y, t.z, q[0], q[1], q[2], q[3]
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_formats_round_trip_and_are_detected() {
        let poses = [
            Pose::identity(),
            Pose::from_parts(
                Translation3::new(1.0, -2.0, 3.5),
                UnitQuaternion::from_euler_angles(0.1, -0.2, 0.3),
            ),
        ];
        let dir = crate::test_support::scratch_dir("traj");
        let (mut kitti, mut tum) = (Vec::new(), b"# timestamp tx ty tz qx qy qz qw\n".to_vec());
        for (i, p) in poses.iter().enumerate() {
            write_kitti_line(&mut kitti, p).unwrap();
            write_tum_line(&mut tum, i as f64 * 0.1, p).unwrap();
        }
        for (name, bytes, format) in [("k.txt", kitti, Format::Kitti), ("t.txt", tum, Format::Tum)]
        {
            let path = dir.join(name);
            std::fs::write(&path, bytes).unwrap();
            let t = read(&path).unwrap();
            assert_eq!(t.format, format);
            for (a, b) in t.poses.iter().zip(&poses) {
                assert!((a.translation.vector - b.translation.vector).norm() < 1e-8);
                assert!(a.rotation.angle_to(&b.rotation) < 1e-8);
            }
        }
        std::fs::write(dir.join("bad.txt"), "1 2 3\n").unwrap();
        let e = read(&dir.join("bad.txt")).unwrap_err();
        assert!(
            e.to_string().contains("bad.txt:1") && e.reason.contains("neither"),
            "{e}"
        );
    }

    #[test]
    fn lines_that_are_not_poses_are_named() {
        let identity = "1 0 0 0 0 1 0 0 0 0 1 0\n";
        let path = Path::new("poses.txt");
        for (line, bad) in [
            // An entry 4e50: nalgebra's re-orthonormalisation looped for ever on it.
            ("1 0 -4e50 0 0 1 0 0 0 0 1 0\n", "far"),
            ("2 0 0 0 0 2 0 0 0 0 2 0\n", "scaled"),
            ("-1 0 0 0 0 1 0 0 0 0 1 0\n", "mirrored"),
        ] {
            let e = parse(path, &format!("{identity}{line}")).unwrap_err();
            assert!(
                e.to_string().contains("poses.txt:2") && e.reason.contains("not a pose"),
                "{bad}: {e}"
            );
        }
        let e = parse(path, "0.1 1 2 3 1e300 1e300 0 0\n").unwrap_err();
        assert!(e.reason.contains("quaternion"), "{e}");
    }

    #[test]
    fn tum_poses_match_frames_by_time_not_line() {
        let at = |x: f64| Pose::translation(x, 0.0, 0.0);
        let t = Trajectory {
            format: Format::Tum,
            stamps: Some(vec![100.0, 100.1, 100.3, 100.4]),
            poses: vec![at(0.0), at(1.0), at(3.0), at(4.0)],
        };
        assert!((t.tolerance_s() - 0.05).abs() < 1e-9);
        // Frame 2 (at 100.2) has no pose: the trajectory skipped it.
        assert_eq!(t.pose_at(2, 100.2), None);
        assert_eq!(t.pose_at(3, 100.31), Some(at(3.0)));
        assert_eq!(t.pose_at(0, 99.0), None);
        let frames = Trajectory {
            stamps: Some(vec![100.0, 100.1, 100.2, 100.3, 100.4]),
            ..t.clone()
        };
        let (pairs, missing) = frames.pair_with(&t);
        assert_eq!(pairs, vec![(0, 0), (1, 1), (3, 2), (4, 3)]);
        assert_eq!(missing, vec![2]);
        let kitti = Trajectory {
            format: Format::Kitti,
            stamps: None,
            poses: vec![at(0.0); 3],
        };
        assert_eq!(kitti.pose_at(1, 55.0), Some(at(0.0)));
        assert_eq!(kitti.pair_with(&t).0, vec![(0, 0), (1, 1), (2, 2)]);
    }
}
