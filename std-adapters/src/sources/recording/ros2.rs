//! ROS 2 bag folders: `metadata.yaml` and the storage files it lists (`.db3` SQLite files, as
//! Humble writes, or `.mcap` files, from Iron on), read in the listed order as one recording.
//! A `.db3` file is read a few messages at a time, ordered by time (feature `db3`).

use super::error::RecordingError::{self, Damaged, Unsupported};
use super::{mcap, Topic};
use std::path::{Path, PathBuf};

/// The first bytes of every SQLite file.
pub const SQLITE_MAGIC: &[u8] = b"SQLite format 3\0";

/// The storage files of a bag folder, in order: `relative_file_paths` from `metadata.yaml`.
pub fn files(folder: &Path) -> Result<Vec<PathBuf>, RecordingError> {
    let meta = folder.join("metadata.yaml");
    let text = std::fs::read_to_string(&meta)
        .map_err(|e| RecordingError::Io(format!("metadata.yaml: {e}")))?;
    if let Some(line) = text
        .lines()
        .find(|l| l.trim_start().starts_with("compression_format:"))
    {
        let v = line
            .split_once(':')
            .map_or("", |(_, v)| v.trim().trim_matches(['"', '\'']));
        if !v.is_empty() {
            return Err(Unsupported(format!(
                "metadata.yaml: compressed bags ({v}) are not read; `ros2 bag decompress` first"
            )));
        }
    }
    let mut paths = Vec::new();
    let mut lines = text
        .lines()
        .skip_while(|l| !l.trim_start().starts_with("relative_file_paths:"));
    if let Some(first) = lines.next() {
        let inline = first.split_once(':').map_or("", |(_, v)| v.trim());
        if let Some(list) = inline.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            paths.extend(
                list.split(',')
                    .map(|s| s.trim().trim_matches(['"', '\'']).to_owned()),
            );
        } else {
            for l in lines {
                let Some(item) = l.trim_start().strip_prefix("- ") else {
                    break;
                };
                paths.push(item.trim().trim_matches(['"', '\'']).to_owned());
            }
        }
    }
    paths.retain(|p| !p.is_empty());
    if paths.is_empty() {
        return Err(Damaged("metadata.yaml lists no relative_file_paths".into()));
    }
    Ok(paths.into_iter().map(|p| folder.join(p)).collect())
}

/// The topics of one storage file, with their types and message counts.
pub fn topics(path: &Path) -> Result<Vec<Topic>, RecordingError> {
    if !super::has_magic(path, SQLITE_MAGIC) {
        return mcap::topics(path);
    }
    #[cfg(feature = "db3")]
    return super::db3::topics(path);
    #[cfg(not(feature = "db3"))]
    Err(Unsupported(
        "a .db3 file: this slamesh was built without the db3 feature".into(),
    ))
}
