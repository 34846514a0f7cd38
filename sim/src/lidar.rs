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

    /// The unit rays of every beam (evenly spread between the two elevations) at every firing
    /// of the turn, in the sensor frame, as their sines and cosines: a scan's 64 000 rays from
    /// a thousand-odd of them.
    fn rays(&self) -> Rays {
        let elevation = |beam: usize| {
            let f = if self.beams > 1 {
                beam as f64 / (self.beams - 1) as f64
            } else {
                0.0
            };
            (self.elevation_min_deg + f * (self.elevation_max_deg - self.elevation_min_deg))
                .to_radians()
        };
        let azimuth = |step: usize| std::f64::consts::TAU * step as f64 / self.azimuth_steps as f64;
        Rays {
            beams: (0..self.beams)
                .map(|b| {
                    let el = elevation(b);
                    (el.cos(), el.sin())
                })
                .collect(),
            steps: (0..self.azimuth_steps)
                .map(|k| {
                    let az = azimuth(k);
                    (az.cos(), az.sin())
                })
                .collect(),
        }
    }

    /// One noise-free scan of `scene` from `t_world_sensor`, in the sensor frame.
    pub fn scan(&self, scene: &Scene, t_world_sensor: &Pose) -> Vec<Point> {
        self.scan_hits(scene, t_world_sensor).0
    }

    /// [`scan`](Self::scan) with what each point lies on: the index of the scene's box, or
    /// `None` for the ground or a sphere.
    pub fn scan_hits(&self, scene: &Scene, t_world_sensor: &Pose) -> (Vec<Point>, Vec<Hit>) {
        let origin = t_world_sensor.translation.vector;
        let scene = Prepared::new(scene, &origin, self.max_range_m, 0.0);
        let rays = self.rays();
        let mut out = Vec::with_capacity(self.beams * self.azimuth_steps);
        let mut hits = Vec::with_capacity(self.beams * self.azimuth_steps);
        for beam in 0..self.beams {
            for step in 0..self.azimuth_steps {
                let dir_s = rays.direction(beam, step);
                let dir_w = t_world_sensor.rotation * dir_s;
                if let Some((range, hit)) = scene.cast_to(&origin, &dir_w, self.max_range_m) {
                    let p = Point3::from(dir_s * range);
                    out.push([p.x as f32, p.y as f32, p.z as f32]);
                    hits.push(hit);
                }
            }
        }
        (out, hits)
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
        let (points, times, _) = self.scan_rolling_hits(scene, pose_at, period_s);
        (points, times)
    }

    /// [`scan_rolling`](Self::scan_rolling) with what each point lies on
    /// ([`scan_hits`](Self::scan_hits)).
    pub fn scan_rolling_hits(
        &self,
        scene: &Scene,
        pose_at: impl Fn(f64) -> Pose,
        period_s: f64,
    ) -> (Vec<Point>, Vec<f32>, Vec<Hit>) {
        let (start, end) = (pose_at(0.0), pose_at(period_s));
        let travel = (end.translation.vector - start.translation.vector).norm();
        let time = |step: usize| period_s * step as f64 / self.azimuth_steps as f64;
        let poses: Vec<Pose> = (0..self.azimuth_steps).map(|k| pose_at(time(k))).collect();
        // How far the sweep's origin strays from where it began (more than `travel` on a bend).
        let strayed = poses
            .iter()
            .map(|p| (p.translation.vector - start.translation.vector).norm())
            .fold(travel, f64::max);
        let scene = Prepared::new(
            scene,
            &start.translation.vector,
            self.max_range_m + travel,
            strayed,
        );
        let rays = self.rays();
        let mut points = Vec::with_capacity(self.beams * self.azimuth_steps);
        let mut times = Vec::with_capacity(self.beams * self.azimuth_steps);
        let mut hits = Vec::with_capacity(self.beams * self.azimuth_steps);
        for (step, pose) in poses.iter().enumerate() {
            let t = time(step);
            let origin = pose.translation.vector;
            for beam in 0..self.beams {
                let dir_s = rays.direction(beam, step);
                let dir_w = pose.rotation * dir_s;
                if let Some((range, hit)) = scene.cast_to(&origin, &dir_w, self.max_range_m) {
                    let p = dir_s * range;
                    points.push([p.x as f32, p.y as f32, p.z as f32]);
                    times.push(t as f32);
                    hits.push(hit);
                }
            }
        }
        (points, times, hits)
    }
}

/// What a ray met: the index of the scene's box, or `None` for the ground or a sphere.
pub type Hit = Option<usize>;

/// The sines and cosines of a [`Lidar`]'s beams' elevations and of its firings' azimuths.
struct Rays {
    /// Per beam, the cosine and sine of its elevation.
    beams: Vec<(f64, f64)>,
    /// Per firing, the cosine and sine of its azimuth.
    steps: Vec<(f64, f64)>,
}

impl Rays {
    /// The unit ray of `beam` at firing `step` of the turn, in the sensor frame.
    fn direction(&self, beam: usize, step: usize) -> Vector3<f64> {
        let ((ce, se), (ca, sa)) = (self.beams[beam], self.steps[step]);
        Vector3::new(ce * ca, ce * sa, se)
    }
}
