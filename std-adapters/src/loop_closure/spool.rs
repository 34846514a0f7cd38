//! The scans a loop closure may need again, on disk: each frame's filtered points in the
//! sensor frame (what the pipeline fused), appended to one file, read back by frame.
//!
//! Memory holds only the index (12 bytes a frame); the points take 12 bytes each on disk
//! (about 170 KB a frame for a 64-beam street scan filtered at 1.4 m cells). The file is
//! removed when the spool is dropped.

use crate::io::error::FileError;
use slamesh_core::Point;
use std::fs::File;
use std::io::{BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// Filtered scans by frame, on disk.
pub struct ScanSpool {
    path: PathBuf,
    writer: BufWriter<File>,
    reader: File,
    /// Each spooled frame's byte offset and point count, in the order spooled.
    index: Vec<(u64, u32)>,
    end: u64,
}

impl ScanSpool {
    /// A new, empty spool at `path` (replaced if present).
    pub fn create(path: &Path) -> Result<Self, FileError> {
        let cannot = |e: std::io::Error| FileError::at(path, format!("cannot create: {e}"));
        let file = File::create(path).map_err(cannot)?;
        let reader = File::open(path).map_err(cannot)?;
        Ok(Self {
            path: path.to_path_buf(),
            writer: BufWriter::new(file),
            reader,
            index: Vec::new(),
            end: 0,
        })
    }

    /// Appends a scan; its number is the count of scans before it.
    pub fn push(&mut self, points: &[Point]) -> Result<usize, FileError> {
        let mut bytes = Vec::with_capacity(points.len() * 12);
        for p in points {
            for v in p {
                bytes.extend_from_slice(&v.to_le_bytes());
            }
        }
        self.writer
            .write_all(&bytes)
            .map_err(|e| FileError::at(&self.path, format!("cannot write: {e}")))?;
        self.index.push((self.end, points.len() as u32));
        self.end += bytes.len() as u64;
        Ok(self.index.len() - 1)
    }

    /// Scans spooled so far.
    pub fn len(&self) -> usize {
        self.index.len()
    }

    /// Whether nothing was spooled.
    pub fn is_empty(&self) -> bool {
        self.index.is_empty()
    }

    /// Scan `n`'s points (empty for a number never spooled).
    pub fn read(&mut self, n: usize) -> Result<Vec<Point>, FileError> {
        let Some(&(offset, count)) = self.index.get(n) else {
            return Ok(Vec::new());
        };
        let fail = |e: std::io::Error| FileError::at(&self.path, format!("cannot read: {e}"));
        self.writer.flush().map_err(fail)?;
        let mut bytes = vec![0u8; count as usize * 12];
        self.reader.seek(SeekFrom::Start(offset)).map_err(fail)?;
        self.reader.read_exact(&mut bytes).map_err(fail)?;
        Ok(bytes
            .chunks_exact(12)
            .map(|c| {
                let f = |i: usize| f32::from_le_bytes([c[i], c[i + 1], c[i + 2], c[i + 3]]);
                [f(0), f(4), f(8)]
            })
            .collect())
    }

    /// Bytes on disk.
    pub fn bytes(&self) -> u64 {
        self.end
    }
}

impl Drop for ScanSpool {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scans_come_back_as_spooled_and_the_file_goes_with_the_spool() {
        let path = std::env::temp_dir().join(format!("slamesh-scan-spool-{}", std::process::id()));
        let mut spool = ScanSpool::create(&path).unwrap();
        let a = vec![[1.0, 2.0, 3.0], [-4.5, 0.25, f32::MAX]];
        let b: Vec<Point> = (0..1000).map(|i| [i as f32, 0.5, -(i as f32)]).collect();
        assert_eq!(spool.push(&a).unwrap(), 0);
        assert_eq!(spool.push(&[]).unwrap(), 1);
        assert_eq!(spool.push(&b).unwrap(), 2);
        assert_eq!(spool.read(2).unwrap(), b);
        assert_eq!(spool.read(0).unwrap(), a);
        assert!(spool.read(1).unwrap().is_empty());
        assert!(spool.read(3).unwrap().is_empty(), "never spooled");
        assert_eq!((spool.len(), spool.bytes()), (3, 1002 * 12));
        drop(spool);
        assert!(!path.exists());
    }
}
