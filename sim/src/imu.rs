//! A simulated IMU riding on a drive's scanner, and a vibrating body to shake it with.
//!
//! [`ImuModel`] reads the drive's continuous true motion ([`Drive::pose_at`]) at its own rate:
//! the gyro the IMU frame's angular velocity, the accelerometer its specific force (its
//! acceleration less gravity, lever arm included), each with white noise and a bias that walks
//! at random (knots a second apart, drawn once, linear between). Deterministic: the same seed
//! gives the same readings, asked in any order.
//!
//! [`Vibration`] is a body's shaking on a rough road: roll, pitch and yaw oscillations, each a
//! sum of sines, laid over a drive's smooth attitude (within a sweep, where no constant-velocity
//! model can follow it).

use crate::drive::Drive;
use nalgebra::{UnitQuaternion, Vector3};
use slamesh_core::imu::{ImuSample, GRAVITY_M_S2};
use slamesh_core::random::SplitMix64;
use slamesh_core::Pose;

/// How an IMU reads (noise and bias per axis) and where it sits on the scanner.
#[derive(Debug, Clone, PartialEq)]
pub struct ImuModel {
    /// Readings a second.
    pub rate_hz: f64,
    /// White noise of a gyro reading (rad/s, one standard deviation).
    pub gyro_noise: f64,
    /// Standard deviation of the gyro's starting bias (rad/s).
    pub gyro_bias: f64,
    /// The gyro bias's random walk (rad/s per √s).
    pub gyro_walk: f64,
    /// White noise of an accelerometer reading (m/s²).
    pub accel_noise: f64,
    /// Standard deviation of the accelerometer's starting bias (m/s²).
    pub accel_bias: f64,
    /// The accelerometer bias's random walk (m/s² per √s).
    pub accel_walk: f64,
    /// The IMU's pose in the scanner's frame (rotation and lever arm).
    pub lidar_from_imu: Pose,
    /// Seed of the noise and the biases.
    pub seed: u64,
    /// Bias knots, one a second from 0: gyro then accelerometer (made by [`Drive::with_imu`]).
    knots: Vec<[f64; 6]>,
}

impl ImuModel {
    /// A common MEMS unit (a BMI088-class part) at `rate_hz`, at the scanner's origin and in
    /// its axes: gyro noise 0.014 °/s/√Hz, starting bias up to 0.3 °/s, walk 0.002 °/s/√s;
    /// accelerometer 150 µg/√Hz, bias 0.05 m/s², walk 0.001 m/s²/√s.
    pub fn mems(rate_hz: f64, seed: u64) -> Self {
        let density = |d: f64| d * rate_hz.sqrt();
        ImuModel {
            rate_hz,
            gyro_noise: density(0.014f64.to_radians()),
            gyro_bias: 0.1f64.to_radians(),
            gyro_walk: 0.002f64.to_radians(),
            accel_noise: density(150e-6 * GRAVITY_M_S2),
            accel_bias: 0.05,
            accel_walk: 0.001,
            lidar_from_imu: Pose::identity(),
            seed,
            knots: Vec::new(),
        }
    }

    /// The biases' knots over `seconds` (and two more).
    fn with_knots(mut self, seconds: f64) -> Self {
        let mut rng = SplitMix64(self.seed ^ 0xb1a5);
        let mut b: [f64; 6] = std::array::from_fn(|k| {
            gaussian(&mut rng)
                * if k < 3 {
                    self.gyro_bias
                } else {
                    self.accel_bias
                }
        });
        self.knots = (0..seconds.max(0.0) as usize + 3)
            .map(|_| {
                let now = b;
                for (k, v) in b.iter_mut().enumerate() {
                    *v += gaussian(&mut rng)
                        * if k < 3 {
                            self.gyro_walk
                        } else {
                            self.accel_walk
                        };
                }
                now
            })
            .collect();
        self
    }

    /// The biases at `t` seconds.
    pub fn bias_at(&self, t: f64) -> [f64; 6] {
        let Some(last) = self.knots.last() else {
            return [0.0; 6];
        };
        let x = t.max(0.0);
        let k = x as usize;
        match (self.knots.get(k), self.knots.get(k + 1)) {
            (Some(a), Some(b)) => std::array::from_fn(|j| a[j] + (b[j] - a[j]) * (x - k as f64)),
            _ => *last,
        }
    }
}

/// One standard normal sample (Box-Muller).
fn gaussian(rng: &mut SplitMix64) -> f64 {
    let (u, v) = (rng.next_f64().max(1e-12), rng.next_f64());
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

/// A body's shaking: roll, pitch and yaw (about the sensor's x, y, z), each a sum of sines
/// `(amplitude in degrees, frequency in Hz, phase in radians)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Vibration {
    /// About x, y and z.
    pub axes: [Vec<(f64, f64, f64)>; 3],
}

impl Vibration {
    /// A car on a rough road: roll, pitch and yaw swings of 0.5 to 2.5 degrees at 2 to 8 Hz.
    pub fn rough_road() -> Self {
        Vibration {
            axes: [
                vec![(1.5, 3.1, 0.0), (0.6, 7.3, 1.0)],
                vec![(2.0, 2.3, 0.5), (0.5, 5.7, 2.0)],
                vec![(0.8, 4.3, 1.5), (0.5, 7.9, 0.3)],
            ],
        }
    }

    /// The shake's rotation at `t` seconds.
    pub fn at(&self, t: f64) -> UnitQuaternion<f64> {
        let [r, p, y] = self.axes.each_ref().map(|terms| {
            terms
                .iter()
                .map(|&(deg, hz, phase)| {
                    deg.to_radians() * (std::f64::consts::TAU * hz * t + phase).sin()
                })
                .sum::<f64>()
        });
        UnitQuaternion::from_euler_angles(r, p, y)
    }
}

impl Drive {
    /// The drive with an IMU on its scanner, reading as `model` says.
    pub fn with_imu(mut self, model: ImuModel) -> Self {
        let seconds = self.poses.len() as f64 * self.period_s;
        self.imu = Some(model.with_knots(seconds));
        self
    }

    /// The IMU's readings with stamps in `(after, until]` seconds (none without an IMU). Before
    /// the first frame (negative times) the IMU reads the drive carried back at its first
    /// step's velocity: a body steady while the LiDAR spins up.
    pub fn imu_between(&self, after: f64, until: f64) -> Vec<ImuSample> {
        let Some(m) = &self.imu else {
            return Vec::new();
        };
        let first = (after * m.rate_hz).floor() as i64 + 1;
        let last = (until * m.rate_hz).floor() as i64;
        (first..=last).map(|k| self.imu_reading(m, k)).collect()
    }

    /// Reading `k` of the IMU (at `k / rate_hz` seconds).
    fn imu_reading(&self, m: &ImuModel, k: i64) -> ImuSample {
        let t = k as f64 / m.rate_hz;
        let imu_at = |t: f64| self.pose_at(t) * m.lidar_from_imu;
        // The angular velocity over ±0.1 ms; the acceleration over ±20 ms (the smooth drive's
        // velocity changes at the frames: a wider window spreads the change).
        let h = 1e-4;
        let turn =
            (imu_at(t - h).rotation.inverse() * imu_at(t + h).rotation).scaled_axis() / (2.0 * h);
        let a = 0.02;
        let p = |t: f64| imu_at(t).translation.vector;
        let accel = (p(t + a) - 2.0 * p(t) + p(t - a)) / (a * a);
        let force = imu_at(t).rotation.inverse() * (accel + Vector3::z() * GRAVITY_M_S2);
        let bias = m.bias_at(t);
        let mut rng = SplitMix64(m.seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ k as u64);
        let gyro = std::array::from_fn(|j| turn[j] + bias[j] + m.gyro_noise * gaussian(&mut rng));
        let accel =
            std::array::from_fn(|j| force[j] + bias[3 + j] + m.accel_noise * gaussian(&mut rng));
        ImuSample {
            stamp: t,
            gyro,
            accel,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Translation3;

    #[test]
    fn a_noiseless_imu_reads_the_drives_turn_and_gravity() {
        let mut m = ImuModel::mems(200.0, 3);
        (m.gyro_noise, m.gyro_bias, m.gyro_walk) = (0.0, 0.0, 0.0);
        (m.accel_noise, m.accel_bias, m.accel_walk) = (0.0, 0.0, 0.0);
        // Turned 90 degrees about z and 0.3 m off.
        m.lidar_from_imu = Pose::from_parts(
            Translation3::new(0.3, 0.0, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::FRAC_PI_2),
        );
        let drive = Drive::car(40, 1).with_imu(m.clone());
        let readings = drive.imu_between(1.0, 2.0);
        assert_eq!(readings.len(), 200);
        // The gyro's rotation over a frame is the true one, in the IMU's axes.
        let (a, b) = (1.2, 1.3);
        let mut q = UnitQuaternion::identity();
        for r in readings.iter().filter(|r| r.stamp > a && r.stamp <= b) {
            q *= UnitQuaternion::from_scaled_axis(Vector3::from(r.gyro) / 200.0);
        }
        let imu = |t: f64| drive.pose_at(t) * m.lidar_from_imu;
        let truth = imu(a).rotation.inverse() * imu(b).rotation;
        assert!(q.angle_to(&truth) < 1e-4, "{} rad off", q.angle_to(&truth));
        // A car's accelerometer reads about 1 g, up in the IMU's axes.
        let mean: Vector3<f64> = readings
            .iter()
            .map(|r| Vector3::from(r.accel))
            .sum::<Vector3<f64>>()
            / 200.0;
        assert!((mean.norm() - GRAVITY_M_S2).abs() < 0.5, "{mean}");
    }

    #[test]
    fn readings_are_the_same_asked_in_any_order() {
        let drive = Drive::car(20, 1).with_imu(ImuModel::mems(400.0, 5));
        let whole = drive.imu_between(0.0, 1.0);
        let halves = [drive.imu_between(0.0, 0.5), drive.imu_between(0.5, 1.0)].concat();
        assert_eq!(whole, halves);
        assert_eq!(whole.len(), 400);
    }

    #[test]
    fn the_rough_road_shakes_within_its_stated_range() {
        let v = Vibration::rough_road();
        let largest = (0..10_000)
            .map(|k| v.at(k as f64 * 1e-3).angle().to_degrees())
            .fold(0.0, f64::max);
        assert!((2.0..=5.0).contains(&largest), "{largest} degrees");
    }
}
