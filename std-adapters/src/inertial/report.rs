//! What the IMU did, as a run reports it: each frame's dealings (`report.json`'s frames'
//! `imu`), the run's summary (`summary.imu`) and which way was up, with the words that say
//! why a frame or the map went without it.

use crate::inertial::moving_up::MovingUp;
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use slamesh_core::gravity::{Gravity, NotLevel};
use slamesh_core::imu::ImuGap;

/// A frame's dealings with the IMU, for its record (`report.json`'s `imu`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ImuFrame {
    /// Deskewed with the gyro's rotations.
    pub deskewed: bool,
    /// Registered from the gyro's prior.
    pub prior: bool,
    /// Why the readings could not serve the frame, when they could not (it ran on the motion
    /// model): `ImuGap`, with the uncovered time.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gap: Option<String>,
}

impl ImuFrame {
    /// Notes that the readings did not cover the frame.
    pub fn missed(&mut self, gap: ImuGap) {
        self.gap = Some(format!("ImuGap: {}", gap_words(gap)));
    }
}

/// Why the readings do not cover a time, in words.
pub(super) fn gap_words(gap: ImuGap) -> String {
    match gap {
        ImuGap::NoReadings => "no IMU reading yet".into(),
        ImuGap::Between { from, to } => format!("no IMU reading from {from:.4} s to {to:.4} s"),
    }
}

/// What the IMU did over a run (`report.json`'s `summary.imu`; absent without readings).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ImuSummary {
    /// Readings taken and refused.
    pub readings: ImuCountsReport,
    /// Frames deskewed with the gyro.
    pub deskewed_frames: usize,
    /// Frames registered from the gyro's prior.
    pub prior_frames: usize,
    /// Frames the readings did not cover (run on the motion model).
    pub gap_frames: usize,
    /// The gyro bias the registrations taught it at the end (rad/s, the LiDAR's axes).
    pub gyro_bias: [f64; 3],
    /// Why the IMU was set aside during the run (its rotations kept missing the registered
    /// ones), if it was.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub set_aside: Option<String>,
    /// Times the IMU came back after it was set aside (its rotations matched again).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub returned: usize,
    /// Runs of frames whose rotation the gyro missed that were put down to the registrations
    /// (the misses' scale and axes agree with the gyro's: [`crate::inertial::trust`]).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub registrations_doubted: usize,
    /// Why the readings were ignored for the whole run (too slow or too still to be an IMU's),
    /// if they were.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ignored: Option<String>,
    /// Which way was up at the map's first scan, and whether the map was levelled by it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gravity: Option<GravityReport>,
    /// Whether `[imu]` agreed with the registration over the first seconds
    /// ([`crate::inertial::calibration`]), when judged.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub calibration_check: Option<String>,
    /// The accelerometer's unit, and whether it was configured or told from the readings;
    /// absent while the readings have not told it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub accelerometer_unit: Option<String>,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

/// What the accelerometer said of up at the map's first scan (`summary.imu.gravity`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GravityReport {
    /// The first scan was placed level (the map's z axis is up).
    pub levelled: bool,
    /// Up in the first scan's frame (a unit vector), when the readings said.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub up: Option<[f64; 3]>,
    /// The first scan's z axis from up (degrees), when the readings said.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tilt_deg: Option<f64>,
    /// Readings averaged, the time they spanned (s), their mean's length and their spread
    /// about it (m/s²); zero where none covered the scan.
    pub readings: usize,
    /// See [`readings`](Self::readings).
    pub seconds: f64,
    /// See [`readings`](Self::readings).
    pub magnitude_m_s2: f64,
    /// See [`readings`](Self::readings).
    pub spread_m_s2: f64,
    /// Why the map was not levelled, when it was not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub why_not: Option<String>,
    /// Up from the first seconds of motion, when the map was not levelled
    /// ([`crate::inertial::moving_up`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub moving: Option<MovingUp>,
}

impl GravityReport {
    /// The report of a judgement: up, or the force the readings gave (if they covered the
    /// scan) and why it was not up.
    pub(super) fn of(
        judged: Result<Gravity, (Option<slamesh_core::imu::ForceMean>, String)>,
    ) -> Self {
        match judged {
            Ok(g) => GravityReport {
                levelled: true,
                up: Some(g.up.into()),
                tilt_deg: Some(g.tilt().to_degrees()),
                readings: g.force.readings,
                seconds: g.force.seconds,
                magnitude_m_s2: g.force.mean.norm(),
                spread_m_s2: g.force.spread,
                why_not: None,
                moving: None,
            },
            Err((force, why)) => GravityReport {
                levelled: false,
                up: None,
                tilt_deg: None,
                readings: force.map_or(0, |f| f.readings),
                seconds: force.map_or(0.0, |f| f.seconds),
                magnitude_m_s2: force.map_or(0.0, |f| f.mean.norm()),
                spread_m_s2: force.map_or(0.0, |f| f.spread),
                why_not: Some(why),
                moving: None,
            },
        }
    }

    /// Up for a navigation map (map frame) and what to say of it (`map.yaml`,
    /// `navmap.json`): the map's z when the IMU levelled it, else up from the first seconds of
    /// motion when they gave it.
    pub fn navmap_up(&self) -> Option<(Vector3<f64>, String)> {
        if self.levelled {
            return Some((
                Vector3::z(),
                format!(
                    "gravity: the IMU's accelerometer over {:.1} s levelled the map at its \
                     first scan (tilted {:.1} degrees)",
                    self.seconds,
                    self.tilt_deg.unwrap_or(0.0)
                ),
            ));
        }
        let m = self.moving.as_ref()?;
        let up = Vector3::from(m.up?);
        Some((
            up,
            format!(
                "gravity: the IMU's accelerometer over the first {:.1} s of motion (the map's \
                 z axis {:.1} degrees from it)",
                m.seconds,
                m.z_off_deg.unwrap_or(0.0)
            ),
        ))
    }
}

/// Why readings did not say which way is up, in words.
pub(super) fn not_level(why: NotLevel) -> String {
    match why {
        NotLevel::TooShort { seconds } => format!(
            "the readings span {seconds:.2} s, less than {} s",
            slamesh_core::gravity::MIN_SECONDS
        ),
        NotLevel::Unsteady { spread } => format!(
            "the body was not steady: the specific force spread {spread:.2} m/s² about its \
             mean (at most {})",
            slamesh_core::gravity::MAX_SPREAD_M_S2
        ),
        NotLevel::NotGravity { magnitude } => format!(
            "the mean specific force is {magnitude:.2} m/s², not gravity's 9.81 (a steady \
             acceleration, or readings not in m/s²)"
        ),
    }
}

/// [`ImuCounts`](slamesh_core::imu::ImuCounts) as the report writes them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct ImuCountsReport {
    /// Taken.
    pub taken: usize,
    /// Refused: a number not finite.
    pub not_finite: usize,
    /// Refused: out of order.
    pub out_of_order: usize,
    /// Refused: a duplicate stamp.
    pub duplicate: usize,
    /// Taken at a sensor limit.
    pub saturated: usize,
    /// Forgotten early (the track's buffer was full: a frame too long for the capacity).
    pub forgotten_early: usize,
}
