//! The mesh on its way to disk.
//!
//! A [`MeshSpool`] collects layers as they come (cells evicted from a sliding-window map, then
//! the map at the end) into two spool files next to the output, so that memory stays flat
//! however long the run; [`MeshSpool::finish`] writes the final file atomically. Within a layer
//! the lattice vertices are shared by its triangles; only vertices of shown triangles are
//! written. Neighbouring cells predict their face vertices independently, so vertices are not
//! merged across layers.

use crate::io::atomic::write_atomic;
use crate::io::error::FileError;
use slamesh_core::config::MeshConfig;
use slamesh_core::lattice::{Lattice, LatticeTable, VERTICES};
use slamesh_core::layer::Shown;
use slamesh_core::map::{LayerRef, MeshMap};
use slamesh_core::Point;
use std::collections::VecDeque;
use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

/// Bytes of a spooled vertex: x, y, z, variance as little-endian `f32` (a PLY vertex record).
pub const VERTEX_BYTES: usize = 16;
/// Bytes of a spooled face: a `u8` 3 and three little-endian `u32` (a PLY face record).
pub const FACE_BYTES: usize = 13;

/// Mesh file formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MeshFormat {
    /// Binary little-endian PLY with a per-vertex variance.
    Ply,
    /// Wavefront OBJ (positions and faces; OBJ has no per-vertex scalar).
    Obj,
}

/// What a finished mesh file holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MeshCounts {
    /// Vertices written.
    pub vertices: u64,
    /// Triangles written.
    pub triangles: u64,
}

/// Mesh pieces spooled to disk until [`finish`](Self::finish).
#[derive(Debug)]
pub struct MeshSpool {
    lattice: LatticeTable,
    shown: Shown,
    paths: [PathBuf; 2],
    vertices: BufWriter<File>,
    faces: BufWriter<File>,
    counts: MeshCounts,
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
        let name = target
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let paths = [
            target.with_file_name(format!(".{name}.vertices.spool")),
            target.with_file_name(format!(".{name}.faces.spool")),
        ];
        let open = |p: &Path, keep_bytes: Option<u64>| {
            let file = match keep_bytes {
                None => File::create(p)
                    .map_err(|e| FileError::at(p, format!("cannot create spool file: {e}")))?,
                Some(bytes) => crate::io::atomic::open_cut(p, bytes)?,
            };
            Ok::<_, FileError>(BufWriter::new(file))
        };
        Ok(MeshSpool {
            lattice: lattice.table(),
            shown: Shown::new(shown),
            vertices: open(&paths[0], kept.map(|k| k.vertices * VERTEX_BYTES as u64))?,
            faces: open(&paths[1], kept.map(|k| k.triangles * FACE_BYTES as u64))?,
            paths,
            counts: kept.unwrap_or_default(),
        })
    }

    /// Writes what is buffered to the spool files (before a checkpoint counts them).
    pub fn flush(&mut self) -> Result<(), FileError> {
        for (w, p) in [
            (&mut self.vertices, &self.paths[0]),
            (&mut self.faces, &self.paths[1]),
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

    /// Adds the shown triangles of one layer, with the vertices they use.
    pub fn add_layer(&mut self, l: LayerRef<'_>) -> Result<(), FileError> {
        let mut index = [u32::MAX; VERTICES];
        let mut next = self.counts.vertices;
        let io = |e: std::io::Error, p: &Path| FileError::at(p, format!("cannot write: {e}"));
        for t in l.layer.triangles(&self.lattice, self.shown) {
            let mut face = [0u8; FACE_BYTES];
            face[0] = 3;
            for (k, &j) in t.iter().enumerate() {
                if index[j] == u32::MAX {
                    index[j] = next as u32;
                    next += 1;
                    let v = l.layer.vertex(&self.lattice, &l.key, l.axis, j);
                    let mut rec = [0u8; VERTEX_BYTES];
                    for (c, x) in [v.x as f32, v.y as f32, v.z as f32, l.layer.var[j]]
                        .iter()
                        .enumerate()
                    {
                        rec[4 * c..4 * c + 4].copy_from_slice(&x.to_le_bytes());
                    }
                    self.vertices
                        .write_all(&rec)
                        .map_err(|e| io(e, &self.paths[0]))?;
                }
                face[1 + 4 * k..5 + 4 * k].copy_from_slice(&index[j].to_le_bytes());
            }
            self.faces
                .write_all(&face)
                .map_err(|e| io(e, &self.paths[1]))?;
            self.counts.triangles += 1;
        }
        self.counts.vertices = next;
        Ok(())
    }

    /// Adds every layer of `map`.
    pub fn add_map(&mut self, map: &MeshMap) -> Result<(), FileError> {
        map.layers().try_for_each(|l| self.add_layer(l))
    }

    /// Calls `each` with every triangle added so far, as its three corners, and the highest
    /// vertex `z` of the mesh (for colour scales), in the order they were added. Reads the
    /// spool files (flushed first) without holding them in memory: a face uses only its
    /// layer's vertices, at most [`VERTICES`] of them, all spooled before it, so the last
    /// [`VERTICES`] vertices read are all a face can need.
    pub fn for_each_triangle(
        &mut self,
        mut each: impl FnMut([Point; 3], f32),
    ) -> Result<(), FileError> {
        self.flush()?;
        let io = |e: std::io::Error, p: &Path| FileError::at(p, format!("cannot read: {e}"));
        let read_vertex = |r: &mut BufReader<File>| -> std::io::Result<Point> {
            let mut rec = [0u8; VERTEX_BYTES];
            r.read_exact(&mut rec)?;
            let f = |c: usize| {
                f32::from_le_bytes([rec[4 * c], rec[4 * c + 1], rec[4 * c + 2], rec[4 * c + 3]])
            };
            Ok([f(0), f(1), f(2)])
        };
        // First pass: the highest vertex.
        let open = |p: &Path| File::open(p).map(BufReader::new).map_err(|e| io(e, p));
        let mut vertices = open(&self.paths[0])?;
        let mut z_top = f32::NEG_INFINITY;
        for _ in 0..self.counts.vertices {
            let v = read_vertex(&mut vertices).map_err(|e| io(e, &self.paths[0]))?;
            z_top = z_top.max(v[2]);
        }
        // Second pass: faces, with the last VERTICES vertices read.
        let mut vertices = open(&self.paths[0])?;
        let mut faces = open(&self.paths[1])?;
        let mut window: VecDeque<Point> = VecDeque::new();
        let (mut base, mut next) = (0u64, 0u64);
        for _ in 0..self.counts.triangles {
            let mut rec = [0u8; FACE_BYTES];
            faces
                .read_exact(&mut rec)
                .map_err(|e| io(e, &self.paths[1]))?;
            let index = |k: usize| {
                u64::from(u32::from_le_bytes([
                    rec[1 + 4 * k],
                    rec[2 + 4 * k],
                    rec[3 + 4 * k],
                    rec[4 + 4 * k],
                ]))
            };
            let ids = [index(0), index(1), index(2)];
            let (lo, hi) = (
                ids.iter().min().copied().unwrap_or(0),
                ids.iter().max().copied().unwrap_or(0),
            );
            if hi >= self.counts.vertices {
                return Err(FileError::at(
                    &self.paths[1],
                    "a face refers to a vertex not spooled",
                ));
            }
            while next <= hi {
                window.push_back(read_vertex(&mut vertices).map_err(|e| io(e, &self.paths[0]))?);
                next += 1;
            }
            while next - base > VERTICES as u64 {
                window.pop_front();
                base += 1;
            }
            if lo < base {
                return Err(FileError::at(
                    &self.paths[1],
                    "a face refers to another layer's vertex",
                ));
            }
            each(ids.map(|i| window[(i - base) as usize]), z_top);
        }
        Ok(())
    }

    /// Writes everything added to each `(path, format)` (atomically) and removes the spool.
    pub fn finish(mut self, outputs: &[(PathBuf, MeshFormat)]) -> Result<MeshCounts, FileError> {
        self.flush()?;
        for (target, format) in outputs {
            self.write(target, *format)?;
        }
        Ok(self.counts)
    }

    fn write(&self, target: &Path, format: MeshFormat) -> Result<(), FileError> {
        let counts = self.counts;
        let paths = &self.paths;
        write_atomic(target, |w| {
            let mut vertices = BufReader::new(File::open(&paths[0])?);
            let mut faces = BufReader::new(File::open(&paths[1])?);
            match format {
                MeshFormat::Ply => crate::io::ply::write_mesh_records(
                    w,
                    &mut vertices,
                    &mut faces,
                    counts.vertices,
                    counts.triangles,
                ),
                MeshFormat::Obj => crate::io::obj::write_mesh_records(
                    w,
                    &mut vertices,
                    &mut faces,
                    counts.vertices,
                    counts.triangles,
                ),
            }
        })
    }
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
    use crate::io::ply::read_ply_points;
    use slamesh_core::cell::{Axis, CellKey};
    use slamesh_core::layer::Layer;

    /// Streaming the spool gives the map's triangles, corner for corner and in order, over
    /// many layers of different axes and heights (each layer's faces reuse earlier vertices
    /// of that layer only).
    #[test]
    fn the_spooled_triangles_stream_back_as_the_map_has_them() {
        let lattice = Lattice {
            cell_size: 1.6,
            full_cover: true,
        };
        let mut map = MeshMap::with_capacity(64, 64, lattice);
        let mut k = 0u32;
        for x in 0..4 {
            for (y, axis) in [(0, Axis::Z), (1, Axis::X), (2, Axis::Y)] {
                let mut layer = Layer {
                    pred: [0.0; VERTICES],
                    var: [0.01; VERTICES],
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
        let cfg = MeshConfig {
            variance_show: 0.3,
            max_slope_deg: 90.0,
        };
        let dir = crate::test_support::scratch_dir("mesh-stream");
        let mut spool = MeshSpool::new(&dir.join("m.ply"), lattice, &cfg).unwrap();
        spool.add_map(&map).unwrap();
        let mut streamed = Vec::new();
        let mut tops = Vec::new();
        spool
            .for_each_triangle(|t, z_top| {
                streamed.push(t);
                tops.push(z_top);
            })
            .unwrap();
        let expected: Vec<[Point; 3]> = slamesh_core::mesh::triangles(&map, &cfg)
            .map(|t| t.vertices)
            .collect();
        assert!(expected.len() > 400, "{} triangles", expected.len());
        assert_eq!(streamed, expected);
        let z_top = expected
            .iter()
            .flatten()
            .map(|v| v[2])
            .fold(f32::MIN, f32::max);
        assert!(tops.iter().all(|&z| z == z_top));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_flat_layer_writes_36_shared_vertices_and_50_triangles() {
        let lattice = Lattice {
            cell_size: 1.0,
            full_cover: true,
        };
        let mut map = MeshMap::with_capacity(4, 4, lattice);
        let mut layer = Layer {
            pred: [0.5; VERTICES],
            var: [0.01; VERTICES],
        };
        layer.var[35] = 0.02;
        map.insert_layer(CellKey::new(0, 0, 0), Axis::Z, layer, 0)
            .unwrap();
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
                let mesh = crate::io::ply::read_ply_mesh(&target).unwrap();
                assert_eq!((mesh.vertices.len(), mesh.triangles.len()), (36, 50));
                assert!(pts.iter().all(|p| (p[2] - 0.5).abs() < 1e-6));
                // The variance is the last float of each vertex record.
                let body = &text[text.len() - 50 * FACE_BYTES - 36 * VERTEX_BYTES..];
                let var = |i: usize| {
                    f32::from_le_bytes(body[i * 16 + 12..i * 16 + 16].try_into().unwrap())
                };
                let mut vars: Vec<f32> = (0..36).map(var).collect();
                vars.sort_by(f32::total_cmp);
                assert_eq!((vars[0], vars[35]), (0.01, 0.02));
            } else {
                let text = String::from_utf8(text).unwrap();
                assert_eq!(text.lines().filter(|l| l.starts_with("v ")).count(), 36);
                assert_eq!(text.lines().filter(|l| l.starts_with("f ")).count(), 50);
            }
            assert!(std::fs::read_dir(&dir).unwrap().all(|e| !e
                .unwrap()
                .file_name()
                .to_string_lossy()
                .ends_with(".spool")));
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
