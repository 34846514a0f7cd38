//! PLY written: point clouds and the run's mesh (binary little-endian).

use crate::formats::mesh_records::{
    float, MeshCounts, VertexColour, VertexProperties, VERTEX_BYTES,
};
use crate::io::error::FileError;
use slamesh_core::Point;
use std::io::{Read, Write};
use std::path::Path;

/// Writes `points` as a binary little-endian PLY point cloud (atomically).
pub fn write_points(path: &Path, points: &[Point]) -> Result<(), FileError> {
    crate::io::atomic::write_atomic(path, |w| {
        use std::io::Write;
        write!(
            w,
            "ply\nformat binary_little_endian 1.0\ncomment slamesh points\nelement vertex {}\n\
             property float x\nproperty float y\nproperty float z\nend_header\n",
            points.len()
        )?;
        for v in points.iter().flatten() {
            w.write_all(&v.to_le_bytes())?;
        }
        Ok(())
    })
}

/// Writes a binary little-endian PLY mesh from spooled records ([`crate::outputs::mesh_spool`]):
/// `counts.vertices` vertex records (x, y, z, nx, ny, nz, variance as little-endian `f32`,
/// PLY's own binary records, copied after the header, with `red green blue` appended when
/// `colour` is given, then each of `extra`'s properties as a `float`) and `counts.triangles`
/// face records (a `u8` 3 and three little-endian `u32`).
pub fn write_mesh_records(
    w: &mut impl Write,
    vertices: &mut impl Read,
    faces: &mut impl Read,
    counts: MeshCounts,
    colour: Option<VertexColour>,
    mut extra: Option<&mut dyn VertexProperties>,
) -> std::io::Result<()> {
    let mut properties = String::new();
    if colour.is_some() {
        properties.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
    }
    let names: Vec<&str> = extra.as_ref().map_or(Vec::new(), |e| e.names().to_vec());
    for name in &names {
        properties.push_str(&format!("property float {name}\n"));
    }
    write!(
        w,
        "ply\nformat binary_little_endian 1.0\ncomment slamesh mesh\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         property float nx\nproperty float ny\nproperty float nz\n\
         property float variance\n{properties}element face {}\n\
         property list uchar uint vertex_indices\nend_header\n",
        counts.vertices, counts.triangles
    )?;
    if colour.is_none() && extra.is_none() {
        std::io::copy(&mut vertices.take(counts.vertices * VERTEX_BYTES as u64), w)?;
    } else {
        let mut rec = [0u8; VERTEX_BYTES];
        let mut values = vec![0f32; names.len()];
        for _ in 0..counts.vertices {
            vertices.read_exact(&mut rec)?;
            w.write_all(&rec)?;
            if let Some(c) = colour {
                w.write_all(&c.of(&rec))?;
            }
            if let Some(e) = extra.as_mut() {
                e.values([0, 1, 2].map(|k| float(&rec, k)), &mut values);
                for v in &values {
                    w.write_all(&v.to_le_bytes())?;
                }
            }
        }
    }
    std::io::copy(faces, w)?;
    Ok(())
}

/// Writes a binary little-endian PLY mesh: `vertices` (x, y, z as `float`), each of
/// `properties` as a named `float` vertex property (one value a vertex, in order), and
/// `triangles` (a `u8` 3 and three `u32` indices each) under the comment `comment`.
pub fn write_mesh_with_properties(
    w: &mut impl Write,
    comment: &str,
    vertices: &[Point],
    properties: &[(&str, &[f32])],
    triangles: &[[u32; 3]],
) -> std::io::Result<()> {
    write!(
        w,
        "ply\nformat binary_little_endian 1.0\ncomment {comment}\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\n",
        vertices.len()
    )?;
    for (name, _) in properties {
        writeln!(w, "property float {name}")?;
    }
    write!(
        w,
        "element face {}\nproperty list uchar uint vertex_indices\nend_header\n",
        triangles.len()
    )?;
    for (k, v) in vertices.iter().enumerate() {
        for x in v {
            w.write_all(&x.to_le_bytes())?;
        }
        for (_, values) in properties {
            w.write_all(&values.get(k).copied().unwrap_or(f32::NAN).to_le_bytes())?;
        }
    }
    for t in triangles {
        w.write_all(&[3])?;
        for i in t {
            w.write_all(&i.to_le_bytes())?;
        }
    }
    Ok(())
}
