//! Finding the sensor in a known map with no pose to start from (docs/design.md §1.13): the
//! coarse score that ranks pose hypotheses, and the settings of the search
//! ([`Pipeline::step`](crate::Pipeline::step) runs it for
//! [`Known::Somewhere`](crate::pipeline::Known::Somewhere)).
//!
//! A hypothesis is a candidate position (the caller's: e.g. where the map's own sensor went)
//! turned to one of [`Search::yaw_steps`] headings about the world's vertical. Each is scored
//! by [`surface_hits`]: how many of a fixed subsample of the scan's points land on a map
//! surface, read straight off the lattice of the cell they fall in (no GP, no registration:
//! a hash look-up and a comparison a point). The best distinct hypotheses are then registered
//! in full, as recovery registers its guesses (§1.11), and the result is accepted only when
//! enough of the scan lies on the map there and no other place explains it nearly as well.
//!
//! No allocation: the kept hypotheses live in a fixed array of [`MAX_KEEP`].

use crate::cell::{Axis, CellKey};
use crate::lattice::{LatticeTable, N};
use crate::map::MeshMap;
#[cfg(test)]
use crate::math::turned_in_yaw;
use crate::math::{rotation_angle, to_vec3, Point, Pose};

/// Candidate positions along a path (docs/design.md §1.13): its poses every `spacing_m`
/// metres of travel, each also moved `spacing_m` to its left and to its right (horizontally,
/// across its heading), given to `emit` in path order.
pub fn along_path<'a>(
    path: impl IntoIterator<Item = &'a Pose>,
    spacing_m: f64,
    mut emit: impl FnMut(Pose),
) {
    let mut last: Option<Pose> = None;
    for p in path {
        if last.is_some_and(|l| (l.translation.vector - p.translation.vector).norm() < spacing_m) {
            continue;
        }
        last = Some(*p);
        let heading = p.rotation * nalgebra::Vector3::x();
        let left = nalgebra::Vector3::new(-heading.y, heading.x, 0.0);
        let norm = left.norm();
        let left = if norm > 1e-6 {
            left / norm
        } else {
            nalgebra::Vector3::y()
        };
        for side in [0.0, 1.0, -1.0] {
            let mut c = *p;
            c.translation.vector += left * side * spacing_m;
            emit(c);
        }
    }
}

/// Most hypotheses a search registers in full.
pub const MAX_KEEP: usize = 16;
/// Most headings a search tries at one candidate position (every 5 degrees).
pub const MAX_YAW_STEPS: usize = 72;

/// How a search for the pose in a known map is run and judged.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Search {
    /// Headings tried at each candidate position, evenly round (24: every 15 degrees; at
    /// most [`MAX_YAW_STEPS`]).
    pub yaw_steps: usize,
    /// Points of the scan the coarse score uses (an even subsample of the filtered scan).
    pub coarse_points: usize,
    /// Distinct hypotheses registered in full, best coarse score first (at most [`MAX_KEEP`]).
    pub keep: usize,
    /// Two hypotheses are the same when closer than this (m) and turned less than
    /// `distinct_deg`.
    pub distinct_m: f64,
    /// See `distinct_m` (degrees).
    pub distinct_deg: f64,
    /// A point is on the map's surface when within this distance of it along the layer's
    /// axis in the coarse score (m).
    pub coarse_tol_m: f32,
    /// The same for the final judgement, after registration (m).
    pub fine_tol_m: f32,
    /// Least share of the scan's points on the map's surface at the pose found.
    pub min_hit_share: f64,
    /// Least share of the scan's points on the map's walls (x and y layers) at the pose
    /// found: the ground matches almost anywhere.
    pub min_wall_share: f64,
    /// The best distinct other pose must explain less than this share of what the found
    /// one does: a place that looks like another is not a place found.
    pub ambiguity_ratio: f64,
}

impl Default for Search {
    fn default() -> Self {
        Self {
            yaw_steps: 24,
            coarse_points: 256,
            keep: 8,
            distinct_m: 2.0,
            distinct_deg: 20.0,
            coarse_tol_m: 0.3,
            fine_tol_m: 0.1,
            min_hit_share: 0.3,
            min_wall_share: 0.1,
            ambiguity_ratio: 0.9,
        }
    }
}

/// Makes the map around a pose resident before the search uses it there: for a map paged in
/// from a file under a memory cap (the std crate's pager). The search calls it before each
/// chunk of [`CHUNK`] candidates (at the chunk's middle one) and before each registration.
pub trait Paging {
    /// Makes `map` hold what lies around `at`, as far as its budget allows.
    fn around(&mut self, map: &mut MeshMap, at: &Pose);
}

/// The whole map is resident: nothing to page.
#[derive(Debug, Clone, Copy, Default)]
pub struct AllResident;

impl Paging for AllResident {
    fn around(&mut self, _: &mut MeshMap, _: &Pose) {}
}

/// Candidates scored between two calls of [`Paging::around`] (consecutive candidates, which
/// lie close together when they follow a path).
pub const CHUNK: usize = 32;

/// How many points of a scan lie on the map's surfaces at a pose ([`surface_hits`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Hits {
    /// Points on any surface.
    pub any: usize,
    /// Points on a wall: a layer along x or y (the ground and ceilings, z layers, match a
    /// scan almost anywhere once its height is right; walls tell places apart).
    pub walls: usize,
    /// Points tried.
    pub total: usize,
}

impl Hits {
    /// `any` as a share of `total`.
    pub fn share(&self) -> f64 {
        self.any as f64 / self.total.max(1) as f64
    }

    /// `walls` as a share of `total`.
    pub fn wall_share(&self) -> f64 {
        self.walls as f64 / self.total.max(1) as f64
    }
}

/// Which of `points` (sensor frame) lie, at `pose`, within `tol_m` of a map surface whose
/// vertex there has a variance below `max_var`. A point is compared with each layer of the
/// cell it falls in, at the lattice vertex nearest to it.
pub fn surface_hits<'a>(
    map: &MeshMap,
    lattice: &LatticeTable,
    points: impl Iterator<Item = &'a Point>,
    pose: &Pose,
    tol_m: f32,
    max_var: f32,
) -> Hits {
    let mut h = Hits::default();
    for p in points {
        h.total += 1;
        let w = pose * nalgebra::Point3::from(to_vec3(p));
        let Some(key) = CellKey::containing(&w.coords, lattice.cell_size) else {
            continue;
        };
        let Some(cell) = map.cell(&key) else {
            continue;
        };
        let local = w.coords - key.min_corner(lattice.cell_size);
        let on = |axis: Axis| {
            let Some(layer) = map.layer(&key, axis) else {
                return false;
            };
            let (a, b) = axis.locations();
            let j = nearest(lattice, local[a]) * N + nearest(lattice, local[b]);
            match (layer.pred.get(j), layer.var.get(j)) {
                (Some(&d), Some(&v)) => {
                    v < max_var && libm::fabsf(d - local[axis.index()] as f32) < tol_m
                }
                _ => false,
            }
        };
        let wall = cell.axes().any(|a| a != Axis::Z && on(a));
        if wall || (cell.has(Axis::Z) && on(Axis::Z)) {
            h.any += 1;
        }
        h.walls += usize::from(wall);
    }
    h
}

/// The lattice index whose coordinate is nearest to `c` (metres from the cell's face).
fn nearest(lattice: &LatticeTable, c: f64) -> usize {
    let mut best = (f64::INFINITY, 0);
    for (i, x) in lattice.coordinates.iter().enumerate() {
        let d = libm::fabs(x - c);
        if d < best.0 {
            best = (d, i);
        }
    }
    best.1
}

/// Whether two poses are the same hypothesis under `search`'s distinctness rule.
pub fn same_place(a: &Pose, b: &Pose, search: &Search) -> bool {
    (a.translation.vector - b.translation.vector).norm() < search.distinct_m
        && rotation_angle(&(a.inverse() * b)) < search.distinct_deg.to_radians()
}

/// The best distinct hypotheses by score, best first: a fixed list of at most [`MAX_KEEP`].
#[derive(Debug, Clone)]
pub struct Shortlist {
    items: heapless::Vec<(usize, Pose), MAX_KEEP>,
    keep: usize,
}

impl Shortlist {
    /// An empty list keeping at most `keep` (and [`MAX_KEEP`]).
    pub fn new(keep: usize) -> Self {
        Self {
            items: heapless::Vec::new(),
            keep: keep.clamp(1, MAX_KEEP),
        }
    }

    /// Offers a hypothesis: kept if it beats the same place's entry (which it replaces) or,
    /// at a new place, the worst entry of a full list.
    pub fn offer(&mut self, score: usize, pose: Pose, search: &Search) {
        if let Some(i) = self
            .items
            .iter()
            .position(|(_, p)| same_place(p, &pose, search))
        {
            if self.items.get(i).is_some_and(|(s, _)| score > *s) {
                self.items.remove(i);
            } else {
                return;
            }
        }
        let at = self.items.partition_point(|(s, _)| *s >= score);
        if at >= self.keep {
            return;
        }
        if self.items.len() >= self.keep {
            self.items.pop();
        }
        let _ = self.items.insert(at, (score, pose));
    }

    /// The kept hypotheses, best first.
    pub fn items(&self) -> &[(usize, Pose)] {
        &self.items
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lattice::Lattice;
    use crate::layer::Layer;

    #[test]
    fn points_on_a_layer_hit_and_points_off_it_do_not() {
        let lattice = Lattice {
            cell_size: 1.6,
            full_cover: false,
        };
        let mut map = MeshMap::with_capacity(4, 4, lattice);
        // A floor 0.5 m above the bottom of cell (0, 0, 0).
        let mut floor = Layer::UNKNOWN;
        floor.pred = [0.5; 36];
        floor.var = [0.1; 36];
        map.insert_layer(CellKey::new(0, 0, 0), Axis::Z, floor, 0)
            .unwrap();
        let t = lattice.table();
        let points = [
            [0.3f32, 0.9, 0.52],
            [1.5, 0.1, 0.45],
            [0.8, 0.8, 1.2],
            [5.0, 0.0, 0.5],
        ];
        let h = surface_hits(&map, &t, points.iter(), &Pose::identity(), 0.1, 0.5);
        assert_eq!((h.any, h.walls, h.total), (2, 0, 4));
        // Lifted 0.3 m, no point is on it.
        let up = Pose::translation(0.0, 0.0, -0.3);
        assert_eq!(surface_hits(&map, &t, points.iter(), &up, 0.1, 0.5).any, 0);
        // Too uncertain a vertex does not count.
        assert_eq!(
            surface_hits(&map, &t, points.iter(), &Pose::identity(), 0.1, 0.05).any,
            0
        );
    }

    #[test]
    fn the_shortlist_keeps_the_best_distinct_places() {
        let s = Search {
            keep: 3,
            ..Search::default()
        };
        let mut list = Shortlist::new(s.keep);
        let at = |x: f64| Pose::translation(x, 0.0, 0.0);
        list.offer(5, at(0.0), &s);
        list.offer(9, at(0.5), &s); // the same place, better: replaces it
        list.offer(7, at(10.0), &s);
        list.offer(1, at(20.0), &s);
        list.offer(8, at(30.0), &s); // pushes the worst out
        list.offer(3, at(10.2), &s); // the same place, worse: ignored
        let scores: heapless::Vec<usize, 4> = list.items().iter().map(|(s, _)| *s).collect();
        assert_eq!(&scores[..], &[9, 8, 7]);
        // The same position turned far is another hypothesis.
        list.offer(8, turned_in_yaw(&at(30.0), 1.0), &s);
        assert_eq!(list.items().len(), 3);
        assert_eq!(list.items()[1].0, 8);
    }
}
