//! The scans a loop closure may need again, on disk: each frame's filtered points in the
//! sensor frame (what the pipeline fused), appended to one file, read back by frame.
//!
//! Memory holds only the index (12 bytes a frame). On disk a scan is its scale (an `f32`)
//! and its points as three `i16` each, in units of the scale: the largest coordinate over
//! 32 767, 3 mm for a scan reaching 100 m, well under the filter's voxel (a sixth of a cell)
//! and the range noise. About 85 KB a frame for a 64-beam street scan filtered at 1.4 m
//! cells. The file is removed when the spool is dropped, and never grows past its budget: a
//! scan that would take it there is refused (loop closure then stops, and the run goes on).

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
    /// The scan being written, kept between scans.
    buffer: Vec<u8>,
    /// The most bytes the file may hold.
    budget: u64,
}

impl ScanSpool {
    /// A new, empty spool at `path` (replaced if present) that holds at most `budget` bytes.
    pub fn create(path: &Path, budget: u64) -> Result<Self, FileError> {
        let cannot = |e: std::io::Error| FileError::at(path, format!("cannot create: {e}"));
        let file = File::create(path).map_err(cannot)?;
        let reader = File::open(path).map_err(cannot)?;
        Ok(Self {
            path: path.to_path_buf(),
            writer: BufWriter::new(file),
            reader,
            index: Vec::new(),
            end: 0,
            buffer: Vec::new(),
            budget,
        })
    }

    /// Appends a scan; its number is the count of scans before it. Points that are not
    /// finite are left out. A scan that would take the file past its budget is an error.
    pub fn push(&mut self, points: &[Point]) -> Result<usize, FileError> {
        let finite = || points.iter().filter(|p| p.iter().all(|v| v.is_finite()));
        let largest = finite().flatten().fold(0.0f32, |m, v| m.max(v.abs()));
        let scale = (largest / i16::MAX as f32).max(f32::MIN_POSITIVE);
        let bytes = &mut self.buffer;
        bytes.clear();
        bytes.extend_from_slice(&scale.to_le_bytes());
        let mut count = 0u32;
        for p in finite() {
            let q = p.map(|v| units(v / scale).to_le_bytes());
            bytes.extend_from_slice(&[q[0][0], q[0][1], q[1][0], q[1][1], q[2][0], q[2][1]]);
            count += 1;
        }
        if self.end + bytes.len() as u64 > self.budget {
            return Err(FileError::at(
                &self.path,
                format!(
                    "the scans kept for loop closure reached their budget of {:.0} MB after {} \
                     frames",
                    self.budget as f64 / 1e6,
                    self.index.len()
                ),
            ));
        }
        self.writer
            .write_all(bytes)
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

/// `x` rounded to the nearest integer (halves away from zero), saturated to an `i16`: what
/// `x.round() as i16` gives, without the call to `round` that a CPU without SSE4.1 makes
/// (a fifth of the spool's time). Exact for a finite `x`: below 2^23 in magnitude its
/// fraction `x - trunc(x)` is representable.
fn units(x: f32) -> i16 {
    if x.abs() >= 32_768.0 {
        return if x > 0.0 { i16::MAX } else { i16::MIN };
    }
    let whole = x as i32;
    let fraction = x - whole as f32;
    let rounded = whole + i32::from(fraction >= 0.5) - i32::from(fraction <= -0.5);
    rounded.clamp(i16::MIN.into(), i16::MAX.into()) as i16
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
    fn units_round_as_round_does() {
        let mut x = -33_000.0f32;
        while x < 33_000.0 {
            for v in [
                x,
                x + 0.5,
                x - 0.5,
                x + 0.499_999_97,
                x.next_up(),
                x.next_down(),
            ] {
                assert_eq!(units(v), v.round() as i16, "{v}");
            }
            x += 0.37;
        }
        for v in [
            0.0, -0.0, 0.5, -0.5, 1.5, -2.5, 32_767.5, -32_768.5, 1e30, -1e30,
        ] {
            assert_eq!(units(v), v.round() as i16, "{v}");
        }
    }

    #[test]
    fn scans_come_back_as_spooled_and_the_file_goes_with_the_spool() {
        let path = std::env::temp_dir().join(format!("slamesh-scan-spool-{}", std::process::id()));
        let mut spool = ScanSpool::create(&path, 6_050).unwrap();
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
        // 6 024 bytes held; a scan of 10 points more (64 bytes) is over the budget of 6 050.
        let refused = spool.push(&b[..10]).unwrap_err().to_string();
        assert!(
            refused.contains("budget of 0 MB after 3 frames"),
            "{refused}"
        );
        assert_eq!(spool.len(), 3);
        assert_eq!(spool.read(2).unwrap().len(), 1000);
        drop(spool);
        assert!(!path.exists());
    }
}
