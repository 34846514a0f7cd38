//! Map update by inverse-variance fusion of 1-D predictions (docs/design.md §1.5).
//!
//! Vertex locations are fixed, so fusing a scan into the map is fusing, per vertex, two
//! scalar estimates, when the two face the same way ([`Facing`], decided by [`face`]) or lie
//! within a sheet's thickness of each other; a scan layer facing the other way and farther
//! off (the other face of a wall) replaces the map's. New cells are inserted; a layer a known
//! cell lacks is added when [`MapConfig::add_missing_layers`] is set. Map-capacity refusals
//! are counted, never fatal.

use crate::cell::Axis;
use crate::config::MapConfig;
use crate::executor::Executor;
use crate::facing::{Facing, MIN_THICKNESS_M};
use crate::lattice::{LatticeTable, VERTICES};
use crate::layer::{Layer, ScanLayer};
use crate::map::MeshMap;
use crate::math::Vec3;

/// Fuses map estimate `(u, var_u)` with observation `(o, var_o)`: inverse-variance weighting
/// when both variances are below `variance_update`, else the one with the smaller variance.
#[inline]
pub fn fuse_vertex(u: f32, var_u: f32, o: f32, var_o: f32, variance_update: f32) -> (f32, f32) {
    // Every case computed, then one chosen: no branch, so a layer's 36 vertices vectorize
    // (a quotient by a zero sum is computed and dropped).
    let sum = var_u + var_o;
    let weighted = ((u * var_o + o * var_u) / sum, var_u * var_o / sum);
    let midway = ((u + o) * 0.5, 0.0);
    let better = select(var_o < var_u, (o, var_o), (u, var_u));
    let both_known = (var_u < variance_update) & (var_o < variance_update);
    select(both_known, select(sum > 0.0, weighted, midway), better)
}

/// `a` if `c`, else `b`.
#[inline]
fn select(c: bool, a: (f32, f32), b: (f32, f32)) -> (f32, f32) {
    if c {
        a
    } else {
        b
    }
}

/// What one map update did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FusionStats {
    /// Layers fused into existing map layers.
    pub fused: usize,
    /// Layers added to the map.
    pub added: usize,
    /// Layers not added because the map was full.
    pub refused: usize,
    /// Stale cells whose layers the scan replaced.
    pub refreshed: usize,
    /// Map layers replaced by a scan layer facing the other way (docs/design.md §1.5).
    pub turned: usize,
}

/// The frame before which a cell last seen is stale at `frame`
/// ([`MapConfig::stale_after_frames`]; 0: none is).
pub fn stale_before(frame: u32, cfg: &MapConfig) -> u32 {
    match cfg.stale_after_frames {
        0 => 0,
        n => frame.saturating_sub(n),
    }
}

/// Decides the [`Facing`] of each of the scan's layers, seen from the sensor at `viewpoint`
/// (world), counting the vertices with a variance below `max_var`. Each layer's on its own,
/// spread over `exec`.
pub fn face(
    scan: &mut [ScanLayer],
    lattice: &LatticeTable,
    viewpoint: &Vec3,
    max_var: f32,
    exec: &impl Executor,
) {
    exec.update_each(scan, |s| {
        let surface = (&s.layer.pred, &s.layer.var);
        s.layer.facing = Facing::seen_from(surface, lattice, &s.key, s.axis, viewpoint, max_var);
    });
}

/// Fuses the scan's layers into `map`, marking their cells seen at `frame`. A stale cell
/// ([`stale_before`]) has every layer's vertices made unknown first, so that the scan
/// replaces what it held.
pub fn integrate(
    map: &mut MeshMap,
    scan: &[ScanLayer],
    cfg: &MapConfig,
    frame: u32,
) -> FusionStats {
    let threshold = cfg.variance_update as f32;
    let since = stale_before(frame, cfg);
    let mut stats = FusionStats::default();
    for s in scan {
        if since > 0 && map.cell(&s.key).is_some_and(|c| c.last_seen < since) {
            for axis in Axis::ALL {
                if let Some(m) = map.layer_mut(&s.key, axis, frame) {
                    // Mapped afresh: what it faced is forgotten with what it held.
                    m.var = [f32::INFINITY; VERTICES];
                    m.facing = Facing::Unknown;
                }
            }
            stats.refreshed += 1;
        }
        if let Some(m) = map.layer_mut(&s.key, s.axis, frame) {
            if !m.facing.agrees(s.layer.facing) && apart(m, &s.layer, threshold) {
                // The other face of a wall thinner than the cell: the face in view replaces
                // the one seen from the other side, never averaged with it.
                *m = s.layer;
                stats.turned += 1;
                continue;
            }
            m.facing = m.facing.fused_with(s.layer.facing);
            for j in 0..m.pred.len() {
                let (u, v) = fuse_vertex(
                    m.pred[j],
                    m.var[j],
                    s.layer.pred[j],
                    s.layer.var[j],
                    threshold,
                );
                m.pred[j] = u;
                m.var[j] = v;
            }
            stats.fused += 1;
            continue;
        }
        if map.cell(&s.key).is_some() && !cfg.add_missing_layers {
            continue;
        }
        match map.insert_layer(s.key, s.axis, s.layer, frame) {
            Ok(()) => stats.added += 1,
            Err(_) => stats.refused += 1,
        }
    }
    stats
}

/// Whether layers `a` and `b` (one cell, one axis) lie more than [`MIN_THICKNESS_M`] apart on
/// average over the vertices both have below `variance_update` (none: not apart).
fn apart(a: &Layer, b: &Layer, variance_update: f32) -> bool {
    let (mut sum, mut n) = (0.0f32, 0u32);
    for j in 0..VERTICES {
        if a.var[j] < variance_update && b.var[j] < variance_update {
            sum += libm::fabsf(a.pred[j] - b.pred[j]);
            n += 1;
        }
    }
    n > 0 && sum > MIN_THICKNESS_M * n as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_variance_fusion() {
        // u = 1 (var 0.1), o = 2 (var 0.3): u' = (1·0.3 + 2·0.1)/0.4 = 1.25, var' = 0.03/0.4.
        let (u, v) = fuse_vertex(1.0, 0.1, 2.0, 0.3, 0.5);
        assert!((u - 1.25).abs() < 1e-6);
        assert!((v - 0.075).abs() < 1e-7);
        // Fusion never increases the variance and lands between the two estimates.
        for (a, b) in [(0.01f32, 0.4f32), (0.2, 0.2), (0.49, 0.001)] {
            let (u, v) = fuse_vertex(0.0, a, 1.0, b, 0.5);
            assert!(v <= a.min(b) && (0.0..=1.0).contains(&u));
        }
    }

    #[test]
    fn keep_the_better_when_either_is_uncertain() {
        assert_eq!(fuse_vertex(1.0, 0.9, 2.0, 0.1, 0.5), (2.0, 0.1));
        assert_eq!(fuse_vertex(1.0, 0.1, 2.0, 0.7, 0.5), (1.0, 0.1));
        assert_eq!(fuse_vertex(1.0, 0.8, 2.0, 0.9, 0.5), (1.0, 0.8));
    }

    /// A known flat surface at 0.5 m seen 25 times with Gaussian noise of 2 cm: every vertex
    /// must come out at the inverse-variance weighted mean of what it was shown (to f32
    /// rounding), its variance at the harmonic combination, and the surface must converge as
    /// the rule predicts, to about 2 cm / sqrt(25) = 4 mm RMS from the truth.
    /// A cell not seen for more than `stale_after_frames` is mapped afresh: the scan's layer
    /// replaces what it held, and its other layers become unknown; a fresh cell fuses.
    #[test]
    fn a_stale_cell_is_replaced_and_a_fresh_one_fused() {
        use crate::cell::{Axis, CellKey};
        use crate::facing::Facing;
        use crate::lattice::{Lattice, VERTICES};
        use crate::layer::Layer;

        let lattice = Lattice {
            cell_size: 1.0,
            full_cover: true,
        };
        let cfg = MapConfig {
            variance_update: 0.5,
            add_missing_layers: true,
            reconstruct_at_final_pose: true,
            stale_after_frames: 100,
        };
        let layer = |d: f32| Layer {
            pred: [d; VERTICES],
            var: [0.1; VERTICES],
            facing: Facing::Unknown,
        };
        let (old, fresh) = (CellKey::new(0, 0, 0), CellKey::new(5, 0, 0));
        let mut map = MeshMap::with_capacity(4, 8, lattice);
        map.insert_layer(old, Axis::Z, layer(0.2), 10).unwrap();
        map.insert_layer(old, Axis::X, layer(0.5), 10).unwrap();
        map.insert_layer(fresh, Axis::Z, layer(0.2), 150).unwrap();
        let scan = [old, fresh].map(|key| ScanLayer {
            key,
            axis: Axis::Z,
            layer: layer(0.6),
        });
        assert_eq!(stale_before(200, &cfg), 100);
        let stats = integrate(&mut map, &scan, &cfg, 200);
        assert_eq!((stats.refreshed, stats.fused), (1, 2));
        assert_eq!(map.layer(&old, Axis::Z).unwrap().pred[0], 0.6, "replaced");
        assert!(
            map.layer(&old, Axis::X).unwrap().var[0].is_infinite(),
            "made unknown"
        );
        assert!(
            (map.layer(&fresh, Axis::Z).unwrap().pred[0] - 0.4).abs() < 1e-6,
            "fused"
        );
        assert_eq!(map.cell(&old).unwrap().last_seen, 200);
        // Off (0), nothing is stale.
        assert_eq!(
            stale_before(
                200,
                &MapConfig {
                    stale_after_frames: 0,
                    ..cfg
                }
            ),
            0
        );
    }

    /// A lattice of cells `cell_size` wide and a map update that adds layers, never stale.
    fn fusing(cell_size: f64) -> (crate::lattice::Lattice, MapConfig) {
        let lattice = crate::lattice::Lattice {
            cell_size,
            full_cover: false,
        };
        let cfg = MapConfig {
            variance_update: 0.5,
            add_missing_layers: true,
            reconstruct_at_final_pose: true,
            stale_after_frames: 0,
        };
        (lattice, cfg)
    }

    /// A wall 0.3 m thick has both faces in one cell: the face in view replaces the other. A
    /// sheet seen from its other side (2 cm off) is one surface, fused, facing both ways.
    #[test]
    fn a_wall_s_far_face_is_replaced_and_a_sheet_s_fused() {
        use crate::cell::{Axis, CellKey};
        use crate::facing::Facing;
        use crate::lattice::VERTICES;
        use crate::layer::Layer;

        let (lattice, cfg) = fusing(1.0);
        let key = CellKey::new(4, 0, 0);
        let face = |d: f32, facing| ScanLayer {
            key,
            axis: Axis::X,
            layer: Layer {
                pred: [d; VERTICES],
                var: [0.05; VERTICES],
                facing,
            },
        };
        let mut map = MeshMap::with_capacity(4, 4, lattice);
        integrate(&mut map, &[face(0.3, Facing::Negative)], &cfg, 0);
        let turned = integrate(&mut map, &[face(0.6, Facing::Positive)], &cfg, 1);
        assert_eq!((turned.turned, turned.fused), (1, 0));
        let wall = map.layer(&key, Axis::X).unwrap();
        assert_eq!((wall.pred[0], wall.facing), (0.6, Facing::Positive));
        // Seen again facing the same way: fused as before.
        let again = integrate(&mut map, &[face(0.6, Facing::Positive)], &cfg, 2);
        assert_eq!((again.turned, again.fused), (0, 1));
        assert!(map.layer(&key, Axis::X).unwrap().var[0] < 0.05);

        let mut map = MeshMap::with_capacity(4, 4, lattice);
        integrate(&mut map, &[face(0.50, Facing::Negative)], &cfg, 0);
        let sheet = integrate(&mut map, &[face(0.52, Facing::Positive)], &cfg, 1);
        assert_eq!((sheet.turned, sheet.fused), (0, 1));
        let fused = map.layer(&key, Axis::X).unwrap();
        assert!((fused.pred[0] - 0.51).abs() < 1e-6);
        assert_eq!(fused.facing, Facing::Both);
        // An unknown facing takes the first known one.
        let mut map = MeshMap::with_capacity(4, 4, lattice);
        integrate(&mut map, &[face(0.3, Facing::Unknown)], &cfg, 0);
        integrate(&mut map, &[face(0.6, Facing::Positive)], &cfg, 1);
        assert_eq!(map.layer(&key, Axis::X).unwrap().facing, Facing::Positive);
    }

    #[test]
    fn repeated_noisy_views_of_a_known_surface_converge_as_inverse_variance_predicts() {
        use crate::cell::{Axis, CellKey};
        use crate::facing::Facing;
        use crate::lattice::VERTICES;
        use crate::layer::Layer;
        use crate::random::SplitMix64;

        let (lattice, cfg) = fusing(1.6);
        let (truth, sigma) = (0.5f64, 0.02f64);
        let key = CellKey::new(3, -2, 0);
        let mut map = MeshMap::with_capacity(4, 4, lattice);
        let mut rng = SplitMix64(42);
        let mut gauss = || {
            let (u, v) = (rng.next_f64().max(1e-12), rng.next_f64());
            (-2.0 * u.ln()).sqrt() * (core::f64::consts::TAU * v).cos()
        };
        // Per vertex: sum of w·o and of w = 1/var over the views, in f64.
        let (mut sum_wo, mut sum_w) = ([0.0f64; VERTICES], [0.0f64; VERTICES]);
        let views = 25;
        for k in 0..views {
            // Alternate a confident and a less confident view (variance 0.01 and 0.04).
            let var = if k % 2 == 0 { 0.01f32 } else { 0.04 };
            let mut layer = Layer {
                pred: [0.0; VERTICES],
                var: [var; VERTICES],
                facing: Facing::Unknown,
            };
            for j in 0..VERTICES {
                layer.pred[j] = (truth + sigma * gauss()) as f32;
                sum_wo[j] += f64::from(layer.pred[j]) / f64::from(var);
                sum_w[j] += 1.0 / f64::from(var);
            }
            let scan = [ScanLayer {
                key,
                axis: Axis::Z,
                layer,
            }];
            let stats = integrate(&mut map, &scan, &cfg, k);
            assert_eq!(
                (stats.added, stats.fused),
                if k == 0 { (1, 0) } else { (0, 1) }
            );
        }
        let fused = map.layer(&key, Axis::Z).unwrap();
        let mut squared = 0.0;
        for j in 0..VERTICES {
            let mean = sum_wo[j] / sum_w[j];
            assert!((f64::from(fused.pred[j]) - mean).abs() < 2e-6, "vertex {j}");
            let var = 1.0 / sum_w[j];
            assert!(
                (f64::from(fused.var[j]) - var).abs() < 1e-4 * var,
                "vertex {j}"
            );
            squared += (f64::from(fused.pred[j]) - truth).powi(2);
        }
        // The weighted mean of 13 views of variance 0.01 and 12 of 0.04 has the noise of
        // sigma / sqrt(13 + 12 / 4) = 5 mm; 36 vertices give its RMS within about 25 %.
        let rms = (squared / VERTICES as f64).sqrt();
        let expected = sigma / (13.0f64 + 3.0).sqrt();
        assert!(
            rms < 1.5 * expected && rms > 0.5 * expected,
            "RMS {rms} m, expected {expected} m"
        );
    }
}
