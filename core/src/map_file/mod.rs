//! The map file: a [`MeshMap`] that outlives its run, in blocks a caller writes to any byte
//! sink and reads back from byte slices (docs/design.md §1.12).
//!
//! Owns the format and nothing else: no file system, no allocation, no clock. Writing goes to
//! a [`ByteSink`] the caller provides; reading takes the bytes of one block at a time, so a
//! reader holds at most one block (a tile's cells) however large the map.
//!
//! ## Layout (little-endian throughout)
//! | part | bytes | what |
//! |---|---|---|
//! | header | 16 + body + 4 | [`MAGIC`], [`VERSION`], the body's length; the body: cell size (f64), full cover (u8), the frames fused so far (u32), the frame's name (u16 length + UTF-8), the configuration that made it (u32 length + bytes, opaque here); CRC-32 |
//! | tile blocks | 24 + cells + 4 each | `TILE`, the tile's key (3 × i32), cells (u32), payload bytes (u32); per cell: key (3 × i32), last seen (u32), axes present (u8 bit mask), then per axis present in X, Y, Z order 36 predictions and 36 variances (f32); CRC-32 |
//! | path | 8 + 64 × poses + 4 | `PATH`, poses (u32); per pose: time (f64 s), translation (3 × f64), rotation quaternion i, j, k, w (4 × f64); CRC-32 |
//! | index | 8 + 24 × blocks + 4 | `INDX`, entries (u32); per tile block: tile key (3 × i32), offset (u64), length (u32); CRC-32 |
//! | trailer | [`TRAILER_BYTES`] | the index's offset and the path's (u64 each), CRC-32 of both, `MEND` |
//!
//! A tile is [`TILE_CELLS`]³ cells ([`tile_of`]): a reader pages the map in by tile, finding
//! a tile's blocks through the index. A tile may have several blocks (cells that left a
//! sliding window at different times); a later block's cell replaces an earlier one's.
//!
//! ## Guarantees
//! - Every block carries a CRC-32 of its bytes and is checked whole before anything of it is
//!   used: a truncated, bit-flipped or foreign block is a [`MapFileError`] naming the cause
//!   and the offset within the block, never a half-read cell.
//! - Writing is deterministic: the same cells, path and header give the same bytes
//!   (cells are written in the order given; the std writer sorts them).
//! - No panics on any input bytes (a fuzz target reads arbitrary files through these functions).

pub mod crc32;

use crate::cell::{Axis, CellKey};
use crate::lattice::{Lattice, VERTICES};
use crate::layer::Layer;
use crate::map::{MapError, MeshMap};
use crate::math::Pose;
use core::fmt;
use crc32::Crc32;
use nalgebra::{Quaternion, Translation3, UnitQuaternion};

/// The file's first eight bytes.
pub const MAGIC: [u8; 8] = *b"SLMSHMAP";
/// The format this code writes and reads.
pub const VERSION: u32 = 1;
/// Cells along each edge of a tile, the unit of paging.
pub const TILE_CELLS: i32 = 16;
/// Bytes of the trailer at the file's end.
pub const TRAILER_BYTES: usize = 24;
/// Bytes before a header's body: magic, version, body length.
pub const HEADER_PREFIX_BYTES: usize = 16;
/// Bytes before a tile block's cells: tag, tile key, cell count, payload length.
pub const TILE_PREFIX_BYTES: usize = 24;
/// Bytes of one index entry.
pub const INDEX_ENTRY_BYTES: usize = 24;
/// Bytes of one pose of the path.
pub const PATH_POSE_BYTES: usize = 64;
/// Longest frame name, in bytes.
pub const MAX_FRAME_ID_BYTES: usize = 255;

const TILE_TAG: [u8; 4] = *b"TILE";
const PATH_TAG: [u8; 4] = *b"PATH";
const INDEX_TAG: [u8; 4] = *b"INDX";
const END_TAG: [u8; 4] = *b"MEND";
const LAYER_BYTES: usize = 8 * VERTICES;
const CELL_HEAD_BYTES: usize = 17;

/// Where the bytes of a map file go: a file, a buffer, a flash page writer.
pub trait ByteSink {
    /// Why a write failed.
    type Error;
    /// Appends `bytes`.
    fn put(&mut self, bytes: &[u8]) -> Result<(), Self::Error>;
}

/// A [`ByteSink`] into a caller's buffer; refuses what does not fit ([`SinkFull`]).
#[derive(Debug)]
pub struct SliceSink<'a> {
    buf: &'a mut [u8],
    len: usize,
}

/// The buffer of a [`SliceSink`] is full.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SinkFull;

impl<'a> SliceSink<'a> {
    /// A sink writing `buf` from its start.
    pub fn new(buf: &'a mut [u8]) -> Self {
        Self { buf, len: 0 }
    }

    /// The bytes written so far.
    pub fn written(&self) -> &[u8] {
        self.buf.get(..self.len).unwrap_or(&[])
    }
}

impl ByteSink for SliceSink<'_> {
    type Error = SinkFull;
    fn put(&mut self, bytes: &[u8]) -> Result<(), SinkFull> {
        let end = self.len.checked_add(bytes.len()).ok_or(SinkFull)?;
        let dst = self.buf.get_mut(self.len..end).ok_or(SinkFull)?;
        dst.copy_from_slice(bytes);
        self.len = end;
        Ok(())
    }
}

/// Why a block could not be written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WriteError<E> {
    /// The sink refused the bytes.
    Sink(E),
    /// A field is longer than the format allows (its name).
    TooLong(&'static str),
    /// A cell given for a tile block lies outside the tile.
    CellOutsideTile(CellKey),
}

impl<E: fmt::Display> fmt::Display for WriteError<E> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            WriteError::Sink(e) => write!(f, "{e}"),
            WriteError::TooLong(what) => write!(f, "the {what} is longer than a map file holds"),
            WriteError::CellOutsideTile(k) => {
                write!(f, "cell ({}, {}, {}) is outside its tile", k.x, k.y, k.z)
            }
        }
    }
}

/// Why bytes are not a usable part of a map file. Offsets are within the bytes given.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MapFileError {
    /// The bytes do not start with [`MAGIC`].
    NotAMapFile,
    /// The file is of another format version.
    Version {
        /// The file's.
        file: u32,
        /// This code's ([`VERSION`]).
        reader: u32,
    },
    /// The bytes end before the block does.
    Truncated {
        /// Bytes the block needs.
        needed: u64,
        /// Bytes there are.
        available: u64,
    },
    /// The stored checksum differs from the bytes' (a bit flipped, or bytes of another block).
    Checksum {
        /// The block's stored CRC-32.
        stored: u32,
        /// The CRC-32 of its bytes.
        computed: u32,
    },
    /// The block starts with another tag than the one expected here.
    Tag {
        /// The tag expected.
        expected: [u8; 4],
        /// The bytes found.
        found: [u8; 4],
    },
    /// A value is out of its range (what, and where in the block).
    Malformed {
        /// What is wrong.
        what: &'static str,
        /// Its offset in the block.
        at: usize,
    },
    /// The map refused a cell (its capacity).
    Map(MapError),
}

impl fmt::Display for MapFileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MapFileError::NotAMapFile => write!(f, "not a slamesh map file (no SLMSHMAP signature)"),
            MapFileError::Version { file, reader } => write!(
                f,
                "map format version {file}, this program reads version {reader}"
            ),
            MapFileError::Truncated { needed, available } => write!(
                f,
                "truncated: the block needs {needed} bytes, {available} are there"
            ),
            MapFileError::Checksum { stored, computed } => write!(
                f,
                "checksum mismatch (stored {stored:08x}, computed {computed:08x}): the block is corrupted"
            ),
            MapFileError::Tag { expected, found } => {
                write!(f, "expected a ")?;
                write_tag(f, expected)?;
                write!(f, " block, found ")?;
                write_tag(f, found)
            }
            MapFileError::Malformed { what, at } => write!(f, "{what} (byte {at} of the block)"),
            MapFileError::Map(e) => write!(f, "{e}: the map does not fit this capacity"),
        }
    }
}

fn write_tag(f: &mut fmt::Formatter<'_>, tag: &[u8; 4]) -> fmt::Result {
    for &b in tag {
        if b.is_ascii_graphic() {
            write!(f, "{}", b as char)?;
        } else {
            write!(f, "\\x{b:02x}")?;
        }
    }
    Ok(())
}

impl core::error::Error for MapFileError {}

/// What a map file says about its map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Header<'a> {
    /// The lattice its layers lie on (a map is only usable with the same one).
    pub lattice: Lattice,
    /// Scans fused into the map so far: a session mapping on counts its frames from here.
    pub frames: u32,
    /// The name of the frame the map is in (e.g. `map`).
    pub frame_id: &'a str,
    /// The configuration that made it, as the writer chose to encode it (the std crate: TOML).
    pub config: &'a [u8],
}

/// One cell as written: its key, when it was last seen, and its layers by axis index.
#[derive(Debug, Clone, Copy)]
pub struct CellRecord<'a> {
    /// The cell.
    pub key: CellKey,
    /// The frame it was last seen in.
    pub last_seen: u32,
    /// Its layers along x, y, z.
    pub layers: [Option<&'a Layer>; 3],
}

/// The tile holding cell `key`: its key divided by [`TILE_CELLS`], rounded down.
pub fn tile_of(key: &CellKey) -> CellKey {
    CellKey::new(
        key.x.div_euclid(TILE_CELLS),
        key.y.div_euclid(TILE_CELLS),
        key.z.div_euclid(TILE_CELLS),
    )
}

/// The record of cell `key` of `map`, to write (`None` when the map has no such cell).
pub fn record_of(map: &MeshMap, key: CellKey) -> Option<CellRecord<'_>> {
    let cell = map.cell(&key)?;
    Some(CellRecord {
        key,
        last_seen: cell.last_seen,
        layers: Axis::ALL.map(|a| map.layer(&key, a)),
    })
}

/// A sink that checksums and counts what passes through it.
struct Summed<'s, S: ByteSink> {
    sink: &'s mut S,
    crc: Crc32,
    bytes: u64,
}

impl<'s, S: ByteSink> Summed<'s, S> {
    fn new(sink: &'s mut S) -> Self {
        Self {
            sink,
            crc: Crc32::new(),
            bytes: 0,
        }
    }

    fn put(&mut self, bytes: &[u8]) -> Result<(), WriteError<S::Error>> {
        self.crc.update(bytes);
        self.bytes += bytes.len() as u64;
        self.sink.put(bytes).map_err(WriteError::Sink)
    }

    /// Writes the checksum; returns the block's length.
    fn close(self) -> Result<u64, WriteError<S::Error>> {
        self.sink
            .put(&self.crc.value().to_le_bytes())
            .map_err(WriteError::Sink)?;
        Ok(self.bytes + 4)
    }
}

/// Writes the header; returns its length in bytes.
pub fn write_header<S: ByteSink>(
    sink: &mut S,
    h: &Header<'_>,
) -> Result<u64, WriteError<S::Error>> {
    if h.frame_id.len() > MAX_FRAME_ID_BYTES {
        return Err(WriteError::TooLong("frame name"));
    }
    let config_len =
        u32::try_from(h.config.len()).map_err(|_| WriteError::TooLong("configuration"))?;
    let body = 8 + 1 + 4 + 2 + h.frame_id.len() + 4 + h.config.len();
    let body = u32::try_from(body).map_err(|_| WriteError::TooLong("configuration"))?;
    let mut s = Summed::new(sink);
    s.put(&MAGIC)?;
    s.put(&VERSION.to_le_bytes())?;
    s.put(&body.to_le_bytes())?;
    s.put(&h.lattice.cell_size.to_le_bytes())?;
    s.put(&[u8::from(h.lattice.full_cover)])?;
    s.put(&h.frames.to_le_bytes())?;
    s.put(&(h.frame_id.len() as u16).to_le_bytes())?;
    s.put(h.frame_id.as_bytes())?;
    s.put(&config_len.to_le_bytes())?;
    s.put(h.config)?;
    s.close()
}

/// The whole header's length from its first [`HEADER_PREFIX_BYTES`] bytes (which this checks:
/// signature and version).
pub fn header_len(prefix: &[u8]) -> Result<usize, MapFileError> {
    let n = prefix.len().min(MAGIC.len());
    if prefix.get(..n) != MAGIC.get(..n) {
        return Err(MapFileError::NotAMapFile);
    }
    let mut r = Reader::new(prefix);
    r.skip(MAGIC.len())?;
    let version = r.u32()?;
    if version != VERSION {
        return Err(MapFileError::Version {
            file: version,
            reader: VERSION,
        });
    }
    Ok(HEADER_PREFIX_BYTES + r.u32()? as usize + 4)
}

/// Reads a header from `bytes` (exactly [`header_len`] of them, or more: the rest is ignored).
pub fn read_header(bytes: &[u8]) -> Result<Header<'_>, MapFileError> {
    let len = header_len(bytes)?;
    let block = checked(bytes, len)?;
    let mut r = Reader::new(block);
    r.skip(HEADER_PREFIX_BYTES)?;
    let at = r.pos;
    let cell_size = r.f64()?;
    if !(cell_size > 0.0 && cell_size < 1e6) {
        return Err(MapFileError::Malformed {
            what: "the cell size is not a positive length",
            at,
        });
    }
    let at = r.pos;
    let full_cover = match r.u8()? {
        0 => false,
        1 => true,
        _ => {
            return Err(MapFileError::Malformed {
                what: "the lattice flag is neither 0 nor 1",
                at,
            })
        }
    };
    let frames = r.u32()?;
    let n = r.u16()? as usize;
    let at = r.pos;
    let frame_id = core::str::from_utf8(r.take(n)?).map_err(|_| MapFileError::Malformed {
        what: "the frame name is not UTF-8",
        at,
    })?;
    let n = r.u32()? as usize;
    let config = r.take(n)?;
    if r.pos != len - 4 {
        return Err(MapFileError::Malformed {
            what: "the header's length disagrees with its fields",
            at: r.pos,
        });
    }
    Ok(Header {
        lattice: Lattice {
            cell_size,
            full_cover,
        },
        frames,
        frame_id,
        config,
    })
}

/// Bytes of a cell's record with `layers` layers.
const fn record_bytes(layers: usize) -> usize {
    CELL_HEAD_BYTES + layers * LAYER_BYTES
}

/// Writes a tile block of the cells `cells` (all in `tile`, in the order given); returns its
/// length in bytes. The iterator is walked twice: to size the block, then to write it.
pub fn write_tile<'a, S: ByteSink>(
    sink: &mut S,
    tile: CellKey,
    cells: impl Iterator<Item = CellRecord<'a>> + Clone,
) -> Result<u64, WriteError<S::Error>> {
    let (mut count, mut payload) = (0u64, 0u64);
    for c in cells.clone() {
        if tile_of(&c.key) != tile {
            return Err(WriteError::CellOutsideTile(c.key));
        }
        count += 1;
        payload += record_bytes(c.layers.iter().flatten().count()) as u64;
    }
    let count = u32::try_from(count).map_err(|_| WriteError::TooLong("tile"))?;
    let payload = u32::try_from(payload).map_err(|_| WriteError::TooLong("tile"))?;
    let mut s = Summed::new(sink);
    s.put(&TILE_TAG)?;
    put_key(&mut s, &tile)?;
    s.put(&count.to_le_bytes())?;
    s.put(&payload.to_le_bytes())?;
    for c in cells {
        put_key(&mut s, &c.key)?;
        s.put(&c.last_seen.to_le_bytes())?;
        let mask = c
            .layers
            .iter()
            .enumerate()
            .filter(|(_, l)| l.is_some())
            .fold(0u8, |m, (i, _)| m | 1 << i);
        s.put(&[mask])?;
        for layer in c.layers.iter().flatten() {
            for v in layer.pred.iter().chain(&layer.var) {
                s.put(&v.to_le_bytes())?;
            }
        }
    }
    s.close()
}

fn put_key<S: ByteSink>(s: &mut Summed<'_, S>, k: &CellKey) -> Result<(), WriteError<S::Error>> {
    for v in [k.x, k.y, k.z] {
        s.put(&v.to_le_bytes())?;
    }
    Ok(())
}

/// A tile block, checked: its checksum, and every record's form.
#[derive(Debug, Clone, Copy)]
pub struct TileBlock<'a> {
    /// The tile.
    pub tile: CellKey,
    /// Its cells.
    pub cells: u32,
    payload: &'a [u8],
}

/// The whole tile block's length from its first [`TILE_PREFIX_BYTES`] bytes.
pub fn tile_block_len(prefix: &[u8]) -> Result<usize, MapFileError> {
    let mut r = Reader::new(prefix);
    expect_tag(&mut r, TILE_TAG)?;
    r.skip(16)?;
    Ok(TILE_PREFIX_BYTES + r.u32()? as usize + 4)
}

/// Reads and checks the tile block at the start of `bytes`.
pub fn read_tile(bytes: &[u8]) -> Result<TileBlock<'_>, MapFileError> {
    let len = tile_block_len(bytes)?;
    let block = checked(bytes, len)?;
    let mut r = Reader::new(block);
    r.skip(4)?;
    let tile = r.key()?;
    let cells = r.u32()?;
    r.skip(4)?;
    let payload = r.take(len - TILE_PREFIX_BYTES - 4)?;
    let t = TileBlock {
        tile,
        cells,
        payload,
    };
    // Every record is checked before any is used.
    let mut n = 0u32;
    let mut records = t.records_at();
    while let Some(item) = records.next_record() {
        let (at, cell) = item?;
        if tile_of(&cell.key) != tile {
            return Err(MapFileError::Malformed {
                what: "a cell lies outside its tile",
                at,
            });
        }
        n += 1;
    }
    if n != cells {
        return Err(MapFileError::Malformed {
            what: "the tile's cell count disagrees with its cells",
            at: 16,
        });
    }
    Ok(t)
}

/// One cell as read: its key, when it was last seen, its layers by axis index.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StoredCell {
    /// The cell.
    pub key: CellKey,
    /// The frame it was last seen in.
    pub last_seen: u32,
    /// Its layers along x, y, z.
    pub layers: [Option<Layer>; 3],
}

/// The cells of a [`TileBlock`], in order.
#[derive(Debug, Clone)]
pub struct TileCells<'a> {
    r: Reader<'a>,
}

impl TileCells<'_> {
    fn next_record(&mut self) -> Option<Result<(usize, StoredCell), MapFileError>> {
        if self.r.rest().is_empty() {
            return None;
        }
        let at = TILE_PREFIX_BYTES + self.r.pos;
        Some(self.read().map(|c| (at, c)))
    }

    fn read(&mut self) -> Result<StoredCell, MapFileError> {
        let key = self.r.key()?;
        let last_seen = self.r.u32()?;
        let at = TILE_PREFIX_BYTES + self.r.pos;
        let mask = self.r.u8()?;
        if mask == 0 || mask > 7 {
            return Err(MapFileError::Malformed {
                what: "a cell's axes are not a set of x, y and z",
                at,
            });
        }
        let mut layers = [None; 3];
        for (i, slot) in layers.iter_mut().enumerate() {
            if mask & (1 << i) == 0 {
                continue;
            }
            let mut layer = Layer::UNKNOWN;
            for v in layer.pred.iter_mut() {
                let at = TILE_PREFIX_BYTES + self.r.pos;
                *v = self.r.f32()?;
                if !v.is_finite() {
                    return Err(MapFileError::Malformed {
                        what: "a prediction is not finite",
                        at,
                    });
                }
            }
            for v in layer.var.iter_mut() {
                let at = TILE_PREFIX_BYTES + self.r.pos;
                *v = self.r.f32()?;
                // Unknown vertices have an infinite variance; none is negative or NaN.
                if !(*v >= 0.0) {
                    return Err(MapFileError::Malformed {
                        what: "a variance is negative or not a number",
                        at,
                    });
                }
            }
            *slot = Some(layer);
        }
        Ok(StoredCell {
            key,
            last_seen,
            layers,
        })
    }
}

impl Iterator for TileCells<'_> {
    type Item = StoredCell;
    /// The next cell (the block was checked when read: a record that does not read ends it).
    fn next(&mut self) -> Option<StoredCell> {
        self.next_record()?.ok().map(|(_, c)| c)
    }
}

impl<'a> TileBlock<'a> {
    fn records_at(&self) -> TileCells<'a> {
        TileCells {
            r: Reader::new(self.payload),
        }
    }

    /// The block's cells, in order.
    pub fn cells(&self) -> TileCells<'a> {
        self.records_at()
    }

    /// Inserts every cell of the block into `map` (a later cell replaces an earlier one with
    /// the same key and axis); returns the layers inserted.
    pub fn load_into(&self, map: &mut MeshMap) -> Result<usize, MapFileError> {
        let mut layers = 0;
        for cell in self.cells() {
            for (axis, layer) in Axis::ALL.iter().zip(cell.layers) {
                if let Some(layer) = layer {
                    map.insert_layer(cell.key, *axis, layer, cell.last_seen)
                        .map_err(MapFileError::Map)?;
                    layers += 1;
                }
            }
        }
        Ok(layers)
    }
}

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

/// One entry of the index: where a tile block lies in the file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct IndexEntry {
    /// The tile.
    pub tile: CellKey,
    /// The block's offset from the file's start.
    pub offset: u64,
    /// The block's length.
    pub len: u32,
}

/// Writes the index block. Returns its length in bytes.
pub fn write_index<S: ByteSink>(
    sink: &mut S,
    entries: impl Iterator<Item = IndexEntry> + Clone,
) -> Result<u64, WriteError<S::Error>> {
    let n = u32::try_from(entries.clone().count()).map_err(|_| WriteError::TooLong("index"))?;
    let mut s = Summed::new(sink);
    s.put(&INDEX_TAG)?;
    s.put(&n.to_le_bytes())?;
    for e in entries {
        put_key(&mut s, &e.tile)?;
        s.put(&e.offset.to_le_bytes())?;
        s.put(&e.len.to_le_bytes())?;
    }
    s.close()
}

/// The index block's length from its first 8 bytes.
pub fn index_block_len(prefix: &[u8]) -> Result<usize, MapFileError> {
    let mut r = Reader::new(prefix);
    expect_tag(&mut r, INDEX_TAG)?;
    Ok(8 + r.u32()? as usize * INDEX_ENTRY_BYTES + 4)
}

/// The entries of a checked index block.
#[derive(Debug, Clone)]
pub struct IndexEntries<'a> {
    r: Reader<'a>,
}

impl Iterator for IndexEntries<'_> {
    type Item = IndexEntry;
    fn next(&mut self) -> Option<IndexEntry> {
        Some(IndexEntry {
            tile: self.r.key().ok()?,
            offset: self.r.u64().ok()?,
            len: self.r.u32().ok()?,
        })
    }
}

/// Reads and checks the index block at the start of `bytes`.
pub fn read_index(bytes: &[u8]) -> Result<IndexEntries<'_>, MapFileError> {
    let len = index_block_len(bytes)?;
    let block = checked(bytes, len)?;
    Ok(IndexEntries {
        r: Reader::new(block.get(8..len - 4).unwrap_or(&[])),
    })
}

/// Where the index and the path lie: the file's last [`TRAILER_BYTES`] bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Trailer {
    /// The index block's offset.
    pub index_offset: u64,
    /// The path block's offset.
    pub path_offset: u64,
}

/// Writes the trailer.
pub fn write_trailer<S: ByteSink>(sink: &mut S, t: &Trailer) -> Result<u64, WriteError<S::Error>> {
    let mut s = Summed::new(sink);
    s.put(&t.index_offset.to_le_bytes())?;
    s.put(&t.path_offset.to_le_bytes())?;
    let n = s.close()?;
    sink.put(&END_TAG).map_err(WriteError::Sink)?;
    Ok(n + 4)
}

/// Reads the trailer from the file's last [`TRAILER_BYTES`] bytes.
pub fn read_trailer(bytes: &[u8]) -> Result<Trailer, MapFileError> {
    let mut r = Reader::new(bytes);
    let body = r.take(16)?;
    let stored = r.u32()?;
    let tag = r.array::<4>()?;
    if tag != END_TAG {
        return Err(MapFileError::Tag {
            expected: END_TAG,
            found: tag,
        });
    }
    let computed = Crc32::of(body);
    if stored != computed {
        return Err(MapFileError::Checksum { stored, computed });
    }
    let mut b = Reader::new(body);
    Ok(Trailer {
        index_offset: b.u64()?,
        path_offset: b.u64()?,
    })
}

/// The first `len` bytes of `bytes`, their last four being the CRC-32 of the rest.
fn checked(bytes: &[u8], len: usize) -> Result<&[u8], MapFileError> {
    let block = bytes.get(..len).ok_or(MapFileError::Truncated {
        needed: len as u64,
        available: bytes.len() as u64,
    })?;
    let body = block.get(..len.saturating_sub(4)).unwrap_or(&[]);
    let mut r = Reader::new(block);
    r.skip(body.len())?;
    let stored = r.u32()?;
    let computed = Crc32::of(body);
    if stored != computed {
        return Err(MapFileError::Checksum { stored, computed });
    }
    Ok(block)
}

fn expect_tag(r: &mut Reader<'_>, expected: [u8; 4]) -> Result<(), MapFileError> {
    let found = r.array::<4>()?;
    if found != expected {
        return Err(MapFileError::Tag { expected, found });
    }
    Ok(())
}

/// Checked little-endian reads from a byte slice.
#[derive(Debug, Clone)]
struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, pos: 0 }
    }

    fn rest(&self) -> &'a [u8] {
        self.bytes.get(self.pos..).unwrap_or(&[])
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], MapFileError> {
        let end = self.pos.saturating_add(n);
        let s = self
            .bytes
            .get(self.pos..end)
            .ok_or(MapFileError::Truncated {
                needed: end as u64,
                available: self.bytes.len() as u64,
            })?;
        self.pos = end;
        Ok(s)
    }

    fn skip(&mut self, n: usize) -> Result<(), MapFileError> {
        self.take(n).map(|_| ())
    }

    fn array<const K: usize>(&mut self) -> Result<[u8; K], MapFileError> {
        let mut a = [0u8; K];
        a.copy_from_slice(self.take(K)?);
        Ok(a)
    }

    fn u8(&mut self) -> Result<u8, MapFileError> {
        Ok(self.array::<1>()?[0])
    }

    fn u16(&mut self) -> Result<u16, MapFileError> {
        Ok(u16::from_le_bytes(self.array()?))
    }

    fn u32(&mut self) -> Result<u32, MapFileError> {
        Ok(u32::from_le_bytes(self.array()?))
    }

    fn u64(&mut self) -> Result<u64, MapFileError> {
        Ok(u64::from_le_bytes(self.array()?))
    }

    fn f32(&mut self) -> Result<f32, MapFileError> {
        Ok(f32::from_le_bytes(self.array()?))
    }

    fn f64(&mut self) -> Result<f64, MapFileError> {
        Ok(f64::from_le_bytes(self.array()?))
    }

    fn key(&mut self) -> Result<CellKey, MapFileError> {
        Ok(CellKey::new(
            i32::from_le_bytes(self.array()?),
            i32::from_le_bytes(self.array()?),
            i32::from_le_bytes(self.array()?),
        ))
    }
}

#[cfg(test)]
mod tests;
