//! Welding: one indexed mesh from a set of map layers, with the vertices that neighbouring
//! cells share merged into one, and a normal at every vertex (docs/design.md §1.10).
//!
//! With the lattice on the cell faces (`full_cover`), a layer's border vertices sit where the
//! border vertices of the same-axis layers of its neighbours sit. Along axis `d`, with
//! location axes `(a, b)`, vertex `(i_a, i_b)` of cell `k` lies on the lattice line
//! `U = k_a (N - 1) + i_a`, `V = k_b (N - 1) + i_b`, and each layer predicts the coordinate
//! along `d` there on its own. Border vertices on one line `(d, U, V)` whose predictions are
//! within half a lattice spacing of the first of them are one surface point: they become one
//! vertex at their inverse-variance weighted mean, with the fused variance `1 / Σ 1/σ²`, as
//! the map update fuses predictions ([`slamesh_core::fusion`]). The cells may be side by side
//! or one above the other along `d` (a surface crossing the face between them). Interior
//! vertices are never shared.
//!
//! What is not welded:
//! - where layers of different axes meet (a wall standing on a floor), no vertex of one lies
//!   on a lattice line of the other; the mesh keeps an open crease there;
//! - with vertices at the interval centres (`full_cover = false`, the `fast` preset) no two
//!   layers share a vertex place: every layer stays its own piece.
//!
//! Which triangles are shown is [`Layer::shown_mask`](slamesh_core::layer::Layer::shown_mask)
//! of each layer with the welded variances: a merged vertex has its cluster's fused
//! variance, so two cells that each saw a face poorly may together show it (and the notch
//! and speck rules apply to the result). Clusters take in the vertices of every triangle
//! within the slope limit, shown or not.
//!
//! A triangle that uses the same three vertices as an earlier one after welding is dropped.
//! Normals are the area-weighted sums of the normals of the triangles around each vertex, on
//! the side of the layer's `+axis` (a vertex in no usable triangle gets the axis itself).
//!
//! Memory: what is welded together is held at once (each used vertex with its position,
//! weld line and output index), so callers weld bounded sets ([`crate::outputs::mesh_spool`]).

use slamesh_core::cell::{Axis, CellKey};
use slamesh_core::lattice::{Lattice, N, VERTICES};
use slamesh_core::layer::{lattice_triangle, Shown, TRIANGLES};
use slamesh_core::map::LayerRef;
use std::collections::{HashMap, HashSet};

/// A vertex of a welded mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshVertex {
    /// World position (metres).
    pub position: [f32; 3],
    /// Unit normal.
    pub normal: [f32; 3],
    /// GP variance (fused where vertices were welded).
    pub variance: f32,
}

/// An indexed triangle mesh.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct WeldedMesh {
    /// The vertices, in the order their layers came.
    pub vertices: Vec<MeshVertex>,
    /// Triangles as indices into the whole mesh (`vertices` from the set's first index on;
    /// lower ones are earlier sets' vertices), counter-clockwise seen from their layer's
    /// `+axis`.
    pub triangles: Vec<[u32; 3]>,
    /// The position of each corner of `triangles`, in order, that is an earlier set's
    /// vertex (so that a reader of one set at a time can draw them).
    pub imported: Vec<[f32; 3]>,
    /// Vertices that were merged into another one.
    pub merged: u64,
    /// Which lattice triangles each layer showed, in the order the layers came (bit `t` for
    /// `lattice_triangle(t)`): its [`Layer::shown_mask`](slamesh_core::layer::Layer::shown_mask)
    /// with the fused variances of its merged vertices.
    pub shown: Vec<u64>,
}

/// A vertex of a layer, by its cell, axis and lattice index.
type VertexId = (CellKey, Axis, u8);

/// Where a set's vertex went, for the sets welded after it ([`weld_set`]): for a vertex of
/// a later set merged into one this set wrote, that vertex's index and position. Entries
/// are taken when the later set is welded.
#[derive(Debug, Default)]
pub struct SeamLinks {
    written: HashMap<VertexId, (u32, [f32; 3])>,
}

/// A layer next to a set but outside it, welded with the set's vertices (its predictions
/// join their clusters) without its triangles.
#[derive(Debug, Clone, Copy)]
pub struct Neighbour<'a> {
    /// The layer.
    pub layer: LayerRef<'a>,
    /// Whether its set is welded after this one.
    pub later: bool,
}

/// A vertex of one layer, before welding.
struct Slot {
    position: [f64; 3],
    variance: f32,
    axis: Axis,
    id: VertexId,
    /// For a neighbour's vertex: whether its set comes later.
    neighbour: Option<bool>,
    /// `(d, U, V)` and the coordinate along `d`, for a border vertex of a face lattice.
    line: Option<([i64; 3], f64)>,
}

/// Where a cluster of slots goes in the output.
#[derive(Clone, Copy)]
enum Out {
    Unused,
    /// Used by a shown triangle, not yet placed.
    Used,
    /// This set's vertex `i`.
    Here(u32),
    /// A vertex an earlier set wrote: its index and position.
    Written(u32, [f32; 3]),
}

fn component(key: &CellKey, i: usize) -> i64 {
    i64::from(match i {
        0 => key.x,
        1 => key.y,
        _ => key.z,
    })
}

/// The welded mesh of `layers`' shown triangles (see the module's documentation).
pub fn weld<'a>(
    layers: impl IntoIterator<Item = LayerRef<'a>>,
    lattice: &Lattice,
    shown: Shown,
) -> WeldedMesh {
    weld_set(layers, &[], &mut SeamLinks::default(), 0, lattice, shown)
}

/// The welded mesh of one set of layers, with their `neighbours` in other sets: vertices
/// shared with a set welded earlier are that set's (from `links`), and vertices this set
/// writes that later sets share go into `links`. Triangle indices count from `first`, the
/// index of this set's first vertex in the whole mesh.
pub fn weld_set<'a>(
    layers: impl IntoIterator<Item = LayerRef<'a>>,
    neighbours: &[Neighbour<'a>],
    links: &mut SeamLinks,
    first: u32,
    lattice: &Lattice,
    shown: Shown,
) -> WeldedMesh {
    let table = lattice.table();
    let mut slots = Slots {
        lattice,
        table: &table,
        min_axis_cosine: shown.min_axis_cosine,
        all: Vec::new(),
    };
    // Each layer with the slot of each vertex of its triangles within the slope limit.
    let placed: Vec<(LayerRef<'a>, [u32; VERTICES])> = layers
        .into_iter()
        .map(|l| (l, slots.add(&l, None)))
        .collect();
    for n in neighbours {
        slots.add(&n.layer, Some(n.later));
    }
    let slots = slots.all;
    let root = clusters(&slots, lattice.cell_size / (N - 1) as f64);
    let sums = cluster_sums(&slots, &root);
    // What each layer shows: its shown_mask with the fused variances of its merged vertices.
    let mut corners: Vec<[u32; 3]> = Vec::new();
    let shown_masks = placed
        .iter()
        .map(|(l, index)| {
            let mask = welded_mask(l, index, &root, &sums, &table, shown);
            corners.extend(
                (0..TRIANGLES)
                    .filter(|t| mask & (1 << t) != 0)
                    .map(|t| lattice_triangle(t).map(|j| index[j]))
                    .filter(|tri| !tri.contains(&u32::MAX)),
            );
            mask
        })
        .collect();
    let mut out = vec![Out::Unused; slots.len()];
    for &s in corners.iter().flatten() {
        out[root[s as usize] as usize] = Out::Used;
    }
    let own = place(&slots, &root, &sums, &mut out, links);
    link_later(&slots, &root, &out, &own.positions, first, links);
    let Faces {
        triangles,
        imported,
        normals,
    } = faces(&corners, &root, &out, &own.positions, first);
    let vertices = own.vertices(&normals);
    WeldedMesh {
        vertices,
        triangles,
        imported,
        merged: own.merged,
        shown: shown_masks,
    }
}

/// The slots of a set's layers and neighbours, as they are added.
struct Slots<'t> {
    lattice: &'t Lattice,
    table: &'t slamesh_core::lattice::LatticeTable,
    min_axis_cosine: f32,
    all: Vec<Slot>,
}

impl Slots<'_> {
    /// Adds a slot for each vertex of `l`'s triangles within the slope limit (a neighbour's
    /// border vertices only) and returns each lattice vertex's slot (`u32::MAX`: none).
    fn add(&mut self, l: &LayerRef<'_>, neighbour: Option<bool>) -> [u32; VERTICES] {
        let mut index = [u32::MAX; VERTICES];
        let (a, b) = l.axis.locations();
        let d = l.axis.index();
        let slope = l.layer.slope_mask(self.table, self.min_axis_cosine);
        for t in (0..TRIANGLES).filter(|t| slope & (1 << t) != 0) {
            for j in lattice_triangle(t) {
                let (ia, ib) = (j / N, j % N);
                let border = ia == 0 || ia == N - 1 || ib == 0 || ib == N - 1;
                if index[j] != u32::MAX || (neighbour.is_some() && !border) {
                    continue;
                }
                index[j] = self.all.len() as u32;
                let p = l.layer.vertex(self.table, &l.key, l.axis, j);
                let line = (self.lattice.full_cover && border).then(|| {
                    let u = component(&l.key, a) * (N as i64 - 1) + ia as i64;
                    let v = component(&l.key, b) * (N as i64 - 1) + ib as i64;
                    ([d as i64, u, v], p[d])
                });
                self.all.push(Slot {
                    position: [p.x, p.y, p.z],
                    variance: l.layer.var[j],
                    axis: l.axis,
                    id: (l.key, l.axis, j as u8),
                    neighbour,
                    line,
                });
            }
        }
        index
    }
}

/// Each slot's cluster: the first slot on its weld line within half a `spacing` of it (a
/// slot on no line is its own).
fn clusters(slots: &[Slot], spacing: f64) -> Vec<u32> {
    let mut root: Vec<u32> = (0..slots.len() as u32).collect();
    let mut on_lines: Vec<u32> = (0..slots.len() as u32)
        .filter(|&s| slots[s as usize].line.is_some())
        .collect();
    let line_of = |s: u32| slots[s as usize].line.unwrap_or(([0; 3], 0.0));
    on_lines.sort_by(|&p, &q| {
        let ((lp, dp), (lq, dq)) = (line_of(p), line_of(q));
        lp.cmp(&lq).then(dp.total_cmp(&dq)).then(p.cmp(&q))
    });
    let mut start = 0;
    for i in 1..=on_lines.len() {
        let same = i < on_lines.len() && {
            let ((l0, d0), (l1, d1)) = (line_of(on_lines[start]), line_of(on_lines[i]));
            l0 == l1 && d1 - d0 <= spacing / 2.0
        };
        if !same {
            let members = &on_lines[start..i];
            let first = members.iter().copied().min().unwrap_or(0);
            for &m in members {
                root[m as usize] = first;
            }
            start = i;
        }
    }
    root
}

/// A cluster's inverse-variance weighted sum of positions, total inverse variance and size.
type ClusterSum = ([f64; 3], f64, u32);

/// Each cluster's [`ClusterSum`], at its root slot.
fn cluster_sums(slots: &[Slot], root: &[u32]) -> Vec<ClusterSum> {
    let mut sums = vec![([0.0f64; 3], 0.0f64, 0u32); slots.len()];
    for (s, slot) in slots.iter().enumerate() {
        let w = 1.0 / f64::from(slot.variance).max(1e-6);
        let sum = &mut sums[root[s] as usize];
        for c in 0..3 {
            sum.0[c] += w * slot.position[c];
        }
        sum.1 += w;
        sum.2 += 1;
    }
    sums
}

/// The triangles layer `l` shows with the fused variances of its merged vertices (`index`:
/// its vertices' slots).
fn welded_mask(
    l: &LayerRef<'_>,
    index: &[u32; VERTICES],
    root: &[u32],
    sums: &[ClusterSum],
    table: &slamesh_core::lattice::LatticeTable,
    shown: Shown,
) -> u64 {
    let mut welded = *l.layer;
    for (var, &s) in welded.var.iter_mut().zip(index) {
        let cluster = root.get(s as usize).and_then(|&r| sums.get(r as usize));
        if let Some(&(_, w, members)) = cluster {
            if members > 1 {
                *var = (1.0 / w) as f32;
            }
        }
    }
    welded.shown_mask(table, shown)
}

/// The vertices a set writes itself.
#[derive(Default)]
struct OwnVertices {
    positions: Vec<[f64; 3]>,
    variances: Vec<f32>,
    axes: Vec<Axis>,
    /// Slots merged into another one.
    merged: u64,
}

impl OwnVertices {
    /// The mesh's vertices, each with its normal: the sum `normals` gives it, made unit (the
    /// layer's axis where no usable triangle gave one).
    fn vertices(&self, normals: &[[f64; 3]]) -> Vec<MeshVertex> {
        self.positions
            .iter()
            .zip(&self.variances)
            .zip(normals.iter().zip(&self.axes))
            .map(|((p, &variance), (n, axis))| {
                let norm = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                let normal = if norm > 1e-12 {
                    n.map(|c| (c / norm) as f32)
                } else {
                    let mut e = [0.0; 3];
                    e[axis.index()] = 1.0;
                    e
                };
                MeshVertex {
                    position: p.map(|c| c as f32),
                    normal,
                    variance,
                }
            })
            .collect()
    }
}

/// Places each used cluster (`out`): on the vertex an earlier set wrote for one of its slots
/// (taken from `links`), else as this set's next vertex at its fused position, in slot order.
fn place(
    slots: &[Slot],
    root: &[u32],
    sums: &[ClusterSum],
    out: &mut [Out],
    links: &mut SeamLinks,
) -> OwnVertices {
    // A used cluster with a vertex an earlier set wrote is that vertex.
    for (s, slot) in slots.iter().enumerate() {
        let r = root[s] as usize;
        if slot.neighbour.is_some() {
            continue;
        }
        if let Some((i, p)) = links.written.remove(&slot.id) {
            if matches!(out[r], Out::Used) {
                out[r] = Out::Written(i, p);
            }
        }
    }
    // The others are this set's vertices, in slot order.
    let mut own = OwnVertices::default();
    let mut placed_root = vec![false; slots.len()];
    for (s, slot) in slots.iter().enumerate() {
        let r = root[s] as usize;
        if slot.neighbour.is_some() || matches!(out[r], Out::Unused) {
            continue;
        }
        if std::mem::replace(&mut placed_root[r], true) {
            own.merged += 1;
            continue;
        }
        match out[r] {
            Out::Used => {
                let (sum, w, _) = sums[r];
                out[r] = Out::Here(own.positions.len() as u32);
                own.positions.push(sum.map(|c| c / w));
                own.variances.push((1.0 / w) as f32);
                own.axes.push(slot.axis);
            }
            _ => own.merged += 1,
        }
    }
    own
}

/// Notes in `links` where each vertex of a later set's neighbour went.
fn link_later(
    slots: &[Slot],
    root: &[u32],
    out: &[Out],
    positions: &[[f64; 3]],
    first: u32,
    links: &mut SeamLinks,
) {
    for (s, slot) in slots.iter().enumerate() {
        if slot.neighbour != Some(true) {
            continue;
        }
        let at = match out[root[s] as usize] {
            Out::Here(i) => (first + i, positions[i as usize].map(|c| c as f32)),
            Out::Written(i, p) => (i, p),
            Out::Unused | Out::Used => continue,
        };
        links.written.insert(slot.id, at);
    }
}

/// A set's triangles as [`faces`] finds them.
struct Faces {
    /// Indices into the whole mesh.
    triangles: Vec<[u32; 3]>,
    /// The positions of their corners an earlier set wrote, in order.
    imported: Vec<[f32; 3]>,
    /// The area-weighted sum of the triangles' normals at each of this set's vertices.
    normals: Vec<[f64; 3]>,
}

/// The set's triangles from their `corners`' slots (a repeat of an earlier one's vertices,
/// or one with a vertex twice, dropped).
fn faces(
    corners: &[[u32; 3]],
    root: &[u32],
    out: &[Out],
    positions: &[[f64; 3]],
    first: u32,
) -> Faces {
    let mut seen = HashSet::new();
    let mut triangles = Vec::with_capacity(corners.len());
    let mut imported = Vec::new();
    let mut normals = vec![[0.0f64; 3]; positions.len()];
    for c in corners {
        let o = c.map(|s| out[root[s as usize] as usize]);
        let at = o.map(|o| match o {
            Out::Here(i) => (first + i, positions[i as usize]),
            Out::Written(i, p) => (i, p.map(f64::from)),
            Out::Unused | Out::Used => (u32::MAX, [0.0; 3]),
        });
        let t = at.map(|(i, _)| i);
        let mut key = t;
        key.sort_unstable();
        if key[0] == key[1] || key[1] == key[2] || !seen.insert(key) {
            continue;
        }
        let [p0, p1, p2] = at.map(|(_, p)| p);
        let (u, v) = (sub(p1, p0), sub(p2, p0));
        let n = [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ];
        for o in o {
            match o {
                Out::Here(i) => {
                    for k in 0..3 {
                        normals[i as usize][k] += n[k];
                    }
                }
                Out::Written(_, p) => imported.push(p),
                Out::Unused | Out::Used => {}
            }
        }
        triangles.push(t);
    }
    Faces {
        triangles,
        imported,
        normals,
    }
}

fn sub(p: [f64; 3], q: [f64; 3]) -> [f64; 3] {
    [p[0] - q[0], p[1] - q[1], p[2] - q[2]]
}

#[cfg(test)]
mod tests {
    use super::*;
    use slamesh_core::config::MeshConfig;
    use slamesh_core::facing::Facing;
    use slamesh_core::layer::Layer;
    use slamesh_core::map::MeshMap;

    fn shown() -> Shown {
        Shown::new(&MeshConfig {
            variance_show: 0.5,
            max_slope_deg: 90.0,
        })
    }

    fn flat(height: f32, var: f32) -> Layer {
        Layer {
            pred: [height; VERTICES],
            var: [var; VERTICES],
            facing: Facing::Unknown,
        }
    }

    const FACES: Lattice = Lattice {
        cell_size: 1.0,
        full_cover: true,
    };

    #[test]
    fn two_floor_cells_side_by_side_share_their_face_vertices_at_the_fused_height() {
        let mut map = MeshMap::with_capacity(4, 4, FACES);
        map.insert_layer(CellKey::new(0, 0, 0), Axis::Z, flat(0.50, 0.01), 0)
            .unwrap();
        map.insert_layer(CellKey::new(1, 0, 0), Axis::Z, flat(0.53, 0.03), 0)
            .unwrap();
        let m = weld(map.layers(), &FACES, shown());
        assert_eq!(m.vertices.len(), 2 * 36 - 6, "one shared column of six");
        assert_eq!((m.merged, m.triangles.len()), (6, 100));
        // Inverse-variance weights 100 and 33.3: 0.50 + 0.03 / 4.
        let on_face: Vec<&MeshVertex> = m
            .vertices
            .iter()
            .filter(|v| (v.position[0] - 1.0).abs() < 1e-6)
            .collect();
        assert_eq!(on_face.len(), 6);
        for v in on_face {
            assert!((v.position[2] - 0.5075).abs() < 1e-5, "{:?}", v.position);
            assert!((v.variance - 0.0075).abs() < 1e-6, "{}", v.variance);
        }
        assert!(m.vertices.iter().all(|v| v.normal[2] > 0.99));
        let edges = crate::eval::topology::Topology::of(&m.triangles);
        assert_eq!(edges.pieces, 1);
    }

    #[test]
    fn border_triangles_show_for_the_fused_variance_of_their_corners() {
        // Two floor cells side by side, uncertain (0.9) on their shared face and confident
        // (0.4) elsewhere, against a limit of 0.5: alone, each hides the ten triangles along
        // that face (mean variances 0.73 and 0.57); welded, the face's variance is 0.45 and
        // all of them show.
        let layer = |face_column: usize| {
            let mut l = flat(0.5, 0.4);
            for j in (0..VERTICES).filter(|j| j / N == face_column) {
                l.var[j] = 0.9;
            }
            l
        };
        let mut map = MeshMap::with_capacity(4, 4, FACES);
        map.insert_layer(CellKey::new(0, 0, 0), Axis::Z, layer(N - 1), 0)
            .unwrap();
        map.insert_layer(CellKey::new(1, 0, 0), Axis::Z, layer(0), 0)
            .unwrap();
        let alone = weld(map.layers().take(1), &FACES, shown());
        assert_eq!(alone.triangles.len(), 40);
        let m = weld(map.layers(), &FACES, shown());
        assert_eq!(m.triangles.len(), 100);
        assert_eq!(m.shown, vec![(1u64 << 50) - 1; 2]);
        assert_eq!(crate::eval::topology::Topology::of(&m.triangles).pieces, 1);
        let on_face = m
            .vertices
            .iter()
            .filter(|v| (v.position[0] - 1.0).abs() < 1e-6);
        assert!(on_face.map(|v| v.variance).all(|v| (v - 0.45).abs() < 1e-6));
    }

    #[test]
    fn a_surface_crossing_the_face_between_stacked_cells_is_welded_there() {
        // A slope rising 1 m over 2 m: in cell z = 0 for x in 0..1, in z = 1 beyond, and
        // both cells predict 1.0 m at x = 1 (0.98 and 1.01: within half a spacing).
        let mut low = flat(0.0, 0.01);
        let mut high = flat(0.0, 0.01);
        for j in 0..VERTICES {
            let x = (j / N) as f32 / 5.0;
            low.pred[j] = (0.5 + x / 2.0 - if j / N == N - 1 { 0.02 } else { 0.0 }).min(1.0);
            high.pred[j] = (x / 2.0 + if j / N == 0 { 0.01 } else { 0.0 }).max(0.0);
        }
        let mut map = MeshMap::with_capacity(4, 4, FACES);
        map.insert_layer(CellKey::new(0, 0, 0), Axis::Z, low, 0)
            .unwrap();
        map.insert_layer(CellKey::new(1, 0, 1), Axis::Z, high, 0)
            .unwrap();
        let m = weld(map.layers(), &FACES, shown());
        assert_eq!((m.merged, m.vertices.len()), (6, 66));
        assert_eq!(crate::eval::topology::Topology::of(&m.triangles).pieces, 1);
    }

    #[test]
    fn far_apart_predictions_walls_on_floors_and_centre_lattices_stay_apart() {
        let mut map = MeshMap::with_capacity(8, 8, FACES);
        map.insert_layer(CellKey::new(0, 0, 0), Axis::Z, flat(0.2, 0.01), 0)
            .unwrap();
        // Half a metre higher next door: another surface (a kerb), not welded.
        map.insert_layer(CellKey::new(1, 0, 0), Axis::Z, flat(0.7, 0.01), 0)
            .unwrap();
        // A wall along x = 0.5 in the first cell: its vertices lie on other lines.
        map.insert_layer(CellKey::new(0, 0, 0), Axis::X, flat(0.5, 0.01), 0)
            .unwrap();
        let m = weld(map.layers(), &FACES, shown());
        assert_eq!((m.merged, m.vertices.len()), (0, 3 * 36));
        assert_eq!(crate::eval::topology::Topology::of(&m.triangles).pieces, 3);
        let centres = Lattice {
            cell_size: 1.0,
            full_cover: false,
        };
        let mut map = MeshMap::with_capacity(4, 4, centres);
        for x in 0..2 {
            map.insert_layer(CellKey::new(x, 0, 0), Axis::Z, flat(0.5, 0.01), 0)
                .unwrap();
        }
        assert_eq!(weld(map.layers(), &centres, shown()).merged, 0);
    }
}
