//! KITTI odometry files: Velodyne `.bin` scans and `calib.txt` (its `poses.txt` is a KITTI
//! trajectory: [`crate::formats::trajectory`]).
//!
//! Every error names the file and, where it applies, the line and the reason.

use crate::formats::trajectory::parse_numbers;
use crate::io::error::FileError;
use slamesh_core::math::pose_from_row;
use slamesh_core::{Point, Pose};
use std::path::{Path, PathBuf};

fn err(path: &Path, line: Option<usize>, reason: impl Into<String>) -> FileError {
    FileError::new(path, line, reason)
}

/// The record of a `.bin` scan: little-endian float32 fields, in order. KITTI's is
/// `x,y,z,i` (the default); nuScenes' is `x,y,z,i,ring`. Only `x`, `y` and `z` are read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BinFields {
    /// The field names, in order.
    pub names: Vec<String>,
    /// The float index of x, y and z.
    xyz: [usize; 3],
}

impl Default for BinFields {
    fn default() -> Self {
        Self::parse("x,y,z,i").expect("KITTI's layout")
    }
}

impl BinFields {
    /// Parses a comma-separated list of field names; it must name `x`, `y` and `z` once each.
    pub fn parse(list: &str) -> Result<Self, String> {
        let names: Vec<String> = list.split(',').map(|n| n.trim().to_owned()).collect();
        let find = |c: &str| match names.iter().filter(|n| *n == c).count() {
            1 => Ok(names.iter().position(|n| n == c).expect("counted")),
            0 => Err(format!("--bin-fields {list:?} has no {c}")),
            _ => Err(format!("--bin-fields {list:?} names {c} twice")),
        };
        if names.iter().any(String::is_empty) {
            return Err(format!("--bin-fields {list:?} has an empty name"));
        }
        Ok(BinFields {
            xyz: [find("x")?, find("y")?, find("z")?],
            names,
        })
    }

    /// Bytes per point.
    pub fn record_bytes(&self) -> usize {
        4 * self.names.len()
    }
}

/// Reads a Velodyne scan: little-endian `f32` x, y, z, reflectance per point.
pub fn read_bin(path: &Path) -> Result<Vec<Point>, FileError> {
    read_bin_as(path, &BinFields::default())
}

/// Reads a `.bin` scan whose records are `fields`, streaming: the file passes through a
/// buffer of a few thousand records, so a read holds the points and no copy of the file.
pub fn read_bin_as(path: &Path, fields: &BinFields) -> Result<Vec<Point>, FileError> {
    use std::io::Read;
    let io = |e: std::io::Error| err(path, None, e.to_string());
    let mut file = std::fs::File::open(path).map_err(io)?;
    let len = file.metadata().map_err(io)?.len() as usize;
    check_length(path, len, fields)?;
    let size = fields.record_bytes();
    let mut points = Vec::with_capacity(len / size);
    let mut chunk = vec![0u8; size * 4096];
    let mut read = 0;
    loop {
        // Fill the chunk (or what is left of the file), then parse its whole records.
        let mut filled = 0;
        while filled < chunk.len() {
            match file.read(&mut chunk[filled..]) {
                Ok(0) => break,
                Ok(n) => filled += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(io(e)),
            }
        }
        read += filled;
        if !filled.is_multiple_of(size) || read > len {
            return Err(err(
                path,
                None,
                format!("the file changed while it was read ({len} bytes, then {read})"),
            ));
        }
        push_records(&chunk[..filled], fields, &mut points);
        if filled < chunk.len() {
            break;
        }
    }
    if read != len {
        return Err(err(
            path,
            None,
            format!("the file changed while it was read ({len} bytes, then {read})"),
        ));
    }
    Ok(points)
}

/// Parses the bytes of a Velodyne scan read from `path` (named in errors).
pub fn parse_bin(path: &Path, bytes: &[u8]) -> Result<Vec<Point>, FileError> {
    parse_bin_as(path, bytes, &BinFields::default())
}

/// Parses the bytes of a `.bin` scan whose records are `fields`.
pub fn parse_bin_as(
    path: &Path,
    bytes: &[u8],
    fields: &BinFields,
) -> Result<Vec<Point>, FileError> {
    check_length(path, bytes.len(), fields)?;
    let mut points = Vec::with_capacity(bytes.len() / fields.record_bytes());
    push_records(bytes, fields, &mut points);
    Ok(points)
}

/// Refuses a file of `len` bytes that is empty or not a whole number of `fields` records,
/// with a hint when its length fits another record size.
fn check_length(path: &Path, len: usize, fields: &BinFields) -> Result<(), FileError> {
    if len == 0 {
        return Err(err(path, None, "empty file"));
    }
    let size = fields.record_bytes();
    if !len.is_multiple_of(size) {
        let other: Vec<String> = [16, 20, 24]
            .into_iter()
            .filter(|s| *s != size && len.is_multiple_of(*s))
            .map(|s| format!("{} floats", s / 4))
            .collect();
        let hint = if other.is_empty() {
            "the file may be cut short".to_owned()
        } else {
            format!(
                "its size fits records of {}: set --bin-fields (x,y,z,i,ring is nuScenes' 5 floats)",
                other.join(" or ")
            )
        };
        return Err(err(
            path,
            None,
            format!(
                "{len} bytes is not a whole number of {size}-byte points ({}); {hint}",
                fields.names.join(",")
            ),
        ));
    }
    Ok(())
}

/// Appends the points of `bytes`' whole `fields` records to `points`.
fn push_records(bytes: &[u8], fields: &BinFields, points: &mut Vec<Point>) {
    let f = |b: &[u8]| f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    let [x, y, z] = fields.xyz.map(|k| 4 * k);
    points.extend(
        bytes
            .chunks_exact(fields.record_bytes())
            .map(|c| [f(&c[x..x + 4]), f(&c[y..y + 4]), f(&c[z..z + 4])]),
    );
}

/// Reads `Tr` (LiDAR to camera) from a KITTI `calib.txt`.
pub fn read_calib_tr(path: &Path) -> Result<Pose, FileError> {
    let text = std::fs::read_to_string(path).map_err(|e| err(path, None, e.to_string()))?;
    parse_calib_tr(path, &text)
}

/// [`read_calib_tr`] on the text of the file at `path` (named in the errors).
pub fn parse_calib_tr(path: &Path, text: &str) -> Result<Pose, FileError> {
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
            return pose_from_row(&v).ok_or_else(|| {
                err(
                    path,
                    Some(i + 1),
                    "Tr is not a rigid transform (its numbers finite, its 3 x 3 a rotation)",
                )
            });
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
    let camera = crate::formats::trajectory::read_kitti(&sequence.join("poses.txt"))?;
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
        assert!(e.to_string().contains("000000.bin"), "{e}");
        assert_eq!(
            e.reason,
            "20 bytes is not a whole number of 16-byte points (x,y,z,i); its size fits \
             records of 5 floats: set --bin-fields (x,y,z,i,ring is nuScenes' 5 floats)"
        );
        std::fs::write(&p, [0u8; 18]).unwrap();
        assert!(read_bin(&p)
            .unwrap_err()
            .reason
            .ends_with("the file may be cut short"));
        std::fs::write(&p, []).unwrap();
        assert!(read_bin(&p).unwrap_err().reason.contains("empty"));
    }

    #[test]
    fn bin_fields_pick_the_coordinates_out_of_any_float_record() {
        let ring_first = BinFields::parse("ring,x,y,z,i").unwrap();
        let bytes: Vec<u8> = [7.0f32, 1.0, 2.0, 3.0, 0.5, 8.0, 4.0, 5.0, 6.0, 0.5]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let pts = parse_bin_as(Path::new("a.bin"), &bytes, &ring_first).unwrap();
        assert_eq!(pts, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        assert!(BinFields::parse("x,y,i").unwrap_err().contains("has no z"));
        assert!(BinFields::parse("x,y,z,x")
            .unwrap_err()
            .contains("names x twice"));
    }
}
