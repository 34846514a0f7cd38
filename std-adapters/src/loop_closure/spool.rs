//! The scans a loop closure may need again, on disk: each frame's filtered points in the
//! sensor frame (what the pipeline fused), appended to one file, read back by frame.
//!
//! Memory holds only the index (12 bytes a frame). On disk a scan is its scale (an `f32`)
//! and its points as three `i16` each, in units of the scale: the largest coordinate over
//! 32 767, 3 mm for a scan reaching 100 m, well under the filter's voxel (a sixth of a cell)
//! and the range noise. About 85 KB a frame for a 64-beam street scan filtered at 1.4 m
//! cells. The file is removed when the spool is dropped.

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

    /// Appends a scan; its number is the count of scans before it. Points that are not
    /// finite are left out.
    pub fn push(&mut self, points: &[Point]) -> Result<usize, FileError> {
        let finite = || points.iter().filter(|p| p.iter().all(|v| v.is_finite()));
        let largest = finite().flatten().fold(0.0f32, |m, v| m.max(v.abs()));
        let scale = (largest / i16::MAX as f32).max(f32::MIN_POSITIVE);
        let mut bytes = Vec::with_capacity(4 + points.len() * 6);
        bytes.extend_from_slice(&scale.to_le_bytes());
        let mut count = 0u32;
        for p in finite() {
            for v in p {
                bytes.extend_from_slice(&((v / scale).round() as i16).to_le_bytes());
            }
            count += 1;
        }
        self.writer
            .write_all(&bytes)
            .map_err(|e| FileError::at(&self.path, format!("cannot write: {e}")))?;
        self.index.push((self.end, count));
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
        let mut bytes = vec![0u8; 4 + count as usize * 6];
        self.reader.seek(SeekFrom::Start(offset)).map_err(fail)?;
        self.reader.read_exact(&mut bytes).map_err(fail)?;
        let scale = f32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]]);
        Ok(bytes[4..]
            .chunks_exact(6)
            .map(|c| {
                let v = |i: usize| f32::from(i16::from_le_bytes([c[i], c[i + 1]])) * scale;
                [v(0), v(2), v(4)]
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
        let a = vec![
            [1.0, 2.0, 3.0],
            [-4.5, 0.25, f32::NAN],
            [-100.0, 0.001, 99.9],
        ];
        let b: Vec<Point> = (0..1000)
            .map(|i| [i as f32 * 0.1, 0.5, -(i as f32)])
            .collect();
        assert_eq!(spool.push(&a).unwrap(), 0);
        assert_eq!(spool.push(&[]).unwrap(), 1);
        assert_eq!(spool.push(&b).unwrap(), 2);
        let near = |x: &[Point], y: &[Point], tol: f32| {
            x.len() == y.len()
                && x.iter()
                    .zip(y)
                    .all(|(p, q)| (0..3).all(|k| (p[k] - q[k]).abs() <= tol))
        };
        // Within half a unit: the largest coordinate over 32 767, halved.
        assert!(near(
            &spool.read(2).unwrap(),
            &b,
            999.0 / 32767.0 / 2.0 * 1.001
        ));
        let finite = [a[0], a[2]];
        assert!(near(
            &spool.read(0).unwrap(),
            &finite,
            100.0 / 32767.0 / 2.0 * 1.001
        ));
        assert!(spool.read(1).unwrap().is_empty());
        assert!(spool.read(3).unwrap().is_empty(), "never spooled");
        assert_eq!((spool.len(), spool.bytes()), (3, 3 * 4 + 1002 * 6));
        drop(spool);
        assert!(!path.exists());
    }
}
