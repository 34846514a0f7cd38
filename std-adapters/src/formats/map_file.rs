//! Map files on disk (`map.slamesh`): a map written so that a later run can localize in it
//! or map on from it, and read back whole or a tile at a time.
//!
//! The format is the core's ([`slamesh_core::map_file`]: blocks with a CRC-32 each, an index
//! of tile blocks, the path the map was made along). This module adds the file:
//! - [`MapWriter`] streams blocks to a temporary file beside the target (cells that leave a
//!   sliding window as they go, then the map), holding one tile's cells at a time, and renames
//!   it over the target when finished: a run killed while writing leaves any older map whole.
//!   Cells are sorted by tile and key, so the same map gives the same bytes.
//! - [`MapFile`] opens a file, checking its header, trailer, index and path, then loads tiles
//!   on demand ([`MapFile::load_tile`]) or all of them ([`MapFile::load_all`]). Every block is
//!   checked whole before it is used; a damaged one is an error naming the file, the block and
//!   its offset.

use crate::io::atomic::temporary_path;
use crate::io::error::FileError;
use slamesh_core::cell::CellKey;
use slamesh_core::lattice::{Lattice, VERTICES};
use slamesh_core::map::{LayerRef, MeshMap};
use slamesh_core::map_file::{
    self as format, ByteSink, CellRecord, Header, IndexEntry, MapFileError, StoredCell, Trailer,
    WriteError, HEADER_PREFIX_BYTES, TILE_PREFIX_BYTES, TRAILER_BYTES,
};
use slamesh_core::Pose;
use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

/// What a map file says about its map besides the cells.
#[derive(Debug, Clone, PartialEq)]
pub struct MapInfo {
    /// The lattice of its layers.
    pub lattice: Lattice,
    /// Scans fused into it so far.
    pub frames: u32,
    /// The name of its frame.
    pub frame_id: String,
    /// The configuration that made it (TOML, as `slamesh config` prints it).
    pub config_toml: String,
}

/// What a finished map file holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MapFileStats {
    /// Bytes of the file.
    pub bytes: u64,
    /// Cells written (a cell that left a window and came back counts twice).
    pub cells: u64,
    /// Layers written.
    pub layers: u64,
    /// Tile blocks.
    pub blocks: u64,
    /// Poses of the path.
    pub poses: u64,
}

/// A byte sink over a buffered file, counting what it wrote.
struct FileSink<'a> {
    w: &'a mut BufWriter<File>,
}

impl ByteSink for FileSink<'_> {
    type Error = std::io::Error;
    fn put(&mut self, bytes: &[u8]) -> Result<(), std::io::Error> {
        self.w.write_all(bytes)
    }
}

/// Writes a map file (see the module docs).
pub struct MapWriter {
    target: PathBuf,
    tmp: PathBuf,
    w: BufWriter<File>,
    offset: u64,
    index: Vec<IndexEntry>,
    stats: MapFileStats,
    info: MapInfo,
    header_len: u64,
}

impl MapWriter {
    /// Starts `path` (written as a temporary file until [`finish`](Self::finish)).
    pub fn create(path: &Path, info: &MapInfo) -> Result<Self, FileError> {
        Self::create_at(path, temporary_path(path), info)
    }

    /// [`create`](Self::create) with a temporary file of its own, named with `tag`: a second
    /// writer for the same target (a loop closure's rebuild, [`crate::loop_closure`]) while
    /// the first writes; the one finished is the one renamed over the target.
    pub fn create_staged(path: &Path, info: &MapInfo, tag: &str) -> Result<Self, FileError> {
        let tmp = temporary_path(path);
        let tagged = tmp.with_file_name(format!(
            "{}-{tag}",
            tmp.file_name().unwrap_or_default().to_string_lossy()
        ));
        Self::create_at(path, tagged, info)
    }

    /// Gives up the map file: its temporary file is removed, the target left as it was.
    pub fn discard(self) {
        drop(self.w);
        let _ = std::fs::remove_file(&self.tmp);
    }

    fn create_at(path: &Path, tmp: PathBuf, info: &MapInfo) -> Result<Self, FileError> {
        let file = File::create(&tmp)
            .map_err(|e| FileError::at(path, format!("cannot create the map file: {e}")))?;
        let mut w = Self {
            target: path.to_path_buf(),
            tmp,
            w: BufWriter::new(file),
            offset: 0,
            index: Vec::new(),
            stats: MapFileStats::default(),
            info: info.clone(),
            header_len: 0,
        };
        let n = w.write_header().map_err(|e| w.fail(e))?;
        w.offset = n;
        w.header_len = n;
        Ok(w)
    }

    fn write_header(&mut self) -> Result<u64, WriteError<std::io::Error>> {
        let header = Header {
            lattice: self.info.lattice,
            frames: self.info.frames,
            frame_id: &self.info.frame_id,
            config: self.info.config_toml.as_bytes(),
        };
        format::write_header(&mut FileSink { w: &mut self.w }, &header)
    }

    /// Sets the header's count of scans fused into the map (written when finished).
    pub fn set_frames(&mut self, frames: u32) {
        self.info.frames = frames;
    }

    fn fail(&self, e: WriteError<std::io::Error>) -> FileError {
        let _ = std::fs::remove_file(&self.tmp);
        FileError::at(&self.target, format!("cannot write the map file: {e}"))
    }

    /// Writes `cells` (any order; a key at most once), a block per tile.
    pub fn add_cells(&mut self, cells: &mut [StoredCell]) -> Result<(), FileError> {
        cells.sort_by_key(|c| (format::tile_of(&c.key), c.key));
        for tile in cells.chunk_by(|a, b| format::tile_of(&a.key) == format::tile_of(&b.key)) {
            let records = tile.iter().map(|c| CellRecord {
                key: c.key,
                last_seen: c.last_seen,
                layers: [0, 1, 2].map(|i| c.layers[i].as_ref()),
            });
            self.add_block(format::tile_of(&tile[0].key), records)?;
        }
        Ok(())
    }

    /// Writes layers as a map shows them ([`MeshMap::evict_where`]'s, or
    /// [`MeshMap::layers`]): the layers of a cell come together.
    pub fn add_layers<'a>(
        &mut self,
        layers: impl Iterator<Item = LayerRef<'a>>,
    ) -> Result<(), FileError> {
        let mut cells: BTreeMap<CellKey, StoredCell> = BTreeMap::new();
        for l in layers {
            let c = cells.entry(l.key).or_insert(StoredCell {
                key: l.key,
                last_seen: l.last_seen,
                layers: [None; 3],
            });
            c.layers[l.axis.index()] = Some(*l.layer);
        }
        let mut cells: Vec<StoredCell> = cells.into_values().collect();
        self.add_cells(&mut cells)
    }

    /// Writes every cell of `map`, a tile at a time.
    pub fn add_map(&mut self, map: &MeshMap) -> Result<(), FileError> {
        let mut keys: Vec<(CellKey, CellKey)> =
            map.cells().map(|(k, _)| (format::tile_of(&k), k)).collect();
        keys.sort_unstable();
        for tile in keys.chunk_by(|a, b| a.0 == b.0) {
            let records = tile.iter().filter_map(|(_, k)| format::record_of(map, *k));
            self.add_block(tile[0].0, records)?;
        }
        Ok(())
    }

    fn add_block<'a>(
        &mut self,
        tile: CellKey,
        records: impl Iterator<Item = CellRecord<'a>> + Clone,
    ) -> Result<(), FileError> {
        for r in records.clone() {
            self.stats.cells += 1;
            self.stats.layers += r.layers.iter().flatten().count() as u64;
        }
        let n = format::write_tile(&mut FileSink { w: &mut self.w }, tile, records)
            .map_err(|e| self.fail(e))?;
        self.index.push(IndexEntry {
            tile,
            offset: self.offset,
            len: u32::try_from(n).unwrap_or(u32::MAX),
        });
        self.offset += n;
        self.stats.blocks += 1;
        Ok(())
    }

    /// Writes the path (the sensor's stamped poses), the index and the trailer, flushes the
    /// file to disk and renames it over the target.
    pub fn finish(mut self, path: &[(f64, Pose)]) -> Result<MapFileStats, FileError> {
        let path_offset = self.offset;
        let mut sink = FileSink { w: &mut self.w };
        let result = (|| {
            let p = format::write_path(&mut sink, path.iter().copied())?;
            let index_offset = path_offset + p;
            let i = format::write_index(&mut sink, self.index.iter().copied())?;
            let t = format::write_trailer(
                &mut sink,
                &Trailer {
                    index_offset,
                    path_offset,
                },
            )?;
            Ok(index_offset + i + t)
        })();
        let bytes = result.map_err(|e| self.fail(e))?;
        // The header again, with the final frame count (its length does not change).
        let rewind = self
            .w
            .flush()
            .and_then(|()| self.w.seek(SeekFrom::Start(0)));
        if let Err(e) = rewind {
            return Err(self.fail(WriteError::Sink(e)));
        }
        let n = self.write_header().map_err(|e| self.fail(e))?;
        debug_assert_eq!(n, self.header_len);
        let done = (|| {
            self.w.flush()?;
            self.w.get_ref().sync_all()?;
            std::fs::rename(&self.tmp, &self.target)
        })();
        if let Err(e) = done {
            return Err(self.fail(WriteError::Sink(e)));
        }
        self.stats.bytes = bytes;
        self.stats.poses = path.len() as u64;
        Ok(self.stats)
    }
}

/// Distance from `p` to the box of tile `t` (tiles `tile_m` on a side; 0 inside): how near a
/// place a tile comes, for a reader that pages tiles in around it.
pub fn tile_distance(t: &CellKey, tile_m: f64, p: &nalgebra::Vector3<f64>) -> f64 {
    let lo = nalgebra::Vector3::new(f64::from(t.x), f64::from(t.y), f64::from(t.z)) * tile_m;
    nalgebra::Vector3::from_fn(|i, _| (lo[i] - p[i]).max(p[i] - lo[i] - tile_m).max(0.0)).norm()
}

/// An open map file: its header, index and path read and checked; tiles load on demand.
/// `R` is the file (or, for tests and fuzzing, any seekable bytes).
#[derive(Debug)]
pub struct MapFile<R = File> {
    path: PathBuf,
    file: R,
    /// What it says about its map.
    pub info: MapInfo,
    /// Its tile blocks, in file order.
    pub index: Vec<IndexEntry>,
    /// The path its map was made along: stamped sensor poses.
    pub poses: Vec<(f64, Pose)>,
    /// Its length in bytes.
    pub bytes: u64,
}

impl MapFile<File> {
    /// Opens `path`, checking every block but the tiles (see the module docs).
    pub fn open(path: &Path) -> Result<Self, FileError> {
        let file =
            File::open(path).map_err(|e| FileError::at(path, format!("cannot open: {e}")))?;
        Self::from_reader(path, file)
    }
}

impl<R: Read + Seek> MapFile<R> {
    /// [`MapFile::open`] on the bytes of `file`, named `path` in errors: the header, then
    /// the trailer, then the path and the index it points to, each checked.
    pub fn from_reader(path: &Path, mut file: R) -> Result<Self, FileError> {
        let len = file
            .seek(SeekFrom::End(0))
            .map_err(|e| FileError::at(path, format!("cannot read: {e}")))?;
        if len == 0 {
            return Err(FileError::at(
                path,
                "not a usable map file: the file is empty",
            ));
        }
        let (info, body_start) = read_info(&mut file, path, len)?;
        let (trailer, trailer_at) = read_trailer_within(&mut file, path, len, body_start)?;
        // The path, then the index: each sized by its prefix, checked whole.
        let at = trailer.path_offset;
        let p = read_block(&mut file, path, at, trailer_at, format::path_block_len)?;
        let poses = format::read_path(&p)
            .map_err(|e| unusable(path, "the path", at, e))?
            .collect();
        let at = trailer.index_offset;
        let i = read_block(&mut file, path, at, trailer_at, format::index_block_len)?;
        let index: Vec<IndexEntry> = format::read_index(&i)
            .map_err(|e| unusable(path, "the index", at, e))?
            .collect();
        check_index(path, &index, body_start, trailer.path_offset)?;
        Ok(MapFile {
            path: path.to_path_buf(),
            file,
            info,
            index,
            poses,
            bytes: len,
        })
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Reads and checks the tile block of index entry `e`, then inserts its cells into `map`;
    /// returns the layers inserted.
    fn load_entry(&mut self, e: IndexEntry, map: &mut MeshMap) -> Result<usize, FileError> {
        let bytes = read_at(&mut self.file, &self.path, e.offset, e.len as usize)?;
        let bad = |err: MapFileError| {
            let reason = match err {
                MapFileError::Map(m) => format!(
                    "the map is larger than this run's map may grow ({m}, at the tile block \
                     at byte {}): give a larger --capacity or --memory-cap, or localize without \
                     --update, which pages the map by tile under a memory cap",
                    e.offset
                ),
                _ => format!(
                    "not a usable map file: the tile block ({}, {}, {}) at byte {}: {err}",
                    e.tile.x, e.tile.y, e.tile.z, e.offset
                ),
            };
            FileError::at(&self.path, reason)
        };
        let block = format::read_tile(&bytes).map_err(bad)?;
        if block.tile != e.tile || format::tile_block_len(&bytes).ok() != Some(bytes.len()) {
            return Err(bad(MapFileError::Malformed {
                what: "the block is not the one the index names",
                at: 4,
            }));
        }
        block.load_into(map).map_err(bad)
    }

    /// Loads every tile block into `map`, in file order; returns the layers inserted. On an
    /// error the map holds part of the file: drop it (the run refuses to start).
    pub fn load_all(&mut self, map: &mut MeshMap) -> Result<usize, FileError> {
        self.check_lattice(map)?;
        let mut layers = 0;
        for e in self.index.clone() {
            layers += self.load_entry(e, map)?;
        }
        Ok(layers)
    }

    /// The whole map in a map of its own, sized by the file (a layer takes at least the 288
    /// bytes of its predictions and variances): for reading a map outside a run.
    pub fn load_new(&mut self) -> Result<MeshMap, FileError> {
        let most = (self.bytes / 288) as usize;
        let mut map = MeshMap::with_capacity(most, most, self.info.lattice);
        self.load_all(&mut map)?;
        Ok(map)
    }

    /// Each tile and the most layers its blocks can hold (a layer takes at least the 288 bytes
    /// of its predictions and variances): a bound known before a tile is read.
    pub fn tile_bounds(&self) -> BTreeMap<CellKey, usize> {
        let mut bounds: BTreeMap<CellKey, usize> = BTreeMap::new();
        for e in &self.index {
            let layers = (e.len as usize).saturating_sub(TILE_PREFIX_BYTES + 4) / (8 * VERTICES);
            *bounds.entry(e.tile).or_default() += layers;
        }
        bounds
    }

    /// Loads the blocks of `tile` into `map`, in file order; returns the layers inserted.
    pub fn load_tile(&mut self, tile: CellKey, map: &mut MeshMap) -> Result<usize, FileError> {
        self.check_lattice(map)?;
        let entries: Vec<IndexEntry> = self
            .index
            .iter()
            .filter(|e| e.tile == tile)
            .copied()
            .collect();
        let mut layers = 0;
        for e in entries {
            layers += self.load_entry(e, map)?;
        }
        Ok(layers)
    }

    /// A map is usable only on the lattice it was made on.
    fn check_lattice(&self, map: &MeshMap) -> Result<(), FileError> {
        let (a, b) = (self.info.lattice, *map.lattice());
        if a != b {
            return Err(FileError::at(
                &self.path,
                format!(
                    "the map was made with cells of {} m (full cover {}), this run uses {} m \
                     (full cover {}): run with the map's configuration (its header holds it)",
                    a.cell_size, a.full_cover, b.cell_size, b.full_cover
                ),
            ));
        }
        Ok(())
    }
}

/// A map file's damage, named: `what` at byte `at` and why.
fn unusable(path: &Path, what: &str, at: u64, e: MapFileError) -> FileError {
    FileError::at(
        path,
        format!("not a usable map file: {what} at byte {at}: {e}"),
    )
}

/// The header of `file` (`len` bytes): what it says of the map, and where the body starts.
fn read_info(
    file: &mut (impl Read + Seek),
    path: &Path,
    len: u64,
) -> Result<(MapInfo, u64), FileError> {
    let prefix = read_at(file, path, 0, HEADER_PREFIX_BYTES.min(len as usize))?;
    let header_len = format::header_len(&prefix).map_err(|e| unusable(path, "the header", 0, e))?;
    let header_bytes = read_at(file, path, 0, header_len.min(len as usize))?;
    let header =
        format::read_header(&header_bytes).map_err(|e| unusable(path, "the header", 0, e))?;
    let config_toml = String::from_utf8(header.config.to_vec()).map_err(|_| {
        FileError::at(
            path,
            "not a usable map file: its configuration is not UTF-8",
        )
    })?;
    let info = MapInfo {
        lattice: header.lattice,
        frames: header.frames,
        frame_id: header.frame_id.to_string(),
        config_toml,
    };
    Ok((info, header_len as u64))
}

/// The trailer of `file` (`len` bytes, its body from `body_start`) and where it starts,
/// checked to point at blocks within the body.
fn read_trailer_within(
    file: &mut (impl Read + Seek),
    path: &Path,
    len: u64,
    body_start: u64,
) -> Result<(Trailer, u64), FileError> {
    if len < body_start + TRAILER_BYTES as u64 {
        return Err(FileError::at(
            path,
            format!(
                "not a usable map file: truncated: {len} bytes end before the trailer \
                 (a map file ends with its index and a {TRAILER_BYTES}-byte trailer)"
            ),
        ));
    }
    let trailer_at = len - TRAILER_BYTES as u64;
    let t = read_at(file, path, trailer_at, TRAILER_BYTES)?;
    let trailer =
        format::read_trailer(&t).map_err(|e| unusable(path, "the trailer", trailer_at, e))?;
    let within = |at: u64| at >= body_start && at < trailer_at;
    if !within(trailer.path_offset) || !within(trailer.index_offset) {
        return Err(FileError::at(
            path,
            "not a usable map file: its trailer points outside the file",
        ));
    }
    Ok((trailer, trailer_at))
}

/// The block of `file` at `at`, sized by its prefix (`size`), whole before `end`.
fn read_block(
    file: &mut (impl Read + Seek),
    path: &Path,
    at: u64,
    end: u64,
    size: fn(&[u8]) -> Result<usize, MapFileError>,
) -> Result<Vec<u8>, FileError> {
    let what = "a block";
    let p = read_at(file, path, at, 8.min((end - at) as usize))?;
    let n = size(&p).map_err(|e| unusable(path, what, at, e))?;
    if at + n as u64 > end {
        let available = end - at;
        let e = MapFileError::Truncated {
            needed: n as u64,
            available,
        };
        return Err(unusable(path, what, at, e));
    }
    read_at(file, path, at, n)
}

/// Checks that every tile block of `index` lies among the tiles, from `body_start` to
/// `tiles_end`.
fn check_index(
    path: &Path,
    index: &[IndexEntry],
    body_start: u64,
    tiles_end: u64,
) -> Result<(), FileError> {
    match index
        .iter()
        .find(|e| e.offset < body_start || e.offset + u64::from(e.len) > tiles_end)
    {
        Some(e) => Err(FileError::at(
            path,
            format!(
                "not a usable map file: the index places a tile block at byte {} \
                 ({} bytes), outside the tiles",
                e.offset, e.len
            ),
        )),
        None => Ok(()),
    }
}

/// `n` bytes of `file` from `at` (the caller has checked that they lie within the file).
fn read_at(
    file: &mut (impl Read + Seek),
    path: &Path,
    at: u64,
    n: usize,
) -> Result<Vec<u8>, FileError> {
    let mut buf = vec![0u8; n];
    file.seek(SeekFrom::Start(at))
        .and_then(|_| file.read_exact(&mut buf))
        .map_err(|e| FileError::at(path, format!("cannot read {n} bytes at byte {at}: {e}")))?;
    Ok(buf)
}
