//! The map update's reconstruction from the last registration round's (docs/design.md §1.1
//! step 6, `MapConfig::reuse_unchanged_layers`).
//!
//! The last round reconstructs the scan a centimetre or so from its final pose. At the final
//! pose most layers choose the very same points as training samples, and the GP's kernel
//! depends only on the samples' differences: a layer trained on the same points moved
//! rigidly is the old layer moved, up to the motion's second order. [`refresh_cell`] takes
//! the last round's layer, moved ([`Layer::moved`](crate::layer::Layer::moved)), where the layer's samples at the final
//! pose are its samples at the last round's ([`TrainingBrief`]), and reconstructs the others.
//! Owns no memory.

use crate::cell::{Axis, CellKey};
use crate::config::Config;
use crate::gp::{self, GpScratch, TrainingBrief};
use crate::lattice::LatticeTable;
use crate::layer::ScanLayer;
use crate::map::MeshMap;
use crate::math::{Point, Pose, Vec3};
use crate::reconstruct::{layer_axes, CellLayers};

/// Two training sets whose briefs differ by less than this a sample (metres, each coordinate)
/// are the same points: one point placed at two poses differs by the rounding of its `f32`
/// coordinates and the brief's `f32` sum (a few micrometres), two points of a down-sampled
/// scan by centimetres.
const SAME_POINT_M: f64 = 1e-4;

/// The last registration round's reconstruction, as [`refresh_cell`] reads it.
#[derive(Debug, Clone, Copy)]
pub struct Before<'a> {
    /// Its layers, in cell order, with exact variances.
    pub layers: &'a [ScanLayer],
    /// The world motion from the pose it was made at to the final pose.
    pub motion: Pose,
    /// The lattice the layers live on.
    pub lattice: LatticeTable,
}

impl Before<'_> {
    /// The last round's layer of `axis` in cell `key`.
    fn layer(&self, key: CellKey, axis: Axis) -> Option<&ScanLayer> {
        let start = self.layers.partition_point(|l| l.key < key);
        self.layers
            .get(start..)?
            .iter()
            .take_while(|l| l.key == key)
            .find(|l| l.axis == axis)
    }
}

/// Cell `key`'s layers at the final pose from its cell-local `points` there, as
/// [`reconstruct_cell`](crate::reconstruct::reconstruct_cell) makes them for the map update
/// (every layer, exact variances), taking `before`'s layer, moved, where the layer's training
/// samples are the same points, and reconstructing the rest.
pub fn refresh_cell(
    scratch: &mut GpScratch,
    points: &[(CellKey, Point)],
    key: CellKey,
    map: &MeshMap,
    cfg: &Config,
    before: &Before<'_>,
) -> CellLayers {
    let lattice = cfg.lattice();
    let corner = key.min_corner(lattice.cell_size);
    let back = before.motion.inverse();
    let mut out = CellLayers::default();
    for axis in layer_axes(points, key, map) {
        let samples = gp::select_training(points, axis, lattice.cell_size);
        let trained = TrainingBrief::of(&samples);
        let then = placed(&trained, axis, &back, &corner);
        let layer = match before.layer(key, axis) {
            Some(old) if old.trained.matches(&then, SAME_POINT_M) => {
                out.reused += 1;
                old.layer.moved(&before.lattice, &key, axis, &before.motion)
            }
            _ => match gp::predict_in(scratch, &samples, &lattice, &cfg.gp, gp::Variances::Exact) {
                Ok(layer) => layer,
                Err(_) => continue,
            },
        };
        // At most three axes: cannot overflow.
        let _ = out.layers.push(ScanLayer {
            key,
            axis,
            layer,
            trained,
        });
    }
    out
}

/// The brief of `brief`'s samples (`(a, b, d)` of `axis`, local to the cell at `corner`) each
/// moved by `motion`, local to the same cell: the motion is affine, so the sum of the moved
/// samples is the sum moved, `R Σ s + n (R c + t - c)`.
fn placed(brief: &TrainingBrief, axis: Axis, motion: &Pose, corner: &Vec3) -> TrainingBrief {
    let (ia, ib) = axis.locations();
    let d = axis.index();
    let mut sum = Vec3::zeros();
    (sum[ia], sum[ib], sum[d]) = (
        f64::from(brief.sum[0]),
        f64::from(brief.sum[1]),
        f64::from(brief.sum[2]),
    );
    let offset = (motion * nalgebra::Point3::from(*corner)).coords - corner;
    let moved = motion.rotation * sum + offset * f64::from(brief.count);
    TrainingBrief {
        count: brief.count,
        sum: [moved[ia] as f32, moved[ib] as f32, moved[d] as f32],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gp::GpScratch;
    use crate::reconstruct::{reconstruct_cell, Purpose};

    /// A gently curved ground patch, cell-local: 20 x 20 points over a 1.6 m cell.
    fn ground(shift: [f32; 3]) -> heapless::Vec<(CellKey, Point), 401> {
        (0..400)
            .map(|i| {
                let (a, b) = ((i / 20) as f32 * 0.08 + 0.04, (i % 20) as f32 * 0.08 + 0.04);
                let z = 0.5 + 0.05 * (a - 0.8) * (a - 0.8);
                (
                    CellKey::default(),
                    [a + shift[0], b + shift[1], z + shift[2]],
                )
            })
            .collect()
    }

    fn config() -> Config {
        Config::default()
    }

    fn layers(points: &[(CellKey, Point)]) -> heapless::Vec<ScanLayer, 3> {
        let map = MeshMap::with_capacity(4, 4, config().lattice());
        reconstruct_cell(
            &mut GpScratch::new(),
            points,
            CellKey::default(),
            &map,
            &config(),
            Purpose::Update,
        )
        .layers
    }

    fn refreshed(before: &[ScanLayer], points: &[(CellKey, Point)], motion: Pose) -> CellLayers {
        let map = MeshMap::with_capacity(4, 4, config().lattice());
        let b = Before {
            layers: before,
            motion,
            lattice: config().lattice().table(),
        };
        refresh_cell(
            &mut GpScratch::new(),
            points,
            CellKey::default(),
            &map,
            &config(),
            &b,
        )
    }

    #[test]
    fn a_layer_trained_on_the_same_points_is_moved_not_reconstructed() {
        let then = layers(&ground([0.0; 3]));
        assert_eq!(then.len(), 1);
        // The same points 3 mm up: every sample is the same point.
        let now = ground([0.0, 0.0, 0.003]);
        let motion = Pose::translation(0.0, 0.0, 0.003);
        let got = refreshed(&then, &now, motion);
        assert_eq!((got.reused, got.layers.len()), (1, 1));
        let fresh = layers(&now);
        let (a, b) = (&got.layers[0].layer, &fresh[0].layer);
        for j in 0..a.pred.len() {
            assert!((a.pred[j] - b.pred[j]).abs() < 1e-4, "vertex {j}");
            assert!((a.var[j] - b.var[j]).abs() < 1e-4, "vertex {j}");
        }
        assert_eq!(got.layers[0].trained, fresh[0].trained);
    }

    #[test]
    fn a_layer_whose_samples_changed_is_reconstructed() {
        let then = layers(&ground([0.0; 3]));
        // A new point at the centre of the first bin is that bin's sample now.
        let mut now = ground([0.0; 3]);
        let centre = 1.6 / 6.0 / 2.0;
        let _ = now.push((CellKey::default(), [centre, centre, 0.52]));
        let got = refreshed(&then, &now, Pose::identity());
        assert_eq!((got.reused, got.layers.len()), (0, 1));
        assert_eq!(got.layers[0], layers(&now)[0]);
        // No layer of the last round to take: reconstructed too.
        let got = refreshed(&[], &now, Pose::identity());
        assert_eq!(got.reused, 0);
        assert_eq!(got.layers[0], layers(&now)[0]);
    }
}
