//! Checked little-endian reads and checksummed writes: what every block of the map file is
//! made with. No allocation, no panics.

use super::crc32::Crc32;
use super::{ByteSink, MapFileError, WriteError};
use crate::cell::CellKey;
/// A sink that checksums and counts what passes through it.
pub(super) struct Summed<'s, S: ByteSink> {
    sink: &'s mut S,
    crc: Crc32,
    bytes: u64,
}

impl<'s, S: ByteSink> Summed<'s, S> {
    pub(super) fn new(sink: &'s mut S) -> Self {
        Self {
            sink,
            crc: Crc32::new(),
            bytes: 0,
        }
    }

    pub(super) fn put(&mut self, bytes: &[u8]) -> Result<(), WriteError<S::Error>> {
        self.crc.update(bytes);
        self.bytes += bytes.len() as u64;
        self.sink.put(bytes).map_err(WriteError::Sink)
    }

    /// Writes the checksum; returns the block's length.
    pub(super) fn close(self) -> Result<u64, WriteError<S::Error>> {
        self.sink
            .put(&self.crc.value().to_le_bytes())
            .map_err(WriteError::Sink)?;
        Ok(self.bytes + 4)
    }
}

pub(super) fn put_key<S: ByteSink>(
    s: &mut Summed<'_, S>,
    k: &CellKey,
) -> Result<(), WriteError<S::Error>> {
    for v in [k.x, k.y, k.z] {
        s.put(&v.to_le_bytes())?;
    }
    Ok(())
}

/// The first `len` bytes of `bytes`, their last four being the CRC-32 of the rest.
pub(super) fn checked(bytes: &[u8], len: usize) -> Result<&[u8], MapFileError> {
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

pub(super) fn expect_tag(r: &mut Reader<'_>, expected: [u8; 4]) -> Result<(), MapFileError> {
    let found = r.array::<4>()?;
    if found != expected {
        return Err(MapFileError::Tag { expected, found });
    }
    Ok(())
}

/// Checked little-endian reads from a byte slice.
#[derive(Debug, Clone)]
pub(super) struct Reader<'a> {
    bytes: &'a [u8],
    pub(super) pos: usize,
}

impl<'a> Reader<'a> {
    pub(super) fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, pos: 0 }
    }

    pub(super) fn rest(&self) -> &'a [u8] {
        self.bytes.get(self.pos..).unwrap_or(&[])
    }

    pub(super) fn take(&mut self, n: usize) -> Result<&'a [u8], MapFileError> {
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

    pub(super) fn skip(&mut self, n: usize) -> Result<(), MapFileError> {
        self.take(n).map(|_| ())
    }

    pub(super) fn array<const K: usize>(&mut self) -> Result<[u8; K], MapFileError> {
        let mut a = [0u8; K];
        a.copy_from_slice(self.take(K)?);
        Ok(a)
    }

    pub(super) fn u8(&mut self) -> Result<u8, MapFileError> {
        Ok(self.array::<1>()?[0])
    }

    pub(super) fn u16(&mut self) -> Result<u16, MapFileError> {
        Ok(u16::from_le_bytes(self.array()?))
    }

    pub(super) fn u32(&mut self) -> Result<u32, MapFileError> {
        Ok(u32::from_le_bytes(self.array()?))
    }

    pub(super) fn u64(&mut self) -> Result<u64, MapFileError> {
        Ok(u64::from_le_bytes(self.array()?))
    }

    pub(super) fn f32(&mut self) -> Result<f32, MapFileError> {
        Ok(f32::from_le_bytes(self.array()?))
    }

    pub(super) fn f64(&mut self) -> Result<f64, MapFileError> {
        Ok(f64::from_le_bytes(self.array()?))
    }

    pub(super) fn key(&mut self) -> Result<CellKey, MapFileError> {
        Ok(CellKey::new(
            i32::from_le_bytes(self.array()?),
            i32::from_le_bytes(self.array()?),
            i32::from_le_bytes(self.array()?),
        ))
    }
}
