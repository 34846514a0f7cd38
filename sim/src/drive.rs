//! Simulated drives: true poses through a scene and the noisy scans a [`Lidar`] sees along them.

use crate::imu::{ImuModel, Vibration};
use crate::lidar::Lidar;
use crate::scene::Scene;
use crate::traffic::{Label, Traffic};
use nalgebra::{Point3, Translation3, UnitQuaternion};
use slamesh_core::math::{se3_exp, se3_log};
use slamesh_core::random::SplitMix64;
use slamesh_core::{Point, Pose};
use std::borrow::Cow;

/// A level sensor pose: position (metres) and heading about z (degrees).
pub fn sensor_pose(x: f64, y: f64, z: f64, yaw_deg: f64) -> Pose {
    Pose::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(0.0, 0.0, yaw_deg.to_radians()),
    )
}

/// A simulated drive: the scans a [`Lidar`] sees along `poses` through `scene`, with Gaussian
/// range noise, made on demand ([`Drive::scan`]), so long runs need no disk.
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
    /// Share of returns lost (0 to 1).
    pub dropout: f64,
    /// Seed of the noise and dropouts (frame `i` uses `seed + i`).
    pub seed: u64,
    /// A rolling sweep of this many seconds (the frame period, 0.1 s at 10 Hz): each firing
    /// from the pose at its own time, moving from `poses[i]` towards `poses[i + 1]`
    /// ([`Drive::scan_timed`]). `None`: every firing from `poses[i]`.
    pub sweep_s: Option<f64>,
    /// Seconds between frames (frame `i` is stamped `i · period_s`).
    pub period_s: f64,
    /// An IMU on the scanner ([`Drive::with_imu`]).
    pub imu: Option<ImuModel>,
    /// The body's shaking over the smooth poses it was laid on ([`Drive::shaken`]).
    pub shake: Option<(Vibration, Vec<Pose>)>,
    /// Cars and people moving through the scene ([`Drive::with_traffic`]).
    pub traffic: Option<Traffic>,
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
            dropout: 0.0,
            seed,
            sweep_s: None,
            period_s: 0.1,
            imu: None,
            shake: None,
            traffic: None,
        }
    }

    /// Up to `frames` frames (at most once round, about 1 200) of the loop through
    /// [`crate::town`]'s town: HDL-64-like scans (1 000 firings a turn, 80 m), 2 cm range
    /// noise, 5 % dropouts.
    pub fn town(frames: usize, seed: u64) -> Self {
        let scene = crate::town::scene(seed);
        let poses = crate::town::drive_poses(&scene, frames);
        Self::car_scanner(scene, poses, seed)
    }

    /// [`Drive::town`]'s car and scanner through any `scene` along `poses`.
    fn car_scanner(scene: Scene, poses: Vec<Pose>, seed: u64) -> Self {
        let mut lidar = Lidar::hdl64(1000);
        lidar.max_range_m = 80.0;
        Drive {
            scene,
            lidar,
            poses,
            noise_m: 0.02,
            dropout: 0.05,
            seed,
            sweep_s: None,
            period_s: 0.1,
            imu: None,
            shake: None,
            traffic: None,
        }
    }

    /// [`Drive::town`] going on round the loop past its start ([`crate::town::drive_poses_round`]):
    /// about 1 200 frames come back to the start, more see the first street again.
    pub fn town_round(frames: usize, seed: u64) -> Self {
        let mut d = Self::town(0, seed);
        d.poses = crate::town::drive_poses_round(&d.scene, frames);
        d
    }

    /// Up to `frames` frames of [`Drive::town`]'s car and scanner along another `path` through
    /// the town ([`crate::town::campus_path`], [`crate::town::block_path`]).
    pub fn town_along(path: Vec<[f64; 2]>, frames: usize, seed: u64) -> Self {
        let mut d = Self::town(0, seed);
        d.poses = crate::town::drive_poses_along(&d.scene, path, frames);
        d
    }

    /// Up to `frames` frames through [`Scene::twin_streets`] (`length_m` long, `gap_m` apart),
    /// as [`Drive::town`]'s car and scanner: along the first street, round its end into the
    /// second and back along it (a look-alike of the first, never driven before), round
    /// into the first again and 60 m along it (a true return).
    pub fn twin_streets(frames: usize, length_m: f64, gap_m: f64, seed: u64) -> Self {
        let scene = Scene::twin_streets(length_m, gap_m, seed);
        let (x0, x1) = (-35.0, length_m + 35.0);
        let path = crate::town::path_through(&[
            [0.0, 0.0],
            [x1, 0.0],
            [x1, gap_m],
            [x0, gap_m],
            [x0, 0.0],
            [60.0, 0.0],
        ]);
        let poses = crate::town::drive_poses_along(&scene, path, frames);
        Self::car_scanner(scene, poses, seed)
    }

    /// [`Drive::town`] with a car's smooth attitude ([`crate::town::car_poses`]): for rolling
    /// sweeps, where a jittery pitch and roll would be motion no scanner deskews without an
    /// IMU.
    pub fn car(frames: usize, seed: u64) -> Self {
        let mut d = Self::town(frames, seed);
        d.poses = crate::town::car_poses(&d.scene, frames);
        d
    }

    /// Up to `frames` scans (2 a second) of a rig carried through [`crate::town`]'s town and
    /// an indoor hall over its first street ([`crate::town::hall`]) as `how` says (a hand-held scanner, a drone: [`crate::town::Carried`]), seen by a 32-beam
    /// sensor (Ouster OS-32 like: 32 beams over ±22.5 degrees, 1 024 firings a turn, 80 m),
    /// 2 cm range noise, 5 % dropouts.
    pub fn carried(frames: usize, how: crate::town::Carried, seed: u64) -> Self {
        let mut scene = crate::town::scene(seed);
        let hall = crate::town::hall(&scene);
        scene.boxes.extend(hall);
        let poses = crate::town::carried_poses(&scene, frames, how, seed);
        Drive {
            period_s: 1.0 / crate::town::CARRIED_HZ,
            scene,
            lidar: Lidar {
                beams: 32,
                elevation_min_deg: -22.5,
                elevation_max_deg: 22.5,
                azimuth_steps: 1024,
                max_range_m: 80.0,
            },
            poses,
            noise_m: 0.02,
            dropout: 0.05,
            seed,
            sweep_s: None,
            imu: None,
            shake: None,
            traffic: None,
        }
    }

    /// Up to `frames` scans (10 a second) of a hand-held walk through [`crate::office`]'s
    /// two rooms and corridor (ranges of 1 to 15 m), seen by a 16-beam sensor (VLP-16 like,
    /// 900 firings a turn), 2 cm range noise, 5 % dropouts.
    pub fn office(frames: usize, seed: u64) -> Self {
        Drive {
            scene: crate::office::scene(seed),
            lidar: Lidar::vlp16(900),
            poses: crate::office::walk_poses(frames),
            noise_m: 0.02,
            dropout: 0.05,
            seed,
            sweep_s: None,
            period_s: 0.1,
            imu: None,
            shake: None,
            traffic: None,
        }
    }

    /// Up to `frames` scans (10 a second, 2 m/s) along [`crate::yard`]'s court past its kerbs
    /// and ramps, seen by [`Drive::town`]'s scanner, 2 cm range noise, 5 % dropouts.
    pub fn yard(frames: usize, seed: u64) -> Self {
        Self::car_scanner(crate::yard::scene(), crate::yard::drive_poses(frames), seed)
    }

    /// The drive shaken by `vibration` over its smooth attitude: every frame's pose (and every
    /// firing's, in a rolling sweep) turned by the shake at its time.
    pub fn shaken(mut self, vibration: Vibration) -> Self {
        let smooth = std::mem::take(&mut self.poses);
        let n = smooth.len();
        self.shake = Some((vibration, smooth));
        let shaken = (0..n).map(|i| self.pose_after(i, 0.0)).collect();
        self.poses = shaken;
        self
    }

    /// The true pose at `t` seconds (frame `i` at `i · period_s`): between two frames, moving
    /// at the constant velocity from one to the next (past the last, the last step's), shaken
    /// if the drive is ([`Drive::shaken`]).
    pub fn pose_at(&self, t: f64) -> Pose {
        let n = self.smooth_poses().len();
        let i = ((t / self.period_s).floor().max(0.0) as usize).min(n.saturating_sub(1));
        self.pose_after(i, t - i as f64 * self.period_s)
    }

    /// The poses the drive moves between, smooth (before any shake).
    fn smooth_poses(&self) -> &[Pose] {
        self.shake.as_ref().map_or(&self.poses, |(_, p)| p)
    }

    /// The true pose `dt` seconds after frame `i`'s stamp (see [`Drive::pose_at`]).
    pub fn pose_after(&self, i: usize, dt: f64) -> Pose {
        let poses = self.smooth_poses();
        let Some(&from) = poses.get(i) else {
            return Pose::identity();
        };
        let to = match (poses.get(i + 1), i.checked_sub(1)) {
            (Some(next), _) => *next,
            // The last frame: the step before, repeated.
            (None, Some(prev)) => from * (poses[prev].inverse() * from),
            (None, None) => from,
        };
        let step = se3_log(&(from.inverse() * to));
        let smooth = from * se3_exp(&(step * (dt / self.period_s)));
        match &self.shake {
            Some((v, _)) => {
                let t = i as f64 * self.period_s + dt;
                smooth * nalgebra::Isometry3::from_parts(Translation3::identity(), v.at(t))
            }
            None => smooth,
        }
    }

    /// The noise-free, complete scan of frame `i` in the world frame: samples of the true
    /// surfaces where the sensor saw them (a reference for mesh accuracy).
    pub fn true_points(&self, i: usize) -> Vec<Point> {
        let pose = &self.poses[i];
        self.lidar
            .scan(&self.scene, pose)
            .into_iter()
            .map(|p| {
                let w = pose * Point3::new(p[0] as f64, p[1] as f64, p[2] as f64);
                [w.x as f32, w.y as f32, w.z as f32]
            })
            .collect()
    }

    /// The noisy scan of frame `i` in the sensor frame: the [`Lidar`]'s returns, a share
    /// `dropout` of them lost and Gaussian noise of `noise_m` along each ray, from seed
    /// `seed + i` (the same scan every time). With a rolling sweep, each point is in the
    /// sensor frame of its own time ([`Drive::scan_timed`] gives the times).
    pub fn scan(&self, i: usize) -> Vec<Point> {
        self.scan_timed(i).0
    }

    /// [`Drive::scan`] with each point's time after the frame's stamp (seconds): all 0 without
    /// a rolling sweep.
    pub fn scan_timed(&self, i: usize) -> (Vec<Point>, Vec<f32>) {
        let (points, times, _) = self.scan_labelled(i);
        (points, times)
    }

    /// The drive with `traffic` moving through its scene: its scans see the movers where
    /// they are at each frame's stamp.
    pub fn with_traffic(mut self, traffic: Traffic) -> Self {
        self.traffic = Some(traffic);
        self
    }

    /// The scene at frame `i`'s stamp, movers included (their boxes after the scene's own),
    /// and which mover each of those boxes is.
    fn scene_at(&self, i: usize) -> (Cow<'_, Scene>, Vec<usize>) {
        let Some(traffic) = &self.traffic else {
            return (Cow::Borrowed(&self.scene), Vec::new());
        };
        let mut scene = self.scene.clone();
        let mut movers = Vec::new();
        let boxes = traffic.boxes_at(&self.scene, i as f64 * self.period_s);
        for (k, b) in boxes.into_iter().enumerate() {
            if let Some(b) = b {
                scene.boxes.push(b);
                movers.push(k);
            }
        }
        (Cow::Owned(scene), movers)
    }

    /// [`Drive::scan_timed`] with each point's truth: [`Label::Static`] throughout without
    /// traffic.
    pub fn scan_labelled(&self, i: usize) -> (Vec<Point>, Vec<f32>, Vec<Label>) {
        let mut rng = SplitMix64(self.seed.wrapping_add(i as u64));
        let (scene, movers) = self.scene_at(i);
        let (mut points, mut times, hits) = match self.sweep_s {
            None => {
                let (p, hits) = self.lidar.scan_hits(&scene, &self.poses[i]);
                let n = p.len();
                (p, vec![0.0; n], hits)
            }
            Some(period) => self
                .lidar
                .scan_rolling_hits(&scene, |t| self.pose_after(i, t), period),
        };
        let first_mover = self.scene.boxes.len();
        let mut labels: Vec<Label> = hits
            .iter()
            .map(|hit| match hit.and_then(|b| b.checked_sub(first_mover)) {
                Some(k) => self
                    .traffic
                    .as_ref()
                    .map_or(Label::Static, |t| t.label_of(movers[k])),
                None => Label::Static,
            })
            .collect();
        if self.dropout > 0.0 {
            let dropout = self.dropout;
            let keep: Vec<bool> = points.iter().map(|_| rng.next_f64() >= dropout).collect();
            let mut k = keep.iter();
            points.retain(|_| *k.next().expect("one flag a point"));
            let mut k = keep.iter();
            times.retain(|_| *k.next().expect("one flag a point"));
            let mut k = keep.iter();
            labels.retain(|_| *k.next().expect("one flag a point"));
        }
        for p in &mut points {
            // Box-Muller: one Gaussian sample along the ray.
            let (u, v) = (rng.next_f64().max(1e-12), rng.next_f64());
            let n = self.noise_m * (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos();
            let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() as f64;
            let k = ((r + n) / r) as f32;
            *p = p.map(|c| c * k);
        }
        (points, times, labels)
    }
}
