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
//! | tile blocks | 24 + cells + 4 each | `TILE`, the tile's key (3 × i32), cells (u32), payload bytes (u32); per cell: key (3 × i32), last seen (u32), axes present (u8 bit mask; bit 7: a facings byte follows, always in version 2), the layers' [`Facing`](crate::facing::Facing)s (u8, two bits per axis from bit 0, X first), then per axis present in X, Y, Z order 36 predictions and 36 variances (f32); CRC-32 |
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

mod bytes;
pub mod crc32;
mod header;
mod index;
mod path;
mod tile;

pub use header::{header_len, read_header, write_header};
pub use index::{
    index_block_len, read_index, read_trailer, write_index, write_trailer, IndexEntries,
    IndexEntry, Trailer,
};
pub use path::{path_block_len, read_path, write_path, PathPoses};
pub use tile::{read_tile, tile_block_len, write_tile, StoredCell, TileBlock, TileCells};

use crate::cell::{Axis, CellKey};
use crate::lattice::{Lattice, VERTICES};
use crate::layer::Layer;
use crate::map::{MapError, MeshMap};
use core::fmt;

/// The file's first eight bytes.
pub const MAGIC: [u8; 8] = *b"SLMSHMAP";
/// The format this code writes (2: cells carry their layers' facings).
pub const VERSION: u32 = 2;
/// The oldest format this code reads (1: no facings; its layers read as facing unknown).
pub const FIRST_READ_VERSION: u32 = 1;
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
/// The bit of a cell's axes byte that says a facings byte follows it.
const FACINGS_FOLLOW: u8 = 0x80;

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
        /// The newest this code reads ([`VERSION`]).
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
    /// The file does not end with the trailer: cut off (a map is written whole, then renamed,
    /// so a file without its end was truncated after it was written).
    NoTrailer {
        /// The 4 bytes where the trailer's `MEND` should be.
        found: [u8; 4],
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
                "map format version {file}, this program reads versions {FIRST_READ_VERSION} to {reader}"
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
            MapFileError::NoTrailer { found } => {
                write!(f, "truncated: the file does not end with its MEND trailer (found ")?;
                write_tag(f, found)?;
                write!(f, "); it was cut off after it was written")
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

#[cfg(test)]
mod tests;
