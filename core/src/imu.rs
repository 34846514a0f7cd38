//! The IMU as a motion prior (docs/design.md §1.19): the gyro's rotation between two scans
//! starts the registration, and its rotation at each point's time deskews the sweep.
//!
//! [`ImuTrack`] owns a bounded buffer of readings (its capacity declared with the others:
//! [`Capacity::IMU_SAMPLES`](crate::Capacity::IMU_SAMPLES)), already turned into the LiDAR's
//! axes and onto its clock by the [`ImuCalibration`], and the gyro bias it estimates online
//! from the registered rotations. It guarantees:
//! - a reading that cannot be used is refused with its reason and counted ([`ImuFault`],
//!   [`ImuCounts`]): a number that is not finite, a stamp not after the last one (out of order
//!   or a duplicate); a saturated reading is kept and counted;
//! - a rotation is given only over time the readings cover, with no gap longer than
//!   [`GAP_PERIODS`] sampling periods (a rate is held at most that long past either end);
//!   otherwise the caller hears [`ImuGap`] and falls back to its motion model;
//! - nothing is allocated after construction: a full buffer forgets its oldest half.
//!
//! Between readings the rate is taken as linear (the trapezoid rule), minus the bias; the
//! rotation over an interval is the product of the exponentials of its pieces. The lever arm
//! does not enter a rotation (every point of a rigid body turns alike); it matters only for the
//! accelerometer.

use crate::bounded::{BoundedVec, Empty};
use crate::math::{Pose, Vec3};
use nalgebra::UnitQuaternion;

/// A gap longer than this many sampling periods breaks the readings' cover.
pub const GAP_PERIODS: f64 = 2.0;

/// Standard gravity (m/s²): what a still accelerometer reads, in magnitude.
pub const GRAVITY_M_S2: f64 = 9.80665;

/// One IMU reading as the sensor gives it: its stamp (seconds, the IMU's clock), the angular
/// velocity (rad/s) and the specific force (m/s², gravity included), in the IMU's axes.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ImuSample {
    /// Seconds.
    pub stamp: f64,
    /// Angular velocity about x, y, z (rad/s, or the unit
    /// [`ImuCalibration::gyro_unit_rad_s`] says).
    pub gyro: [f64; 3],
    /// Specific force along x, y, z (m/s², or the unit [`ImuCalibration::accel_unit_m_s2`]
    /// says).
    pub accel: [f64; 3],
}

/// Where the IMU sits on the LiDAR and how their clocks differ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuCalibration {
    /// The IMU's pose in the LiDAR frame: its rotation turns the IMU's axes into the LiDAR's,
    /// its translation is the lever arm (metres).
    pub lidar_from_imu: Pose,
    /// Added to an IMU stamp to put it on the LiDAR's clock (seconds).
    pub time_offset_s: f64,
    /// A gyro reading at or above this magnitude on any axis is counted as saturated (rad/s).
    pub gyro_limit_rad_s: f64,
    /// An accelerometer reading at or above this on any axis is counted as saturated (m/s²).
    pub accel_limit_m_s2: f64,
    /// What one accelerometer unit is in m/s²: 1 for readings in m/s², [`GRAVITY_M_S2`] for
    /// readings in g (as some LiDARs' built-in IMUs give them).
    pub accel_unit_m_s2: f64,
    /// What one gyro unit is in rad/s: 1 for readings in rad/s, π/180 for degrees a second.
    pub gyro_unit_rad_s: f64,
}

impl Default for ImuCalibration {
    /// At the LiDAR's origin, in its axes, on its clock; the limits of a common MEMS unit
    /// (±2 000 °/s, ±16 g).
    fn default() -> Self {
        Self {
            lidar_from_imu: Pose::identity(),
            time_offset_s: 0.0,
            gyro_limit_rad_s: 2000f64.to_radians(),
            accel_limit_m_s2: 16.0 * GRAVITY_M_S2,
            accel_unit_m_s2: 1.0,
            gyro_unit_rad_s: 1.0,
        }
    }
}

/// Why a reading was refused.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ImuFault {
    /// A number in it is not finite.
    NotFinite,
    /// Its stamp comes before the last reading's.
    OutOfOrder {
        /// Its stamp on the LiDAR's clock (seconds).
        t: f64,
        /// The last reading's.
        last: f64,
    },
    /// Its stamp is the last reading's.
    Duplicate {
        /// The stamp (seconds).
        t: f64,
    },
}

/// What the readings do not cover.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ImuGap {
    /// No reading yet.
    NoReadings,
    /// No reading between `from` and `to` (seconds, the LiDAR's clock), which the interval
    /// asked for needs.
    Between {
        /// Start of the uncovered time.
        from: f64,
        /// Its end.
        to: f64,
    },
}

/// Readings taken and refused, for a report.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ImuCounts {
    /// Taken into the buffer.
    pub taken: usize,
    /// Refused: a number not finite.
    pub not_finite: usize,
    /// Refused: out of order.
    pub out_of_order: usize,
    /// Refused: a duplicate stamp.
    pub duplicate: usize,
    /// Taken, but at a sensor limit.
    pub saturated: usize,
    /// Forgotten early because the buffer was full.
    pub forgotten_early: usize,
}

/// The specific force over a stretch of readings ([`ImuTrack::mean_force`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceMean {
    /// The mean (m/s², the LiDAR's frame at the reference time).
    pub mean: Vec3,
    /// The readings' root-mean-square distance from the mean (m/s²): the body's own
    /// acceleration and the sensor's noise.
    pub spread: f64,
    /// Readings averaged.
    pub readings: usize,
    /// The time they span (seconds).
    pub seconds: f64,
}

/// A reading as the track keeps it, in the LiDAR's axes and on its clock: a slot of its
/// buffer ([`ImuTrack::in_slice`] takes caller storage of these).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Reading {
    t: f64,
    gyro: Vec3,
    /// The specific force where the IMU sits, in the LiDAR's axes (m/s²).
    accel: Vec3,
}

impl Reading {
    /// A reading as a track keeps it: its time on the LiDAR's clock, the gyro (rad/s) and the
    /// specific force (m/s²) in the LiDAR's axes ([`ImuTrack::held`] gives them back).
    pub fn new(t: f64, gyro: Vec3, accel: Vec3) -> Self {
        Reading { t, gyro, accel }
    }

    /// Its time, gyro and specific force, as [`Reading::new`] takes them.
    pub fn parts(&self) -> (f64, Vec3, Vec3) {
        (self.t, self.gyro, self.accel)
    }
}

impl Empty for Reading {
    /// An empty slot, for a `static` buffer.
    const EMPTY: Reading = Reading {
        t: 0.0,
        gyro: Vec3::new(0.0, 0.0, 0.0),
        accel: Vec3::new(0.0, 0.0, 0.0),
    };
}

/// The IMU's readings, their calibration, and the gyro bias (LiDAR axes, rad/s).
#[derive(Debug)]
#[cfg_attr(feature = "alloc", derive(Clone))]
pub struct ImuTrack {
    readings: BoundedVec<Reading>,
    calibration: ImuCalibration,
    bias: Vec3,
    /// The sampling period, smoothed over the readings (seconds; 0 before two readings).
    period_s: f64,
    counts: ImuCounts,
}

impl ImuTrack {
    /// A track holding at most `capacity` readings, allocated now (feature `alloc`).
    #[cfg(any(feature = "alloc", test))]
    pub fn new(capacity: usize, calibration: ImuCalibration) -> Self {
        Self::in_buffer(BoundedVec::with_capacity(capacity), calibration)
    }

    /// A track in caller storage (no allocator): it holds at most `slots.len()` readings.
    pub fn in_slice(slots: &'static mut [Reading], calibration: ImuCalibration) -> Self {
        Self::in_buffer(BoundedVec::in_slice(slots), calibration)
    }

    fn in_buffer(readings: BoundedVec<Reading>, calibration: ImuCalibration) -> Self {
        Self {
            readings,
            calibration,
            bias: Vec3::zeros(),
            period_s: 0.0,
            counts: ImuCounts::default(),
        }
    }

    /// The calibration.
    pub fn calibration(&self) -> &ImuCalibration {
        &self.calibration
    }

    /// Counts so far.
    pub fn counts(&self) -> ImuCounts {
        self.counts
    }

    /// The gyro bias estimated so far, in the LiDAR's axes (rad/s).
    pub fn bias(&self) -> Vec3 {
        self.bias
    }

    /// The sampling period (seconds; 0 before two readings).
    pub fn period_s(&self) -> f64 {
        self.period_s
    }

    /// The newest reading's time on the LiDAR's clock.
    pub fn last_t(&self) -> Option<f64> {
        self.readings.last().map(|r| r.t)
    }

    /// Takes one reading; refuses it, counted, when it cannot be used.
    pub fn push(&mut self, s: &ImuSample) -> Result<(), ImuFault> {
        let finite = s.stamp.is_finite() && s.gyro.iter().chain(&s.accel).all(|v| v.is_finite());
        if !finite {
            self.counts.not_finite += 1;
            return Err(ImuFault::NotFinite);
        }
        let t = s.stamp + self.calibration.time_offset_s;
        if let Some(last) = self.last_t() {
            if t == last {
                self.counts.duplicate += 1;
                return Err(ImuFault::Duplicate { t });
            }
            if t < last {
                self.counts.out_of_order += 1;
                return Err(ImuFault::OutOfOrder { t, last });
            }
            let dt = t - last;
            // A gap is no sampling period: the smoothed period follows regular steps only.
            if self.period_s == 0.0 {
                self.period_s = dt;
            } else if dt <= GAP_PERIODS * self.period_s {
                self.period_s += (dt - self.period_s) / 16.0;
            }
        }
        let c = &self.calibration;
        let gyro = Vec3::from(s.gyro) * c.gyro_unit_rad_s;
        let accel = Vec3::from(s.accel) * c.accel_unit_m_s2;
        if gyro.iter().any(|v| libm::fabs(*v) >= c.gyro_limit_rad_s)
            || accel.iter().any(|v| libm::fabs(*v) >= c.accel_limit_m_s2)
        {
            self.counts.saturated += 1;
        }
        let turn = c.lidar_from_imu.rotation;
        let reading = Reading {
            t,
            gyro: turn * gyro,
            accel: turn * accel,
        };
        if self.readings.is_full() {
            self.forget_oldest_half();
        }
        // Room was made above: a buffer of capacity 0 takes nothing.
        if self.readings.push(reading).is_ok() {
            self.counts.taken += 1;
        }
        Ok(())
    }

    /// The readings held, oldest first.
    pub fn held(&self) -> &[Reading] {
        &self.readings
    }

    /// Puts back what a track held (its readings, [`held`](Self::held), its bias, sampling
    /// period, counts and accelerometer unit), as a resumed run does: what it held before is
    /// dropped. Readings past its capacity, or not in time order, are refused, saying which
    /// (nothing held).
    pub fn restore(
        &mut self,
        held: &[Reading],
        bias: Vec3,
        period_s: f64,
        counts: ImuCounts,
        accel_unit_m_s2: f64,
    ) -> Result<(), &'static str> {
        self.readings.clear();
        if held.len() > self.readings.capacity() {
            return Err("more readings than the track holds");
        }
        if !held.windows(2).all(|w| w[0].t < w[1].t) {
            return Err("readings out of time order");
        }
        for r in held {
            // Within the capacity: cannot fail.
            let _ = self.readings.push(*r);
        }
        (self.bias, self.period_s, self.counts) = (bias, period_s, counts);
        self.calibration.accel_unit_m_s2 = accel_unit_m_s2;
        Ok(())
    }

    /// Takes the accelerometer's readings to be in units of `unit_m_s2` from now on, those
    /// held included (they were taken in the calibration's unit until now).
    pub fn set_accel_unit(&mut self, unit_m_s2: f64) {
        let was = self.calibration.accel_unit_m_s2;
        if !(unit_m_s2.is_finite() && unit_m_s2 > 0.0) || unit_m_s2 == was {
            return;
        }
        for r in self.readings.iter_mut() {
            r.accel = r.accel / was * unit_m_s2;
        }
        self.calibration.accel_unit_m_s2 = unit_m_s2;
    }

    /// Forgets the readings no rotation from `t` on needs (all before the last one at or
    /// before `t`).
    pub fn forget_before(&mut self, t: f64) {
        let keep_from = self
            .readings
            .partition_point(|r| r.t <= t)
            .saturating_sub(1);
        self.drop_first(keep_from);
    }

    fn forget_oldest_half(&mut self) {
        let n = self.readings.len().div_ceil(2);
        self.counts.forgotten_early += n;
        self.drop_first(n);
    }

    fn drop_first(&mut self, n: usize) {
        if n == 0 {
            return;
        }
        let len = self.readings.len();
        self.readings.copy_within(n..len, 0);
        self.readings.truncate(len - n);
    }

    /// The longest a rate is held past the readings, or a gap between two may last.
    fn gap_limit(&self) -> f64 {
        GAP_PERIODS * self.period_s
    }

    /// The gyro rate (bias removed) at `t`, linear between readings, held past the ends.
    fn rate_at(&self, k: usize, t: f64) -> Vec3 {
        let r = &self.readings;
        let w = match (k.checked_sub(1).and_then(|j| r.get(j)), r.get(k)) {
            (Some(a), Some(b)) => {
                let f = ((t - a.t) / (b.t - a.t)).clamp(0.0, 1.0);
                a.gyro + (b.gyro - a.gyro) * f
            }
            (Some(a), None) => a.gyro,
            (None, Some(b)) => b.gyro,
            (None, None) => Vec3::zeros(),
        };
        w - self.bias
    }

    /// Checks that the readings cover `[a, b]` (a ≤ b): within the gap limit of either end and
    /// with no longer gap inside.
    fn covers(&self, a: f64, b: f64) -> Result<(), ImuGap> {
        let r = &self.readings;
        let (Some(first), Some(last)) = (r.first(), r.last()) else {
            return Err(ImuGap::NoReadings);
        };
        let limit = self.gap_limit();
        if b > last.t + limit {
            return Err(ImuGap::Between {
                from: last.t,
                to: b,
            });
        }
        if a < first.t - limit {
            return Err(ImuGap::Between {
                from: a,
                to: first.t,
            });
        }
        let start = r.partition_point(|x| x.t <= a).saturating_sub(1);
        for w in r[start..].windows(2) {
            if w[0].t >= b {
                break;
            }
            if w[1].t - w[0].t > limit {
                return Err(ImuGap::Between {
                    from: w[0].t,
                    to: w[1].t,
                });
            }
        }
        Ok(())
    }

    /// The LiDAR's rotation from time `a` to time `b` (seconds, its clock): `R(a)ᵀ R(b)`, in
    /// its frame at `a`. Either order; an error when the readings do not cover the interval.
    pub fn rotation(&self, a: f64, b: f64) -> Result<UnitQuaternion<f64>, ImuGap> {
        if !(a.is_finite() && b.is_finite()) {
            return Err(ImuGap::Between { from: a, to: b });
        }
        if b < a {
            return self.rotation(b, a).map(|q| q.inverse());
        }
        self.covers(a, b)?;
        let r = &self.readings;
        let mut q = UnitQuaternion::identity();
        // Pieces split at the readings' stamps; piece k ends at reading k (or at `b`).
        let mut k = r.partition_point(|x| x.t <= a);
        let mut u = a;
        while u < b {
            let v = r.get(k).map_or(b, |x| x.t.min(b));
            let mean = (self.rate_at(k, u) + self.rate_at(k, v)) / 2.0;
            q *= UnitQuaternion::from_scaled_axis(mean * (v - u));
            u = v;
            k += 1;
        }
        Ok(q)
    }

    /// The specific force at the LiDAR's origin averaged over the readings held after `after`
    /// up to `t_ref`, each turned by the gyro into the LiDAR's frame at `t_ref`
    /// ([`crate::gravity`] reads gravity from it: the time before a first scan, when a body is
    /// most often still, or the time between two registered frames).
    /// The lever arm's share is taken out of each reading: an IMU off the LiDAR's origin feels
    /// `α × r + ω × (ω × r)` more as the body turns (`r` the IMU's place, `ω` the rate less the
    /// bias, `α` its change between the neighbouring readings). An error when fewer than three
    /// readings come before `t_ref`, or a gap breaks them or parts them from it.
    pub fn mean_force(&self, after: f64, t_ref: f64) -> Result<ForceMean, ImuGap> {
        self.mean_force_over(after, t_ref, t_ref)
    }

    /// [`mean_force`](Self::mean_force) over the readings after `after` up to `until`, which
    /// may come after `t_ref`: a body still at a scan's stamp says where up is with the
    /// readings after it as well as with those before (a recording whose IMU starts with its
    /// first scan has none before).
    pub fn mean_force_over(&self, after: f64, until: f64, t_ref: f64) -> Result<ForceMean, ImuGap> {
        let r = &self.readings[..self.readings.partition_point(|x| x.t <= until)];
        let r = &r[r.partition_point(|x| x.t <= after)..];
        let (Some(first), Some(last)) = (r.first(), r.last()) else {
            return Err(ImuGap::NoReadings);
        };
        if r.len() < 3 {
            return Err(ImuGap::NoReadings);
        }
        let arm = self.calibration.lidar_from_imu.translation.vector;
        let rate = |k: usize| r[k].gyro - self.bias;
        // The frame at `t_ref` from the frame at the first reading (which also checks that no
        // gap breaks the readings from there to `t_ref`), then piece by piece on, as
        // `rotation` integrates them.
        let mut q = self.rotation(t_ref, first.t)?;
        let (mut sum, mut sum_sq) = (Vec3::zeros(), 0.0);
        for k in 0..r.len() {
            if k > 0 {
                let dt = r[k].t - r[k - 1].t;
                q *= UnitQuaternion::from_scaled_axis((rate(k - 1) + rate(k)) * (dt / 2.0));
            }
            let (a, b) = (k.saturating_sub(1), (k + 1).min(r.len() - 1));
            let alpha = (rate(b) - rate(a)) / (r[b].t - r[a].t);
            let w = rate(k);
            let at_origin = r[k].accel - alpha.cross(&arm) - w.cross(&w.cross(&arm));
            let f = q * at_origin;
            sum += f;
            sum_sq += f.norm_squared();
        }
        let n = r.len() as f64;
        let mean = sum / n;
        Ok(ForceMean {
            mean,
            spread: libm::sqrt((sum_sq / n - mean.norm_squared()).max(0.0)),
            readings: r.len(),
            seconds: last.t - first.t,
        })
    }

    /// Corrects the bias by `gain` of what the registered rotation over `dt` seconds says it
    /// is off by: `gyro`, the track's [`rotation`](Self::rotation) over the same time with the
    /// current bias, against the registration's, `log(registeredᵀ · gyro) / dt`. A
    /// disagreement above `max_rad` (a registration that went wrong, or a wrong calibration)
    /// is not taken; returns the disagreement.
    pub fn correct_bias(
        &mut self,
        gyro: &UnitQuaternion<f64>,
        dt: f64,
        registered: &UnitQuaternion<f64>,
        gain: f64,
        max_rad: f64,
    ) -> f64 {
        let off = (registered.inverse() * gyro).scaled_axis();
        let angle = off.norm();
        if dt > 0.0 && angle <= max_rad {
            self.bias += off * (gain / dt);
        }
        angle
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Translation3;

    fn sample(t: f64, gyro: [f64; 3]) -> ImuSample {
        ImuSample {
            stamp: t,
            gyro,
            accel: [0.0, 0.0, GRAVITY_M_S2],
        }
    }

    /// A track of readings at `hz` from 0 to `until` s of a constant rate.
    fn steady(hz: f64, until: f64, gyro: [f64; 3], c: ImuCalibration) -> ImuTrack {
        let mut t = ImuTrack::new(8192, c);
        for k in 0..=((until * hz) as usize) {
            t.push(&sample(k as f64 / hz, gyro)).unwrap();
        }
        t
    }

    #[test]
    fn a_turning_imu_off_the_lidar_still_reads_gravity_at_its_origin() {
        // The LiDAR turns about its own z at 2 rad/s, level; the IMU sits 0.3 m along its x,
        // turned 90 degrees about z: it feels the centripetal pull besides gravity.
        let mount = Pose::from_parts(
            Translation3::new(0.3, 0.0, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, core::f64::consts::FRAC_PI_2),
        );
        let c = ImuCalibration {
            lidar_from_imu: mount,
            ..ImuCalibration::default()
        };
        let mut t = ImuTrack::new(512, c);
        let w = Vec3::new(0.0, 0.0, 2.0);
        let arm = mount.translation.vector;
        let force_in_lidar = Vec3::z() * GRAVITY_M_S2 + w.cross(&w.cross(&arm));
        let to_imu = mount.rotation.inverse();
        for k in 0..=200 {
            let s = ImuSample {
                stamp: k as f64 / 200.0,
                gyro: (to_imu * w).into(),
                accel: (to_imu * force_in_lidar).into(),
            };
            t.push(&s).unwrap();
        }
        let f = t.mean_force(f64::NEG_INFINITY, 1.0).unwrap();
        assert!(
            (f.mean - Vec3::z() * GRAVITY_M_S2).norm() < 1e-6,
            "{:?}",
            f.mean
        );
        assert!(f.spread < 1e-6, "{}", f.spread);
        assert_eq!((f.readings, f.seconds), (201, 1.0));
        // Those up to the time asked, turned into its frame.
        let half = t.mean_force(f64::NEG_INFINITY, 0.5).unwrap();
        assert_eq!((half.readings, half.seconds), (101, 0.5));
        assert!((half.mean - f.mean).norm() < 1e-6);
        let late = t.mean_force(0.5, 1.0).unwrap();
        assert_eq!((late.readings, late.seconds), (100, 0.495));
        assert!((late.mean - f.mean).norm() < 1e-6);
        // A gap breaks them; no readings say nothing.
        t.push(&ImuSample {
            stamp: 2.0,
            ..sample(2.0, [0.0; 3])
        })
        .unwrap();
        assert!(matches!(
            t.mean_force(f64::NEG_INFINITY, 2.0),
            Err(ImuGap::Between { .. })
        ));
        let empty = ImuTrack::new(8, ImuCalibration::default());
        assert_eq!(
            empty.mean_force(f64::NEG_INFINITY, 0.0),
            Err(ImuGap::NoReadings)
        );
    }

    #[test]
    fn a_steady_rate_integrates_to_its_rotation() {
        let w = [0.1, -0.2, 0.5];
        let t = steady(200.0, 1.0, w, ImuCalibration::default());
        let q = t.rotation(0.13, 0.57).unwrap();
        let want = UnitQuaternion::from_scaled_axis(Vec3::from(w) * 0.44);
        assert!(q.angle_to(&want) < 1e-12);
        let back = t.rotation(0.57, 0.13).unwrap();
        assert!(back.angle_to(&want.inverse()) < 1e-12);
        assert_eq!(t.rotation(0.3, 0.3).unwrap(), UnitQuaternion::identity());
    }

    #[test]
    fn a_turned_imu_gives_the_rotation_in_the_lidar_axes() {
        // The IMU turned 90 degrees about z and 0.3 m off: its x is the LiDAR's y.
        let c = ImuCalibration {
            lidar_from_imu: Pose::from_parts(
                Translation3::new(0.3, 0.0, 0.0),
                UnitQuaternion::from_scaled_axis(Vec3::z() * core::f64::consts::FRAC_PI_2),
            ),
            ..ImuCalibration::default()
        };
        let t = steady(100.0, 1.0, [0.4, 0.0, 0.0], c);
        let q = t.rotation(0.0, 0.5).unwrap();
        let want = UnitQuaternion::from_scaled_axis(Vec3::y() * 0.2);
        assert!(q.angle_to(&want) < 1e-9, "{q:?}");
    }

    #[test]
    fn readings_in_g_are_taken_in_metres_per_second_squared() {
        let in_g = ImuCalibration {
            accel_unit_m_s2: GRAVITY_M_S2,
            ..ImuCalibration::default()
        };
        let mut configured = ImuTrack::new(64, in_g);
        let mut told_later = ImuTrack::new(64, ImuCalibration::default());
        for k in 0..20 {
            let s = ImuSample {
                stamp: f64::from(k) * 0.01,
                gyro: [0.0; 3],
                accel: [0.0, 0.0, 1.0],
            };
            configured.push(&s).unwrap();
            told_later.push(&s).unwrap();
        }
        told_later.set_accel_unit(GRAVITY_M_S2);
        for t in [&configured, &told_later] {
            let f = t.mean_force(f64::NEG_INFINITY, 0.19).unwrap();
            assert!((f.mean - Vec3::z() * GRAVITY_M_S2).norm() < 1e-12, "{f:?}");
        }
        // 16 g is the default limit: 17 in g is saturated, 17 in m/s² is not.
        let high = ImuSample {
            stamp: 0.2,
            gyro: [0.0; 3],
            accel: [17.0, 0.0, 0.0],
        };
        configured.push(&high).unwrap();
        let mut plain = ImuTrack::new(64, ImuCalibration::default());
        plain.push(&high).unwrap();
        assert_eq!(
            (configured.counts().saturated, plain.counts().saturated),
            (1, 0)
        );
    }

    #[test]
    fn a_restored_track_holds_what_the_first_held() {
        let mut a = steady(100.0, 0.5, [0.1, 0.0, 0.2], ImuCalibration::default());
        a.set_accel_unit(GRAVITY_M_S2);
        let mut b = ImuTrack::new(64, ImuCalibration::default());
        let bias = Vec3::new(0.01, 0.0, -0.02);
        let held = a.held().to_vec();
        b.restore(&held, bias, a.period_s(), a.counts(), GRAVITY_M_S2)
            .unwrap();
        assert_eq!(b.held(), a.held());
        assert_eq!(
            (b.bias(), b.period_s(), b.counts()),
            (bias, a.period_s(), a.counts())
        );
        assert_eq!(b.calibration().accel_unit_m_s2, GRAVITY_M_S2);
        // Too many for its capacity, or out of order: refused, nothing held.
        let mut small = ImuTrack::new(8, ImuCalibration::default());
        assert!(small.restore(&held, bias, 0.01, a.counts(), 1.0).is_err());
        let mut turned = held[..4].to_vec();
        turned.reverse();
        assert!(b.restore(&turned, bias, 0.01, a.counts(), 1.0).is_err());
        assert!(b.held().is_empty());
    }

    #[test]
    fn a_gyro_in_degrees_a_second_is_taken_in_radians() {
        let degrees = ImuCalibration {
            gyro_unit_rad_s: core::f64::consts::PI / 180.0,
            ..ImuCalibration::default()
        };
        // 0.4 rad/s about x given as degrees a second, for a second.
        let t = steady(100.0, 1.0, [0.4f64.to_degrees(), 0.0, 0.0], degrees);
        let q = t.rotation(0.0, 0.5).unwrap();
        let want = UnitQuaternion::from_scaled_axis(Vec3::x() * 0.2);
        assert!(q.angle_to(&want) < 1e-9, "{q:?}");
    }

    #[test]
    fn the_time_offset_moves_the_readings_onto_the_lidar_clock() {
        let c = ImuCalibration {
            time_offset_s: 10.0,
            ..ImuCalibration::default()
        };
        let t = steady(100.0, 1.0, [0.0, 0.0, 1.0], c);
        assert_eq!(t.last_t(), Some(11.0));
        assert!(t.rotation(10.0, 10.5).is_ok());
        assert!(matches!(t.rotation(0.0, 0.5), Err(ImuGap::Between { .. })));
    }

    #[test]
    fn the_sampling_period_follows_regular_steps_and_not_a_gap() {
        let mut t = ImuTrack::new(512, ImuCalibration::default());
        assert_eq!(t.period_s(), 0.0, "none before two readings");
        // 200 Hz, a jitter of 0.5 ms every other step.
        let mut at = 0.0;
        for k in 0..100 {
            at += if k % 2 == 0 { 0.0045 } else { 0.0055 };
            t.push(&sample(at, [0.0; 3])).unwrap();
        }
        assert!((t.period_s() - 0.005).abs() < 2e-4, "{}", t.period_s());
        // A second without readings is a gap, not a period.
        t.push(&sample(at + 1.0, [0.0; 3])).unwrap();
        assert!((t.period_s() - 0.005).abs() < 2e-4, "{}", t.period_s());
        // A reading as the track keeps it, given back whole.
        let r = Reading::new(1.5, Vec3::new(0.1, 0.2, 0.3), Vec3::new(0.0, 0.0, 9.8));
        assert_eq!(
            r.parts(),
            (1.5, Vec3::new(0.1, 0.2, 0.3), Vec3::new(0.0, 0.0, 9.8))
        );
    }

    #[test]
    fn a_rising_rate_is_integrated_between_readings() {
        // About z at 2t rad/s, read at 100 Hz: over [0.25, 0.75] s the turn is t² between
        // them, 0.5 rad, whatever the readings' places (the rate is linear between them).
        let mut t = ImuTrack::new(512, ImuCalibration::default());
        for k in 0..=100 {
            let at = k as f64 / 100.0;
            t.push(&sample(at, [0.0, 0.0, 2.0 * at])).unwrap();
        }
        for (a, b) in [(0.25, 0.75), (0.253, 0.747), (0.0, 1.0)] {
            let turn = t.rotation(a, b).unwrap().scaled_axis().z;
            assert!((turn - (b * b - a * a)).abs() < 1e-9, "{a} to {b}: {turn}");
        }
        assert!(t.rotation(f64::NAN, 0.5).is_err());
        assert!(t.rotation(0.5, f64::INFINITY).is_err());
    }

    #[test]
    fn a_track_restored_takes_its_readings_whole_and_in_order_only() {
        let src = steady(100.0, 0.07, [0.0, 0.0, 0.5], ImuCalibration::default());
        let held = src.held().to_vec();
        assert_eq!(held.len(), 8);
        let c = src.counts();
        let mut exact = ImuTrack::new(8, ImuCalibration::default());
        assert!(
            exact.restore(&held, Vec3::zeros(), 0.01, c, 1.0).is_ok(),
            "as many as it holds"
        );
        assert_eq!(exact.held().len(), 8);
        let mut small = ImuTrack::new(7, ImuCalibration::default());
        assert!(small.restore(&held, Vec3::zeros(), 0.01, c, 1.0).is_err());
        let mut twice = held.clone();
        twice[4] = twice[3];
        let mut t = ImuTrack::new(8, ImuCalibration::default());
        assert!(
            t.restore(&twice, Vec3::zeros(), 0.01, c, 1.0).is_err(),
            "a stamp twice"
        );
    }

    #[test]
    fn readings_held_take_a_new_accelerometer_unit_and_a_bad_one_is_ignored() {
        let mut t = steady(100.0, 0.05, [0.0; 3], ImuCalibration::default());
        let g = t.held()[0].parts().2.z;
        t.set_accel_unit(GRAVITY_M_S2);
        assert!((t.held()[0].parts().2.z - g * GRAVITY_M_S2).abs() < 1e-9);
        // And back: the readings held as they came.
        t.set_accel_unit(1.0);
        assert!((t.held()[0].parts().2.z - g).abs() < 1e-9);
        t.set_accel_unit(GRAVITY_M_S2);
        for bad in [0.0, -1.0, f64::NAN] {
            t.set_accel_unit(bad);
            assert_eq!(t.calibration().accel_unit_m_s2, GRAVITY_M_S2, "{bad}");
        }
        // Three readings are enough for a mean of the force; two are not.
        let three = steady(100.0, 0.02, [0.0; 3], ImuCalibration::default());
        let m = three.mean_force(-1.0, 0.02).unwrap();
        assert_eq!(m.readings, 3);
        assert!(three.mean_force(0.0, 0.02).is_err(), "two after 0.0");
    }

    #[test]
    fn a_tumbling_imu_off_the_lidar_reads_gravity_in_the_frame_asked_for() {
        // The LiDAR turns about its x at 1 + 2t rad/s (turned t + t² by t); the IMU sits 0.2 m
        // along its y, axes as the LiDAR's: it feels gravity turning, the tangential push
        // α × r and the centripetal pull ω × (ω × r).
        let arm = Vec3::new(0.0, 0.2, 0.0);
        let c = ImuCalibration {
            lidar_from_imu: Pose::from_parts(Translation3::from(arm), UnitQuaternion::identity()),
            ..ImuCalibration::default()
        };
        let up = Vec3::new(0.0, 0.0, GRAVITY_M_S2);
        let seen_at = |t: f64| UnitQuaternion::from_scaled_axis(Vec3::x() * (t + t * t));
        // Without a gyro bias, and with one the track has learned (the readings carry it).
        for bias in [Vec3::zeros(), Vec3::new(0.05, -0.02, 0.03)] {
            let mut track = ImuTrack::new(512, c);
            let learned = UnitQuaternion::from_scaled_axis(bias);
            track.correct_bias(&learned, 1.0, &UnitQuaternion::identity(), 1.0, 1.0);
            for k in 0..=100 {
                let t = k as f64 / 200.0;
                let w = Vec3::new(1.0 + 2.0 * t, 0.0, 0.0);
                let alpha = Vec3::new(2.0, 0.0, 0.0);
                let f = seen_at(t).inverse() * up + alpha.cross(&arm) + w.cross(&w.cross(&arm));
                let g = w + bias;
                let s = ImuSample {
                    stamp: t,
                    gyro: [g.x, g.y, g.z],
                    accel: [f.x, f.y, f.z],
                };
                track.push(&s).unwrap();
            }
            for t_ref in [0.1, 0.25, 0.5] {
                let m = track.mean_force(-1.0, t_ref).unwrap();
                let expected = seen_at(t_ref).inverse() * up;
                let off = (m.mean - expected).norm();
                assert!(off < 1e-3, "bias {bias}, at {t_ref}: {}", m.mean);
                assert!(
                    m.spread < 1e-3,
                    "bias {bias}, at {t_ref}: spread {}",
                    m.spread
                );
            }
        }
        // Readings that swing 1 m/s² either side of gravity: their spread is 1.
        let mut swing = ImuTrack::new(64, ImuCalibration::default());
        for k in 0..20 {
            let z = GRAVITY_M_S2 + if k % 2 == 0 { 1.0 } else { -1.0 };
            let s = ImuSample {
                stamp: k as f64 * 0.01,
                gyro: [0.0; 3],
                accel: [0.0, 0.0, z],
            };
            swing.push(&s).unwrap();
        }
        let m = swing.mean_force(-1.0, 0.19).unwrap();
        assert!((m.mean.z - GRAVITY_M_S2).abs() < 1e-9 && (m.spread - 1.0).abs() < 1e-9);
    }

    #[test]
    fn one_bias_correction_takes_its_gain_of_the_disagreement_over_its_time() {
        let mut t = ImuTrack::new(8, ImuCalibration::default());
        let gyro = UnitQuaternion::from_scaled_axis(Vec3::new(0.0, 0.0, 0.02));
        let registered = UnitQuaternion::identity();
        let off = t.correct_bias(&gyro, 0.1, &registered, 0.5, 1.0);
        assert!((off - 0.02).abs() < 1e-12);
        assert!(
            (t.bias() - Vec3::new(0.0, 0.0, 0.1)).norm() < 1e-12,
            "{}",
            t.bias()
        );
        // No time between them: nothing learned.
        t.correct_bias(&gyro, 0.0, &registered, 0.5, 1.0);
        assert!(
            (t.bias() - Vec3::new(0.0, 0.0, 0.1)).norm() < 1e-12,
            "{}",
            t.bias()
        );
    }

    #[test]
    fn gaps_and_uncovered_time_are_named() {
        let mut t = ImuTrack::new(64, ImuCalibration::default());
        assert_eq!(t.rotation(0.0, 1.0), Err(ImuGap::NoReadings));
        for k in 0..10 {
            t.push(&sample(k as f64 * 0.01, [0.0; 3])).unwrap();
        }
        for k in 20..30 {
            t.push(&sample(k as f64 * 0.01, [0.0; 3])).unwrap();
        }
        // 0.09 to 0.20 is eleven periods.
        assert_eq!(
            t.rotation(0.0, 0.25),
            Err(ImuGap::Between {
                from: 0.09,
                to: 0.2
            })
        );
        assert!(
            t.rotation(0.2, 0.3).is_ok(),
            "held two periods past the end"
        );
        assert!(t.rotation(0.2, 0.35).is_err());
        assert!(t.rotation(0.0, 0.08).is_ok());
    }

    #[test]
    fn bad_readings_are_refused_and_counted() {
        let mut t = ImuTrack::new(8, ImuCalibration::default());
        t.push(&sample(1.0, [0.0; 3])).unwrap();
        assert_eq!(
            t.push(&sample(1.0, [0.0; 3])),
            Err(ImuFault::Duplicate { t: 1.0 })
        );
        assert_eq!(
            t.push(&sample(0.5, [0.0; 3])),
            Err(ImuFault::OutOfOrder { t: 0.5, last: 1.0 })
        );
        assert_eq!(
            t.push(&sample(f64::NAN, [0.0; 3])),
            Err(ImuFault::NotFinite)
        );
        assert_eq!(
            t.push(&sample(2.0, [f64::INFINITY, 0.0, 0.0])),
            Err(ImuFault::NotFinite)
        );
        t.push(&sample(1.1, [50.0, 0.0, 0.0])).unwrap();
        let c = t.counts();
        assert_eq!(
            (
                c.taken,
                c.duplicate,
                c.out_of_order,
                c.not_finite,
                c.saturated
            ),
            (2, 1, 1, 2, 1)
        );
    }

    #[test]
    fn a_full_buffer_forgets_its_oldest_half_and_never_grows() {
        let mut t = ImuTrack::new(10, ImuCalibration::default());
        for k in 0..25 {
            t.push(&sample(k as f64 * 0.01, [0.0; 3])).unwrap();
        }
        assert!(t.readings.len() <= 10);
        assert_eq!(t.readings.capacity(), 10);
        assert_eq!(t.last_t(), Some(0.24));
        assert_eq!(t.counts().forgotten_early + t.readings.len(), 25);
        t.forget_before(0.235);
        assert_eq!(t.readings.len(), 2);
        assert!(t.rotation(0.235, 0.24).is_ok());
    }

    #[test]
    fn the_bias_is_learned_from_registered_rotations() {
        // The gyro reads 0.01 rad/s about z more than the truth, which does not turn.
        let mut t = steady(200.0, 30.0, [0.0, 0.0, 0.01], ImuCalibration::default());
        for k in 0..200 {
            let a = k as f64 * 0.1;
            let gyro = t.rotation(a, a + 0.1).unwrap();
            t.correct_bias(&gyro, 0.1, &UnitQuaternion::identity(), 0.1, 0.05);
        }
        assert!(
            (t.bias() - Vec3::new(0.0, 0.0, 0.01)).norm() < 1e-6,
            "{}",
            t.bias()
        );
        let q = t.rotation(20.0, 29.0).unwrap();
        assert!(q.angle() < 1e-5);
        // A registration far off is not taken.
        let wrong = UnitQuaternion::from_scaled_axis(Vec3::x() * 0.2);
        let before = t.bias();
        let gyro = t.rotation(1.0, 1.1).unwrap();
        assert!(t.correct_bias(&gyro, 0.1, &wrong, 0.1, 0.05) > 0.19);
        assert_eq!(t.bias(), before);
    }
}
