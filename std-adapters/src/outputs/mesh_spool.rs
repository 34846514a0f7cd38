//! The mesh on its way to disk.
//!
//! A [`MeshSpool`] collects sets of layers as they come (the cells one eviction of a
//! sliding-window map removes, then the map at the end) into spool files next to the output,
//! so that memory stays flat however long the run; [`MeshSpool::finish`] writes the final
//! files atomically. Each set is welded ([`crate::outputs::mesh_weld`]) with its neighbours in
//! the other sets of the same call: the vertices neighbouring cells share are merged, across
//! sets too, and every vertex has a normal. Vertices of layers added by different calls are
//! not merged (a seam where an eviction cut the map).
//!
//! A face may use a vertex of an earlier set; the spool keeps that vertex's position once
//! more, in face order, so that [`MeshSpool::for_each_triangle`] reads one set at a time.

use crate::formats::mesh_records::{float, VertexProperties};
pub use crate::formats::mesh_records::{MeshCounts, VertexColour, FACE_BYTES, VERTEX_BYTES};
use crate::io::atomic::write_atomic;
use crate::io::error::FileError;
use crate::outputs::mesh_weld::{weld_set, Neighbour, SeamLinks, WeldedMesh};
use files::{imports_within, read_sets, sets_within, spool_paths};
use slamesh_core::cell::{Axis, CellKey};
use slamesh_core::config::MeshConfig;
use slamesh_core::lattice::Lattice;
use slamesh_core::layer::Shown;
use slamesh_core::map::{LayerRef, MeshMap};
use slamesh_core::Point;
use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

mod files;

/// Bytes of an imported position: x, y, z as little-endian `f32`.
const IMPORT_BYTES: usize = 12;
/// Bytes of a spooled set's end: vertices and faces spooled up to its end, as `u64`.
const SET_BYTES: usize = 16;

/// The most layers welded together by default ([`MeshSpool::set_layers`] sets another), so
/// that what welding holds at once does not grow with the map (welding the whole map of
/// `tests/memory.rs` at once took it 13 MB over its cap), and at most `SET_LAYERS × 36` vertex
/// positions for [`MeshSpool::for_each_triangle`].
pub const SET_LAYERS: usize = 1024;

/// The Z-order (Morton) code of a cell: the bits of its three indices (their low 21, offset
/// to be non-negative) interleaved, so that cells close in space are mostly close in order.
fn z_order(key: &CellKey) -> u64 {
    let spread = |v: i32| {
        let mut x = u64::from((v as u32).wrapping_add(1 << 20) & 0x1f_ffff);
        x = (x | x << 32) & 0x1f_0000_0000_ffff;
        x = (x | x << 16) & 0x1f_0000_ff00_00ff;
        x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
        x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
        (x | x << 2) & 0x1249_2492_4924_9249
    };
    spread(key.x) | spread(key.y) << 1 | spread(key.z) << 2
}

/// Where the set starting at `start` of `layers` (sorted by Z-order code) ends: within
/// `most` layers, at the boundary between the largest aligned blocks of cells, so that the
/// seams between sets are few and straight (two codes first differ in a high bit where
/// large blocks meet).
fn set_end(layers: &[(u64, LayerRef<'_>)], start: usize, most: usize) -> usize {
    let last = layers.len().min(start + most.max(1));
    if last == layers.len() {
        return last;
    }
    (start + 1..=last)
        .max_by_key(|&e| {
            let split = layers[e - 1].0 ^ layers[e].0;
            (64 - split.leading_zeros(), e)
        })
        .unwrap_or(last)
}

/// Mesh file formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeshFormat {
    /// Binary little-endian PLY with per-vertex normals and variance (and colour, if asked).
    Ply,
    /// Wavefront OBJ (positions, normals and faces; OBJ has no per-vertex scalar).
    Obj,
}

impl MeshFormat {
    /// The file a run writes in this format: `mesh.ply` or `mesh.obj`.
    pub fn file_name(self) -> &'static str {
        match self {
            MeshFormat::Ply => "mesh.ply",
            MeshFormat::Obj => "mesh.obj",
        }
    }
}

/// What colours a PLY mesh's vertices (`red green blue`), on the blue-green-yellow-red ramp.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum MeshColour {
    /// No colour properties.
    #[default]
    None,
    /// Height: from the lowest vertex (blue) to the highest (red).
    Height,
    /// Variance: from 0 (blue) to the largest a shown triangle may have (red).
    Variance,
}

/// Mesh pieces spooled to disk until [`finish`](Self::finish).
#[derive(Debug)]
pub struct MeshSpool {
    lattice: Lattice,
    shown: Shown,
    variance_show: f32,
    colour: MeshColour,
    paths: [PathBuf; 4],
    vertices: BufWriter<File>,
    faces: BufWriter<File>,
    sets: BufWriter<File>,
    /// Positions of earlier sets' vertices that faces use (x, y, z as `f32`), in face order.
    imports: BufWriter<File>,
    counts: MeshCounts,
    merged: u64,
    /// The lowest and highest vertex `z` spooled (infinite for none), kept as vertices come.
    z_range: (f32, f32),
    /// The most layers welded together ([`SET_LAYERS`] unless set).
    set_layers: usize,
}

impl MeshSpool {
    /// A spool for the mesh file `target` (its spool files go beside it).
    pub fn new(target: &Path, lattice: Lattice, shown: &MeshConfig) -> Result<Self, FileError> {
        Self::open(target, lattice, shown, None)
    }

    /// The spool of an interrupted run, cut back to the first `kept` records (what a
    /// checkpoint counted; later records belong to frames that will be redone).
    pub fn resume(
        target: &Path,
        lattice: Lattice,
        shown: &MeshConfig,
        kept: MeshCounts,
    ) -> Result<Self, FileError> {
        Self::open(target, lattice, shown, Some(kept))
    }

    fn open(
        target: &Path,
        lattice: Lattice,
        shown: &MeshConfig,
        kept: Option<MeshCounts>,
    ) -> Result<Self, FileError> {
        let paths = spool_paths(target);
        let open = |p: &Path, keep_bytes: Option<u64>| {
            let file = match keep_bytes {
                None => File::create(p)
                    .map_err(|e| FileError::at(p, format!("cannot create spool file: {e}")))?,
                Some(bytes) => crate::io::atomic::open_cut(p, bytes)?,
            };
            Ok::<_, FileError>(BufWriter::new(file))
        };
        let (kept_sets, kept_imports) = match kept {
            Some(k) => {
                let sets = read_sets(&paths[2])?;
                (
                    Some(sets_within(&sets, k)),
                    Some(imports_within(&paths[1], &sets, k)?),
                )
            }
            None => (None, None),
        };
        let mut spool = MeshSpool {
            lattice,
            shown: Shown::new(shown),
            variance_show: shown.variance_show as f32,
            colour: MeshColour::None,
            vertices: open(&paths[0], kept.map(|k| k.vertices * VERTEX_BYTES as u64))?,
            faces: open(&paths[1], kept.map(|k| k.triangles * FACE_BYTES as u64))?,
            sets: open(&paths[2], kept_sets.map(|(n, _)| n * SET_BYTES as u64))?,
            imports: open(&paths[3], kept_imports.map(|n| n * IMPORT_BYTES as u64))?,
            paths,
            counts: kept.unwrap_or_default(),
            merged: 0,
            z_range: (f32::INFINITY, f32::NEG_INFINITY),
            set_layers: SET_LAYERS,
        };
        if kept.is_some() {
            spool.z_range = spool.read_z_range()?;
        }
        // Records after the last whole set (a damaged spool) become a set of their own.
        if let (Some(k), Some((_, end))) = (kept, kept_sets) {
            if end != k {
                spool.end_set()?;
            }
        }
        Ok(spool)
    }

    /// Gives the spool files the names a spool for `target` has (those of another spool
    /// for it are replaced): a spool made elsewhere takes the place of `target`'s, as a
    /// rebuild's does when loop closure corrects a windowed run
    /// ([`crate::loop_closure::streaming`]), and resumes as it would.
    pub fn move_to(&mut self, target: &Path) -> Result<(), FileError> {
        self.flush()?;
        let to = spool_paths(target);
        for (from, to) in self.paths.iter_mut().zip(to) {
            std::fs::rename(&*from, &to)
                .map_err(|e| FileError::at(&to, format!("cannot move the spool file: {e}")))?;
            *from = to;
        }
        Ok(())
    }

    /// Colours the PLY output's vertices (none unless asked).
    pub fn colour_by(&mut self, colour: MeshColour) {
        self.colour = colour;
    }

    /// Writes what is buffered to the spool files (before a checkpoint counts them).
    pub fn flush(&mut self) -> Result<(), FileError> {
        for (w, p) in [
            (&mut self.vertices, &self.paths[0]),
            (&mut self.faces, &self.paths[1]),
            (&mut self.sets, &self.paths[2]),
            (&mut self.imports, &self.paths[3]),
        ] {
            w.flush()
                .map_err(|e| FileError::at(p, format!("cannot write: {e}")))?;
        }
        Ok(())
    }

    /// What has been added so far.
    pub fn counts(&self) -> MeshCounts {
        self.counts
    }

    /// Vertices merged into a neighbour's by welding, since this spool was opened.
    pub fn merged(&self) -> u64 {
        self.merged
    }

    /// Adds the shown triangles of `layers` with the vertices they use, welded in sets of at
    /// most [`SET_LAYERS`] layers: in Z-order of their cells (nearby cells together), cut
    /// where the largest aligned blocks of cells meet, so that welding holds a bounded
    /// amount at once. Each set is welded with the layers of the other sets next to it, so
    /// that the vertices on a cut are merged too.
    pub fn add_layers<'a>(
        &mut self,
        layers: impl IntoIterator<Item = LayerRef<'a>>,
    ) -> Result<(), FileError> {
        let mut layers: Vec<(u64, LayerRef<'a>)> =
            layers.into_iter().map(|l| (z_order(&l.key), l)).collect();
        layers.sort_by_key(|(code, l)| (*code, l.key, l.axis));
        let mut links = SeamLinks::default();
        let mut start = 0;
        while start < layers.len() {
            let end = set_end(&layers, start, self.set_layers);
            let set = layers[start..end].iter().map(|(_, l)| *l);
            let neighbours = neighbours(&layers, start..end);
            let first = u32::try_from(self.counts.vertices).unwrap_or(u32::MAX);
            let mesh = weld_set(
                set,
                &neighbours,
                &mut links,
                first,
                &self.lattice,
                self.shown,
            );
            self.add_mesh(&mesh)?;
            start = end;
        }
        Ok(())
    }

    /// Welds at most `layers` layers together from now on (at least one): fewer hold less
    /// memory at once and leave more seams between sets.
    pub fn set_layers(&mut self, layers: usize) {
        self.set_layers = layers.max(1);
    }

    /// Adds every layer of `map`.
    pub fn add_map(&mut self, map: &MeshMap) -> Result<(), FileError> {
        self.add_layers(map.layers())
    }

    fn add_mesh(&mut self, mesh: &WeldedMesh) -> Result<(), FileError> {
        if mesh.triangles.is_empty() {
            return Ok(());
        }
        let io = |e: std::io::Error, p: &Path| FileError::at(p, format!("cannot write: {e}"));
        for v in &mesh.vertices {
            let mut rec = [0u8; VERTEX_BYTES];
            let floats = [
                v.position[0],
                v.position[1],
                v.position[2],
                v.normal[0],
                v.normal[1],
                v.normal[2],
                v.variance,
            ];
            for (c, x) in floats.iter().enumerate() {
                rec[4 * c..4 * c + 4].copy_from_slice(&x.to_le_bytes());
            }
            self.vertices
                .write_all(&rec)
                .map_err(|e| io(e, &self.paths[0]))?;
        }
        for t in &mesh.triangles {
            let mut face = [0u8; FACE_BYTES];
            face[0] = 3;
            for (k, &i) in t.iter().enumerate() {
                face[1 + 4 * k..5 + 4 * k].copy_from_slice(&i.to_le_bytes());
            }
            self.faces
                .write_all(&face)
                .map_err(|e| io(e, &self.paths[1]))?;
        }
        for p in &mesh.imported {
            let mut rec = [0u8; IMPORT_BYTES];
            for (c, x) in p.iter().enumerate() {
                rec[4 * c..4 * c + 4].copy_from_slice(&x.to_le_bytes());
            }
            self.imports
                .write_all(&rec)
                .map_err(|e| io(e, &self.paths[3]))?;
        }
        self.counts.vertices += mesh.vertices.len() as u64;
        self.counts.triangles += mesh.triangles.len() as u64;
        self.merged += mesh.merged;
        for v in &mesh.vertices {
            let z = v.position[2];
            self.z_range = (self.z_range.0.min(z), self.z_range.1.max(z));
        }
        self.end_set()
    }

    fn end_set(&mut self) -> Result<(), FileError> {
        let mut rec = [0u8; SET_BYTES];
        rec[..8].copy_from_slice(&self.counts.vertices.to_le_bytes());
        rec[8..].copy_from_slice(&self.counts.triangles.to_le_bytes());
        self.sets
            .write_all(&rec)
            .map_err(|e| FileError::at(&self.paths[2], format!("cannot write: {e}")))
    }

    /// The lowest and highest heights of the mesh's vertices so far (metres).
    pub fn z_range(&self) -> (f32, f32) {
        self.z_range
    }

    /// Calls `each` with every triangle added so far, as its three corners and their
    /// Gaussian-process variances (NaN for a corner welded in from an earlier set: the import
    /// records keep positions only), in the order they were added. Reads the spool files
    /// (flushed first) one welded set at a time: memory holds one set's vertex positions,
    /// never the whole mesh.
    pub fn for_each_triangle(
        &mut self,
        mut each: impl FnMut([Point; 3], [f32; 3]),
    ) -> Result<(), FileError> {
        self.flush()?;
        let io = |e: std::io::Error, p: &Path| FileError::at(p, format!("cannot read: {e}"));
        let read_vertex = |r: &mut BufReader<File>| -> std::io::Result<(Point, f32)> {
            let mut rec = [0u8; VERTEX_BYTES];
            r.read_exact(&mut rec)?;
            Ok((
                [float(&rec, 0), float(&rec, 1), float(&rec, 2)],
                float(&rec, 6),
            ))
        };
        let open = |p: &Path| File::open(p).map(BufReader::new).map_err(|e| io(e, p));
        let sets = read_sets(&self.paths[2])?;
        let mut vertices = open(&self.paths[0])?;
        let mut faces = open(&self.paths[1])?;
        let mut imports = open(&self.paths[3])?;
        let mut window: Vec<(Point, f32)> = Vec::new();
        let mut done = MeshCounts::default();
        for end in sets {
            window.clear();
            for _ in done.vertices..end.vertices {
                window.push(read_vertex(&mut vertices).map_err(|e| io(e, &self.paths[0]))?);
            }
            for _ in done.triangles..end.triangles {
                let mut rec = [0u8; FACE_BYTES];
                faces
                    .read_exact(&mut rec)
                    .map_err(|e| io(e, &self.paths[1]))?;
                let mut corners = [([0f32; 3], f32::NAN); 3];
                for (c, index) in corners.iter_mut().zip(face_indices(&rec)) {
                    *c = if index < done.vertices {
                        let mut rec = [0u8; IMPORT_BYTES];
                        imports
                            .read_exact(&mut rec)
                            .map_err(|e| io(e, &self.paths[3]))?;
                        ([float(&rec, 0), float(&rec, 1), float(&rec, 2)], f32::NAN)
                    } else {
                        window
                            .get((index - done.vertices) as usize)
                            .copied()
                            .ok_or_else(|| {
                                FileError::at(&self.paths[1], "a face refers to a later vertex")
                            })?
                    };
                }
                each(corners.map(|c| c.0), corners.map(|c| c.1));
            }
            done = end;
        }
        Ok(())
    }

    /// The lowest and highest vertex `z` in the spool file (infinite for none): read once,
    /// when a resumed run reopens it.
    fn read_z_range(&mut self) -> Result<(f32, f32), FileError> {
        self.flush()?;
        let p = &self.paths[0];
        let mut r = BufReader::new(
            File::open(p).map_err(|e| FileError::at(p, format!("cannot read: {e}")))?,
        );
        let mut range = (f32::INFINITY, f32::NEG_INFINITY);
        let mut rec = [0u8; VERTEX_BYTES];
        for _ in 0..self.counts.vertices {
            r.read_exact(&mut rec)
                .map_err(|e| FileError::at(p, format!("cannot read: {e}")))?;
            let z = float(&rec, 2);
            range = (range.0.min(z), range.1.max(z));
        }
        Ok(range)
    }

    /// Writes everything added to each `(path, format)` (atomically) and removes the spool.
    pub fn finish(self, outputs: &[(PathBuf, MeshFormat)]) -> Result<MeshCounts, FileError> {
        self.finish_with(outputs, None)
    }

    /// [`finish`](Self::finish), with `extra`'s properties on every vertex of the PLY files.
    pub fn finish_with(
        mut self,
        outputs: &[(PathBuf, MeshFormat)],
        mut extra: Option<&mut dyn VertexProperties>,
    ) -> Result<MeshCounts, FileError> {
        self.flush()?;
        let colour = match self.colour {
            MeshColour::None => None,
            MeshColour::Height => {
                let (low, high) = self.z_range;
                Some(VertexColour {
                    field: 2,
                    low,
                    high,
                })
            }
            MeshColour::Variance => Some(VertexColour {
                field: 6,
                low: 0.0,
                high: self.variance_show,
            }),
        };
        for (target, format) in outputs {
            let extra = extra
                .as_mut()
                .map(|e| &mut **e as &mut dyn VertexProperties);
            self.write(target, *format, colour, extra)?;
        }
        Ok(self.counts)
    }

    fn write(
        &self,
        target: &Path,
        format: MeshFormat,
        colour: Option<VertexColour>,
        mut extra: Option<&mut dyn VertexProperties>,
    ) -> Result<(), FileError> {
        let counts = self.counts;
        let paths = &self.paths;
        write_atomic(target, |w| {
            let mut vertices = BufReader::new(File::open(&paths[0])?);
            let mut faces = BufReader::new(File::open(&paths[1])?);
            match format {
                MeshFormat::Ply => crate::formats::ply::write_mesh_records(
                    w,
                    &mut vertices,
                    &mut faces,
                    counts,
                    colour,
                    extra
                        .as_mut()
                        .map(|e| &mut **e as &mut dyn VertexProperties),
                ),
                MeshFormat::Obj => {
                    crate::formats::obj::write_mesh_records(w, &mut vertices, &mut faces, counts)
                }
            }
        })
    }
}

/// The three vertex indices of a spooled face.
fn face_indices(rec: &[u8; FACE_BYTES]) -> [u64; 3] {
    [0, 1, 2].map(|k| {
        let b = |i: usize| rec[1 + 4 * k + i];
        u64::from(u32::from_le_bytes([b(0), b(1), b(2), b(3)]))
    })
}

/// The layers next to `layers[set]` (same axis, cells that touch) outside it, each with
/// whether it comes after the set; `layers` sorted by their cells' Z-order codes.
fn neighbours<'a>(
    layers: &[(u64, LayerRef<'a>)],
    set: std::ops::Range<usize>,
) -> Vec<Neighbour<'a>> {
    let mut found: Vec<usize> = Vec::new();
    for (_, l) in &layers[set.clone()] {
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(key) = l
                        .key
                        .offset(Axis::X, dx)
                        .and_then(|k| k.offset(Axis::Y, dy))
                        .and_then(|k| k.offset(Axis::Z, dz))
                    else {
                        continue;
                    };
                    let code = z_order(&key);
                    let from = layers.partition_point(|(c, _)| *c < code);
                    found.extend(
                        (from..layers.len())
                            .take_while(|&i| layers[i].0 == code)
                            .filter(|&i| {
                                let n = &layers[i].1;
                                n.key == key && n.axis == l.axis && !set.contains(&i)
                            }),
                    );
                }
            }
        }
    }
    found.sort_unstable();
    found.dedup();
    found
        .into_iter()
        .map(|i| Neighbour {
            layer: layers[i].1,
            later: i >= set.end,
        })
        .collect()
}

impl Drop for MeshSpool {
    fn drop(&mut self) {
        for p in &self.paths {
            let _ = std::fs::remove_file(p);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::eval::topology::Topology;
    use crate::formats::ply::{read_ply_mesh, read_ply_points};
    use crate::outputs::mesh_weld::weld;
    use slamesh_core::cell::{Axis, CellKey};
    use slamesh_core::facing::Facing;
    use slamesh_core::lattice::VERTICES;
    use slamesh_core::layer::Layer;

    /// Twelve layers of every axis at varied heights, some vertices too uncertain to show.
    fn varied_map(lattice: Lattice) -> MeshMap {
        let mut map = MeshMap::with_capacity(64, 64, lattice);
        let mut k = 0u32;
        for x in 0..4 {
            for (y, axis) in [(0, Axis::Z), (1, Axis::X), (2, Axis::Y)] {
                let mut layer = Layer {
                    pred: [0.0; VERTICES],
                    var: [0.01; VERTICES],
                    facing: Facing::Unknown,
                };
                for (j, p) in layer.pred.iter_mut().enumerate() {
                    *p = 0.2 + 0.01 * ((j as u32 * 7 + k) % 13) as f32;
                }
                // Some vertices too uncertain to show: layers with fewer triangles.
                layer.var[(k as usize * 5) % VERTICES] = 0.9;
                map.insert_layer(CellKey::new(x, y, -1), axis, layer, 0)
                    .unwrap();
                k += 1;
            }
        }
        map
    }

    /// Streaming the spool gives the map's triangles, corner for corner and in order, over
    /// many layers of different axes and heights (each layer's faces reuse earlier vertices
    /// of that layer only), each corner with its vertex's variance.
    #[test]
    fn the_spooled_triangles_stream_back_as_the_map_has_them() {
        let lattice = Lattice {
            cell_size: 1.6,
            full_cover: true,
        };
        let map = varied_map(lattice);
        let cfg = MeshConfig {
            variance_show: 0.3,
            max_slope_deg: 90.0,
        };
        let dir = crate::test_support::scratch_dir("mesh-stream");
        let mut spool = MeshSpool::new(&dir.join("m.ply"), lattice, &cfg).unwrap();
        // Two sets: the first four cells' layers, then the rest.
        let layers: Vec<LayerRef<'_>> = map.layers().collect();
        let (first, second) = layers.split_at(4);
        spool.add_layers(first.iter().copied()).unwrap();
        spool.add_layers(second.iter().copied()).unwrap();
        let mut streamed = Vec::new();
        let mut variances = Vec::new();
        spool
            .for_each_triangle(|t, v| {
                streamed.push(t);
                variances.push(v);
            })
            .unwrap();
        let shown = Shown::new(&cfg);
        let mut expected: Vec<[Point; 3]> = Vec::new();
        let mut variance_at = std::collections::HashMap::new();
        for set in [first, second] {
            let m = weld(set.iter().copied(), &lattice, shown);
            expected.extend(
                m.triangles
                    .iter()
                    .map(|t| t.map(|i| m.vertices[i as usize].position)),
            );
            for v in &m.vertices {
                variance_at.insert(v.position.map(f32::to_bits), v.variance);
            }
        }
        assert!(expected.len() > 400, "{} triangles", expected.len());
        // The spool welds each set in Z-order of its cells: the same triangles, in another
        // order.
        let sorted = |mut v: Vec<[Point; 3]>| {
            v.sort_by_key(|t| t.map(|p| p.map(f32::to_bits)));
            v
        };
        assert_eq!(streamed.len(), expected.len());
        // Each corner's variance is its vertex's, but for the corners the second set welded in
        // from the first (NaN), which are few.
        let corners = streamed.iter().flatten().zip(variances.iter().flatten());
        let known = corners.clone().filter(|(_, v)| !v.is_nan()).count();
        assert!(known * 10 > 9 * 3 * streamed.len(), "{known}");
        for (p, v) in corners.filter(|(_, v)| !v.is_nan()) {
            assert_eq!(variance_at[&p.map(f32::to_bits)], *v);
        }
        assert!(sorted(streamed) == sorted(expected.clone()));
        // Resumed at the end of the first set, the spool streams the first set alone.
        let kept = {
            let m = weld(first.iter().copied(), &lattice, shown);
            MeshCounts {
                vertices: m.vertices.len() as u64,
                triangles: m.triangles.len() as u64,
            }
        };
        // A killed run leaves its spool files behind.
        std::mem::forget(spool);
        let mut resumed = MeshSpool::resume(&dir.join("m.ply"), lattice, &cfg, kept).unwrap();
        let mut again = 0;
        resumed.for_each_triangle(|_, _| again += 1).unwrap();
        assert_eq!(again as u64, kept.triangles);
        drop(resumed);
    }

    /// Welded in sets of two layers, a 3 x 3 floor of cells is the mesh one set makes: one
    /// piece, the same vertices and triangles; faces that use an earlier set's vertex draw
    /// it from the imported positions, also after a resume.
    #[test]
    fn the_sets_of_one_call_are_welded_across_their_cuts() {
        let lattice = Lattice {
            cell_size: 1.0,
            full_cover: true,
        };
        let mut map = MeshMap::with_capacity(16, 16, lattice);
        for x in 0..3 {
            for y in 0..3 {
                let h = 0.5 + 0.01 * (x + y) as f32;
                let layer = Layer {
                    pred: [h; VERTICES],
                    var: [0.01; VERTICES],
                    facing: Facing::Unknown,
                };
                map.insert_layer(CellKey::new(x, y, 0), Axis::Z, layer, 0)
                    .unwrap();
            }
        }
        let cfg = MeshConfig {
            variance_show: 0.3,
            max_slope_deg: 90.0,
        };
        let whole = weld(map.layers(), &lattice, Shown::new(&cfg));
        let dir = crate::test_support::scratch_dir("mesh-cuts");
        let target = dir.join("m.ply");
        let mut spool = MeshSpool::new(&target, lattice, &cfg).unwrap();
        spool.set_layers(2);
        spool.add_map(&map).unwrap();
        let counts = MeshCounts {
            vertices: whole.vertices.len() as u64,
            triangles: whole.triangles.len() as u64,
        };
        assert_eq!((spool.counts(), counts.triangles), (counts, 9 * 50));
        let mut streamed = Vec::new();
        spool.for_each_triangle(|t, _| streamed.push(t)).unwrap();
        let corners = |t: &[Point; 3]| {
            let mut c = t.map(|p| p.map(|x| (x * 1e4).round() as i64));
            c.sort_unstable();
            c
        };
        let mut expected: Vec<_> = whole
            .triangles
            .iter()
            .map(|t| corners(&t.map(|i| whole.vertices[i as usize].position)))
            .collect();
        let mut got: Vec<_> = streamed.iter().map(corners).collect();
        expected.sort_unstable();
        got.sort_unstable();
        assert_eq!(got, expected);
        // Resumed after its second set (whose faces use the first set's vertices).
        spool.flush().unwrap();
        let sets = read_sets(&spool.paths[2]).unwrap();
        assert_eq!(sets.len(), 5);
        let imports = imports_within(&spool.paths[1], &sets, sets[1]).unwrap();
        assert!(imports > 0);
        let paths = spool.paths.clone();
        std::mem::forget(spool);
        let mut resumed = MeshSpool::resume(&target, lattice, &cfg, sets[1]).unwrap();
        let mut again = 0;
        resumed.for_each_triangle(|_, _| again += 1).unwrap();
        assert_eq!(again, sets[1].triangles);
        assert_eq!(
            std::fs::metadata(&paths[3]).unwrap().len(),
            imports * IMPORT_BYTES as u64
        );
        resumed
            .finish(&[(target.clone(), MeshFormat::Ply)])
            .unwrap();
        // The whole mesh, written: one piece.
        let mut spool = MeshSpool::new(&target, lattice, &cfg).unwrap();
        spool.set_layers(2);
        spool.add_map(&map).unwrap();
        spool.finish(&[(target.clone(), MeshFormat::Ply)]).unwrap();
        let written = read_ply_mesh(&target).unwrap();
        assert_eq!(Topology::of(&written.triangles).pieces, 1);
    }

    /// A map of one flat floor layer at 0.5 m in cell (0, 0, 0), every vertex of variance
    /// `var`, then `change` applied to it.
    fn one_floor(lattice: Lattice, var: f32, change: impl FnOnce(&mut Layer)) -> MeshMap {
        let mut map = MeshMap::with_capacity(4, 4, lattice);
        let mut layer = Layer {
            pred: [0.5; VERTICES],
            var: [var; VERTICES],
            facing: Facing::Unknown,
        };
        change(&mut layer);
        map.insert_layer(CellKey::new(0, 0, 0), Axis::Z, layer, 0)
            .unwrap();
        map
    }

    #[test]
    fn a_flat_layer_writes_36_shared_vertices_and_50_triangles() {
        let lattice = Lattice {
            cell_size: 1.0,
            full_cover: true,
        };
        let map = one_floor(lattice, 0.01, |l| l.var[35] = 0.02);
        let dir = crate::test_support::scratch_dir("mesh");
        let outputs = [
            (dir.join("m.ply"), MeshFormat::Ply),
            (dir.join("m.obj"), MeshFormat::Obj),
        ];
        let mut spool = MeshSpool::new(
            &outputs[0].0,
            lattice,
            &MeshConfig {
                variance_show: 0.1,
                max_slope_deg: 60.0,
            },
        )
        .unwrap();
        spool.add_map(&map).unwrap();
        let counts = spool.finish(&outputs).unwrap();
        assert_eq!(
            counts,
            MeshCounts {
                vertices: 36,
                triangles: 50
            }
        );
        for (target, format) in outputs {
            let text = std::fs::read(&target).unwrap();
            if format == MeshFormat::Ply {
                let pts = read_ply_points(&target).unwrap();
                assert_eq!(pts.len(), 36);
                let mesh = crate::formats::ply::read_ply_mesh(&target).unwrap();
                assert_eq!((mesh.vertices.len(), mesh.triangles.len()), (36, 50));
                assert!(pts.iter().all(|p| (p[2] - 0.5).abs() < 1e-6));
                // The variance is the last float of each vertex record, after the normal.
                let body = &text[text.len() - 50 * FACE_BYTES - 36 * VERTEX_BYTES..];
                let var = |i: usize| float(&body[i * VERTEX_BYTES..], 6);
                assert!((0..36).all(|i| float(&body[i * VERTEX_BYTES..], 5) > 0.999));
                let mut vars: Vec<f32> = (0..36).map(var).collect();
                vars.sort_by(f32::total_cmp);
                assert_eq!((vars[0], vars[35]), (0.01, 0.02));
            } else {
                let text = String::from_utf8(text).unwrap();
                assert_eq!(text.lines().filter(|l| l.starts_with("v ")).count(), 36);
                assert_eq!(
                    text.lines().filter(|l| l.starts_with("vn 0 0 1")).count(),
                    36
                );
                assert_eq!(text.lines().filter(|l| l.starts_with("f ")).count(), 50);
            }
            assert!(std::fs::read_dir(&dir).unwrap().all(|e| !e
                .unwrap()
                .file_name()
                .to_string_lossy()
                .ends_with(".spool")));
        }
    }

    #[test]
    fn colour_by_variance_appends_red_green_blue_to_each_vertex() {
        let lattice = Lattice {
            cell_size: 1.0,
            full_cover: true,
        };
        let map = one_floor(lattice, 0.0, |l| l.var[0] = 0.1);
        let dir = crate::test_support::scratch_dir("mesh-colour");
        let target = dir.join("m.ply");
        let cfg = MeshConfig {
            variance_show: 0.1,
            max_slope_deg: 60.0,
        };
        let mut spool = MeshSpool::new(&target, lattice, &cfg).unwrap();
        spool.add_map(&map).unwrap();
        spool.colour_by(MeshColour::Variance);
        spool.finish(&[(target.clone(), MeshFormat::Ply)]).unwrap();
        let text = std::fs::read(&target).unwrap();
        let header_end = text.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
        let header = String::from_utf8_lossy(&text[..header_end]);
        assert!(header.contains("property uchar red\nproperty uchar green\nproperty uchar blue\n"));
        let mesh = crate::formats::ply::read_ply_mesh(&target).unwrap();
        assert!(mesh.vertices.iter().all(|p| (p[2] - 0.5).abs() < 1e-6));
        // Vertex 0 (variance 0.1, the hiding limit) is red; the others (0) blue.
        let record = VERTEX_BYTES + 3;
        let colour = |i: usize| {
            let at = header_end + i * record + VERTEX_BYTES;
            [text[at], text[at + 1], text[at + 2]]
        };
        let (first, rest) = (colour(0), colour(1));
        assert!(first[0] > 200 && first[2] < 80, "{first:?}");
        assert!(rest[2] > 150 && rest[0] < 80, "{rest:?}");
    }
}
