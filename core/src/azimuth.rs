//! Azimuth profiles (docs/design.md §1.11): a scan summarised as its mean horizontal range in
//! each of [`BINS`] sectors about the sensor's vertical axis, and the turn about that axis that
//! best lays one scan's profile over another's.
//!
//! A rig turned by `θ` between two scans sees every surface `θ` further round: its profile is
//! the earlier one shifted by `θ`. Comparing the two over every shift finds the turn without a
//! pose, a map or a registration, in [`BINS`]² differences. That gives registration a first
//! guess where the constant-velocity prediction has no idea (a hand-held rig or a drone that
//! looks around between scans). The profile is blind to a turn about other axes and moves a
//! little with a step (a sector's range changes by the step's share of it), which the
//! registration's rounds take up.
//!
//! A profile is a fixed array ([`BINS`] numbers): no allocation, and the same work for every
//! scan of a given size (one arctangent approximation and a division a point).

use crate::math::{wrapped_angle, Point};

/// Sectors in a profile: 2 degrees each.
pub const BINS: usize = 180;

/// A profile needs this many sectors seen in both scans to be compared at a shift.
const MIN_SHARED: usize = BINS / 4;

/// A profile reads at most about this many points, evenly spread through the scan: 91 a
/// sector, and a small fixed cost whatever the scan's size. With 4 096, a KITTI scan's
/// profile was off by up to 3.7° (up to 1.5° with this many; docs/journal.md).
pub const MAX_POINTS: usize = 16384;

/// The mean horizontal range in each sector, as its logarithm (so that a difference is a
/// ratio), NaN where no point fell.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AzimuthProfile {
    log_range: [f32; BINS],
    /// The points it read (finite, off the vertical axis).
    read: u32,
}

/// Two profiles are compared only when neither read more than this many times the other's
/// points: a scan far smaller than its neighbours (a partial sweep, a few stray returns)
/// fills some sectors by chance, and the turn that lays them over a full scan's is a guess.
pub const MAX_READ_RATIO: u32 = 4;

/// The turn that best lays a scan's profile over an earlier one's ([`AzimuthProfile::turn_from`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Turn {
    /// The turn from the earlier scan to this one about the sensor's vertical (radians, in
    /// `(-π, π]`, counter-clockwise seen from above).
    pub yaw: f64,
    /// The mean absolute difference of the log-ranges at that turn.
    pub mismatch: f32,
}

impl AzimuthProfile {
    /// The profile of sensor-frame points, every `n / MAX_POINTS`-th of `n` (points on the
    /// vertical axis, and points not finite, are left out).
    pub fn of(points: &[Point]) -> Self {
        let mut sum = [0.0f32; BINS];
        let mut count = [0u32; BINS];
        for p in points
            .iter()
            .step_by(points.len().div_ceil(MAX_POINTS).max(1))
        {
            let r2 = p[0] * p[0] + p[1] * p[1];
            if !(r2 > 1e-6 && r2.is_finite()) {
                continue;
            }
            let bin = sector(p[0], p[1]);
            sum[bin] += r2;
            count[bin] += 1;
        }
        let mut log_range = [f32::NAN; BINS];
        for ((l, s), n) in log_range.iter_mut().zip(sum).zip(count) {
            if n > 0 {
                // ln of the root of the mean squared range.
                *l = 0.5 * libm::logf(s / n as f32);
            }
        }
        let read = count.iter().sum();
        Self { log_range, read }
    }

    /// The profile of no points: compares with nothing.
    pub const fn empty() -> Self {
        Self {
            log_range: [f32::NAN; BINS],
            read: 0,
        }
    }

    /// The mean absolute log-range difference when this profile is the earlier one turned by
    /// `shift` sectors; `None` when fewer than a quarter of the sectors are seen in both, or
    /// when one profile read over [`MAX_READ_RATIO`] times the other's points.
    fn mismatch_at(&self, earlier: &Self, shift: usize) -> Option<f32> {
        let (few, many) = (self.read.min(earlier.read), self.read.max(earlier.read));
        if few.saturating_mul(MAX_READ_RATIO) < many {
            return None;
        }
        let mut sum = 0.0f32;
        let mut shared = 0usize;
        for (b, now) in self.log_range.iter().enumerate() {
            let then = earlier.log_range[(b + shift) % BINS];
            // NaN compares false: sectors empty in either scan drop out.
            let d = now - then;
            if !d.is_nan() {
                sum += d.abs();
                shared += 1;
            }
        }
        (shared >= MIN_SHARED).then(|| sum / shared as f32)
    }

    /// The turn of at most `max_turn` radians either way from `earlier`'s scan to this one
    /// that best lays the profiles over each other, refined between sectors by a V through the
    /// best shift and its neighbours; `None` when the two share too few sectors at every
    /// shift, or when one read over [`MAX_READ_RATIO`] times the other's points.
    pub fn turn_from(&self, earlier: &Self, max_turn: f64) -> Option<Turn> {
        let reach = libm::round(max_turn.clamp(0.0, core::f64::consts::PI) / SECTOR_RAD) as usize;
        let mut costs = [f32::INFINITY; BINS];
        let mut best: Option<(usize, f32)> = None;
        for (shift, c) in costs.iter_mut().enumerate() {
            if shift.min(BINS - shift) > reach {
                continue;
            }
            if let Some(m) = self.mismatch_at(earlier, shift) {
                *c = m;
                if best.is_none_or(|(_, b)| m < b) {
                    best = Some((shift, m));
                }
            }
        }
        let (best, _) = best?;
        let (before, at, after) = (
            costs[(best + BINS - 1) % BINS],
            costs[best],
            costs[(best + 1) % BINS],
        );
        // The cost is a sum of absolute values: a V about its minimum, not a parabola.
        let rise = before.max(after) - at;
        let offset = if rise > 0.0 && rise.is_finite() {
            (0.5 * (before - after) / rise).clamp(-0.5, 0.5)
        } else {
            0.0
        };
        Some(Turn {
            yaw: wrapped_angle(f64::from(best as f32 + offset) * SECTOR_RAD),
            mismatch: at,
        })
    }

    /// The mismatch at a given turn `yaw` from `earlier` (the nearest shift): how well a turn
    /// found otherwise (the motion's prediction) lays the profiles over each other.
    pub fn mismatch_at_turn(&self, earlier: &Self, yaw: f64) -> Option<f32> {
        let shift = libm::round(yaw / SECTOR_RAD) as i64;
        self.mismatch_at(earlier, shift.rem_euclid(BINS as i64) as usize)
    }
}

/// One sector's angle (radians).
const SECTOR_RAD: f64 = core::f64::consts::TAU / BINS as f64;

/// The sector of the direction `(x, y)` (not both zero): its azimuth, counter-clockwise from
/// `x`, by a polynomial arctangent good to 1e-5 radians, far inside a sector.
fn sector(x: f32, y: f32) -> usize {
    use core::f32::consts::{FRAC_PI_2, PI, TAU};
    let (ax, ay) = (x.abs(), y.abs());
    let (small, large) = if ax < ay { (ax, ay) } else { (ay, ax) };
    let t = small / large;
    let s = t * t;
    // atan(t) on [0, 1].
    let mut a = ((-0.046_496_475 * s + 0.159_314_22) * s - 0.327_622_76) * s * t + t;
    if ay > ax {
        a = FRAC_PI_2 - a;
    }
    if x < 0.0 {
        a = PI - a;
    }
    if y < 0.0 {
        a = TAU - a;
    }
    let bin = (a * (BINS as f32 / TAU)) as usize;
    bin.min(BINS - 1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use alloc::vec::Vec;
    use core::f64::consts::PI;

    /// A room 14 m by 9 m with the sensor off its centre, a pillar and a recess, seen as a ring
    /// of wall points and a ground disc, turned by `yaw` and moved by `(dx, dy)`.
    fn room(yaw: f64, dx: f64, dy: f64) -> Vec<Point> {
        let mut pts = Vec::new();
        for i in 0..2000 {
            let a = i as f64 / 2000.0 * core::f64::consts::TAU;
            let (c, s) = (libm::cos(a), libm::sin(a));
            // Distance to the walls from (2 + dx, 1 + dy) along direction a.
            let (px, py) = (2.0 + dx, 1.0 + dy);
            let tx = if c > 0.0 {
                (7.0 - px) / c
            } else {
                (-7.0 - px) / c
            };
            let ty = if s > 0.0 {
                (4.5 - py) / s
            } else {
                (-4.5 - py) / s
            };
            let mut r = tx.min(ty);
            // A pillar at (-3, 2), radius 0.5.
            let (qx, qy) = (-3.0 - px, 2.0 - py);
            let along = qx * c + qy * s;
            let off2 = qx * qx + qy * qy - along * along;
            if along > 0.0 && off2 < 0.25 {
                r = r.min(along - libm::sqrt(0.25 - off2));
            }
            // The world direction a is seen at a - yaw by the turned sensor.
            let b = a - yaw;
            for z in [-1.0, 0.0, 1.5] {
                pts.push([(r * libm::cos(b)) as f32, (r * libm::sin(b)) as f32, z]);
            }
            let g = 3.0 + (i % 7) as f64;
            pts.push([(g * libm::cos(b)) as f32, (g * libm::sin(b)) as f32, -1.5]);
        }
        pts
    }

    #[test]
    fn the_sector_is_the_azimuth_to_a_hundred_thousandth_of_a_radian() {
        for i in 0..3600 {
            let a = (i as f64 + 0.37) / 3600.0 * core::f64::consts::TAU;
            let (x, y) = (libm::cos(a) as f32 * 7.0, libm::sin(a) as f32 * 7.0);
            let want = (a / SECTOR_RAD) as usize;
            let got = sector(x, y);
            // Directions within 1e-5 rad of a sector's edge may fall either side.
            let edge = (a / SECTOR_RAD).fract().min(1.0 - (a / SECTOR_RAD).fract()) * SECTOR_RAD;
            assert!(got == want || edge < 1e-5, "{i}: {got} vs {want}");
        }
        assert_eq!(sector(1.0, 0.0), 0);
        assert_eq!(sector(0.0, -1.0), 3 * BINS / 4);
    }

    #[test]
    fn finds_the_turn_between_two_scans_of_a_room_in_either_direction() {
        let earlier = AzimuthProfile::of(&room(0.0, 0.0, 0.0));
        for deg in [0.0, 3.3, -17.0, 44.0, -90.0, 135.5, 179.0] {
            let yaw = f64::to_radians(deg);
            let turned = AzimuthProfile::of(&room(yaw, 0.0, 0.0));
            let err = wrapped_angle(turned.turn_from(&earlier, PI).unwrap().yaw - yaw)
                .abs()
                .to_degrees();
            assert!(err < 1.0, "{deg}: {err}");
            // A step of 0.4 m as well: near walls move round by more than far ones.
            let now = AzimuthProfile::of(&room(yaw, 0.3, -0.25));
            let t = now.turn_from(&earlier, PI).unwrap();
            let err = wrapped_angle(t.yaw - yaw).abs().to_degrees();
            assert!(err < 3.0, "{deg}: found {}", t.yaw.to_degrees());
            // The found turn matches better than a wrong one.
            let wrong = now.mismatch_at_turn(&earlier, yaw + 0.5).unwrap();
            assert!(t.mismatch < 0.5 * wrong, "{deg}: {} vs {wrong}", t.mismatch);
            assert!(now.mismatch_at_turn(&earlier, yaw).unwrap() < 2.0 * t.mismatch + 0.01);
        }
    }

    #[test]
    fn the_turn_is_looked_for_within_the_limit_only() {
        let earlier = AzimuthProfile::of(&room(0.0, 0.0, 0.0));
        let now = AzimuthProfile::of(&room(f64::to_radians(60.0), 0.0, 0.0));
        let within = |deg: f64| {
            now.turn_from(&earlier, deg.to_radians())
                .unwrap()
                .yaw
                .to_degrees()
        };
        assert!((within(90.0) - 60.0).abs() < 1.0);
        // Limited to 30 degrees, the best is at most 30 degrees, and no limit is no turn.
        assert!(within(30.0).abs() <= 31.0);
        assert_eq!(within(0.0), 0.0);
    }

    #[test]
    fn a_large_scan_is_read_sparsely_and_gives_the_same_turn() {
        let mut big = Vec::new();
        while big.len() <= 2 * MAX_POINTS {
            big.extend(room(0.4, 0.0, 0.0));
        }
        let earlier = AzimuthProfile::of(&room(0.0, 0.0, 0.0));
        let t = AzimuthProfile::of(&big).turn_from(&earlier, PI).unwrap();
        assert!((t.yaw - 0.4).abs() < 1f64.to_radians());
    }

    #[test]
    fn a_scan_far_smaller_than_the_other_gives_no_turn() {
        let full = room(0.0, 0.0, 0.0);
        let earlier = AzimuthProfile::of(&full);
        let turned = room(0.5, 0.0, 0.0);
        // 64 points of the turned room (every 125th): enough sectors seen, far too few points.
        let few: Vec<Point> = turned.iter().step_by(turned.len() / 64).copied().collect();
        assert!(AzimuthProfile::of(&few).read <= 64);
        assert_eq!(AzimuthProfile::of(&few).turn_from(&earlier, PI), None);
        assert_eq!(earlier.turn_from(&AzimuthProfile::of(&few), PI), None);
        assert_eq!(
            AzimuthProfile::of(&few).mismatch_at_turn(&earlier, 0.5),
            None
        );
        // A third of the points (within the ratio) still compares, and finds the turn.
        let third: Vec<Point> = turned.iter().step_by(3).copied().collect();
        let t = AzimuthProfile::of(&third).turn_from(&earlier, PI).unwrap();
        assert!((t.yaw - 0.5).abs() < 1f64.to_radians(), "{}", t.yaw);
    }

    #[test]
    fn too_little_seen_gives_no_turn_and_bad_points_are_left_out() {
        let earlier = AzimuthProfile::of(&room(0.0, 0.0, 0.0));
        assert_eq!(AzimuthProfile::empty().turn_from(&earlier, PI), None);
        // Points in one narrow sector only.
        let narrow: Vec<Point> = (0..100).map(|i| [5.0, 0.01 * i as f32, 0.0]).collect();
        assert_eq!(AzimuthProfile::of(&narrow).turn_from(&earlier, PI), None);
        let bad = [
            [f32::NAN, 1.0, 0.0],
            [f32::INFINITY, 0.0, 0.0],
            [0.0, 0.0, 3.0],
        ];
        assert!(AzimuthProfile::of(&bad)
            .log_range
            .iter()
            .all(|l| l.is_nan()));
    }
}
