//! The index of tile blocks and the trailer that points at it.

use super::bytes::*;
use super::crc32::Crc32;
use super::*;
use crate::cell::CellKey;
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
        return Err(MapFileError::NoTrailer { found: tag });
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
