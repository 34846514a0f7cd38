//! Duplicated surfaces in a map: the sign of a loop left open, where a revisited street was
//! mapped a second time beside the first (docs/design.md §1.14).
//!
//! A cell holds one layer per axis, so a second copy of a surface offset by drift lands in a
//! neighbouring cell along the layer's axis. Two layers of the same axis in cells next to
//! each other along it are a duplicate when at least [`MIN_VERTICES`] lattice positions,
//! confident in both (variance below `max_var`), put the surface within `within_m` of each
//! other: two parallel sheets, where the world has one.

use slamesh_core::map::MeshMap;
use slamesh_core::Pose;

/// Lattice positions two layers must share to count as one surface mapped twice.
pub const MIN_VERTICES: usize = 6;

/// Pairs of layers that map one surface twice, `within_m` apart (see the module docs), among
/// the cells whose centre `keep` accepts.
pub fn duplicated_surfaces(
    map: &MeshMap,
    max_var: f32,
    within_m: f64,
    keep: impl Fn(&[f64; 3]) -> bool,
) -> usize {
    let lattice = map.lattice().table();
    let size = lattice.cell_size;
    let mut count = 0;
    for l in map.layers() {
        let centre: [f64; 3] = l.key.centre(size).into();
        if !keep(&centre) {
            continue;
        }
        // Each pair once: the neighbour on the axis's positive side.
        let Some(next) = l.key.offset(l.axis, 1) else {
            continue;
        };
        let Some(other) = map.layer(&next, l.axis) else {
            continue;
        };
        let close = (0..l.layer.pred.len())
            .filter(|&j| l.layer.var[j] < max_var && other.var[j] < max_var)
            .filter(|&j| {
                let a = lattice.vertex_world(&l.key, l.axis, j, f64::from(l.layer.pred[j]));
                let b = lattice.vertex_world(&next, l.axis, j, f64::from(other.pred[j]));
                (a - b).norm() < within_m
            })
            .count();
        if close >= MIN_VERTICES {
            count += 1;
        }
    }
    count
}

/// [`duplicated_surfaces`] within `radius_m` of `at` (horizontally).
pub fn duplicated_near(
    map: &MeshMap,
    max_var: f32,
    within_m: f64,
    at: &Pose,
    radius_m: f64,
) -> usize {
    let c = at.translation.vector;
    duplicated_surfaces(map, max_var, within_m, |p| {
        (p[0] - c.x).hypot(p[1] - c.y) <= radius_m
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use slamesh_core::cell::{Axis, CellKey};
    use slamesh_core::facing::Facing;
    use slamesh_core::lattice::Lattice;
    use slamesh_core::layer::Layer;

    fn flat(d: f32) -> Layer {
        Layer {
            pred: [d; 36],
            var: [0.01; 36],
            facing: Facing::Unknown,
        }
    }

    #[test]
    fn a_wall_mapped_twice_across_a_cell_face_is_one_duplicate() {
        let lattice = Lattice {
            cell_size: 1.0,
            full_cover: true,
        };
        let mut map = MeshMap::with_capacity(16, 16, lattice);
        // A wall near x = 1.0: once at 0.95 (cell 0), once at 1.1 (cell 1).
        map.insert_layer(CellKey::new(0, 0, 0), Axis::X, flat(0.95), 0)
            .unwrap();
        map.insert_layer(CellKey::new(1, 0, 0), Axis::X, flat(0.1), 0)
            .unwrap();
        // Another wall far from its neighbour: not a duplicate.
        map.insert_layer(CellKey::new(0, 5, 0), Axis::X, flat(0.1), 0)
            .unwrap();
        map.insert_layer(CellKey::new(1, 5, 0), Axis::X, flat(0.9), 0)
            .unwrap();
        assert_eq!(duplicated_surfaces(&map, 0.5, 0.3, |_| true), 1);
        assert_eq!(duplicated_surfaces(&map, 0.5, 0.1, |_| true), 0);
        assert_eq!(
            duplicated_surfaces(&map, 0.005, 0.3, |_| true),
            0,
            "not confident"
        );
        assert_eq!(duplicated_surfaces(&map, 0.5, 0.3, |c| c[1] > 3.0), 0);
    }
}
