//! An office floor for indoor drives at a small scale (ranges of 1 to 15 m): two rooms joined
//! by a corridor, with desks, cabinets, pillars and a partition, walked through with a
//! hand-held 16-beam scanner at 10 scans a second. Deterministic from a seed.

use crate::scene::{slab, Scene};
use nalgebra::{Translation3, UnitQuaternion};
use slamesh_core::random::SplitMix64;
use slamesh_core::Pose;

/// Height of the ceiling (metres).
pub const CEILING_M: f64 = 3.0;
/// Sensor height above the floor (metres).
pub const SENSOR_HEIGHT_M: f64 = 1.2;

/// The floor: a 14 x 9 m room (x 0 to 14, y 0 to 9) and a 10 x 8 m room (x 18 to 28) joined by
/// a 4 m corridor 2.5 m wide, 3 m ceilings, with furniture placed from `seed`.
pub fn scene(seed: u64) -> Scene {
    let mut rng = SplitMix64(seed);
    let (t, h) = (0.15, CEILING_M);
    let mut boxes = vec![
        // Room A's walls, with the corridor's opening in the east wall (y 3.25 to 5.75).
        slab([-t, -t, 0.0], [14.0 + t, t, h]),
        slab([-t, 9.0 - t, 0.0], [14.0 + t, 9.0 + t, h]),
        slab([-t, -t, 0.0], [t, 9.0 + t, h]),
        slab([14.0 - t, -t, 0.0], [14.0 + t, 3.25, h]),
        slab([14.0 - t, 5.75, 0.0], [14.0 + t, 9.0 + t, h]),
        // The corridor.
        slab([14.0, 3.25 - t, 0.0], [18.0, 3.25 + t, h]),
        slab([14.0, 5.75 - t, 0.0], [18.0, 5.75 + t, h]),
        // Room B (x 18 to 28, y 0.5 to 8.5), its west wall open to the corridor.
        slab([18.0 - t, 0.5 - t, 0.0], [28.0 + t, 0.5 + t, h]),
        slab([18.0 - t, 8.5 - t, 0.0], [28.0 + t, 8.5 + t, h]),
        slab([28.0 - t, 0.5 - t, 0.0], [28.0 + t, 8.5 + t, h]),
        slab([18.0 - t, 0.5 - t, 0.0], [18.0 + t, 3.25, h]),
        slab([18.0 - t, 5.75, 0.0], [18.0 + t, 8.5 + t, h]),
        // Ceilings.
        slab([-t, -t, h], [14.0 + t, 9.0 + t, h + 0.2]),
        slab([14.0, 3.25, h], [18.0, 5.75, h + 0.2]),
        slab([18.0 - t, 0.5 - t, h], [28.0 + t, 8.5 + t, h + 0.2]),
        // Pillars and a partition in room A.
        slab([4.7, 4.2, 0.0], [5.3, 4.8, h]),
        slab([9.7, 4.2, 0.0], [10.3, 4.8, h]),
        slab([6.5, 7.0, 0.0], [8.5, 7.1, 1.8]),
    ];
    // Desks along the walls and cabinets, room A then room B.
    for (x0, x1, y_lo, y_hi) in [(1.0, 13.0, 0.3, 8.7), (19.0, 27.0, 0.8, 8.2)] {
        let mut x = x0;
        while x < x1 - 1.6 {
            let w = rng.range(1.2, 1.8);
            let (y_near, y_far) = if rng.next_f64() < 0.5 {
                (y_lo, y_lo + 0.8)
            } else {
                (y_hi - 0.8, y_hi)
            };
            if rng.next_f64() < 0.7 {
                boxes.push(slab([x, y_near, 0.72], [x + w, y_far, 0.76]));
                boxes.push(slab([x, y_near, 0.0], [x + 0.05, y_far, 0.72]));
                boxes.push(slab([x + w - 0.05, y_near, 0.0], [x + w, y_far, 0.72]));
            } else {
                let top = rng.range(1.0, 2.0);
                boxes.push(slab([x, y_near, 0.0], [x + w, y_near + 0.5, top]));
            }
            x += w + rng.range(0.3, 1.2);
        }
    }
    Scene {
        ground_z: 0.0,
        terrain: None,
        boxes,
        spheres: Vec::new(),
    }
}

/// The walk: round room A, along the corridor into room B, round it and back, at 0.8 m/s and
/// 10 scans a second (8 cm a scan), looking along the way with a slow sway of the heading (up
/// to 25 degrees) and of the pitch and roll (up to 5 degrees); up to `frames` poses.
pub fn walk_poses(frames: usize) -> Vec<Pose> {
    let path: [[f64; 2]; 9] = [
        [2.0, 2.0],
        [12.0, 2.0],
        [12.0, 7.0],
        [2.0, 7.0],
        [2.0, 4.5],
        [23.0, 4.5],
        [26.0, 2.0],
        [26.0, 7.0],
        [20.0, 4.5],
    ];
    let mut cum = vec![0.0];
    for w in path.windows(2) {
        cum.push(cum[cum.len() - 1] + (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]));
    }
    let total = cum[cum.len() - 1];
    let mut heading = None::<f64>;
    (0..frames)
        .map(|k| {
            let s = (k as f64 * 0.08).min(total);
            let i = cum.partition_point(|&c| c <= s).clamp(1, path.len() - 1);
            let f = ((s - cum[i - 1]) / (cum[i] - cum[i - 1]).max(1e-9)).clamp(0.0, 1.0);
            let (a, b) = (path[i - 1], path[i]);
            let along = (b[1] - a[1]).atan2(b[0] - a[0]);
            // Turn towards the new leg at most 10 degrees a scan (a walker turning a corner).
            let h = heading.map_or(along, |h: f64| {
                let d = (along - h + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                    - std::f64::consts::PI;
                h + d.clamp(-0.17, 0.17)
            });
            heading = Some(h);
            let t = k as f64 * 0.1;
            let look = 25f64.to_radians() * (0.7 * t).sin();
            let (pitch, roll) = (5f64 * (1.1 * t).sin(), 4f64 * (1.7 * t + 0.5).sin());
            Pose::from_parts(
                Translation3::new(
                    a[0] + f * (b[0] - a[0]),
                    a[1] + f * (b[1] - a[1]),
                    SENSOR_HEIGHT_M + 0.03 * (5.0 * t).sin(),
                ),
                UnitQuaternion::from_euler_angles(roll.to_radians(), pitch.to_radians(), h + look),
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Lidar;

    #[test]
    fn the_walk_stays_indoors_and_sees_mostly_within_15_m() {
        let s = scene(1);
        let poses = walk_poses(900);
        let lidar = Lidar::vlp16(900);
        for p in poses.iter().step_by(60) {
            let pts = lidar.scan(&s, p);
            assert!(pts.len() > 5_000, "{}", pts.len());
            let mut r: Vec<f32> = pts
                .iter()
                .map(|q| (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt())
                .collect();
            r.sort_by(f32::total_cmp);
            // Mostly within 15 m; down the corridor, across both rooms.
            let (p90, far) = (r[r.len() * 9 / 10], r[r.len() - 1]);
            assert!(p90 < 15.0 && far < 30.0, "{p90} {far}");
        }
        // The walk goes from room A into room B.
        assert!(poses[0].translation.x < 14.0);
        assert!(poses.iter().any(|p| p.translation.x > 20.0));
    }
}
