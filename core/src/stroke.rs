//! A stroke: one scan ring's crossing of a cell, a line no wider than the range noise
//! ([`crate::pca::Shape::Stroke`]).
//!
//! Any surface that holds the line fits a stroke, and the normal PCA finds for it is the
//! direction across the ring in which the noise does not spread: level for a ring along a wall
//! as for a ring across the ground, since both run level and are spread along the ray. A
//! 16-beam scanner indoors crosses most wall cells with a single ring, so taken as it comes a
//! stroke on a wall becomes a level layer: a shelf along the wall that is not there (the
//! GP's prediction, a few centimetres out from the wall at the ring's height, which the
//! navigation map calls an obstacle beside the wall's own cell; docs/benchmarks.md,
//! "A wall's ring is no shelf").
//!
//! [`stroke_axes`] reads the map around the cell: a level guess whose line lies on a standing
//! layer of the map, in the cell or the cells above and below it (the wall it crosses), takes
//! that layer's axis instead. Anywhere else (far ground, a desk's top, a cell the map has not
//! seen) the guess stands: a single ring is most of what a 16-beam scanner sees of a floor.
//!
//! Owns: the choice of a stroke's layers. Guarantees: reads the map only; stack only; never
//! panics (a layer with too few known vertices tells nothing).

use crate::cell::{Axis, CellKey};
use crate::config::Config;
use crate::map::MeshMap;
use crate::math::Point;
use heapless::Vec as HVec;

/// How far (m) a stroke's line may lie from a standing layer's surface, along its axis, to be
/// taken as a ring on it: twice the range noise of the sensors in docs/design.md §3.
pub const ON_SURFACE_M: f64 = 0.05;

/// The fewest vertices of a standing layer under the shown variance for its surface to be
/// compared: a row of the lattice.
const KNOWN_VERTICES: usize = 6;

/// The layers of the stroke `points` (cell-local) of cell `key`, whose PCA gave `guess`
/// (best-aligned axis first): a level guess on a wall's surface (see the module) becomes that
/// wall's axis.
pub fn stroke_axes(
    points: &[(CellKey, Point)],
    key: CellKey,
    map: &MeshMap,
    cfg: &Config,
    guess: HVec<Axis, 3>,
) -> HVec<Axis, 3> {
    if guess.first() != Some(&Axis::Z) || points.is_empty() {
        return guess;
    }
    let n = points.len() as f64;
    let mean = |k: usize| points.iter().map(|(_, p)| f64::from(p[k])).sum::<f64>() / n;
    let show = cfg.mesh.variance_show as f32;
    for axis in [Axis::X, Axis::Y] {
        let line_at = mean(axis.index());
        let on_wall = [Some(key), key.offset(Axis::Z, 1), key.offset(Axis::Z, -1)]
            .into_iter()
            .flatten()
            .filter_map(|k| map.layer(&k, axis))
            .any(|layer| {
                let known = layer
                    .pred
                    .iter()
                    .zip(&layer.var)
                    .filter(|(_, v)| **v < show);
                let count = known.clone().count();
                count >= KNOWN_VERTICES && {
                    let at = known.map(|(p, _)| f64::from(*p)).sum::<f64>() / count as f64;
                    libm::fabs(at - line_at) <= ON_SURFACE_M
                }
            });
        if on_wall {
            let mut axes = HVec::new();
            // One axis into a capacity of three cannot fail.
            let _ = axes.push(axis);
            return axes;
        }
    }
    guess
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::facing::Facing;
    use crate::gp::GpScratch;
    use crate::lattice::VERTICES;
    use crate::layer::Layer;
    use crate::pca::{choose_layers, Shape};
    use crate::reconstruct::{reconstruct_cell, Purpose};

    /// One ring's stroke across cell `(0, 0, 0)`, cell-local: along y at `x` (2 cm of range
    /// noise across it), level at 0.5 m.
    fn ring_at(x: f32) -> heapless::Vec<(CellKey, Point), 64> {
        (0..40)
            .map(|i| {
                let noise = if i % 2 == 0 { 0.02 } else { -0.02 };
                let wobble = if i % 3 == 0 { 0.001 } else { 0.0 };
                (
                    CellKey::default(),
                    [x + noise, 0.05 + 0.035 * i as f32, 0.5 + wobble],
                )
            })
            .collect()
    }

    /// A map whose cell above `(0, 0, 0)` holds a wall along x at `x` (cell-local).
    fn wall_above_at(cfg: &Config, x: f32) -> MeshMap {
        let mut map = MeshMap::with_capacity(8, 8, cfg.lattice());
        let wall = Layer {
            pred: [x; VERTICES],
            var: [0.05; VERTICES],
            facing: Facing::Unknown,
        };
        map.insert_layer(CellKey::new(0, 0, 1), Axis::X, wall, 0)
            .unwrap();
        map
    }

    fn axes(v: &[Axis]) -> HVec<Axis, 3> {
        HVec::from_slice(v).unwrap()
    }

    #[test]
    fn a_ring_is_a_stroke_whose_normal_is_level() {
        assert_eq!(
            choose_layers::<f64>(&ring_at(0.3)),
            Shape::Stroke(axes(&[Axis::Z]))
        );
    }

    #[test]
    fn a_ring_on_the_wall_above_takes_the_wall_s_axis() {
        let cfg = Config::default();
        let map = wall_above_at(&cfg, 0.3);
        let key = CellKey::default();
        let got = stroke_axes(&ring_at(0.3), key, &map, &cfg, axes(&[Axis::Z]));
        assert_eq!(got, axes(&[Axis::X]));
        // Through the reconstruction: one layer, standing, at the wall.
        let mut scratch = GpScratch::<f64>::new();
        let cell = reconstruct_cell(
            &mut scratch,
            &ring_at(0.3),
            key,
            &map,
            &cfg,
            Purpose::Update,
        );
        assert_eq!(cell.layers.len(), 1);
        assert_eq!(cell.layers[0].axis, Axis::X);
        let known = cell.layers[0]
            .layer
            .pred
            .iter()
            .zip(&cell.layers[0].layer.var);
        for (p, _) in known.filter(|(_, v)| **v < 0.3) {
            assert!((p - 0.3).abs() < 0.03, "{p}");
        }
    }

    #[test]
    fn a_ring_off_the_wall_or_with_no_wall_near_stays_level() {
        let cfg = Config::default();
        let key = CellKey::default();
        let level = axes(&[Axis::Z]);
        // A desk's top 25 cm out from the wall.
        let map = wall_above_at(&cfg, 0.3);
        assert_eq!(
            stroke_axes(&ring_at(0.55), key, &map, &cfg, level.clone()),
            level
        );
        // Nothing in the map; a wall two cells up.
        let empty = MeshMap::with_capacity(8, 8, cfg.lattice());
        assert_eq!(
            stroke_axes(&ring_at(0.3), key, &empty, &cfg, level.clone()),
            level
        );
        let mut far = MeshMap::with_capacity(8, 8, cfg.lattice());
        let wall = *map.layer(&CellKey::new(0, 0, 1), Axis::X).unwrap();
        far.insert_layer(CellKey::new(0, 0, 2), Axis::X, wall, 0)
            .unwrap();
        assert_eq!(
            stroke_axes(&ring_at(0.3), key, &far, &cfg, level.clone()),
            level
        );
        // A wall the map is unsure of tells nothing.
        let mut unsure = MeshMap::with_capacity(8, 8, cfg.lattice());
        let vague = Layer {
            var: [cfg.mesh.variance_show as f32 * 1.5; VERTICES],
            ..wall
        };
        unsure
            .insert_layer(CellKey::new(0, 0, 1), Axis::X, vague, 0)
            .unwrap();
        assert_eq!(
            stroke_axes(&ring_at(0.3), key, &unsure, &cfg, level.clone()),
            level
        );
        // A guess that already stands is left as it is.
        let standing = axes(&[Axis::Y]);
        assert_eq!(
            stroke_axes(&ring_at(0.3), key, &map, &cfg, standing.clone()),
            standing
        );
    }
}
