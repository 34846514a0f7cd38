//! Which way is up, from the accelerometer (docs/design.md §1.19): a body that is still, or
//! moves without accelerating, feels gravity alone, so the mean of its specific force points
//! up. The map's first scan is placed turned by [`Gravity::level`], and the map's z axis is
//! up from then on: the navigation maps need it.
//!
//! It owns the judgement of a [`ForceMean`] (from [`ImuTrack::mean_force`](crate::imu::ImuTrack::mean_force)):
//! it guarantees that up is given only from readings that span [`MIN_SECONDS`], whose spread
//! about their mean is at most [`MAX_SPREAD_M_S2`] (the body was steady) and whose mean is
//! within [`MAX_OFF_G_M_S2`] of standard gravity (no steady acceleration, no wrong units);
//! otherwise it names which of the three failed ([`NotLevel`]). A steady acceleration along
//! the ground that the readings cannot tell from a tilt (about 0.1 rad a metre per second
//! squared) is the one error it cannot see.
//!
//! A body that moves from the start is read over its first seconds instead
//! ([`up_from_motion`]): the specific force in the map's frame (the registered attitudes turn
//! it there) less the acceleration the registered positions show is gravity's reaction, up;
//! the map keeps its frame, and up is handed to what needs it.

use crate::imu::{ForceMean, GRAVITY_M_S2};
use crate::math::{level_rotation, Vec3};
use nalgebra::UnitQuaternion;

/// The least time the readings must span (seconds).
pub const MIN_SECONDS: f64 = 0.2;
/// The most the readings may spread about their mean (m/s², root mean square): a still
/// MEMS sensor spreads a few hundredths; a hand carrying it a few tenths.
pub const MAX_SPREAD_M_S2: f64 = 0.5;
/// How far the mean's length may be from standard gravity (m/s²).
pub const MAX_OFF_G_M_S2: f64 = 0.6;

/// The least time (seconds) a mean of the specific force must span for [`reads_in_g`].
pub const UNIT_SECONDS: f64 = 0.05;
/// The mean specific force's lengths (in the readings' unit) that say the readings are in g:
/// in m/s² they would be a body falling at 8 to 9.3 m/s² all the while, in g they are
/// gravity with a body's own acceleration on it.
pub const G_UNITS: [f64; 2] = [0.5, 2.0];

/// Whether `force` (the readings' mean, in their own unit) says the accelerometer reads in g
/// rather than m/s² ([`G_UNITS`], over at least [`UNIT_SECONDS`]); `None` when it spans too
/// little to say.
pub fn reads_in_g(force: &ForceMean) -> Option<bool> {
    (force.seconds >= UNIT_SECONDS).then(|| {
        let m = force.mean.norm();
        (G_UNITS[0]..=G_UNITS[1]).contains(&m)
    })
}

/// Up, read from the accelerometer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gravity {
    /// Up as a unit vector in the LiDAR's frame at the reference time.
    pub up: Vec3,
    /// What the readings said (their mean's length is gravity's, m/s²).
    pub force: ForceMean,
}

/// Why the readings did not say which way is up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NotLevel {
    /// They span less than [`MIN_SECONDS`].
    TooShort {
        /// The time they span (seconds).
        seconds: f64,
    },
    /// The body moved too much ([`MAX_SPREAD_M_S2`]).
    Unsteady {
        /// Their spread (m/s²).
        spread: f64,
    },
    /// Their mean is not gravity's size ([`MAX_OFF_G_M_S2`]): a steady acceleration, or
    /// readings not in m/s².
    NotGravity {
        /// The mean's length (m/s²).
        magnitude: f64,
    },
}

impl Gravity {
    /// Up from `force`, when it can tell.
    pub fn judge(force: &ForceMean) -> Result<Gravity, NotLevel> {
        let magnitude = force.mean.norm();
        if !(force.seconds >= MIN_SECONDS) {
            Err(NotLevel::TooShort {
                seconds: force.seconds,
            })
        } else if !(force.spread <= MAX_SPREAD_M_S2) {
            Err(NotLevel::Unsteady {
                spread: force.spread,
            })
        } else if !(libm::fabs(magnitude - GRAVITY_M_S2) <= MAX_OFF_G_M_S2) {
            Err(NotLevel::NotGravity { magnitude })
        } else {
            Ok(Gravity {
                up: force.mean / magnitude,
                force: *force,
            })
        }
    }

    /// The smallest rotation that turns up onto the z axis: the attitude of a level frame
    /// whose heading is the LiDAR's (an upside-down LiDAR is turned about its x axis).
    pub fn level(&self) -> UnitQuaternion<f64> {
        level_rotation(&self.up)
    }

    /// The angle between the LiDAR's z axis and up (radians).
    pub fn tilt(&self) -> f64 {
        libm::acos(self.up.z.clamp(-1.0, 1.0))
    }
}

/// Up in the map's frame from a moving body's first seconds: `mean_force`, the specific force
/// averaged over them in the map's frame (m/s²), less the mean acceleration the registered
/// motion shows, `velocity_change / seconds` (m/s over s). Refused when the time is shorter
/// than [`MIN_SECONDS`] or the difference is not gravity's size ([`MAX_OFF_G_M_S2`]).
pub fn up_from_motion(
    mean_force: &Vec3,
    velocity_change: &Vec3,
    seconds: f64,
) -> Result<Vec3, NotLevel> {
    if !(seconds >= MIN_SECONDS) {
        return Err(NotLevel::TooShort { seconds });
    }
    let reaction = mean_force - velocity_change / seconds;
    let magnitude = reaction.norm();
    if !(libm::fabs(magnitude - GRAVITY_M_S2) <= MAX_OFF_G_M_S2) {
        return Err(NotLevel::NotGravity { magnitude });
    }
    Ok(reaction / magnitude)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn force(mean: Vec3, spread: f64, seconds: f64) -> ForceMean {
        ForceMean {
            mean,
            spread,
            readings: 200,
            seconds,
        }
    }

    #[test]
    fn a_still_tilted_sensor_is_levelled_without_turning_its_heading() {
        let tilt = UnitQuaternion::from_euler_angles(0.1, -0.05, 0.7);
        // The sensor's attitude is `tilt`: it feels gravity's reaction, up, in its own axes.
        let up_in_sensor = tilt.inverse() * Vec3::z() * GRAVITY_M_S2;
        let g = Gravity::judge(&force(up_in_sensor, 0.02, 1.0)).unwrap();
        let level = g.level();
        assert!((level * g.up - Vec3::z()).norm() < 1e-12);
        // Level, and the heading kept: the levelled x axis points, seen from above, along the
        // map's x, as an unlevelled first scan's does (to within the tilts' product).
        let x = level * Vec3::x();
        assert!(libm::atan2(x.y, x.x).abs() < 0.01, "{x}");
        assert!((g.tilt() - (tilt * Vec3::z()).z.acos()).abs() < 1e-9);
    }

    #[test]
    fn gravity_read_in_g_is_told_from_gravity_in_metres_per_second_squared() {
        let up = Vec3::new(0.1, -0.2, 1.0).normalize();
        // Still, in g; a shaking body in g; in m/s², still and shaken; too short to say.
        assert_eq!(reads_in_g(&force(up, 0.01, 1.0)), Some(true));
        assert_eq!(reads_in_g(&force(up * 1.3, 0.4, 0.1)), Some(true));
        assert_eq!(reads_in_g(&force(up * GRAVITY_M_S2, 0.1, 1.0)), Some(false));
        assert_eq!(reads_in_g(&force(up * 12.0, 3.0, 0.1)), Some(false));
        assert_eq!(reads_in_g(&force(up, 0.01, 0.01)), None);
    }

    #[test]
    fn moving_short_or_wrong_readings_are_named() {
        let up = Vec3::z() * GRAVITY_M_S2;
        assert_eq!(
            Gravity::judge(&force(up, 0.02, 0.1)),
            Err(NotLevel::TooShort { seconds: 0.1 })
        );
        assert_eq!(
            Gravity::judge(&force(up, 1.5, 1.0)),
            Err(NotLevel::Unsteady { spread: 1.5 })
        );
        assert!(matches!(
            Gravity::judge(&force(up / GRAVITY_M_S2, 0.0, 1.0)),
            Err(NotLevel::NotGravity { .. })
        ));
        assert!(Gravity::judge(&force(Vec3::new(f64::NAN, 0.0, 0.0), 0.0, 1.0)).is_err());
        let down = Gravity::judge(&force(-up, 0.0, 1.0)).unwrap();
        assert!((down.level() * down.up - Vec3::z()).norm() < 1e-12);
    }

    #[test]
    fn a_moving_body_s_up_is_its_force_less_its_acceleration() {
        // Up tilted in the map; the body sped up by 2 m/s along x over 4 s.
        let up = Vec3::new(0.1, 0.0, 1.0).normalize();
        let accel = Vec3::new(0.5, 0.0, 0.0);
        let force = up * GRAVITY_M_S2 + accel;
        let found = up_from_motion(&force, &(accel * 4.0), 4.0).unwrap();
        assert!((found - up).norm() < 1e-12);
        assert!(matches!(
            up_from_motion(&force, &Vec3::zeros(), 0.1),
            Err(NotLevel::TooShort { .. })
        ));
        assert!(matches!(
            up_from_motion(&(force * 2.0), &Vec3::zeros(), 4.0),
            Err(NotLevel::NotGravity { .. })
        ));
    }
}
