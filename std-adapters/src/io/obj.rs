//! OBJ meshes: the writer (text, 1-based indices, positions only).

use crate::io::mesh_spool::{FACE_BYTES, VERTEX_BYTES};
use std::io::{Read, Result, Write};

/// Writes an OBJ mesh from spooled records ([`crate::io::mesh_spool`]): `vertex_count`
/// vertex records (x, y, z, variance as little-endian `f32`; the variance is not written) and
/// `triangle_count` face records (a `u8` 3 and three little-endian `u32` indices from 0).
pub fn write_mesh_records(
    w: &mut impl Write,
    vertices: &mut impl Read,
    faces: &mut impl Read,
    vertex_count: u64,
    triangle_count: u64,
) -> Result<()> {
    writeln!(
        w,
        "# slamesh mesh: {vertex_count} vertices, {triangle_count} triangles"
    )?;
    let le_f32 = |b: &[u8]| f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    let le_u32 = |b: &[u8]| u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    let mut rec = [0u8; VERTEX_BYTES];
    for _ in 0..vertex_count {
        vertices.read_exact(&mut rec)?;
        writeln!(
            w,
            "v {} {} {}",
            le_f32(&rec[0..]),
            le_f32(&rec[4..]),
            le_f32(&rec[8..])
        )?;
    }
    let mut rec = [0u8; FACE_BYTES];
    for _ in 0..triangle_count {
        faces.read_exact(&mut rec)?;
        let i = |k: usize| le_u32(&rec[1 + 4 * k..]) as u64 + 1;
        writeln!(w, "f {} {} {}", i(0), i(1), i(2))?;
    }
    Ok(())
}
