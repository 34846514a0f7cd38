//! OBJ meshes: the writer (text, 1-based indices, positions and normals).

use crate::formats::mesh_records::{MeshCounts, FACE_BYTES, VERTEX_BYTES};
use std::io::{Read, Result, Write};

/// Writes an OBJ mesh from spooled records ([`crate::outputs::mesh_spool`]): `counts.vertices`
/// vertex records (x, y, z, nx, ny, nz, variance as little-endian `f32`; the variance is not
/// written) as `v` and `vn` lines, and `counts.triangles` face records (a `u8` 3 and three
/// little-endian `u32` indices from 0) as `f` lines naming each corner's position and normal.
pub fn write_mesh_records(
    w: &mut impl Write,
    vertices: &mut impl Read,
    faces: &mut impl Read,
    counts: MeshCounts,
) -> Result<()> {
    writeln!(
        w,
        "# slamesh mesh: {} vertices, {} triangles",
        counts.vertices, counts.triangles
    )?;
    let le_f32 = |b: &[u8]| f32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    let le_u32 = |b: &[u8]| u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
    let mut rec = [0u8; VERTEX_BYTES];
    for _ in 0..counts.vertices {
        vertices.read_exact(&mut rec)?;
        let f = |k: usize| le_f32(&rec[4 * k..]);
        writeln!(w, "v {} {} {}", f(0), f(1), f(2))?;
        writeln!(w, "vn {} {} {}", f(3), f(4), f(5))?;
    }
    let mut rec = [0u8; FACE_BYTES];
    for _ in 0..counts.triangles {
        faces.read_exact(&mut rec)?;
        let i = |k: usize| le_u32(&rec[1 + 4 * k..]) as u64 + 1;
        writeln!(w, "f {0}//{0} {1}//{1} {2}//{2}", i(0), i(1), i(2))?;
    }
    Ok(())
}
