//! The path block: the stamped sensor poses the map was made along.

use super::bytes::*;
use super::*;
use crate::math::Pose;
use nalgebra::{Quaternion, Translation3, UnitQuaternion};
/// Writes the path block: the sensor's poses with their times (the trajectory the map was
/// made along). Returns its length in bytes.
pub fn write_path<S: ByteSink>(
    sink: &mut S,
    poses: impl Iterator<Item = (f64, Pose)> + Clone,
) -> Result<u64, WriteError<S::Error>> {
    let n = u32::try_from(poses.clone().count()).map_err(|_| WriteError::TooLong("path"))?;
    let mut s = Summed::new(sink);
    s.put(&PATH_TAG)?;
    s.put(&n.to_le_bytes())?;
    for (t, p) in poses {
        let tr = &p.translation.vector;
        let q = p.rotation.quaternion();
        for v in [t, tr.x, tr.y, tr.z, q.i, q.j, q.k, q.w] {
            s.put(&v.to_le_bytes())?;
        }
    }
    s.close()
}

/// The path block's length from its first 8 bytes.
pub fn path_block_len(prefix: &[u8]) -> Result<usize, MapFileError> {
    let mut r = Reader::new(prefix);
    expect_tag(&mut r, PATH_TAG)?;
    Ok(8 + r.u32()? as usize * PATH_POSE_BYTES + 4)
}

/// The poses of a checked path block.
#[derive(Debug, Clone)]
pub struct PathPoses<'a> {
    r: Reader<'a>,
}

impl Iterator for PathPoses<'_> {
    type Item = (f64, Pose);
    fn next(&mut self) -> Option<(f64, Pose)> {
        read_pose(&mut self.r).ok().flatten()
    }
}

fn read_pose(r: &mut Reader<'_>) -> Result<Option<(f64, Pose)>, MapFileError> {
    if r.rest().is_empty() {
        return Ok(None);
    }
    let at = r.pos;
    let mut v = [0.0; 8];
    for x in &mut v {
        *x = r.f64()?;
    }
    let q = Quaternion::new(v[7], v[4], v[5], v[6]);
    let norm = q.norm();
    if !v.iter().all(|x| x.is_finite()) || (norm - 1.0).abs() > 1e-6 {
        return Err(MapFileError::Malformed {
            what: "a pose of the path is not finite or not a rotation",
            at,
        });
    }
    Ok(Some((
        v[0],
        Pose::from_parts(
            Translation3::new(v[1], v[2], v[3]),
            UnitQuaternion::new_unchecked(q),
        ),
    )))
}

/// Reads and checks the path block at the start of `bytes`.
pub fn read_path(bytes: &[u8]) -> Result<PathPoses<'_>, MapFileError> {
    let len = path_block_len(bytes)?;
    let block = checked(bytes, len)?;
    let body = block.get(8..len - 4).unwrap_or(&[]);
    let mut r = Reader::new(body);
    while read_pose(&mut r)?.is_some() {}
    Ok(PathPoses {
        r: Reader::new(body),
    })
}
