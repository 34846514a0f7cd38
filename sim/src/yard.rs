//! A yard for the navigation maps' truth (kerbs and ramps): a 40 x 24 m court between walls,
//! driven along its middle by the town's car and scanner, with on one side a kerb higher than
//! a wheeled robot's step and one lower, each in front of a raised pavement, and on the other a
//! gentle ramp and a steep one, each up to a platform. Ramps are stairs of 2 cm rises (what
//! the mesh's lattice, several times coarser, sees as a slope), since the scene's boxes do
//! not tilt.

use crate::drive::sensor_pose;
use crate::scene::{slab, Scene};
use slamesh_core::Pose;

/// A ramp from `x0` up along x at `degrees` to a platform `RAMP_RISE_M` high ending at `x1`,
/// from `y` -7 to -4 m: the ramp's own stretch of x, and the platform's.
pub fn ramp(x0: f64, x1: f64, degrees: f64) -> ([f64; 2], [f64; 2]) {
    let run = RAMP_RISE_M / degrees.to_radians().tan();
    ([x0, x0 + run], [x0 + run, x1])
}

/// The height of the platforms the ramps lead up to (m).
pub const RAMP_RISE_M: f64 = 0.5;
/// The rise of each stair a ramp is made of (m).
const STAIR_M: f64 = 0.02;
/// The ramps' lateral extent (m).
pub const RAMP_Y: [f64; 2] = [-7.0, -4.0];
/// The kerbs: x from, x to, height (m). The first stands above a wheeled robot's 0.08 m
/// step, the second below it.
pub const KERBS: [[f64; 3]; 2] = [[5.0, 15.0, 0.15], [22.0, 32.0, 0.05]];
/// The ramps: x from, x to (the platform's end), slope (degrees). The first is within a
/// wheeled robot's 15 degrees, the second beyond it.
pub const RAMPS: [[f64; 3]; 2] = [[5.0, 13.0, 10.0], [22.0, 28.0, 25.0]];

/// The yard's scene.
pub fn scene() -> Scene {
    let h = 4.0;
    let mut boxes = vec![
        // The court's walls: x -2 to 42, y -12 to 12.
        slab([-2.0, -12.3, 0.0], [42.0, -12.0, h]),
        slab([-2.0, 12.0, 0.0], [42.0, 12.3, h]),
        slab([-2.3, -12.0, 0.0], [-2.0, 12.0, h]),
        slab([42.0, -12.0, 0.0], [42.3, 12.0, h]),
        // Posts and a kiosk for the registration's sake, clear of the kerbs and ramps.
        slab([18.0, 9.0, 0.0], [18.3, 9.3, 3.0]),
        slab([36.0, -9.5, 0.0], [36.3, -9.2, 3.0]),
        slab([2.0, -10.0, 0.0], [3.5, -8.5, 2.5]),
        slab([38.0, 8.0, 0.0], [40.0, 10.0, 2.2]),
    ];
    for [x0, x1, height] in KERBS {
        boxes.push(slab([x0, 4.0, 0.0], [x1, 6.0, height]));
    }
    for [x0, x1, degrees] in RAMPS {
        let (up, _) = ramp(x0, x1, degrees);
        let stairs = (RAMP_RISE_M / STAIR_M).round() as usize;
        let tread = (up[1] - up[0]) / stairs as f64;
        for k in 0..stairs {
            let from = up[0] + k as f64 * tread;
            let top = (k + 1) as f64 * STAIR_M;
            boxes.push(slab([from, RAMP_Y[0], 0.0], [x1, RAMP_Y[1], top]));
        }
    }
    Scene {
        ground_z: 0.0,
        terrain: None,
        boxes,
        spheres: Vec::new(),
    }
}

/// Up to `frames` poses along the yard's middle (`y` 0, from `x` 1 to 39) at 2 m/s, 10 scans
/// a second, the scanner 1.73 m up: past everything in 180.
pub fn drive_poses(frames: usize) -> Vec<Pose> {
    (0..frames)
        .map(|k| sensor_pose((1.0 + 0.2 * k as f64).min(39.0), 0.0, 1.73, 0.0))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn the_ramps_rise_at_their_slope_and_the_kerbs_stand_at_their_height() {
        let s = scene();
        let down = Vector3::new(0.0, 0.0, -1.0);
        let height_at =
            |x: f64, y: f64| 5.0 - s.cast(&Vector3::new(x, y, 5.0), &down, 10.0).unwrap();
        for [x0, x1, degrees] in RAMPS {
            let (up, top) = ramp(x0, x1, degrees);
            let x = (up[0] + up[1]) / 2.0;
            let want = (x - x0) * degrees.to_radians().tan();
            assert!((height_at(x, -5.5) - want).abs() <= STAIR_M, "{degrees}");
            assert!((height_at((top[0] + top[1]) / 2.0, -5.5) - RAMP_RISE_M).abs() < 1e-9);
        }
        for [x0, x1, h] in KERBS {
            assert!((height_at((x0 + x1) / 2.0, 5.0) - h).abs() < 1e-9);
            assert!(height_at((x0 + x1) / 2.0, 3.9).abs() < 1e-9);
        }
        assert!(drive_poses(180).last().unwrap().translation.x > 36.0);
    }
}
