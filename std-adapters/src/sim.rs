//! A small ray-casting LiDAR simulator: scenes of oriented boxes over a ground plane, seen by
//! a spinning multi-beam scanner. Deterministic (no noise unless asked, seeded when asked).
//!
//! Used by tests with ground truth: the true sensor pose of every scan is known exactly.

use nalgebra::{Point3, Rotation3, Translation3, UnitQuaternion, Vector3};
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
        let mut best = max_range;
        let mut hit = false;
        if dir.z < -1e-9 {
            let s = (self.ground_z - origin.z) / dir.z;
            if s > 0.0 && s < best {
                best = s;
                hit = true;
            }
        }
        for b in &self.boxes {
            let r = Rotation3::from_axis_angle(&Vector3::z_axis(), -b.yaw);
            let o = r * (origin - Vector3::from(b.centre));
            let d = r * dir;
            let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
            for k in 0..3 {
                if d[k].abs() < 1e-12 {
                    if o[k].abs() > b.half[k] {
                        lo = f64::INFINITY;
                    }
                    continue;
                }
                let (s0, s1) = ((-b.half[k] - o[k]) / d[k], (b.half[k] - o[k]) / d[k]);
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
