//! A small ray-casting LiDAR simulator: scenes of oriented boxes over a ground plane, seen by
//! a spinning multi-beam scanner. Deterministic (no noise unless asked, seeded when asked).
//!
//! Used by tests with ground truth: the true sensor pose of every scan is known exactly.

use crate::file_error::FileError;
use crate::session::FrameSource;
use nalgebra::{Point3, Translation3, UnitQuaternion, Vector3};
use slamesh_core::{Point, Pose};

/// A level sensor pose: position (metres) and heading about z (degrees).
pub fn sensor_pose(x: f64, y: f64, z: f64, yaw_deg: f64) -> Pose {
    Pose::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_deg.to_radians()),
    )
}

/// A box with a yaw about z: centre, half extents along its own axes, yaw in radians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrientedBox {
    /// Centre (world, metres).
    pub centre: [f64; 3],
    /// Half extents along the box's x, y, z (metres).
    pub half: [f64; 3],
    /// Rotation about world z (radians).
    pub yaw: f64,
}

/// A world of boxes above the plane `z = ground_z`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Scene {
    /// Height of the ground plane.
    pub ground_z: f64,
    /// Walls, buildings, boxes, poles.
    pub boxes: Vec<OrientedBox>,
}

impl Scene {
    /// A structured street corner: ground, facades in three directions, boxes (parked cars,
    /// kiosks) and poles; well constrained in all six degrees of freedom.
    pub fn street() -> Self {
        let b = |c: [f64; 3], h: [f64; 3], yaw: f64| OrientedBox {
            centre: c,
            half: h,
            yaw,
        };
        Scene {
            ground_z: 0.0,
            boxes: vec![
                b([0.0, 14.0, 5.0], [30.0, 0.5, 5.0], 0.0), // facade north
                b([0.0, -12.0, 4.0], [30.0, 0.5, 4.0], 0.0), // facade south
                b([32.0, 0.0, 6.0], [0.5, 14.0, 6.0], 0.0), // facade east, end of street
                b([-20.0, 6.0, 3.0], [4.0, 3.0, 3.0], 0.5), // a rotated building
                b([8.0, 8.0, 0.8], [2.2, 0.9, 0.8], 0.0),   // parked car
                b([16.0, -7.0, 0.8], [2.2, 0.9, 0.8], 0.1), // parked car
                b([-6.0, -6.5, 1.2], [1.5, 1.5, 1.2], 0.8), // kiosk
                b([4.0, -3.5, 2.5], [0.12, 0.12, 2.5], 0.0), // pole
                b([12.0, 3.5, 2.5], [0.12, 0.12, 2.5], 0.0), // pole
                b([22.0, 9.0, 1.0], [3.0, 3.0, 1.0], -0.3), // low block
            ],
        }
    }

    /// The range along the unit ray `origin + s·dir` to the nearest surface, up to `max_range`.
    pub fn cast(&self, origin: &Vector3<f64>, dir: &Vector3<f64>, max_range: f64) -> Option<f64> {
        Prepared::new(self, origin, f64::INFINITY).cast(origin, dir, max_range)
    }

    /// A long straight street along +x from `x = 0` to `length_m`, deterministic from `seed`:
    /// facades of varying height, depth and setback with gaps (side streets), parked cars,
    /// poles and kiosks on both sides, a wall at each end. For long runs (memory, eviction).
    pub fn long_street(length_m: f64, seed: u64) -> Self {
        let mut rng = SplitMix64(seed);
        let mut boxes = Vec::new();
        let b = |c: [f64; 3], h: [f64; 3], yaw: f64| OrientedBox {
            centre: c,
            half: h,
            yaw,
        };
        for side in [-1.0, 1.0] {
            let mut x = -20.0;
            while x < length_m + 20.0 {
                let w = rng.range(8.0, 30.0);
                if rng.next_f64() > 0.15 {
                    let (setback, height) = (rng.range(9.0, 13.0), rng.range(4.0, 18.0));
                    let yaw = rng.range(-0.05, 0.05);
                    boxes.push(b(
                        [x + w / 2.0, side * (setback + 4.0), height / 2.0],
                        [w / 2.0, 4.0, height / 2.0],
                        yaw,
                    ));
                }
                x += w + rng.range(0.0, 3.0);
            }
            let mut x = 0.0;
            while x < length_m {
                x += rng.range(4.0, 14.0);
                let y = side * rng.range(4.5, 7.0);
                match rng.next_f64() {
                    f if f < 0.5 => {
                        boxes.push(b([x, y, 0.75], [2.2, 0.9, 0.75], rng.range(-0.1, 0.1)))
                    }
                    f if f < 0.8 => boxes.push(b([x, y, 2.5], [0.12, 0.12, 2.5], 0.0)),
                    _ => boxes.push(b([x, y, 1.2], [1.2, 1.2, 1.2], rng.range(0.0, 1.5))),
                }
            }
        }
        boxes.push(b([-25.0, 0.0, 6.0], [0.5, 20.0, 6.0], 0.0));
        boxes.push(b([length_m + 25.0, 0.0, 6.0], [0.5, 20.0, 6.0], 0.0));
        Scene {
            ground_z: 0.0,
            boxes,
        }
    }
}

/// A small deterministic random generator (SplitMix64).
#[derive(Debug, Clone)]
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)`.
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in `[lo, hi)`.
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next_f64()
    }
}

/// A scene made ready for many rays from one place: boxes out of reach dropped, their
/// rotations computed once.
struct Prepared {
    ground_z: f64,
    /// Centre, half extents, cos and sin of `-yaw`.
    boxes: Vec<([f64; 3], [f64; 3], f64, f64)>,
}

impl Prepared {
    /// The boxes of `scene` that can be hit within `reach` of `origin`.
    fn new(scene: &Scene, origin: &Vector3<f64>, reach: f64) -> Self {
        let boxes = scene
            .boxes
            .iter()
            .filter(|b| {
                let d = Vector3::from(b.centre) - origin;
                d.norm() <= reach + Vector3::from(b.half).norm()
            })
            .map(|b| {
                let (s, c) = (-b.yaw).sin_cos();
                (b.centre, b.half, c, s)
            })
            .collect();
        Prepared {
            ground_z: scene.ground_z,
            boxes,
        }
    }

    fn cast(&self, origin: &Vector3<f64>, dir: &Vector3<f64>, max_range: f64) -> Option<f64> {
        let mut best = max_range;
        let mut hit = false;
        if dir.z < -1e-9 {
            let s = (self.ground_z - origin.z) / dir.z;
            if s > 0.0 && s < best {
                best = s;
                hit = true;
            }
        }
        for (centre, half, c, s) in &self.boxes {
            let (ox, oy) = (origin.x - centre[0], origin.y - centre[1]);
            let o = [c * ox - s * oy, s * ox + c * oy, origin.z - centre[2]];
            let d = [c * dir.x - s * dir.y, s * dir.x + c * dir.y, dir.z];
            let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
            for k in 0..3 {
                if d[k].abs() < 1e-12 {
                    if o[k].abs() > half[k] {
                        lo = f64::INFINITY;
                    }
                    continue;
                }
                let (s0, s1) = ((-half[k] - o[k]) / d[k], (half[k] - o[k]) / d[k]);
                lo = lo.max(s0.min(s1));
                hi = hi.min(s0.max(s1));
            }
            if lo <= hi && lo > 0.0 && lo < best {
                best = lo;
                hit = true;
            }
        }
        hit.then_some(best)
    }
}

/// A spinning multi-beam LiDAR.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lidar {
    /// Number of beams, evenly spread between the two elevations.
    pub beams: usize,
    /// Lowest beam elevation (degrees).
    pub elevation_min_deg: f64,
    /// Highest beam elevation (degrees).
    pub elevation_max_deg: f64,
    /// Firings per revolution.
    pub azimuth_steps: usize,
    /// Maximum range (metres).
    pub max_range_m: f64,
}

impl Lidar {
    /// An HDL-64E-like scanner: 64 beams from -24.8 to +2 degrees.
    pub fn hdl64(azimuth_steps: usize) -> Self {
        Lidar {
            beams: 64,
            elevation_min_deg: -24.8,
            elevation_max_deg: 2.0,
            azimuth_steps,
            max_range_m: 100.0,
        }
    }

    /// One noise-free scan of `scene` from `t_world_sensor`, in the sensor frame.
    pub fn scan(&self, scene: &Scene, t_world_sensor: &Pose) -> Vec<Point> {
        let origin = t_world_sensor.translation.vector;
        let scene = Prepared::new(scene, &origin, self.max_range_m);
        let mut out = Vec::with_capacity(self.beams * self.azimuth_steps);
        for beam in 0..self.beams {
            let f = if self.beams > 1 {
                beam as f64 / (self.beams - 1) as f64
            } else {
                0.0
            };
            let el = (self.elevation_min_deg
                + f * (self.elevation_max_deg - self.elevation_min_deg))
                .to_radians();
            for step in 0..self.azimuth_steps {
                let az = std::f64::consts::TAU * step as f64 / self.azimuth_steps as f64;
                let dir_s = Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
                let dir_w = t_world_sensor.rotation * dir_s;
                if let Some(range) = scene.cast(&origin, &dir_w, self.max_range_m) {
                    let p = Point3::from(dir_s * range);
                    out.push([p.x as f32, p.y as f32, p.z as f32]);
                }
            }
        }
        out
    }
}

/// A simulated drive: the scans a [`Lidar`] sees along `poses` through `scene`, with Gaussian
/// range noise, made on demand (a [`FrameSource`], so long runs need no disk).
#[derive(Debug, Clone)]
pub struct Drive {
    /// The world.
    pub scene: Scene,
    /// The scanner.
    pub lidar: Lidar,
    /// True sensor poses, one per frame.
    pub poses: Vec<Pose>,
    /// Standard deviation of the range noise (metres).
    pub noise_m: f64,
    /// Seed of the noise (frame `i` uses `seed + i`).
    pub seed: u64,
}

impl Drive {
    /// `frames` frames down [`Scene::long_street`] at `step_m` a frame, weaving gently across
    /// the lane and turning with it; HDL-64-like scans (1 000 firings a turn, 80 m), 2 cm noise.
    pub fn long_street(frames: usize, step_m: f64, seed: u64) -> Self {
        let length = frames as f64 * step_m;
        let poses = (0..frames)
            .map(|i| {
                let x = i as f64 * step_m;
                let (y, slope) = (1.2 * (x / 40.0).sin(), 1.2 / 40.0 * (x / 40.0).cos());
                sensor_pose(x, y, 1.73, slope.atan().to_degrees())
            })
            .collect();
        let mut lidar = Lidar::hdl64(1000);
        lidar.max_range_m = 80.0;
        Drive {
            scene: Scene::long_street(length, seed),
            lidar,
            poses,
            noise_m: 0.02,
            seed,
        }
    }
}

impl FrameSource for Drive {
    fn frames(&self) -> usize {
        self.poses.len()
    }
    fn label(&self, i: usize) -> String {
        format!("simulated frame {i}")
    }
    fn stamp(&self, i: usize) -> f64 {
        i as f64 * 0.1
    }
    fn read(&mut self, i: usize) -> Result<Vec<Point>, FileError> {
        let mut rng = SplitMix64(self.seed.wrapping_add(i as u64));
        let mut points = self.lidar.scan(&self.scene, &self.poses[i]);
        for p in &mut points {
            // Box-Muller: one Gaussian sample along the ray.
            let (u, v) = (rng.next_f64().max(1e-12), rng.next_f64());
            let n = self.noise_m * (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos();
            let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() as f64;
            let k = ((r + n) / r) as f32;
            *p = p.map(|c| c * k);
        }
        Ok(points)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rays_hit_ground_and_boxes_at_the_right_range() {
        let scene = Scene {
            ground_z: 0.0,
            boxes: vec![OrientedBox {
                centre: [10.0, 0.0, 1.0],
                half: [1.0, 5.0, 1.0],
                yaw: 0.0,
            }],
        };
        let o = Vector3::new(0.0, 0.0, 1.0);
        assert!((scene.cast(&o, &Vector3::x(), 100.0).unwrap() - 9.0).abs() < 1e-12);
        let down = Vector3::new(1.0, 0.0, -1.0).normalize();
        assert!((scene.cast(&o, &down, 100.0).unwrap() - 2f64.sqrt()).abs() < 1e-12);
        assert!(scene.cast(&o, &Vector3::z(), 100.0).is_none());
        // Turned by 90 degrees, the 5 m half extent lies along x: the face is at x = 5.
        let mut turned = scene.clone();
        turned.boxes[0].yaw = std::f64::consts::FRAC_PI_2;
        assert!((turned.cast(&o, &Vector3::x(), 100.0).unwrap() - 5.0).abs() < 1e-9);
    }
}
