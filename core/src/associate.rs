//! Location-indexed association and per-layer residual combination (docs/design.md §1.4).
//!
//! Scan and map vertices sit on the same world lattice, so vertex `j` of a scan layer pairs
//! with vertex `j` of a map layer of the same axis in the same cell or, with cross-cell reach
//! `L`, in the cells `c ± i·e_axis` (`i ≤ L`); the candidate with the smallest `|Δd|` wins.
//! A pair counts when both variances are below `variance_register` and the map vertex has a
//! normal. The pairs of one scan layer are averaged (mean scan point, mean map point, mean
//! normal) into one residual. No k-d tree, no heap: the output is the caller's bounded buffer.

use crate::bounded::BoundedVec;
use crate::cell::{Axis, CellKey};
use crate::config::MAX_REACH;
use crate::executor::Executor;
use crate::lattice::{LatticeTable, VERTICES};
use crate::layer::{Layer, ScanLayer};
use crate::lm::Residual;
use crate::map::MeshMap;
use crate::math::Vec3;
use crate::real::Real;

/// What association found for one scan.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AssociateStats {
    /// Vertex pairs used.
    pub pairs: usize,
    /// Combined residuals written.
    pub residuals: usize,
}

/// Candidate map layers per scan layer: the cell and `2 · reach` neighbours along the axis;
/// a reach beyond [`MAX_REACH`] is cut to it.
const MAX_CANDIDATES: usize = 2 * MAX_REACH as usize + 1;

/// The map layers of `axis` in cell `key` and the cells `key ± i·e_axis`, `i ≤ reach`, with
/// their offset `i`: what a scan layer there can pair with, looked up once per scan layer.
/// Cells last seen before frame `since` are stale and left out.
fn candidates(
    map: &MeshMap,
    key: CellKey,
    axis: Axis,
    reach: u32,
    since: u32,
) -> heapless::Vec<(i32, CellKey, &Layer), MAX_CANDIDATES> {
    let reach = reach.min(MAX_REACH) as i32;
    let mut out = heapless::Vec::new();
    for i in -reach..=reach {
        let Some(k) = key.offset(axis, i) else {
            continue;
        };
        if let Some(m) = map.layer_seen_since(&k, axis, since) {
            // At most 2 · MAX_REACH + 1 offsets: cannot overflow.
            let _ = out.push((i, k, m));
        }
    }
    out
}

/// Whether a scan layer of `axis` in cell `key` has anything to pair with at `reach` among
/// the cells seen since frame `since`.
pub fn has_candidates(map: &MeshMap, key: CellKey, axis: Axis, reach: u32, since: u32) -> bool {
    // The cell itself first: where the map has the layer (most cells) one lookup decides.
    map.layer_seen_since(&key, axis, since).is_some()
        || !candidates(map, key, axis, reach, since).is_empty()
}

/// Writes one combined residual per scan layer that has map pairs into `out` (cleared first),
/// in scan order, one [`Associator::layer`] per layer run by `exec`; stops when `out` is full.
/// Map cells last seen before frame `since` are left out (0: none).
pub fn associate<R: Real>(
    scan: &[ScanLayer],
    map: &MeshMap,
    reach: u32,
    since: u32,
    variance_register: f64,
    out: &mut BoundedVec<Residual>,
    exec: &impl Executor,
) -> AssociateStats {
    let a = Associator::new(map, reach, variance_register).seen_since(since);
    out.clear();
    let mut stats = AssociateStats::default();
    let mut full = false;
    exec.map_in_order(
        scan,
        || (),
        |(), s| a.layer::<R>(s),
        |per_layer| {
            let Some((r, pairs)) = per_layer else {
                return;
            };
            if full || out.push(r).is_err() {
                full = true;
                return;
            }
            stats.pairs += pairs;
        },
    );
    stats.residuals = out.len();
    stats
}

/// Association of one scan layer at a time against a map: the unit a parallel loop runs.
#[derive(Debug, Clone, Copy)]
pub struct Associator<'a> {
    map: &'a MeshMap,
    lattice: LatticeTable,
    reach: u32,
    since: u32,
    max_var: f32,
}

impl<'a> Associator<'a> {
    /// Pairs against `map` with cross-cell `reach`, vertices below `variance_register`.
    pub fn new(map: &'a MeshMap, reach: u32, variance_register: f64) -> Self {
        Self {
            map,
            lattice: map.lattice().table(),
            reach,
            since: 0,
            max_var: variance_register as f32,
        }
    }

    /// Leaves out the map cells last seen before frame `since`.
    pub fn seen_since(self, since: u32) -> Self {
        Self { since, ..self }
    }

    /// The combined residual of scan layer `s` and how many vertex pairs it averages, or
    /// `None` when nothing pairs. The normals are computed and summed in the scalar `R`
    /// ([`Real`]); the vertices, in world coordinates, in `f64`.
    pub fn layer<R: Real>(&self, s: &ScanLayer) -> Option<(Residual, usize)> {
        let (lattice, max_var) = (&self.lattice, self.max_var);
        let (mut sum_p, mut sum_q, mut sum_n, mut count) =
            (Vec3::zeros(), Vec3::zeros(), [R::ZERO; 3], 0usize);
        let candidates = candidates(self.map, s.key, s.axis, self.reach, self.since);
        for j in 0..VERTICES {
            if !(s.layer.var[j] < max_var) {
                continue;
            }
            let d_scan = f64::from(s.layer.pred[j]);
            // (|Δd|, key, layer) of the nearest usable map vertex along the axis.
            let mut best = None;
            for &(i, key, m) in &candidates {
                if !(m.var[j] < max_var) {
                    continue;
                }
                let dd =
                    libm::fabs(f64::from(i) * lattice.cell_size + f64::from(m.pred[j]) - d_scan);
                if best.is_none_or(|(b, _, _)| dd < b) {
                    best = Some((dd, key, m));
                }
            }
            let Some((_, key, m)) = best else { continue };
            let Some(n) = m.normal_in::<R>(lattice, s.axis, j, max_var) else {
                continue;
            };
            sum_p += s.layer.vertex(lattice, &s.key, s.axis, j);
            sum_q += m.vertex(lattice, &key, s.axis, j);
            for k in 0..3 {
                sum_n[k] += n[k];
            }
            count += 1;
        }
        let sum_n = Vec3::new(sum_n[0].to_f64(), sum_n[1].to_f64(), sum_n[2].to_f64());
        let norm = sum_n.norm();
        if count == 0 || !(norm > 1e-9) {
            return None;
        }
        let c = count as f64;
        let r = Residual {
            p: sum_p / c,
            q: sum_q / c,
            n: sum_n / norm,
            weight: 1.0,
        };
        Some((r, count))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lattice::Lattice;

    const LAT: Lattice = Lattice {
        cell_size: 1.6,
        full_cover: false,
    };

    fn flat(d: f32) -> Layer {
        Layer {
            pred: [d; VERTICES],
            var: [0.05; VERTICES],
            facing: crate::facing::Facing::Unknown,
        }
    }

    #[test]
    fn pairs_same_cell_and_reaches_across_cells() {
        let mut map = MeshMap::with_capacity(8, 8, LAT);
        map.insert_layer(CellKey::new(0, 0, 1), Axis::Z, flat(0.2), 0)
            .unwrap();
        // The scan sees the same ground 0.3 m lower: one cell down, near its top face.
        let scan = [ScanLayer {
            key: CellKey::new(0, 0, 0),
            axis: Axis::Z,
            layer: flat(1.5),
        }];
        let mut out = BoundedVec::with_capacity(4);
        assert_eq!(
            associate::<f64>(&scan, &map, 0, 0, 0.6, &mut out, &crate::executor::Serial).residuals,
            0
        );
        let s = associate::<f64>(&scan, &map, 1, 0, 0.6, &mut out, &crate::executor::Serial);
        assert_eq!((s.pairs, s.residuals), (36, 1));
        let r = out[0];
        assert!((r.n - Vec3::z()).norm() < 1e-9);
        // e = nᵀ(p - q) = 1.5 - (1.6 + 0.2) = -0.3.
        assert!((r.error(&crate::Pose::identity()) + 0.3).abs() < 1e-6);
    }

    #[test]
    fn stale_cells_are_left_out() {
        let mut map = MeshMap::with_capacity(8, 8, LAT);
        map.insert_layer(CellKey::new(0, 0, 0), Axis::Z, flat(0.2), 5)
            .unwrap();
        let scan = [ScanLayer {
            key: CellKey::new(0, 0, 0),
            axis: Axis::Z,
            layer: flat(0.3),
        }];
        let mut out = BoundedVec::with_capacity(4);
        let serial = &crate::executor::Serial;
        assert_eq!(
            associate::<f64>(&scan, &map, 1, 5, 0.6, &mut out, serial).residuals,
            1
        );
        assert_eq!(
            associate::<f64>(&scan, &map, 1, 6, 0.6, &mut out, serial).residuals,
            0
        );
        assert!(has_candidates(&map, CellKey::new(0, 0, 0), Axis::Z, 1, 5));
        assert!(!has_candidates(&map, CellKey::new(0, 0, 0), Axis::Z, 1, 6));
    }

    #[test]
    fn uncertain_vertices_are_not_paired() {
        let mut map = MeshMap::with_capacity(8, 8, LAT);
        let mut m = flat(0.4);
        for v in m.var.iter_mut().take(18) {
            *v = 0.9;
        }
        map.insert_layer(CellKey::new(0, 0, 0), Axis::Z, m, 0)
            .unwrap();
        let scan = [ScanLayer {
            key: CellKey::new(0, 0, 0),
            axis: Axis::Z,
            layer: flat(0.5),
        }];
        let mut out = BoundedVec::with_capacity(4);
        assert_eq!(
            associate::<f64>(&scan, &map, 0, 0, 0.6, &mut out, &crate::executor::Serial).pairs,
            18
        );
    }
}
