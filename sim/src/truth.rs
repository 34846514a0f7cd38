//! Ground truth for mesh accuracy: the exact distance from points to a [`Scene`]'s surfaces.

use crate::scene::Scene;
use nalgebra::Vector3;

/// The distance from points to the true surfaces of a [`Scene`], for exact mesh precision:
/// boxes and spheres are found through a 2D grid of 8 m cells; the ground distance is
/// measured vertically (exact to within the slope's cosine, under 0.1 % here).
pub struct SurfaceDistance<'a> {
    scene: &'a Scene,
    cells: std::collections::HashMap<(i64, i64), Vec<u32>>,
}

/// Cell size of [`SurfaceDistance`]'s grid (metres).
const DISTANCE_CELL_M: f64 = 8.0;

impl<'a> SurfaceDistance<'a> {
    /// Indexes the objects of `scene`.
    pub fn new(scene: &'a Scene) -> Self {
        let mut cells: std::collections::HashMap<(i64, i64), Vec<u32>> =
            std::collections::HashMap::new();
        let mut add = |id: u32, c: [f64; 3], r: f64| {
            let lo = ((c[0] - r) / DISTANCE_CELL_M).floor() as i64 - 1;
            let hi = ((c[0] + r) / DISTANCE_CELL_M).floor() as i64 + 1;
            let lo_y = ((c[1] - r) / DISTANCE_CELL_M).floor() as i64 - 1;
            let hi_y = ((c[1] + r) / DISTANCE_CELL_M).floor() as i64 + 1;
            for i in lo..=hi {
                for j in lo_y..=hi_y {
                    cells.entry((i, j)).or_default().push(id);
                }
            }
        };
        for (k, b) in scene.boxes.iter().enumerate() {
            add(k as u32, b.centre, b.half[0].hypot(b.half[1]));
        }
        for (k, sp) in scene.spheres.iter().enumerate() {
            add((scene.boxes.len() + k) as u32, sp.centre, sp.radius);
        }
        SurfaceDistance { scene, cells }
    }

    /// Distance from `p` to the nearest true surface; objects more than 8 m away are not
    /// considered (the ground always is).
    pub fn distance(&self, p: &Vector3<f64>) -> f64 {
        let mut best = (p.z - self.scene.ground_height(p.x, p.y)).abs();
        let key = (
            (p.x / DISTANCE_CELL_M).floor() as i64,
            (p.y / DISTANCE_CELL_M).floor() as i64,
        );
        for &id in self.cells.get(&key).map(Vec::as_slice).unwrap_or(&[]) {
            let id = id as usize;
            let d = match self.scene.boxes.get(id) {
                Some(b) => {
                    let (s, c) = (-b.yaw).sin_cos();
                    let (ox, oy) = (p.x - b.centre[0], p.y - b.centre[1]);
                    let local = [c * ox - s * oy, s * ox + c * oy, p.z - b.centre[2]];
                    let q: Vec<f64> = (0..3).map(|k| local[k].abs() - b.half[k]).collect();
                    let outside = q.iter().map(|v| v.max(0.0).powi(2)).sum::<f64>().sqrt();
                    let inside = q.iter().copied().fold(f64::NEG_INFINITY, f64::max).min(0.0);
                    outside + inside.abs()
                }
                None => match self.scene.spheres.get(id - self.scene.boxes.len()) {
                    Some(sp) => ((p - Vector3::from(sp.centre)).norm() - sp.radius).abs(),
                    None => f64::INFINITY,
                },
            };
            best = best.min(d);
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{OrientedBox, Sphere};

    #[test]
    fn distances_to_the_true_surfaces() {
        let scene = Scene {
            terrain: None,
            boxes: vec![OrientedBox {
                centre: [10.0, 0.0, 2.0],
                half: [1.0, 2.0, 2.0],
                yaw: 0.0,
            }],
            spheres: vec![Sphere {
                centre: [0.0, 10.0, 5.0],
                radius: 1.0,
            }],
            ground_z: 0.0,
        };
        let d = SurfaceDistance::new(&scene);
        let at = |x: f64, y: f64, z: f64| d.distance(&Vector3::new(x, y, z));
        assert!((at(0.0, 0.0, 0.3) - 0.3).abs() < 1e-12, "above the ground");
        assert!(
            (at(8.5, 0.0, 2.0) - 0.5).abs() < 1e-12,
            "in front of the box"
        );
        assert!(
            (at(10.0, 0.0, 3.5) - 0.5).abs() < 1e-12,
            "inside, under the top"
        );
        assert!((at(0.0, 10.0, 6.5) - 0.5).abs() < 1e-12, "above the sphere");
    }
}
