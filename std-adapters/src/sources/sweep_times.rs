//! Points' times from the sweep (`--sweep`) for scans that carry none: a folder of KITTI
//! `.bin` files, PCD or PLY files without a time field. Each point's time comes from its
//! azimuth ([`slamesh_core::spin`]), so that the run deskews such scans as it deskews a
//! driver's timed points, with the motion model or the IMU.
//!
//! The sweep is named by a preset ([`SweepSpec::parse`]: which way the head turns, where its
//! sweep starts and where the stamp sits in it) or given in full; its period is the scans'
//! own (the median interval of their stamps). A scan that covers less than three quarters of a
//! turn (a solid-state sensor, a cut sweep) keeps no times and is counted, and the first such
//! scan is named in the log.

use serde::Serialize;
use slamesh_core::spin::{firing_times, Spin, SpinError, Turn};
use slamesh_core::Point;
use std::f32::consts::PI;
use std::fmt;

/// The named sweeps: (name, turn, start in degrees from +x toward +y, stamp's share of the
/// sweep, what it describes).
const PRESETS: [(&str, Turn, f32, f32, &str); 4] = [
    (
        "kitti",
        Turn::Clockwise,
        180.0,
        0.5,
        "KITTI's HDL-64E: clockwise from behind, stamped facing forward (mid-sweep)",
    ),
    (
        "velodyne",
        Turn::Clockwise,
        0.0,
        0.0,
        "a Velodyne cut at the front (as slamesh's packet reader cuts), stamped at the cut",
    ),
    (
        "ouster",
        Turn::Clockwise,
        180.0,
        0.0,
        "an Ouster's frame from column 0 (facing the sensor frame's -x), stamped at its start",
    ),
    (
        "hesai",
        Turn::Clockwise,
        0.0,
        0.0,
        "a Hesai Pandar or XT cut at the front, stamped at the cut",
    ),
];

/// A `--sweep` that could not be read.
#[derive(Debug, Clone, PartialEq)]
pub struct BadSweep {
    /// What was given.
    pub given: String,
}

impl fmt::Display for BadSweep {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let names: Vec<&str> = PRESETS.iter().map(|p| p.0).collect();
        write!(
            f,
            "--sweep {}: expected off, {}, or TURN:START_DEG:STAMP_SHARE (TURN cw or ccw, \
             e.g. cw:180:0.5)",
            self.given,
            names.join(", ")
        )
    }
}

impl std::error::Error for BadSweep {}

/// How a sensor's sweep runs, but for its period (the scans' own).
#[derive(Debug, Clone, PartialEq)]
pub struct SweepSpec {
    /// Its name (a preset's, or what was given).
    pub name: String,
    turn: Turn,
    start_deg: f32,
    stamp_share: f32,
}

impl SweepSpec {
    /// `off` (`None`), a preset's name, or `cw:START_DEG:STAMP_SHARE` / `ccw:...`.
    pub fn parse(given: &str) -> Result<Option<Self>, BadSweep> {
        let bad = || BadSweep {
            given: given.to_string(),
        };
        if given == "off" {
            return Ok(None);
        }
        if let Some(p) = PRESETS.iter().find(|p| p.0 == given) {
            return Ok(Some(SweepSpec {
                name: p.0.to_string(),
                turn: p.1,
                start_deg: p.2,
                stamp_share: p.3,
            }));
        }
        let parts: Vec<&str> = given.split(':').collect();
        let [turn, start, share] = parts.as_slice() else {
            return Err(bad());
        };
        let turn = match *turn {
            "cw" => Turn::Clockwise,
            "ccw" => Turn::CounterClockwise,
            _ => return Err(bad()),
        };
        let number = |s: &str| s.parse::<f32>().ok().filter(|v| v.is_finite());
        let (start_deg, stamp_share) = (
            number(start).ok_or_else(bad)?,
            number(share).ok_or_else(bad)?,
        );
        if !(0.0..=1.0).contains(&stamp_share) {
            return Err(bad());
        }
        Ok(Some(SweepSpec {
            name: given.to_string(),
            turn,
            start_deg,
            stamp_share,
        }))
    }

    /// The presets' names and what each describes (for `--help` and the docs).
    pub fn presets() -> impl Iterator<Item = (&'static str, &'static str)> {
        PRESETS.iter().map(|p| (p.0, p.4))
    }

    /// The sweep of a sensor with this spec turning once in `period_s` seconds.
    pub fn with_period(&self, period_s: f64) -> Spin {
        Spin {
            turn: self.turn,
            start_rad: self.start_deg.to_radians().rem_euclid(2.0 * PI),
            period_s: period_s as f32,
            stamp_share: self.stamp_share,
        }
    }
}

/// What timing scans from their sweep did, for `report.json` (`summary.input.sweep_times`).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct SweepCounts {
    /// The sweep's name.
    pub sweep: String,
    /// The period used (s).
    pub period_s: f64,
    /// Scans timed from their azimuths.
    pub timed: usize,
    /// Scans left untimed: they covered less than three quarters of a turn.
    pub not_a_turn: usize,
}

/// Times scans from their sweep, counting what it did.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepTimer {
    spin: Spin,
    counts: SweepCounts,
}

impl SweepTimer {
    /// A timer for `spec`'s sweep, once every `period_s` seconds.
    pub fn new(spec: &SweepSpec, period_s: f64) -> Self {
        SweepTimer {
            spin: spec.with_period(period_s),
            counts: SweepCounts {
                sweep: spec.name.clone(),
                period_s,
                ..SweepCounts::default()
            },
        }
    }

    /// The times of `points` after their stamp, or `None` for a scan that is not a turn
    /// (`label` names it in the log, the first time).
    pub fn times(&mut self, label: &str, points: &[Point]) -> Option<Vec<f32>> {
        let mut times = vec![0.0; points.len()];
        match firing_times(points, &self.spin, &mut times) {
            Ok(_) => {
                self.counts.timed += 1;
                Some(times)
            }
            Err(SpinError::NotATurn { sectors }) => {
                if self.counts.not_a_turn == 0 {
                    log::warn!(
                        "{label}: its points cover {sectors} of {} sectors of a turn, not a \
                         spinning sweep: not timed from their azimuths (nor any other such scan)",
                        slamesh_core::spin::SECTORS
                    );
                }
                self.counts.not_a_turn += 1;
                None
            }
            Err(e) => {
                // The spec's checks and the one buffer a point make these unreachable; say so
                // rather than stop.
                log::warn!("{label}: not timed from its sweep: {e:?}");
                self.counts.not_a_turn += 1;
                None
            }
        }
    }

    /// What it did so far.
    pub fn counts(&self) -> &SweepCounts {
        &self.counts
    }
}

/// The median interval of `stamps` (s), or 0.1 s (10 Hz) when they give none.
pub fn period_of(stamps: &[f64]) -> f64 {
    let mut gaps: Vec<f64> = stamps
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| d.is_finite() && *d > 0.0)
        .collect();
    if gaps.is_empty() {
        return 0.1;
    }
    gaps.sort_by(f64::total_cmp);
    gaps[gaps.len() / 2]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sweeps_are_named_or_given_in_full_and_mistakes_are_refused() {
        assert_eq!(SweepSpec::parse("off"), Ok(None));
        let kitti = SweepSpec::parse("kitti").unwrap().unwrap();
        let spin = kitti.with_period(0.1);
        assert_eq!(spin.turn, Turn::Clockwise);
        assert!((spin.start_rad - PI).abs() < 1e-6);
        assert_eq!(spin.stamp_share, 0.5);
        let custom = SweepSpec::parse("ccw:-90:0").unwrap().unwrap();
        let spin = custom.with_period(0.05);
        assert_eq!(spin.turn, Turn::CounterClockwise);
        assert!((spin.start_rad - 1.5 * PI).abs() < 1e-6);
        for bad in [
            "", "kiti", "cw:180", "up:0:0", "cw:x:0", "cw:0:2", "cw:nan:0",
        ] {
            let e = SweepSpec::parse(bad).unwrap_err();
            assert!(
                e.to_string().contains("kitti, velodyne, ouster, hesai"),
                "{e}"
            );
        }
        assert_eq!(SweepSpec::presets().count(), 4);
    }

    #[test]
    fn a_timer_times_full_turns_and_counts_the_rest() {
        let spec = SweepSpec::parse("kitti").unwrap().unwrap();
        let mut timer = SweepTimer::new(&spec, 0.1);
        let ring: Vec<Point> = (0..360)
            .map(|k| {
                let a = (k as f32).to_radians();
                [10.0 * a.cos(), 10.0 * a.sin(), 0.0]
            })
            .collect();
        let times = timer.times("a.bin", &ring).unwrap();
        assert!(times[0].abs() < 1e-6 && (times[90] + 0.025).abs() < 1e-6);
        assert_eq!(timer.times("b.bin", &ring[..90]), None);
        assert_eq!((timer.counts().timed, timer.counts().not_a_turn), (1, 1));
    }

    #[test]
    fn the_period_is_the_median_interval() {
        assert!((period_of(&[0.0, 0.1, 0.2, 0.5, 0.6]) - 0.1).abs() < 1e-12);
        assert_eq!(period_of(&[3.0]), 0.1);
        assert_eq!(period_of(&[]), 0.1);
    }
}
