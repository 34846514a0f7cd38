//! Firing times from a spinning LiDAR's sweep (docs/design.md §1.9): each point's time from
//! its azimuth, for scans that carry no times of their own (a KITTI `.bin`, a PCD or PLY
//! without a time field).
//!
//! A spinning LiDAR fires all its beams at one azimuth, then turns on at a constant rate: a
//! point's azimuth says when in the sweep it was taken. Given which way the head turns
//! ([`Turn`]), where the sweep starts ([`Spin::start_rad`]), its period and where the scan's
//! stamp sits in it, the time of a point at azimuth `a` after the stamp is
//! `(share(a) - stamp_share) · period`, where `share(a)` is the part of the turn from the
//! start to `a` (in `[0, 1)`). KISS-ICP derives KITTI's times the same way. [`crate::deskew`]
//! then moves the points as it does a driver's own times.
//!
//! A scan that does not cover [`MIN_SECTORS`] of [`SECTORS`] sectors of the turn (a
//! solid-state sensor's field of view, a sweep cut short) is not a sweep to time this way:
//! [`firing_times`] refuses it and the caller leaves it as it is. No allocation: the times go
//! into the caller's slice, the coverage is one `u64`.

use crate::math::Point;
use core::f32::consts::TAU;

/// Sectors of the turn a scan's coverage is counted in (5.6 degrees each).
pub const SECTORS: u32 = 64;

/// A scan is timed from its azimuths only when its points fall in at least this many sectors:
/// three quarters of a turn, so that a sensor whose rear the robot hides still counts and a
/// solid-state sensor (at most about 120 degrees) does not.
pub const MIN_SECTORS: u32 = 48;

/// Which way the head turns, seen from above (from +z down onto the x-y plane).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Turn {
    /// Azimuth (from +x toward +y) falling with time: Velodyne's and Hesai's heads.
    Clockwise,
    /// Azimuth rising with time.
    CounterClockwise,
}

/// How a spinning LiDAR's sweep runs: enough to time a point from its azimuth.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Spin {
    /// Which way the head turns.
    pub turn: Turn,
    /// The azimuth the sweep starts at (radians, from +x toward +y in the sensor frame).
    pub start_rad: f32,
    /// The sweep's period (s).
    pub period_s: f32,
    /// Where the scan's stamp sits in the sweep, as a share of the period: 0 at its start (most
    /// ROS drivers), 0.5 in its middle (KITTI, whose cameras fire as the head faces forward).
    pub stamp_share: f32,
}

/// Why [`firing_times`] did not time a scan.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum SpinError {
    /// The times and the points differ in number.
    LengthMismatch {
        /// Points.
        points: usize,
        /// Times.
        times: usize,
    },
    /// The period is not a positive finite number of seconds, or the start or the stamp's
    /// share is not finite.
    BadSpin,
    /// The points cover fewer than [`MIN_SECTORS`] sectors of the turn.
    NotATurn {
        /// The sectors they cover, of [`SECTORS`].
        sectors: u32,
    },
}

impl Spin {
    /// The share of the turn from the sweep's start to azimuth `a` (radians), in `[0, 1)`.
    fn share(&self, a: f32) -> f32 {
        let from_start = match self.turn {
            Turn::Clockwise => self.start_rad - a,
            Turn::CounterClockwise => a - self.start_rad,
        };
        let s = libm::fmodf(from_start, TAU) / TAU;
        let s = if s < 0.0 { s + 1.0 } else { s };
        // fmod of a value a hair below a multiple of TAU can round up to 1.
        if s >= 1.0 {
            0.0
        } else {
            s
        }
    }

    /// The time after the stamp (s) of a point fired at azimuth `a` (radians).
    pub fn time_at(&self, a: f32) -> f32 {
        (self.share(a) - self.stamp_share) * self.period_s
    }
}

/// Writes each point's time after the stamp into `times` (seconds; NaN for a point that is
/// not finite, which deskewing leaves where it is) and returns the sectors the points cover.
/// `times` is left as it was when the scan is refused.
pub fn firing_times(points: &[Point], spin: &Spin, times: &mut [f32]) -> Result<u32, SpinError> {
    if points.len() != times.len() {
        return Err(SpinError::LengthMismatch {
            points: points.len(),
            times: times.len(),
        });
    }
    let good = |v: f32| v.is_finite();
    let ok = spin.period_s > 0.0
        && [spin.period_s, spin.start_rad, spin.stamp_share].map(good) == [true; 3];
    if !ok {
        return Err(SpinError::BadSpin);
    }
    let sectors = covered_sectors(points);
    if sectors < MIN_SECTORS {
        return Err(SpinError::NotATurn { sectors });
    }
    for (t, p) in times.iter_mut().zip(points) {
        *t = if p.iter().all(|c| c.is_finite()) {
            spin.time_at(libm::atan2f(p[1], p[0]))
        } else {
            f32::NAN
        };
    }
    Ok(sectors)
}

/// The sectors of the turn the finite points off the vertical axis fall in.
pub fn covered_sectors(points: &[Point]) -> u32 {
    let mut seen = 0u64;
    for p in points {
        let r2 = p[0] * p[0] + p[1] * p[1];
        if !(r2 > 1e-12 && r2.is_finite()) {
            continue;
        }
        let share = libm::atan2f(p[1], p[0]) / TAU + 0.5;
        // `share` is in [0, 1]: the cast saturates, the min keeps 1.0 in the last sector.
        let sector = ((share * SECTORS as f32) as u32).min(SECTORS - 1);
        seen |= 1 << sector;
    }
    seen.count_ones()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ring(n: usize) -> [Point; 360] {
        let mut out = [[0.0f32; 3]; 360];
        for (k, p) in out.iter_mut().enumerate().take(n) {
            let a = (k as f32).to_radians();
            *p = [10.0 * libm::cosf(a), 10.0 * libm::sinf(a), -1.0];
        }
        out
    }

    const KITTI: Spin = Spin {
        turn: Turn::Clockwise,
        start_rad: core::f32::consts::PI,
        period_s: 0.1,
        stamp_share: 0.5,
    };

    #[test]
    fn a_clockwise_sweep_from_the_back_is_timed_about_its_middle() {
        let points = ring(360);
        let mut times = [0.0f32; 360];
        assert_eq!(firing_times(&points, &KITTI, &mut times), Ok(SECTORS));
        // Straight ahead is the middle of a sweep that starts behind: the stamp.
        assert!(times[0].abs() < 1e-6, "{}", times[0]);
        // Clockwise: to the right (-90 degrees) comes a quarter turn after the front, to the
        // left a quarter before.
        assert!((times[270] - 0.025).abs() < 1e-6, "{}", times[270]);
        assert!((times[90] + 0.025).abs() < 1e-6, "{}", times[90]);
        // Just left of the back is the sweep's start, just right of it its end.
        assert!((times[179] + 0.05).abs() < 0.001, "{}", times[179]);
        assert!((times[181] - 0.05).abs() < 0.001, "{}", times[181]);
    }

    #[test]
    fn a_counter_clockwise_sweep_stamped_at_its_start_runs_over_the_period() {
        let spin = Spin {
            turn: Turn::CounterClockwise,
            start_rad: 0.0,
            period_s: 0.1,
            stamp_share: 0.0,
        };
        let points = ring(360);
        let mut times = [0.0f32; 360];
        firing_times(&points, &spin, &mut times).unwrap();
        for (k, t) in times.iter().enumerate() {
            let expected = 0.1 * k as f32 / 360.0;
            assert!((t - expected).abs() < 1e-5, "{k}: {t} against {expected}");
        }
    }

    #[test]
    fn a_partial_view_is_refused_and_left_as_it_was() {
        // A solid-state sensor's 120 degrees.
        let points = ring(120);
        let mut times = [7.0f32; 120];
        assert_eq!(
            firing_times(&points[..120], &KITTI, &mut times),
            Err(SpinError::NotATurn { sectors: 22 })
        );
        assert!(times.iter().all(|t| *t == 7.0));
        // Three quarters of a turn still counts.
        let points = ring(275);
        let mut times = [0.0f32; 275];
        assert!(firing_times(&points[..275], &KITTI, &mut times).is_ok());
    }

    #[test]
    fn bad_input_is_refused_or_marked_not_a_panic() {
        let mut points = ring(360);
        points[5] = [f32::NAN, 0.0, 0.0];
        points[6] = [f32::INFINITY, 1.0, 0.0];
        let mut times = [0.0f32; 360];
        firing_times(&points, &KITTI, &mut times).unwrap();
        assert!(times[5].is_nan() && times[6].is_nan());
        let mut short = [0.0f32; 3];
        assert_eq!(
            firing_times(&points, &KITTI, &mut short),
            Err(SpinError::LengthMismatch {
                points: 360,
                times: 3
            })
        );
        for period_s in [0.0, -0.1, f32::NAN, f32::INFINITY] {
            let spin = Spin { period_s, ..KITTI };
            assert_eq!(
                firing_times(&points, &spin, &mut times),
                Err(SpinError::BadSpin)
            );
        }
        assert_eq!(covered_sectors(&[]), 0);
    }
}
