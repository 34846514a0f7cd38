//! PLY, read and written.
//!
//! Reading: point clouds from the `x`, `y`, `z` properties of the `vertex` element, in `ascii`,
//! `binary_little_endian` or `binary_big_endian` files (any numeric property type); elements
//! before `vertex` are skipped when their records have a fixed size; meshes (vertices and
//! triangle faces) for evaluation. Errors name the file, the header line where it applies,
//! and the reason.
//!
//! Writing: point clouds ([`write_points`]) and the run's mesh from its spool
//! ([`write_mesh_records`]: binary little-endian, a per-vertex `variance`).

use crate::formats::pointcloud2;
use crate::io::error::FileError;
use slamesh_core::Point;
use std::path::Path;

mod write;
pub use write::{write_mesh_records, write_mesh_with_properties, write_points};

#[derive(Debug, Clone, Copy, PartialEq)]
enum Format {
    Ascii,
    Little,
    Big,
}

/// Byte size of a scalar PLY type.
fn type_size(t: &str) -> Option<usize> {
    Some(match t {
        "char" | "uchar" | "int8" | "uint8" => 1,
        "short" | "ushort" | "int16" | "uint16" => 2,
        "int" | "uint" | "float" | "int32" | "uint32" | "float32" => 4,
        "double" | "float64" => 8,
        _ => return None,
    })
}

/// Decodes one scalar of type `t` (already known to be valid) from `b`.
fn scalar(t: &str, b: &[u8], format: Format) -> f64 {
    let mut a = [0u8; 8];
    let n = type_size(t).unwrap_or(1);
    a[..n].copy_from_slice(&b[..n]);
    if format == Format::Big {
        a[..n].reverse();
    }
    match t {
        "char" | "int8" => a[0] as i8 as f64,
        "uchar" | "uint8" => a[0] as f64,
        "short" | "int16" => i16::from_le_bytes([a[0], a[1]]) as f64,
        "ushort" | "uint16" => u16::from_le_bytes([a[0], a[1]]) as f64,
        "int" | "int32" => i32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
        "uint" | "uint32" => u32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
        "float" | "float32" => f32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
        _ => f64::from_le_bytes(a),
    }
}

#[derive(Debug)]
struct Element {
    name: String,
    count: usize,
    /// (name, type); `None` type for a list property.
    properties: Vec<(String, Option<String>)>,
    /// (count type, item type) of each list property, by property index.
    lists: Vec<Option<(String, String)>>,
}

/// A parsed header: the format, the elements, and where the data starts.
struct Header {
    format: Format,
    elements: Vec<Element>,
    start: usize,
}

fn read_header(path: &Path, bytes: &[u8]) -> Result<Header, FileError> {
    if bytes.is_empty() {
        return Err(FileError::at(path, "empty file"));
    }
    let mut pos = 0;
    let mut line_no = 0;
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        line_no += 1;
        let Some(len) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err(FileError::at(path, "PLY header has no end_header line"));
        };
        let bad = |reason: String| FileError::new(path, Some(line_no), reason);
        let line = std::str::from_utf8(&bytes[pos..pos + len])
            .map_err(|_| bad("PLY header is not text".into()))?
            .trim();
        pos += len + 1;
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["ply"] if line_no == 1 => {}
            _ if line_no == 1 => return Err(bad("not a PLY file (no 'ply' magic)".into())),
            ["format", f, _] => {
                format = Some(match *f {
                    "ascii" => Format::Ascii,
                    "binary_little_endian" => Format::Little,
                    "binary_big_endian" => Format::Big,
                    _ => return Err(bad(format!("unknown format {f:?}"))),
                })
            }
            ["comment", ..] | ["obj_info", ..] | [] => {}
            ["element", name, count] => elements.push(Element {
                name: name.to_string(),
                count: count
                    .parse()
                    .map_err(|_| bad(format!("element {name}: not a count: {count:?}")))?,
                properties: Vec::new(),
                lists: Vec::new(),
            }),
            ["property", ..] => add_property(&mut elements, &words[1..]).map_err(bad)?,
            ["end_header"] => break,
            _ => return Err(bad(format!("not a PLY header line: {line:?}"))),
        }
    }
    let format = format.ok_or_else(|| FileError::at(path, "PLY header has no format line"))?;
    // An entry with no properties takes no data, so its count is not bounded by the file:
    // refuse it rather than make that many entries (the fuzzer's 4·10^9 empty vertices).
    if let Some(e) = elements
        .iter()
        .find(|e| e.count > 0 && e.properties.is_empty())
    {
        return Err(FileError::at(
            path,
            format!(
                "element {} has {} entries but no properties",
                e.name, e.count
            ),
        ));
    }
    Ok(Header {
        format,
        elements,
        start: pos,
    })
}

/// A `property` line's words after `property` (`list COUNT ITEM NAME` or `TYPE NAME`) as a
/// property of the last element.
fn add_property(elements: &mut [Element], words: &[&str]) -> Result<(), String> {
    let (name, scalar, list) = match words {
        ["list", count_type, item_type, name] => {
            if type_size(count_type).is_none() || type_size(item_type).is_none() {
                return Err(format!("property {name}: unknown list types"));
            }
            let list = (count_type.to_string(), item_type.to_string());
            (name, None, Some(list))
        }
        [t, name] => {
            if type_size(t).is_none() {
                return Err(format!("property {name}: unknown type {t:?}"));
            }
            (name, Some(t.to_string()), None)
        }
        _ => {
            return Err(format!(
                "not a PLY property line: property {}",
                words.join(" ")
            ))
        }
    };
    let e = elements
        .last_mut()
        .ok_or_else(|| "property before any element".to_string())?;
    e.properties.push((name.to_string(), scalar));
    e.lists.push(list);
    Ok(())
}

/// Reads the vertex positions of a PLY file.
pub fn read_ply_points(path: &Path) -> Result<Vec<Point>, FileError> {
    let bytes = std::fs::read(path).map_err(|e| FileError::at(path, e.to_string()))?;
    parse_ply_points(path, &bytes)
}

/// Parses the vertex positions of PLY bytes read from `path` (named in errors).
pub fn parse_ply_points(path: &Path, bytes: &[u8]) -> Result<Vec<Point>, FileError> {
    parse_ply_timed(path, bytes, None).map(|(p, _)| p)
}

/// Reads a PLY file's vertices and, if they have a time property (`t`, `time`, `timestamp`,
/// `time_stamp` or `offset_time`), each one's time relative to `stamp` (seconds) by the table
/// in [`crate::formats::pointcloud2`].
pub fn read_ply_timed(
    path: &Path,
    stamp: f64,
) -> Result<(Vec<Point>, Option<Vec<f32>>), FileError> {
    let bytes = std::fs::read(path).map_err(|e| FileError::at(path, e.to_string()))?;
    parse_ply_timed(path, &bytes, Some(stamp))
}

/// [`parse_ply_points`], with the vertices' times when `stamp` is given and they have a time
/// property.
pub fn parse_ply_timed(
    path: &Path,
    bytes: &[u8],
    stamp: Option<f64>,
) -> Result<(Vec<Point>, Option<Vec<f32>>), FileError> {
    let header = read_header(path, bytes)?;
    let vi = header
        .elements
        .iter()
        .position(|e| e.name == "vertex")
        .ok_or_else(|| FileError::at(path, "PLY has no vertex element"))?;
    let vertex = &header.elements[vi];
    let index = |n: &str| {
        vertex
            .properties
            .iter()
            .position(|(p, _)| p == n)
            .ok_or_else(|| FileError::at(path, format!("PLY vertex has no {n} property")))
    };
    let mut wanted = vec![index("x")?, index("y")?, index("z")?];
    let time = stamp.and_then(|stamp| {
        let k = pointcloud2::file_time_field(|n| {
            vertex
                .properties
                .iter()
                .position(|(p, t)| p == n && t.is_some())
        })?;
        wanted.push(k);
        let (name, t) = &vertex.properties[k];
        let datatype = match t.as_deref() {
            Some("float" | "float32") => pointcloud2::datatype::FLOAT32,
            Some("double" | "float64") => pointcloud2::datatype::FLOAT64,
            _ => pointcloud2::datatype::UINT32,
        };
        Some((name.as_str(), datatype, stamp))
    });
    let rows = vertex_values(path, &header, vi, &wanted, bytes)?;
    pointcloud2::file_points_and_times(&rows, time).map_err(|e| FileError::at(path, e.to_string()))
}

/// The values of vertex properties `wanted`, vertex by vertex (`wanted.len()` a vertex); the
/// first three (the coordinates) through `f32`, as they always were read.
fn vertex_values(
    path: &Path,
    header: &Header,
    vi: usize,
    wanted: &[usize],
    bytes: &[u8],
) -> Result<Vec<f64>, FileError> {
    let body = &bytes[header.start..];
    match header.format {
        Format::Ascii => ascii_vertex_values(path, &header.elements, vi, wanted, body),
        format => binary_vertex_values(path, &header.elements, vi, wanted, body, format),
    }
}

/// [`vertex_values`] of an ASCII body: a line an entry, the vertex element's after those of
/// the elements before it.
fn ascii_vertex_values(
    path: &Path,
    elements: &[Element],
    vi: usize,
    wanted: &[usize],
    body: &[u8],
) -> Result<Vec<f64>, FileError> {
    let vertex = &elements[vi];
    let text =
        std::str::from_utf8(body).map_err(|_| FileError::at(path, "ascii PLY data is not text"))?;
    let skip: usize = elements[..vi].iter().map(|e| e.count).sum();
    let mut lines = text.lines().filter(|l| !l.trim().is_empty()).skip(skip);
    // The header's count is untrusted: reserve no more than the text has lines for.
    let mut out = Vec::with_capacity(vertex.count.min(body.len() / 2) * wanted.len());
    for i in 0..vertex.count {
        let line = lines.next().ok_or_else(|| {
            FileError::at(
                path,
                format!("truncated: {} vertices declared, {i} present", vertex.count),
            )
        })?;
        let words: Vec<&str> = line.split_whitespace().collect();
        for (c, &k) in wanted.iter().enumerate() {
            let w = words.get(k).ok_or_else(|| {
                FileError::at(path, format!("vertex {i} has only {} values", words.len()))
            })?;
            let bad = |_| FileError::at(path, format!("vertex {i}: not a number: {w:?}"));
            out.push(if c < 3 {
                w.parse::<f32>().map_err(bad)? as f64
            } else {
                w.parse::<f64>().map_err(bad)?
            });
        }
    }
    Ok(out)
}

/// A fixed-size element's record size; `None` when it has a list property.
fn fixed_size(e: &Element) -> Option<usize> {
    e.properties
        .iter()
        .map(|(_, t)| t.as_deref().and_then(type_size))
        .sum()
}

/// [`vertex_values`] of a binary body: fixed-size records after those of the elements
/// before (which may not hold lists), checked to fit in the body.
fn binary_vertex_values(
    path: &Path,
    elements: &[Element],
    vi: usize,
    wanted: &[usize],
    body: &[u8],
    format: Format,
) -> Result<Vec<f64>, FileError> {
    let vertex = &elements[vi];
    let mut start = 0usize;
    for e in &elements[..vi] {
        let size = fixed_size(e).ok_or_else(|| {
            FileError::at(
                path,
                format!("element {} before vertex has a list property", e.name),
            )
        })?;
        start = start.saturating_add(size.saturating_mul(e.count));
    }
    let record = fixed_size(vertex)
        .ok_or_else(|| FileError::at(path, "vertex element has a list property"))?;
    let offsets: Vec<usize> = vertex
        .properties
        .iter()
        .scan(0, |at, (_, t)| {
            let o = *at;
            *at += t.as_deref().and_then(type_size).unwrap_or(0);
            Some(o)
        })
        .collect();
    let need = start.saturating_add(record.saturating_mul(vertex.count));
    if body.len() < need {
        return Err(FileError::at(
            path,
            format!(
                "truncated: {} vertices of {record} bytes need {need} bytes of data, found {}",
                vertex.count,
                body.len()
            ),
        ));
    }
    let offsets = &offsets;
    Ok(body[start..need]
        .chunks_exact(record.max(1))
        .flat_map(|r| {
            wanted.iter().enumerate().map(move |(c, &k)| {
                let t = vertex.properties[k].1.as_deref().unwrap_or("float");
                let v = scalar(t, &r[offsets[k]..], format);
                if c < 3 {
                    v as f32 as f64
                } else {
                    v
                }
            })
        })
        .collect())
}

/// A triangle mesh read from a PLY file.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PlyMesh {
    /// Vertex positions.
    pub vertices: Vec<Point>,
    /// Triangles as vertex indices (polygons are split into fans).
    pub triangles: Vec<[u32; 3]>,
    /// Each vertex's normal (`nx ny nz`), when the file has them (slamesh's meshes do);
    /// otherwise empty.
    pub normals: Vec<[f32; 3]>,
    /// Each vertex's variance (`variance`), when the file has it; otherwise empty.
    pub variances: Vec<f32>,
}

impl PlyMesh {
    /// The triangles as their corner positions.
    pub fn triangle_corners(&self) -> impl Iterator<Item = [Point; 3]> + Clone + '_ {
        self.triangles
            .iter()
            .map(|t| t.map(|i| self.vertices[i as usize]))
    }
}

/// Reads the vertices and faces (`vertex_indices` or `vertex_index`) of a PLY mesh, in any of
/// the three formats, with the vertices' normals and variances when it has them all. Faces
/// referring to missing vertices are an error.
pub fn read_ply_mesh(path: &Path) -> Result<PlyMesh, FileError> {
    let bytes = std::fs::read(path).map_err(|e| FileError::at(path, e.to_string()))?;
    parse_ply_mesh(path, &bytes)
}

/// Parses PLY mesh bytes read from `path` (named in errors).
pub fn parse_ply_mesh(path: &Path, bytes: &[u8]) -> Result<PlyMesh, FileError> {
    let h = read_header(path, bytes)?;
    let body = &bytes[h.start..];
    let mut mesh = PlyMesh::default();
    let truncated = || {
        FileError::at(
            path,
            "truncated: the data ends before the header's elements",
        )
    };
    // A reader of scalars over the body: binary by offset, ascii by word.
    let words: Vec<&str> = if h.format == Format::Ascii {
        std::str::from_utf8(body)
            .map_err(|_| FileError::at(path, "ascii PLY data is not text"))?
            .split_whitespace()
            .collect()
    } else {
        Vec::new()
    };
    let (mut at, mut word) = (0usize, 0usize);
    let mut next = |t: &str| -> Option<f64> {
        if h.format == Format::Ascii {
            let w = words.get(word)?;
            word += 1;
            w.parse().ok()
        } else {
            let n = type_size(t)?;
            let b = body.get(at..at + n)?;
            at += n;
            Some(scalar(t, b, h.format))
        }
    };
    for e in &h.elements {
        let at = |n: &str| e.properties.iter().position(|(p, _)| p == n);
        let xyz = ["x", "y", "z"].map(at);
        let normal = ["nx", "ny", "nz"].map(at);
        let (has_normal, variance) = (normal.iter().all(Option::is_some), at("variance"));
        let face = e
            .properties
            .iter()
            .position(|(p, _)| p == "vertex_indices" || p == "vertex_index");
        for _ in 0..e.count {
            let (mut p, mut n, mut var) = ([0f32; 3], [0f32; 3], 0f32);
            for (k, ((_, t), list)) in e.properties.iter().zip(&e.lists).enumerate() {
                match (t, list) {
                    (Some(t), _) => {
                        let v = next(t).ok_or_else(truncated)?;
                        if let Some(c) = xyz.iter().position(|&i| i == Some(k)) {
                            p[c] = v as f32;
                        } else if let Some(c) = normal.iter().position(|&i| i == Some(k)) {
                            n[c] = v as f32;
                        } else if variance == Some(k) {
                            var = v as f32;
                        }
                    }
                    (None, Some((ct, it))) => {
                        let corners = read_list(&mut next, ct, it, path)?;
                        if Some(k) == face {
                            for w in corners.windows(2).skip(1) {
                                mesh.triangles.push([corners[0], w[0], w[1]]);
                            }
                        }
                    }
                    (None, None) => return Err(truncated()),
                }
            }
            if e.name == "vertex" {
                mesh.vertices.push(p);
                if has_normal {
                    mesh.normals.push(n);
                }
                if variance.is_some() {
                    mesh.variances.push(var);
                }
            }
        }
    }
    checked(path, mesh)
}

/// A list property's values (a face's corners) through `next` (a scalar of the given type at
/// a time): its count as `ct`, each value as `it`; a count over a million is refused.
fn read_list(
    next: &mut impl FnMut(&str) -> Option<f64>,
    ct: &str,
    it: &str,
    path: &Path,
) -> Result<Vec<u32>, FileError> {
    let truncated = || {
        FileError::at(
            path,
            "truncated: the data ends before the header's elements",
        )
    };
    let count = next(ct).ok_or_else(truncated)?;
    if !(0.0..=1e6).contains(&count) {
        return Err(FileError::at(path, format!("a face with {count} corners")));
    }
    let mut corners = Vec::with_capacity(count as usize);
    for _ in 0..count as usize {
        corners.push(next(it).ok_or_else(truncated)? as u32);
    }
    Ok(corners)
}

/// The mesh read, its normals and variances kept only when every vertex has them, refused when
/// a face refers to a vertex it does not have.
fn checked(path: &Path, mut mesh: PlyMesh) -> Result<PlyMesh, FileError> {
    if mesh.normals.len() != mesh.vertices.len() {
        mesh.normals.clear();
    }
    if mesh.variances.len() != mesh.vertices.len() {
        mesh.variances.clear();
    }
    let n = mesh.vertices.len() as u32;
    if let Some(t) = mesh.triangles.iter().find(|t| t.iter().any(|&i| i >= n)) {
        return Err(FileError::at(
            path,
            format!("a face refers to vertex {:?} of {n}", t),
        ));
    }
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_element_with_entries_but_no_properties_is_refused() {
        // Found by the fuzzer: 4 111 111 111 property-less vertices ran out of memory.
        let bytes = b"ply\nformat ascii 1\nelement vertex 4111111111\nend_header\n2\n";
        for e in [
            parse_ply_mesh(Path::new("m.ply"), bytes).unwrap_err(),
            parse_ply_points(Path::new("m.ply"), bytes).unwrap_err(),
        ] {
            assert!(e.to_string().contains("no properties"), "{e}");
        }
    }

    fn tmp(name: &str, bytes: &[u8]) -> crate::test_support::ScratchFile {
        crate::test_support::scratch_file("ply", name, bytes)
    }

    #[test]
    fn ascii_little_and_big_endian_files_read_the_same_points() {
        let ascii = b"ply\nformat ascii 1.0\ncomment hi\nelement vertex 2\nproperty float x\n\
property float y\nproperty float z\nproperty uchar red\nend_header\n1 2 3 255\n-4.5 0 6 0\n";
        let want = vec![[1.0, 2.0, 3.0], [-4.5, 0.0, 6.0]];
        assert_eq!(read_ply_points(&tmp("a.ply", ascii)).unwrap(), want);
        let dir = crate::test_support::scratch_dir("ply-written");
        let written = dir.join("w.ply");
        write_points(&written, &want).unwrap();
        assert_eq!(read_ply_points(&written).unwrap(), want);
        for (name, big) in [("little", false), ("big", true)] {
            let mut b = format!(
                "ply\nformat binary_{name}_endian 1.0\nelement vertex 2\nproperty double x\n\
property float y\nproperty float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n"
            )
            .into_bytes();
            for p in &want {
                let x = p[0] as f64;
                b.extend(if big {
                    x.to_be_bytes()
                } else {
                    x.to_le_bytes()
                });
                for v in &p[1..] {
                    b.extend(if big {
                        v.to_be_bytes()
                    } else {
                        v.to_le_bytes()
                    });
                }
            }
            assert_eq!(
                read_ply_points(&tmp(&format!("{name}.ply"), &b)).unwrap(),
                want
            );
        }
    }

    #[test]
    fn a_time_property_gives_each_vertexs_time() {
        let ascii = b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n\
                      property float y\nproperty float z\nproperty float time\nend_header\n\
                      1 2 3 -0.05\n4 5 6 0.05\n";
        let (p, t) = parse_ply_timed(Path::new("a.ply"), ascii, Some(3.0)).unwrap();
        assert_eq!(p, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        assert_eq!(
            t,
            Some(vec![-0.05, 0.05]),
            "Velodyne's time: seconds from the stamp"
        );
        let mut binary = b"ply\nformat binary_big_endian 1.0\nelement vertex 1\n\
                           property uint t\nproperty float x\nproperty float y\n\
                           property float z\nend_header\n"
            .to_vec();
        binary.extend(20_000_000u32.to_be_bytes());
        for v in [1.0f32, 2.0, 3.0] {
            binary.extend(v.to_be_bytes());
        }
        let (p, t) = parse_ply_timed(Path::new("b.ply"), &binary, Some(3.0)).unwrap();
        assert_eq!((p, t), (vec![[1.0, 2.0, 3.0]], Some(vec![0.02])));
        assert_eq!(
            parse_ply_timed(Path::new("a.ply"), ascii, None).unwrap().1,
            None
        );
    }

    #[test]
    fn a_meshs_normals_and_variances_are_read_when_every_vertex_has_them() {
        let with = b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
property float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
property float variance\nelement face 1\nproperty list uchar uint vertex_indices\nend_header\n\
0 0 0 0 0 1 0.01\n1 0 0 0 0 1 0.02\n0 1 0 0 1 0 0.03\n3 0 1 2\n";
        let m = parse_ply_mesh(Path::new("n.ply"), with).unwrap();
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
        assert_eq!(
            m.normals,
            vec![[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]
        );
        assert_eq!(m.variances, vec![0.01, 0.02, 0.03]);
        // A second vertex element without them: no vertex's normal is known for sure.
        let mixed =
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
property float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
element vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n\
0 0 0 0 0 1\n1 1 1\n";
        let m = parse_ply_mesh(Path::new("m.ply"), mixed).unwrap();
        assert_eq!(m.vertices.len(), 2);
        assert!(m.normals.is_empty() && m.variances.is_empty());
    }

    #[test]
    fn bad_files_are_errors_naming_the_file_and_reason() {
        let cases: [(&str, &[u8], &str); 4] = [
            ("empty.ply", b"", "empty"),
            ("magic.ply", b"plx\nend_header\n", "not a PLY"),
            ("noxyz.ply", b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float a\nend_header\n1\n", "no x"),
            ("short.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 9\nproperty float x\nproperty float y\nproperty float z\nend_header\n\0\0\0\0", "truncated"),
        ];
        for (name, bytes, reason) in cases {
            let e = read_ply_points(&tmp(name, bytes)).unwrap_err();
            assert!(
                e.to_string().contains(name) && e.reason.contains(reason),
                "{e}"
            );
        }
    }
}
