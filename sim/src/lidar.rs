//! A spinning multi-beam LiDAR that casts its rays into a [`Scene`].

use crate::scene::{Prepared, Scene};
use nalgebra::{Point3, Vector3};
use slamesh_core::{Point, Pose};

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
    /// A VLP-16-like scanner: 16 beams from -15 to +15 degrees, 100 m.
    pub fn vlp16(azimuth_steps: usize) -> Self {
        Lidar {
            beams: 16,
            elevation_min_deg: -15.0,
            elevation_max_deg: 15.0,
            azimuth_steps,
            max_range_m: 100.0,
        }
    }

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

    /// The unit ray of `beam` (evenly spread between the two elevations) at firing `step` of
    /// the turn, in the sensor frame.
    fn direction(&self, beam: usize, step: usize) -> Vector3<f64> {
        let f = if self.beams > 1 {
            beam as f64 / (self.beams - 1) as f64
        } else {
            0.0
        };
        let el = (self.elevation_min_deg + f * (self.elevation_max_deg - self.elevation_min_deg))
            .to_radians();
        let az = std::f64::consts::TAU * step as f64 / self.azimuth_steps as f64;
        Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin())
    }

    /// One noise-free scan of `scene` from `t_world_sensor`, in the sensor frame.
    pub fn scan(&self, scene: &Scene, t_world_sensor: &Pose) -> Vec<Point> {
        let origin = t_world_sensor.translation.vector;
        let scene = Prepared::new(scene, &origin, self.max_range_m);
        let mut out = Vec::with_capacity(self.beams * self.azimuth_steps);
        for beam in 0..self.beams {
            for step in 0..self.azimuth_steps {
                let dir_s = self.direction(beam, step);
                let dir_w = t_world_sensor.rotation * dir_s;
                if let Some(range) = scene.cast(&origin, &dir_w, self.max_range_m) {
                    let p = Point3::from(dir_s * range);
                    out.push([p.x as f32, p.y as f32, p.z as f32]);
                }
            }
        }
        out
    }

    /// One noise-free rolling sweep: firing by firing round the turn, each cast from the pose
    /// the sensor has at its own time, `pose_at(t)` for `t` from 0 to `period_s` (the start of
    /// the sweep is the scan's stamp). Each point is in the sensor frame of its own time, as a
    /// real spinning LiDAR reports it, with that time (seconds after the stamp).
    pub fn scan_rolling(
        &self,
        scene: &Scene,
        pose_at: impl Fn(f64) -> Pose,
        period_s: f64,
    ) -> (Vec<Point>, Vec<f32>) {
        let (start, end) = (pose_at(0.0), pose_at(period_s));
        let travel = (end.translation.vector - start.translation.vector).norm();
        let scene = Prepared::new(scene, &start.translation.vector, self.max_range_m + travel);
        let mut points = Vec::with_capacity(self.beams * self.azimuth_steps);
        let mut times = Vec::with_capacity(self.beams * self.azimuth_steps);
        for step in 0..self.azimuth_steps {
            let t = period_s * step as f64 / self.azimuth_steps as f64;
            let pose = pose_at(t);
            let origin = pose.translation.vector;
            for beam in 0..self.beams {
                let dir_s = self.direction(beam, step);
                let dir_w = pose.rotation * dir_s;
                if let Some(range) = scene.cast(&origin, &dir_w, self.max_range_m) {
                    let p = dir_s * range;
                    points.push([p.x as f32, p.y as f32, p.z as f32]);
                    times.push(t as f32);
                }
            }
        }
        (points, times)
    }
}
