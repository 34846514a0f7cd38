//! Reconstruction of one cell: layer choice, then a GP per layer (docs/design.md §1.1 step 4).
//!
//! [`reconstruct_cell`] is the per-cell unit of work: pure, reading the map only to give a
//! line-like cell the layers the map already has there. [`reconstruct_cells`] runs it over a
//! scan's cells on an [`Executor`], which gives the same layers whatever its threads.

use crate::bounded::BoundedVec;
use crate::bucket::CellSpan;
use crate::cell::{Axis, CellKey};
use crate::config::Config;
use crate::executor::Executor;
use crate::gp::{self, GpScratch};
use crate::layer::ScanLayer;
use crate::map::MeshMap;
use crate::math::Point;
use crate::pca::{choose_layers, Shape};
use crate::real::Real;

/// What a reconstruction is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Purpose {
    /// A registration round with this cross-cell reach: a layer with no map layer of its axis
    /// within reach could not pair with anything, so its GP is not computed, and variances
    /// are exact only where they could reach `variance_register` (elsewhere an upper bound:
    /// see [`gp::Variances::Below`]), which is all association asks of them.
    Register {
        /// The round's reach.
        reach: u32,
        /// Only the cells of [`in_checkerboard`] (a coarse round with
        /// [`RegisterConfig::coarse_half_cells`](crate::config::RegisterConfig::coarse_half_cells)).
        half_cells: bool,
        /// Map cells last seen before this frame are stale and left out
        /// ([`MapConfig::stale_after_frames`](crate::config::MapConfig::stale_after_frames)).
        since: u32,
    },
    /// The map update: every layer.
    Update,
}

/// One cell's reconstruction.
#[derive(Debug, Clone, Default)]
pub struct CellLayers {
    /// Its layers (at most three).
    pub layers: heapless::Vec<ScanLayer, 3>,
    /// Layers its surface called for that a registration round left out for having no map
    /// layer within reach: with the layers paired, the scan's overlap with the map.
    pub unpaired: usize,
}

/// What [`reconstruct_cells`] did besides filling its output.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ReconstructStats {
    /// Layers that did not fit the output.
    pub dropped: usize,
    /// Layers left out for having no map layer within reach (see [`CellLayers::unpaired`]).
    pub unpaired: usize,
}

/// Reconstructs the layers of cell `key` from its cell-local `points` (at most three layers;
/// a layer whose GP fails is left out, and so is one `purpose` has no use for). `scratch` is
/// the GP's working memory (any content: the result does not depend on it); its scalar `R`
/// is the GP's ([`Real`]).
pub fn reconstruct_cell<R: Real>(
    scratch: &mut GpScratch<R>,
    points: &[(CellKey, Point)],
    key: CellKey,
    map: &MeshMap,
    cfg: &Config,
    purpose: Purpose,
) -> CellLayers {
    if let Purpose::Register {
        half_cells: true, ..
    } = purpose
    {
        if !in_checkerboard(key) {
            return CellLayers::default();
        }
    }
    let mut axes = heapless::Vec::<Axis, 3>::new();
    match choose_layers::<R>(points) {
        Shape::Surface(a) => axes = a,
        Shape::LineLike => {
            if let Some(cell) = map.cell(&key) {
                for a in cell.axes() {
                    let _ = axes.push(a);
                }
            }
        }
        Shape::Unclear => {}
    }
    let lattice = cfg.lattice();
    let mut out = CellLayers::default();
    for axis in axes {
        if let Purpose::Register { reach, since, .. } = purpose {
            if !crate::associate::has_candidates(map, key, axis, reach, since) {
                out.unpaired += 1;
                continue;
            }
        }
        let variances = match purpose {
            Purpose::Register { .. } => gp::Variances::Below(cfg.register.variance_register),
            Purpose::Update => gp::Variances::Exact,
        };
        let samples = gp::select_training(points, axis, lattice.cell_size);
        if let Ok(layer) = gp::predict_in(scratch, &samples, &lattice, &cfg.gp, variances) {
            // At most three axes: cannot overflow.
            let _ = out.layers.push(ScanLayer { key, axis, layer });
        }
    }
    out
}

/// Half the cells, every other one along each axis: those whose indices sum to an even number.
#[inline]
pub fn in_checkerboard(key: CellKey) -> bool {
    // The low bit of a two's-complement integer is its parity, negative ones included.
    (key.x ^ key.y ^ key.z) & 1 == 0
}

/// Reconstructs `cells` (spans into `bucketed`), one [`reconstruct_cell`] per cell run by
/// `exec`, and appends their layers to `out` in cell order via [`append_layers`].
pub fn reconstruct_cells<R: Real>(
    cells: &[CellSpan],
    bucketed: &[(CellKey, Point)],
    map: &MeshMap,
    cfg: &Config,
    purpose: Purpose,
    out: &mut BoundedVec<ScanLayer>,
    exec: &impl Executor,
) -> ReconstructStats {
    let mut stats = ReconstructStats::default();
    exec.map_in_order(
        cells,
        GpScratch::<R>::new,
        |scratch, c| reconstruct_cell(scratch, c.points(bucketed), c.key, map, cfg, purpose),
        |cell| {
            stats.dropped += append_layers(out, &cell.layers);
            stats.unpaired += cell.unpaired;
        },
    );
    stats
}

/// Appends one cell's layers to `out`; layers that do not fit are dropped (the scan keeps its
/// first cells in key order) and counted in the return value.
pub fn append_layers(out: &mut BoundedVec<ScanLayer>, layers: &[ScanLayer]) -> usize {
    layers.iter().filter(|l| out.push(**l).is_err()).count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lattice::VERTICES;
    use crate::layer::Layer;

    /// A flat ground patch, cell-local, 20 x 20 points over a 1.6 m cell at height 0.5.
    fn ground() -> heapless::Vec<(CellKey, Point), 400> {
        (0..400)
            .map(|i| {
                let (a, b) = ((i / 20) as f32 * 0.08 + 0.04, (i % 20) as f32 * 0.08 + 0.04);
                (CellKey::default(), [a, b, 0.5])
            })
            .collect()
    }

    #[test]
    fn the_checkerboard_holds_every_other_cell_negative_indices_included() {
        let parity = |x: i32, y: i32, z: i32| in_checkerboard(CellKey::new(x, y, z));
        assert!(parity(0, 0, 0) && parity(1, 1, 0) && parity(-1, 0, 1) && parity(-3, -5, 0));
        assert!(!parity(1, 0, 0) && !parity(0, 0, -1) && !parity(-1, -1, -1));
        // Each cell's six face neighbours are on the other colour.
        for key in [CellKey::new(4, -7, 2), CellKey::new(-1, 0, 3)] {
            for (dx, dy, dz) in [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1)] {
                let n = CellKey::new(key.x + dx, key.y + dy, key.z + dz);
                assert_ne!(in_checkerboard(key), in_checkerboard(n));
            }
        }
    }

    #[test]
    fn coarse_rounds_with_half_cells_skip_the_other_colour_only() {
        let cfg = Config::default();
        let mut map = MeshMap::with_capacity(8, 8, cfg.lattice());
        let flat = Layer {
            pred: [0.5; VERTICES],
            var: [0.05; VERTICES],
            facing: crate::facing::Facing::Unknown,
        };
        let (even, odd) = (CellKey::new(2, 0, 0), CellKey::new(3, 0, 0));
        for key in [even, odd] {
            map.insert_layer(key, Axis::Z, flat, 0).unwrap();
        }
        let points = ground();
        let mut scratch = GpScratch::<f64>::new();
        let mut layers = |key, purpose| {
            reconstruct_cell(&mut scratch, &points, key, &map, &cfg, purpose)
                .layers
                .len()
        };
        let coarse = Purpose::Register {
            reach: 1,
            half_cells: true,
            since: 0,
        };
        let all = Purpose::Register {
            reach: 1,
            half_cells: false,
            since: 0,
        };
        assert_eq!(layers(even, coarse), 1);
        assert_eq!(layers(odd, coarse), 0);
        assert_eq!(layers(odd, all), 1);
        assert_eq!(layers(odd, Purpose::Update), 1);
    }
}
