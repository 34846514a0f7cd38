//! Triangles of the map, without allocation (docs/design.md §1.6).
//!
//! Each layer's lattice gives 5 x 5 quads, two triangles each, kept when the mean variance of
//! their vertices is below `variance_show` and they are no steeper than `max_slope_deg`
//! against the layer's axis ([`MeshConfig`]). Iterate with [`triangles`] or fill a caller's
//! buffer with [`triangles_into`]. For an indexed mesh (shared vertices), walk
//! [`MeshMap::layers`] and use [`Layer::triangles`](crate::layer::Layer::triangles) per layer.

use crate::config::MeshConfig;
use crate::layer::{Shown, TRIANGLES};
use crate::map::MeshMap;
use crate::math::to_point;
use crate::math::Point;

/// One triangle in world coordinates, counter-clockwise seen from its layer's `+axis`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Triangle {
    /// Corner positions (metres, world frame).
    pub vertices: [Point; 3],
    /// Mean variance of the corners.
    pub variance: f32,
}

/// Every shown triangle of `map`, in the map's deterministic order.
pub fn triangles<'a>(map: &'a MeshMap, cfg: &MeshConfig) -> impl Iterator<Item = Triangle> + 'a {
    let lattice = map.lattice().table();
    let shown = Shown::new(cfg);
    map.layers().flat_map(move |l| {
        // The lattice table is copied into each layer's iterator (it is 56 bytes).
        let table = lattice;
        let list: heapless::Vec<[usize; 3], TRIANGLES> = l.layer.triangles(&table, shown).collect();
        list.into_iter().map(move |t| Triangle {
            vertices: t.map(|j| to_point(&l.layer.vertex(&table, &l.key, l.axis, j))),
            variance: l.layer.mean_variance(&t),
        })
    })
}

/// Fills `buf` with shown triangles; returns how many were written (at most `buf.len()`; call
/// [`triangles`]`(..).count()` for the total).
pub fn triangles_into(map: &MeshMap, cfg: &MeshConfig, buf: &mut [Triangle]) -> usize {
    buf.iter_mut()
        .zip(triangles(map, cfg))
        .map(|(slot, t)| *slot = t)
        .count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cell::{Axis, CellKey};
    use crate::facing::Facing;
    use crate::lattice::{Lattice, VERTICES};
    use crate::layer::Layer;

    fn show(variance_show: f64) -> MeshConfig {
        MeshConfig {
            variance_show,
            max_slope_deg: 60.0,
        }
    }

    #[test]
    fn a_flat_layer_gives_fifty_triangles_on_its_plane() {
        let lat = Lattice {
            cell_size: 1.6,
            full_cover: true,
        };
        let mut map = MeshMap::with_capacity(4, 4, lat);
        let layer = Layer {
            pred: [0.5; VERTICES],
            var: [0.1; VERTICES],
            facing: Facing::Unknown,
        };
        map.insert_layer(CellKey::new(1, 2, 3), Axis::Z, layer, 0)
            .unwrap();
        assert_eq!(triangles(&map, &show(0.3)).count(), 50);
        assert_eq!(triangles(&map, &show(0.05)).count(), 0);
        let mut buf = [Triangle::default(); 10];
        assert_eq!(triangles_into(&map, &show(0.3), &mut buf), 10);
        let mut area = 0.0;
        for t in triangles(&map, &show(0.3)) {
            for v in t.vertices {
                assert!((v[2] - (3.0 * 1.6 + 0.5)).abs() < 1e-5);
                assert!(v[0] >= 1.6 - 1e-5 && v[0] <= 3.2 + 1e-5);
            }
            let [a, b, c] = t.vertices.map(|v| crate::math::to_vec3(&v));
            let n = (b - a).cross(&(c - a));
            assert!(n.z > 0.0, "counter-clockwise seen from +z");
            area += n.norm() / 2.0;
        }
        assert!(
            (area - 1.6 * 1.6).abs() < 1e-4,
            "full cover tiles the whole face: {area}"
        );
    }
}
