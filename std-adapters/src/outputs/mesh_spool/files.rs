//! The spool's files: their names beside the mesh file, and what of them a resumed spool
//! keeps (the sets, faces and imported positions a checkpoint counted).

use super::{face_indices, MeshCounts, FACE_BYTES, SET_BYTES};
use crate::io::error::FileError;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

/// The set ends of `sets` up to `kept` (how many, and the last end).
pub(super) fn sets_within(sets: &[MeshCounts], kept: MeshCounts) -> (u64, MeshCounts) {
    let within = sets
        .iter()
        .take_while(|s| s.vertices <= kept.vertices && s.triangles <= kept.triangles)
        .count();
    let last = within
        .checked_sub(1)
        .and_then(|i| sets.get(i))
        .copied()
        .unwrap_or_default();
    (within as u64, last)
}

/// How many imported positions the first `kept` faces in `faces` use (their corners below
/// the first vertex of their set, with `sets` the set ends).
pub(super) fn imports_within(
    faces: &Path,
    sets: &[MeshCounts],
    kept: MeshCounts,
) -> Result<u64, FileError> {
    let io = |e: std::io::Error| FileError::at(faces, format!("cannot read: {e}"));
    let mut r = BufReader::new(File::open(faces).map_err(io)?);
    let (mut count, mut set, mut start) = (0, 0, 0);
    for f in 0..kept.triangles {
        while sets.get(set).is_some_and(|s| f >= s.triangles) {
            start = sets[set].vertices;
            set += 1;
        }
        let mut rec = [0u8; FACE_BYTES];
        r.read_exact(&mut rec).map_err(io)?;
        count += face_indices(&rec).iter().filter(|&&i| i < start).count() as u64;
    }
    Ok(count)
}

/// Every set end spooled in `path`.
pub(super) fn read_sets(path: &Path) -> Result<Vec<MeshCounts>, FileError> {
    let bytes =
        std::fs::read(path).map_err(|e| FileError::at(path, format!("cannot read: {e}")))?;
    Ok(bytes
        .chunks_exact(SET_BYTES)
        .map(|rec| {
            let u = |i: usize| {
                let mut b = [0u8; 8];
                b.copy_from_slice(&rec[i..i + 8]);
                u64::from_le_bytes(b)
            };
            MeshCounts {
                vertices: u(0),
                triangles: u(8),
            }
        })
        .collect())
}

/// The spool files of the mesh file `target`, beside it.
pub(super) fn spool_paths(target: &Path) -> [PathBuf; 4] {
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    ["vertices", "faces", "sets", "imports"]
        .map(|what| target.with_file_name(format!(".{name}.{what}.spool")))
}
