//! Why a welded mesh has boundary edges: each edge of a shown triangle that no other shown
//! triangle shares after welding ([`crate::outputs::mesh_weld`]), put down to one cause.
//!
//! What a layer shows is what it shows in the welded mesh (its `shown_mask` with the fused
//! variances of its merged vertices). An edge inside a layer's
//! lattice is open when the lattice triangle across it is hidden: by its slope
//! (`max_slope_deg`, whatever its variance), or else by its variance (`variance_show`). An edge on a cell
//! face is open when, across the face (the neighbour cell, or the one above or below it
//! along the layer's axis):
//! - no cell has a layer at all: the edge of what was seen;
//! - no cell has a layer of this axis, but one has a layer of another: the surface turns
//!   (a wall meets a floor), and layers of different axes share no vertices;
//! - the neighbour layer's triangle across is hidden (variance or slope, as above);
//! - the neighbour's triangle is shown but its vertices were too far from these to be merged.
//!
//! The counts follow the welding rule edge by edge, so their sum is close to, not exactly,
//! the welded mesh's boundary count (clusters of three or more vertices, dropped duplicate
//! triangles).

use slamesh_core::cell::{Axis, CellKey};
use slamesh_core::lattice::{Lattice, LatticeTable, N};
use slamesh_core::layer::{lattice_triangle, triangle_neighbours, Layer, Shown, TRIANGLES};
use slamesh_core::map::LayerRef;
use std::collections::HashMap;

/// Open edges by cause.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct SeamCauses {
    /// Edges of shown triangles, counted once per triangle side.
    pub edges: u64,
    /// Nothing was seen across the cell face.
    pub unseen: u64,
    /// Only layers of another axis across the face (or in the cell itself).
    pub orientation: u64,
    /// The triangle across is hidden by its variance.
    pub hidden_variance: u64,
    /// The triangle across is hidden by its slope alone.
    pub hidden_slope: u64,
    /// The triangle across is shown, but its vertices were not merged with these.
    pub not_merged: u64,
}

impl SeamCauses {
    /// All open edges.
    pub fn open(&self) -> u64 {
        self.unseen + self.orientation + self.hidden_variance + self.hidden_slope + self.not_merged
    }
}

/// The lattice triangle with both `p` and `q` as corners, for an edge on the lattice's
/// border (where there is one such triangle).
fn on_border(p: usize, q: usize) -> Option<usize> {
    (0..TRIANGLES).find(|&t| {
        let tri = lattice_triangle(t);
        tri.contains(&p) && tri.contains(&q)
    })
}

/// Which triangles a layer shows, and which its slope alone would let it show.
struct Masks {
    shown: u64,
    slope_ok: u64,
}

impl Masks {
    fn of(layer: &Layer, shown_mask: u64, table: &LatticeTable, shown: Shown) -> Self {
        Masks {
            shown: shown_mask,
            slope_ok: layer.slope_mask(table, shown.min_axis_cosine),
        }
    }

    /// Shown, or hidden for its variance (`true`) or its slope (`false`).
    fn state(&self, t: usize) -> Result<(), bool> {
        if self.shown & (1 << t) != 0 {
            Ok(())
        } else {
            Err(self.slope_ok & (1 << t) != 0)
        }
    }
}

/// The layers by place, to look across a cell face from one of them.
struct Neighbourhood<'a> {
    by_place: HashMap<(CellKey, Axis), (&'a Layer, u64)>,
    table: LatticeTable,
    lattice: &'a Lattice,
    shown: Shown,
    /// How close two layers' vertices on a shared face are when merged (m).
    tolerance: f32,
}

impl Neighbourhood<'_> {
    /// Counts the edge `(p, q)` of a shown triangle of `l` into `c` by what lies across its
    /// cell face: merged (not counted), a shown triangle not merged, a hidden one, a layer of
    /// another axis, or nothing seen. An edge not on the lattice's border is not counted.
    fn border_edge(&self, l: &LayerRef<'_>, (p, q): (usize, usize), c: &mut SeamCauses) {
        let (a, b) = l.axis.locations();
        let d = l.axis.index();
        // A border edge: which face, and the mirrored vertices across it.
        let ((pa, pb), (qa, qb)) = ((p / N, p % N), (q / N, q % N));
        let (axis_off, step, mirror) = if pa == qa && (pa == 0 || pa == N - 1) {
            let to = N - 1 - pa;
            (a, if pa == 0 { -1 } else { 1 }, [to * N + pb, to * N + qb])
        } else if pb == qb && (pb == 0 || pb == N - 1) {
            let to = N - 1 - pb;
            (b, if pb == 0 { -1 } else { 1 }, [pa * N + to, qa * N + to])
        } else {
            return;
        };
        let Some(side) = l.key.offset(Axis::from_index(axis_off), step) else {
            return;
        };
        let here = [l.layer.pred[p], l.layer.pred[q]].map(f64::from);
        let world = |key: &CellKey, pred: f64| {
            let corner = key.min_corner(self.lattice.cell_size);
            corner[d] + pred
        };
        // The same-axis layers across: side by side, or one cell up or down.
        let mut best: Option<Result<(), bool>> = None;
        for up in [0, -1, 1] {
            let Some(key) = side.offset(l.axis, up) else {
                continue;
            };
            let Some(&(n, n_mask)) = self.by_place.get(&(key, l.axis)) else {
                continue;
            };
            let close = mirror.iter().zip(&here).all(|(&m, &h)| {
                let theirs = world(&key, f64::from(n.pred[m]));
                (theirs - world(&l.key, h)).abs() <= f64::from(self.tolerance)
            });
            let state = on_border(mirror[0], mirror[1]).map_or(Err(true), |t| {
                Masks::of(n, n_mask, &self.table, self.shown).state(t)
            });
            if state.is_ok() && close {
                // Merged: not an open edge.
                return;
            }
            best = match (best, state) {
                (Some(Ok(())), _) => best,
                _ => Some(state),
            };
        }
        match best {
            Some(Ok(())) => c.not_merged += 1,
            Some(Err(true)) => c.hidden_variance += 1,
            Some(Err(false)) => c.hidden_slope += 1,
            None => {
                let other_axis = Axis::ALL.iter().any(|&x| {
                    x != l.axis
                        && ([0, -1, 1].iter().any(|&up| {
                            side.offset(l.axis, up)
                                .is_some_and(|k| self.by_place.contains_key(&(k, x)))
                        }) || self.by_place.contains_key(&(l.key, x)))
                });
                if other_axis {
                    c.orientation += 1;
                } else {
                    c.unseen += 1;
                }
            }
        }
    }
}

/// Counts the open edges of `layers`' shown triangles by cause, with `shown_masks` what each
/// layer shows in their welded mesh ([`WeldedMesh::shown`](crate::outputs::mesh_weld::WeldedMesh::shown) of
/// `weld(layers, ..)`).
pub fn seam_causes<'a>(
    layers: impl IntoIterator<Item = LayerRef<'a>>,
    shown_masks: &[u64],
    lattice: &Lattice,
    shown: Shown,
) -> SeamCauses {
    let layers: Vec<LayerRef<'a>> = layers.into_iter().collect();
    let near = Neighbourhood {
        by_place: layers
            .iter()
            .zip(shown_masks)
            .map(|(l, &m)| ((l.key, l.axis), (l.layer, m)))
            .collect(),
        table: lattice.table(),
        lattice,
        shown,
        tolerance: (lattice.cell_size / (N - 1) as f64 / 2.0) as f32,
    };
    let mut c = SeamCauses::default();
    for (l, &shown_mask) in layers.iter().zip(shown_masks) {
        let masks = Masks::of(l.layer, shown_mask, &near.table, shown);
        for t in (0..TRIANGLES).filter(|&t| masks.shown & (1 << t) != 0) {
            let tri = lattice_triangle(t);
            for k in 0..3 {
                let (p, q) = (tri[k], tri[(k + 1) % 3]);
                c.edges += 1;
                // Interior edge: the triangle across in this layer.
                let inside = triangle_neighbours(t).into_iter().flatten().find(|&n| {
                    lattice_triangle(n).contains(&p) && lattice_triangle(n).contains(&q)
                });
                if let Some(other) = inside {
                    match masks.state(other) {
                        Ok(()) => {}
                        Err(true) => c.hidden_variance += 1,
                        Err(false) => c.hidden_slope += 1,
                    }
                    continue;
                }
                near.border_edge(l, (p, q), &mut c);
            }
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::outputs::mesh_weld::weld;
    use slamesh_core::config::MeshConfig;
    use slamesh_core::facing::Facing;
    use slamesh_core::lattice::VERTICES;
    use slamesh_core::map::MeshMap;

    #[test]
    fn each_cause_is_told_apart() {
        let lattice = Lattice {
            cell_size: 1.0,
            full_cover: true,
        };
        let shown = Shown::new(&MeshConfig {
            variance_show: 0.5,
            max_slope_deg: 60.0,
        });
        let flat = |h: f32| Layer {
            pred: [h; VERTICES],
            var: [0.01; VERTICES],
            facing: Facing::Unknown,
        };
        let causes = |map: &MeshMap| {
            let welded = weld(map.layers(), &lattice, shown);
            seam_causes(map.layers(), &welded.shown, &lattice, shown)
        };
        // One floor cell alone: its 20 rim edges face nothing.
        let mut map = MeshMap::with_capacity(8, 8, lattice);
        map.insert_layer(CellKey::new(0, 0, 0), Axis::Z, flat(0.5), 0)
            .unwrap();
        let c = causes(&map);
        assert_eq!((c.edges, c.unseen, c.open()), (150, 20, 20));
        // A neighbour 5 cm higher welds the face between them (5 edges on each side); one
        // 40 cm higher does not. 40 rim edges are left facing nothing.
        map.insert_layer(CellKey::new(1, 0, 0), Axis::Z, flat(0.55), 0)
            .unwrap();
        map.insert_layer(CellKey::new(-1, 0, 0), Axis::Z, flat(0.9), 0)
            .unwrap();
        let c = causes(&map);
        assert_eq!((c.not_merged, c.unseen, c.open()), (10, 40, 50), "{c:?}");
        // A wall in the cell beyond the floor's +y face: that face turns (5 edges); the
        // wall's own rim faces nothing.
        let mut map = MeshMap::with_capacity(8, 8, lattice);
        map.insert_layer(CellKey::new(0, 0, 0), Axis::Z, flat(0.5), 0)
            .unwrap();
        map.insert_layer(CellKey::new(0, 1, 0), Axis::Y, flat(0.1), 0)
            .unwrap();
        let c = causes(&map);
        assert_eq!((c.orientation, c.unseen), (5, 35), "{c:?}");
        // A hole: one vertex too uncertain hides its six triangles, whose outer edges open.
        let mut holed = flat(0.5);
        holed.var[2 * N + 2] = 3.0;
        let mut map = MeshMap::with_capacity(8, 8, lattice);
        map.insert_layer(CellKey::new(0, 0, 0), Axis::Z, holed, 0)
            .unwrap();
        let c = causes(&map);
        assert_eq!(
            (c.hidden_variance, c.unseen, c.edges),
            (6, 20, 132),
            "{c:?}"
        );
    }
}
