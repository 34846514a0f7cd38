//! The header block: the signature, the version and what the file says about its map.

use super::bytes::*;
use super::*;
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
    if !(FIRST_READ_VERSION..=VERSION).contains(&version) {
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
