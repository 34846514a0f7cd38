//! The map file's blocks: written and read back bit for bit, and every damage refused.

use super::crc32::Crc32;
use super::*;
use crate::facing::Facing;
use crate::math::Pose;
use alloc::vec::Vec;
use nalgebra::{Translation3, UnitQuaternion};

impl ByteSink for Vec<u8> {
    type Error = core::convert::Infallible;
    fn put(&mut self, bytes: &[u8]) -> Result<(), Self::Error> {
        self.extend_from_slice(bytes);
        Ok(())
    }
}

const LAT: Lattice = Lattice {
    cell_size: 1.6,
    full_cover: false,
};

fn layer(seed: f32) -> Layer {
    let mut l = Layer::UNKNOWN;
    for (j, (p, v)) in l.pred.iter_mut().zip(&mut l.var).enumerate() {
        *p = seed + j as f32 * 0.013;
        *v = if j == 7 {
            f32::INFINITY
        } else {
            0.3 / (1.0 + j as f32)
        };
    }
    l
}

fn facing(mut l: Layer, facing: Facing) -> Layer {
    l.facing = facing;
    l
}

fn sample_map() -> MeshMap {
    let mut map = MeshMap::with_capacity(16, 16, LAT);
    let mut put = |key, axis, l, f, seen| map.insert_layer(key, axis, facing(l, f), seen).unwrap();
    put(
        CellKey::new(-3, 7, 0),
        Axis::Z,
        layer(0.1),
        Facing::Positive,
        4,
    );
    put(CellKey::new(-3, 7, 0), Axis::X, layer(0.5), Facing::Both, 5);
    put(
        CellKey::new(-1, 2, 0),
        Axis::Y,
        layer(0.9),
        Facing::Negative,
        2,
    );
    map
}

fn tile_bytes(map: &MeshMap) -> Vec<u8> {
    let mut keys: Vec<CellKey> = map.cells().map(|(k, _)| k).collect();
    keys.sort();
    let mut out = Vec::new();
    let n = write_tile(
        &mut out,
        tile_of(&keys[0]),
        keys.iter().filter_map(|k| record_of(map, *k)),
    )
    .unwrap();
    assert_eq!(n as usize, out.len());
    out
}

#[test]
fn a_header_reads_back() {
    let h = Header {
        lattice: LAT,
        frames: 1234,
        frame_id: "map",
        config: b"preset = \"kitti\"",
    };
    let mut out = Vec::new();
    let n = write_header(&mut out, &h).unwrap();
    assert_eq!(n as usize, out.len());
    assert_eq!(header_len(&out[..HEADER_PREFIX_BYTES]).unwrap(), out.len());
    assert_eq!(read_header(&out).unwrap(), h);
    // Another version is refused with both numbers.
    let mut other = out.clone();
    other[8] = 9;
    assert_eq!(
        read_header(&other).unwrap_err(),
        MapFileError::Version { file: 9, reader: 2 }
    );
    assert_eq!(
        read_header(b"PK\x03\x04").unwrap_err(),
        MapFileError::NotAMapFile
    );
    let long = "x".repeat(MAX_FRAME_ID_BYTES + 1);
    let h = Header {
        frame_id: &long,
        ..h
    };
    assert_eq!(
        write_header(&mut Vec::new(), &h),
        Err(WriteError::TooLong("frame name"))
    );
}

#[test]
fn a_tile_reads_back_bit_for_bit() {
    let map = sample_map();
    let bytes = tile_bytes(&map);
    let block = read_tile(&bytes).unwrap();
    assert_eq!((block.tile, block.cells), (CellKey::new(-1, 0, 0), 2));
    let mut back = MeshMap::with_capacity(16, 16, LAT);
    assert_eq!(block.load_into(&mut back).unwrap(), 3);
    for (key, cell) in map.cells() {
        assert_eq!(back.cell(&key).unwrap().last_seen, cell.last_seen);
        for axis in Axis::ALL {
            assert_eq!(map.layer(&key, axis), back.layer(&key, axis));
        }
    }
    // Into a map too small: the capacity is named, nothing panics.
    let mut small = MeshMap::with_capacity(1, 16, LAT);
    assert_eq!(
        block.load_into(&mut small).unwrap_err(),
        MapFileError::Map(MapError::CellsFull)
    );
}

/// A version-1 tile block (no facings byte): its layers read back facing unknown.
#[test]
fn a_version_1_tile_reads_with_its_facings_unknown() {
    let key = CellKey::new(-3, 7, 0);
    let l = layer(0.1);
    let mut payload = Vec::new();
    for v in [key.x, key.y, key.z] {
        payload.extend_from_slice(&v.to_le_bytes());
    }
    payload.extend_from_slice(&4u32.to_le_bytes());
    payload.push(0b100);
    for v in l.pred.iter().chain(&l.var) {
        payload.extend_from_slice(&v.to_le_bytes());
    }
    let tile = tile_of(&key);
    let mut bytes = b"TILE".to_vec();
    for v in [tile.x, tile.y, tile.z] {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    bytes.extend_from_slice(&1u32.to_le_bytes());
    bytes.extend_from_slice(&(payload.len() as u32).to_le_bytes());
    bytes.extend_from_slice(&payload);
    let crc = Crc32::of(&bytes);
    bytes.extend_from_slice(&crc.to_le_bytes());
    let mut back = MeshMap::with_capacity(16, 16, LAT);
    assert_eq!(read_tile(&bytes).unwrap().load_into(&mut back).unwrap(), 1);
    assert_eq!(back.layer(&key, Axis::Z), Some(&l));
    assert_eq!(back.layer(&key, Axis::Z).unwrap().facing, Facing::Unknown);
}

#[test]
fn every_truncation_and_every_bit_flip_of_a_tile_is_refused() {
    let bytes = tile_bytes(&sample_map());
    for cut in 0..bytes.len() {
        assert!(read_tile(&bytes[..cut]).is_err(), "cut at {cut}");
    }
    for i in 0..bytes.len() {
        for bit in [0, 3, 7] {
            let mut b = bytes.clone();
            b[i] ^= 1 << bit;
            assert!(read_tile(&b).is_err(), "byte {i} bit {bit}");
        }
    }
}

#[test]
fn a_cell_outside_its_tile_is_refused_on_both_sides() {
    let map = sample_map();
    let far = CellKey::new(40, 0, 0);
    let r = write_tile(
        &mut Vec::new(),
        CellKey::new(0, 0, 0),
        record_of(&map, CellKey::new(-3, 7, 0))
            .into_iter()
            .map(|c| CellRecord { key: far, ..c }),
    );
    assert_eq!(r, Err(WriteError::CellOutsideTile(far)));
}

#[test]
fn a_malformed_record_with_a_good_checksum_is_refused() {
    let mut bytes = tile_bytes(&sample_map());
    // The first cell's axes mask: 0 is no set of axes.
    bytes[TILE_PREFIX_BYTES + 16] = 0;
    let n = bytes.len();
    let crc = Crc32::of(&bytes[..n - 4]);
    bytes[n - 4..].copy_from_slice(&crc.to_le_bytes());
    assert!(matches!(
        read_tile(&bytes),
        Err(MapFileError::Malformed { at: 40, .. })
    ));
}

#[test]
fn path_index_and_trailer_read_back() {
    let poses = [
        (0.0, Pose::identity()),
        (
            0.1,
            Pose::from_parts(
                Translation3::new(1.5, -2.25, 0.125),
                UnitQuaternion::from_euler_angles(0.01, -0.02, 0.3),
            ),
        ),
    ];
    let mut out = Vec::new();
    write_path(&mut out, poses.iter().copied()).unwrap();
    assert_eq!(path_block_len(&out).unwrap(), out.len());
    assert_eq!(read_path(&out).unwrap().collect::<Vec<_>>(), poses);
    let entries = [
        IndexEntry {
            tile: CellKey::new(-1, 0, 0),
            offset: 100,
            len: 900,
        },
        IndexEntry {
            tile: CellKey::new(2, 3, -1),
            offset: 1000,
            len: 28,
        },
    ];
    let mut out = Vec::new();
    write_index(&mut out, entries.iter().copied()).unwrap();
    assert_eq!(read_index(&out).unwrap().collect::<Vec<_>>(), entries);
    out[9] ^= 4;
    assert!(matches!(
        read_index(&out),
        Err(MapFileError::Checksum { .. })
    ));
    let t = Trailer {
        index_offset: 77,
        path_offset: 55,
    };
    let mut out = Vec::new();
    assert_eq!(write_trailer(&mut out, &t).unwrap() as usize, TRAILER_BYTES);
    assert_eq!(out.len(), TRAILER_BYTES);
    assert_eq!(read_trailer(&out).unwrap(), t);
    out[3] ^= 1;
    assert!(read_trailer(&out).is_err());
}

#[test]
fn a_slice_sink_refuses_what_does_not_fit() {
    let mut buf = [0u8; 10];
    let mut s = SliceSink::new(&mut buf);
    assert!(write_trailer(
        &mut s,
        &Trailer {
            index_offset: 1,
            path_offset: 2
        }
    )
    .is_err());
    let mut buf = [0u8; TRAILER_BYTES];
    let mut s = SliceSink::new(&mut buf);
    write_trailer(
        &mut s,
        &Trailer {
            index_offset: 1,
            path_offset: 2,
        },
    )
    .unwrap();
    assert_eq!(s.written().len(), TRAILER_BYTES);
}

#[test]
fn tiles_floor_toward_negative_infinity() {
    assert_eq!(tile_of(&CellKey::new(0, 15, -1)), CellKey::new(0, 0, -1));
    assert_eq!(
        tile_of(&CellKey::new(-16, -17, 16)),
        CellKey::new(-1, -2, 1)
    );
}
