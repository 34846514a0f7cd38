//! Tile blocks: the cells of one tile, with their layers, checked whole before use.

use super::bytes::*;
use super::*;
use crate::cell::Axis;
use crate::facing::Facing;
use crate::map::MeshMap;
/// Bytes of a cell's record with `layers` layers.
const fn record_bytes(layers: usize) -> usize {
    CELL_HEAD_BYTES + 1 + layers * LAYER_BYTES
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
        let facings = c.layers.iter().enumerate().fold(0u8, |f, (i, l)| {
            f | l.map_or(0, |l| l.facing.bits()) << (2 * i)
        });
        s.put(&[mask | FACINGS_FOLLOW, facings])?;
        for layer in c.layers.iter().flatten() {
            for v in layer.pred.iter().chain(&layer.var) {
                s.put(&v.to_le_bytes())?;
            }
        }
    }
    s.close()
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
        let head = self.r.u8()?;
        let facings = match head & FACINGS_FOLLOW {
            0 => 0,
            _ => self.r.u8()?,
        };
        let mask = head & !FACINGS_FOLLOW;
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
            layer.facing = Facing::from_bits(facings >> (2 * i));
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
