//! The scans' floor beside a saved map: what a run with `--navmap` found of the floor in its
//! points ([`crate::navmap::hits`]), kept in a file beside its `--save-map` file
//! ([`beside`]: `map.floor` for `map.slamesh`), so that `slamesh navmap` on that map finds
//! kerbs and the raised floors the mesh dropped as the run did, not the mesh's alone.
//!
//! ## Layout (little-endian)
//! | part | bytes | what |
//! |---|---|---|
//! | header | 36 | [`MAGIC`], [`VERSION`] (u32), the cell size the floors were found in (f64, m), the map's path it goes with: its poses (u64) and its last pose's time (f64, s; 0 for none) |
//! | floors | 13 each | the cell's centre at the floor's height, map frame (3 × f32), flags (u8; bit 0: two points fell in its bin, [`ScanFloor::twice`]) |
//! | check | 4 | CRC-32 of everything before it |
//!
//! How many floors follows from the length, so the file is written in one pass over them.
//!
//! A run with `--navmap` writes it beside the map it saves at its end and beside each map it
//! saves on request (the ROS 2 node's `~/save_map`), and a save without the navigation map
//! removes one left there. A floor file that no longer goes with the map beside it all the
//! same (the map saved again by other means) is told by the path recorded
//! ([`FloorFile::goes_with`]), and passed over, said.
//!
//! Owns: the format. Guarantees: a file is checked whole (length, checksum, every floor finite
//! with known flags) before any floor of it is handed on, and a bad one is an error naming
//! the file and the reason; written atomically ([`write_atomic`]); the same floors give the
//! same bytes; no panics on any bytes (a fuzz target reads arbitrary files through
//! [`FloorFile::parse`]). Memory: the file's bytes, 13 a floor.

use crate::io::atomic::write_atomic;
use crate::io::error::FileError;
use crate::navmap::hits::{Floors, Hits, ScanFloor};
use nalgebra::Vector3;
use slamesh_core::map_file::crc32::Crc32;
use slamesh_core::Pose;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The file's first eight bytes.
pub const MAGIC: [u8; 8] = *b"SLMFLOOR";
/// The format this code writes and reads.
pub const VERSION: u32 = 1;
const HEADER_BYTES: usize = 36;
const FLOOR_BYTES: usize = 13;
const CHECK_BYTES: usize = 4;

/// The floor file beside map file `map`: its name with the extension `floor`.
pub fn beside(map: &Path) -> PathBuf {
    map.with_extension("floor")
}

/// The map path a floor file goes with: its poses and its last pose's time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MapPath {
    /// How many poses.
    pub poses: u64,
    /// The last one's time (s; 0 for none).
    pub last_stamp: f64,
}

impl MapPath {
    /// The path of stamped poses `path` (time, pose).
    pub fn of<T>(path: &[(f64, T)]) -> MapPath {
        MapPath {
            poses: path.len() as u64,
            last_stamp: path.last().map_or(0.0, |(t, _)| *t),
        }
    }
}

/// Removes the floor file beside map file `map`, which went with the map saved there before,
/// when the map saved now gets none; returns its path if there was one and it is gone.
pub fn remove_beside(map: &Path) -> Option<PathBuf> {
    let stale = beside(map);
    (stale.is_file() && std::fs::remove_file(&stale).is_ok()).then_some(stale)
}

/// Hands `each` the floors a map saved now keeps beside it: `carried`'s (the floor file beside
/// the map the run started from), then this run's `hits`, each chunk moved with its frame's
/// pose in `poses` (frame, pose; in frame order, as corrected so far).
pub fn each_kept(
    carried: Option<&FloorFile>,
    hits: Option<&Hits>,
    poses: &[(usize, Pose)],
    each: &mut dyn FnMut(ScanFloor),
) {
    if let Some(c) = carried {
        c.each(each);
    }
    if let Some(h) = hits {
        let now = |frame: usize| {
            let i = poses.binary_search_by_key(&frame, |(j, _)| *j).ok()?;
            Some(poses[i].1)
        };
        h.each_floor(&now, each);
    }
}

/// Writes the floors `floors` hands over (found in cells of `resolution` metres), which go
/// with the map whose path is `map`, to `path`; returns how many.
pub fn write(
    path: &Path,
    resolution: f64,
    map: MapPath,
    floors: &Floors,
) -> Result<u64, FileError> {
    let mut count = 0u64;
    write_atomic(path, |w| {
        let mut crc = Crc32::new();
        let mut put = |w: &mut dyn Write, bytes: &[u8]| {
            crc.update(bytes);
            w.write_all(bytes)
        };
        put(w, &MAGIC)?;
        put(w, &VERSION.to_le_bytes())?;
        put(w, &resolution.to_le_bytes())?;
        put(w, &map.poses.to_le_bytes())?;
        put(w, &map.last_stamp.to_le_bytes())?;
        let mut result = Ok(());
        floors(&mut |f| {
            let mut record = [0u8; FLOOR_BYTES];
            for (k, v) in f.at.iter().enumerate() {
                record[4 * k..4 * k + 4].copy_from_slice(&(*v as f32).to_le_bytes());
            }
            record[12] = u8::from(f.twice);
            if result.is_ok() {
                result = put(w, &record);
                count += 1;
            }
        });
        result?;
        w.write_all(&crc.value().to_le_bytes())
    })?;
    Ok(count)
}

/// The floor file beside map file `map` whose path is `path`, when there is one, it reads
/// and it goes with that map; a damaged one, or one written with another save of the map, is
/// passed over with a warning.
pub fn read_beside<T>(map: &Path, path: &[(f64, T)]) -> Option<FloorFile> {
    let at = beside(map);
    if !at.is_file() {
        return None;
    }
    match FloorFile::read(&at) {
        Ok(f) if f.goes_with(path) => Some(f),
        Ok(_) => {
            log::warn!(
                "{}: written with another save of {} (its path differs); passed over",
                at.display(),
                map.display()
            );
            None
        }
        Err(e) => {
            log::warn!("{e}; passed over");
            None
        }
    }
}

/// A floor file read and checked whole.
pub struct FloorFile {
    /// The cell size (m) the floors were found in.
    pub resolution: f64,
    /// How many floors it holds.
    pub count: usize,
    /// The map path it was written with.
    pub map: MapPath,
    bytes: Vec<u8>,
}

impl FloorFile {
    /// Reads and checks `path` ([`parse`](Self::parse)).
    pub fn read(path: &Path) -> Result<FloorFile, FileError> {
        let bytes = std::fs::read(path).map_err(|e| FileError::at(path, e.to_string()))?;
        FloorFile::parse(path, bytes)
    }

    /// Checks `bytes`, the contents of `path` (named in the errors): its magic, version,
    /// length, checksum and every floor.
    pub fn parse(path: &Path, bytes: Vec<u8>) -> Result<FloorFile, FileError> {
        let bad = |why: String| FileError::at(path, format!("not a floor file: {why}"));
        if bytes.len() < HEADER_BYTES + CHECK_BYTES || bytes[..8] != MAGIC {
            return Err(bad("no SLMFLOOR header".into()));
        }
        let word = |at: usize| {
            u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]])
        };
        let wide = |at: usize| {
            let mut b = [0u8; 8];
            b.copy_from_slice(&bytes[at..at + 8]);
            b
        };
        let version = word(8);
        if version != VERSION {
            return Err(bad(format!(
                "version {version}, this build reads {VERSION}"
            )));
        }
        let resolution = f64::from_le_bytes(wide(12));
        if !(resolution > 0.0 && resolution.is_finite()) {
            return Err(bad(format!("cell size {resolution}")));
        }
        let map = MapPath {
            poses: u64::from_le_bytes(wide(20)),
            last_stamp: f64::from_le_bytes(wide(28)),
        };
        let records = bytes.len() - HEADER_BYTES - CHECK_BYTES;
        if !records.is_multiple_of(FLOOR_BYTES) {
            return Err(bad(format!(
                "{records} bytes of floors, not a whole number of {FLOOR_BYTES}-byte floors"
            )));
        }
        let count = records / FLOOR_BYTES;
        let end = bytes.len() - CHECK_BYTES;
        if Crc32::of(&bytes[..end]) != word(end) {
            return Err(bad("its checksum does not match (damaged)".into()));
        }
        let file = FloorFile {
            resolution,
            count,
            map,
            bytes,
        };
        for i in 0..file.count {
            let (at, flags) = file.record(i);
            if !at.iter().all(|v| v.is_finite()) || flags > 1 {
                return Err(bad(format!(
                    "floor {i} is not a finite point with known flags"
                )));
            }
        }
        Ok(file)
    }

    /// Whether it goes with the map whose path is `path` (time, pose): the same number of
    /// poses, the last at the same time.
    pub fn goes_with<T>(&self, path: &[(f64, T)]) -> bool {
        self.map == MapPath::of(path)
    }

    /// Floor `i`'s point and flags byte (`i` below [`count`](Self::count)).
    fn record(&self, i: usize) -> (Vector3<f64>, u8) {
        let r = &self.bytes[HEADER_BYTES + i * FLOOR_BYTES..][..FLOOR_BYTES];
        let v = |k: usize| f64::from(f32::from_le_bytes([r[k], r[k + 1], r[k + 2], r[k + 3]]));
        (Vector3::new(v(0), v(4), v(8)), r[12])
    }

    /// Calls `each` with every floor, in the file's order (a [`Floors`]).
    pub fn each(&self, each: &mut dyn FnMut(ScanFloor)) {
        for i in 0..self.count {
            let (at, flags) = self.record(i);
            each(ScanFloor {
                at,
                twice: flags & 1 == 1,
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::navmap::hits::hand;

    fn floors() -> Vec<ScanFloor> {
        vec![
            ScanFloor {
                at: Vector3::new(1.05, -2.25, -1.49),
                twice: true,
            },
            ScanFloor {
                at: Vector3::new(3.5, 0.15, 0.01),
                twice: false,
            },
        ]
    }

    #[test]
    fn floors_written_read_back_as_they_were_in_f32() {
        let dir = crate::test_support::scratch_dir("floor-roundtrip");
        let path = dir.join("map.floor");
        assert_eq!(beside(&dir.join("map.slamesh")), path);
        let given = floors();
        let map = [(0.0, ()), (0.1, ()), (0.2, ())];
        assert_eq!(
            write(&path, 0.1, MapPath::of(&map), &hand(&given)).unwrap(),
            2
        );
        let file = FloorFile::read(&path).unwrap();
        assert_eq!((file.resolution, file.count), (0.1, 2));
        // It goes with the map it was written with, not with one saved again since.
        assert!(file.goes_with(&map));
        assert!(!file.goes_with(&map[..2]));
        assert!(!file.goes_with(&[(0.0, ()), (0.1, ()), (0.25, ())]));
        let mut got = Vec::new();
        file.each(&mut |f| got.push(f));
        for (g, w) in got.iter().zip(&given) {
            assert_eq!(g.twice, w.twice);
            assert!((g.at - w.at).norm() < 1e-6, "{:?} {:?}", g.at, w.at);
        }
        // The same floors, the same bytes; none at all is a file too.
        let first = std::fs::read(&path).unwrap();
        write(&path, 0.1, MapPath::of(&map), &hand(&given)).unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), first);
        write(&path, 0.05, MapPath::of(&map), &hand(&[])).unwrap();
        assert_eq!(FloorFile::read(&path).unwrap().count, 0);
    }

    #[test]
    fn the_fuzz_seeds_written_from_the_table_read() {
        let corpus = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz/corpus/floor_file");
        let two = FloorFile::read(&corpus.join("two")).unwrap();
        assert_eq!((two.count, two.resolution), (2, 0.1));
        assert!(two.goes_with(&[(0.0, ()), (0.1, ())]));
        assert_eq!(FloorFile::read(&corpus.join("none")).unwrap().count, 0);
    }

    #[test]
    fn damaged_files_are_refused_with_the_reason() {
        let dir = crate::test_support::scratch_dir("floor-damaged");
        let path = dir.join("map.floor");
        write(&path, 0.1, MapPath::of(&[(1.0, ())]), &hand(&floors())).unwrap();
        let good = std::fs::read(&path).unwrap();
        let refused = |bytes: Vec<u8>| {
            let e = FloorFile::parse(&path, bytes).err().expect("refused");
            assert!(e.to_string().contains("map.floor"), "{e}");
            e.to_string()
        };
        assert!(refused(good[..good.len() - 1].to_vec()).contains("whole number"));
        assert!(refused(b"SLMSHMAP".to_vec()).contains("header"));
        let mut flipped = good.clone();
        flipped[HEADER_BYTES + 2] ^= 0x10;
        assert!(refused(flipped).contains("checksum"));
        let mut version = good.clone();
        version[8] = 7;
        assert!(refused(version).contains("version 7"));
        // A NaN written with a checksum to match: refused by name.
        let mut nan = good[..good.len() - CHECK_BYTES].to_vec();
        nan[HEADER_BYTES..HEADER_BYTES + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        let crc = Crc32::of(&nan);
        nan.extend_from_slice(&crc.to_le_bytes());
        assert!(refused(nan).contains("floor 0"));
    }
}
