//! Whether `[imu]` agrees with the registration (docs/design.md §1.19): over the run's first
//! [`WINDOW_S`] seconds each registered frame's rotation is set against the gyro's over the
//! same time; when a turn of the IMU's axes or a scale (degrees for radians) explains their
//! disagreement, the verdict says which and by how much.
//!
//! It owns sums over the pairs (a fixed size, however long the window), and guarantees one
//! verdict a run: given when the window has passed, or earlier when asked (the IMU is being set
//! aside, the run ends), and not repeated.

use crate::io::le::{put_f64, put_option, put_u64, Damaged, Decoder};
use nalgebra::{Matrix3, UnitQuaternion, Vector3};
use slamesh_core::math::{best_rotation, svd3};

/// The time from the first pair over which pairs are taken (seconds).
pub const WINDOW_S: f64 = 10.0;
/// The least registered turning (degrees, summed over the frames) a verdict on the axes needs.
pub const MIN_TURN_DEG: f64 = 10.0;
/// The least a verdict on the scale needs (its size, not its direction: less).
pub const MIN_SCALE_TURN_DEG: f64 = 2.0;
/// The least turn of the IMU's axes called a disagreement (degrees).
pub const MIN_OFF_DEG: f64 = 3.0;

/// The gyro's angles over a run of misses may be this many times the registered ones before
/// the misses are the gyro's: a bent sweep's registration takes in part of the turn (1.28
/// times on a shaken drive's untimed sweeps), a unit 57.3 times.
pub const BLAME_SCALE: std::ops::RangeInclusive<f64> = 0.5..=2.0;

/// What the check found: its words, and whether they say `[imu]` (or the gyro's units or
/// clock) is wrong.
#[derive(Debug, Clone, PartialEq)]
pub struct Verdict {
    /// The words, for the log and the report.
    pub text: String,
    /// The gyro disagrees in a way a wrong `[imu]`, unit or clock explains.
    pub wrong: bool,
}

/// Sums over pairs of rotations (gyro, registered) as rotation vectors `g` and `r`.
#[derive(Debug, Default)]
pub struct CalibrationCheck {
    /// The IMU's rotation on the LiDAR as configured (`[imu] rotation_rpy_deg`).
    configured: UnitQuaternion<f64>,
    /// `Σ g rᵀ`.
    h: Matrix3<f64>,
    /// `Σ |g|²`, `Σ |r|²`.
    squares: (f64, f64),
    /// `Σ |g|`, `Σ |r|` (radians).
    angles: (f64, f64),
    pairs: usize,
    /// The first pair's time.
    since: Option<f64>,
    /// Given already.
    done: bool,
}

impl CalibrationCheck {
    /// A check of the IMU turned `configured` on the LiDAR (`lidar_from_imu`'s rotation).
    pub fn new(configured: UnitQuaternion<f64>) -> Self {
        Self {
            configured,
            ..Self::default()
        }
    }

    /// Takes the gyro's and the registration's rotation over a frame ending at `t`; the
    /// verdict when this pair ends the window.
    pub fn add(
        &mut self,
        t: f64,
        gyro: &UnitQuaternion<f64>,
        registered: &UnitQuaternion<f64>,
    ) -> Option<Verdict> {
        if self.done {
            return None;
        }
        let since = *self.since.get_or_insert(t);
        let (g, r) = (gyro.scaled_axis(), registered.scaled_axis());
        self.h += g * r.transpose();
        self.squares.0 += g.norm_squared();
        self.squares.1 += r.norm_squared();
        self.angles.0 += g.norm();
        self.angles.1 += r.norm();
        self.pairs += 1;
        (t - since >= WINDOW_S).then(|| self.verdict())
    }

    /// The verdict on the pairs so far (once a run: `None` after it was given, or before any
    /// pair).
    pub fn take(&mut self) -> Option<Verdict> {
        (!self.done && self.pairs > 0).then(|| self.verdict())
    }

    /// The verdict the pairs so far would give, without giving it (`None` once given, or
    /// before any pair): what a run that ends within the window reports.
    pub fn pending(&self) -> Option<Verdict> {
        (!self.done && self.pairs > 0).then(|| self.judge())
    }

    /// Appends its sums to a checkpoint's record ([`crate::io::le`]; the configured turn is
    /// the run's, not kept).
    pub(super) fn put(&self, e: &mut Vec<u8>) {
        for v in self.h.iter() {
            put_f64(e, *v);
        }
        for v in [self.squares.0, self.squares.1, self.angles.0, self.angles.1] {
            put_f64(e, v);
        }
        put_u64(e, self.pairs as u64);
        put_option(e, self.since, 0.0, put_f64);
        e.push(u8::from(self.done));
    }

    /// What [`put`](Self::put) wrote, for the IMU turned `configured` on the LiDAR.
    pub(super) fn read(d: &mut Decoder, configured: UnitQuaternion<f64>) -> Result<Self, Damaged> {
        let mut h = Matrix3::zeros();
        for v in h.iter_mut() {
            *v = d.f64()?;
        }
        Ok(Self {
            configured,
            h,
            squares: (d.f64()?, d.f64()?),
            angles: (d.f64()?, d.f64()?),
            pairs: d.usize()?,
            since: d.option(Decoder::f64)?,
            done: d.flag()?,
        })
    }

    /// Whether it still takes pairs (no verdict given yet).
    pub fn open(&self) -> bool {
        !self.done
    }

    fn verdict(&mut self) -> Verdict {
        self.done = true;
        self.judge()
    }

    /// Whether the pairs so far say the gyro's scale is wrong beyond what a registration's
    /// error explains (outside [`BLAME_SCALE`]: a unit, a clock), in words: what a run of
    /// frames whose rotations the gyro missed is judged by ([`crate::inertial::trust`]).
    pub fn blames(&self) -> Option<String> {
        let (g, r) = self.angles;
        let ratio = g / r.max(1e-12);
        (r.to_degrees() >= MIN_SCALE_TURN_DEG && !BLAME_SCALE.contains(&ratio)).then(|| {
            format!(
                "over the misses the gyro's angles are {ratio:.2} times the registered ones: \
                 a unit or a clock, not a registration's error"
            )
        })
    }

    /// The verdict the pairs so far give.
    fn judge(&self) -> Verdict {
        let wrong = |text: String| Verdict { text, wrong: true };
        let fine = |text: String| Verdict { text, wrong: false };
        let (g, r) = self.angles;
        let turned = r.to_degrees();
        let ratio = g / r.max(1e-12);
        if turned >= MIN_SCALE_TURN_DEG && !(0.8..=1.25).contains(&ratio) {
            return wrong(format!(
                "the gyro's angles are {ratio:.2} times the registered ones over {} frames: \
                 its readings are not in rad/s (57.3 times: degrees per second, [imu] \
                 gyro_unit = \"deg/s\"), or its clock is not the LiDAR's",
                self.pairs
            ));
        }
        if turned < MIN_TURN_DEG {
            return fine(format!(
                "not checked: the first frames turned {turned:.1} degrees, too little to tell \
                 the IMU's axes (at least {MIN_TURN_DEG})"
            ));
        }
        let fit = best_rotation(&self.h);
        let off = fit.angle().to_degrees();
        let (gg, rr) = self.squares;
        // Σ |r - C g|² with C the identity, and with the fitted turn.
        let before = (gg + rr - 2.0 * self.h.trace()).max(0.0);
        let after = (gg + rr - 2.0 * (fit.matrix() * self.h).trace()).max(0.0);
        let per_frame = |sum: f64| (sum / self.pairs as f64).sqrt().to_degrees();
        if off < MIN_OFF_DEG || after > 0.25 * before {
            return fine(format!(
                "consistent: over {} frames ({turned:.0} degrees of turning) the gyro's \
                 rotations match the registered ones to {:.2} degrees a frame",
                self.pairs,
                per_frame(before)
            ));
        }
        let Some(svd) = svd3(&self.h, false) else {
            return fine(format!(
                "not checked: the gyro's and the registered rotations over {} frames give no \
                 axis to compare (their sums do not decompose)",
                self.pairs
            ));
        };
        let s = svd.singular_values;
        let mut s = [s[0], s[1], s[2]];
        s.sort_by(|a, b| b.total_cmp(a));
        if s[1] < 0.1 * s[0] {
            return wrong(format!(
                "the gyro turns about an axis {off:.1} degrees from the registered one's (the \
                 first frames turned about one axis only, so the whole turn is not known): \
                 [imu] rotation_rpy_deg is likely wrong"
            ));
        }
        // The gyro's axes, turned by the fit after the configured rotation.
        let (roll, pitch, yaw) = (fit * self.configured.to_rotation_matrix()).euler_angles();
        // To a tenth, without a sign on zero.
        let deg =
            Vector3::new(roll, pitch, yaw).map(|a| (a.to_degrees() * 10.0).round() / 10.0 + 0.0);
        wrong(format!(
            "the gyro's rotations match the registered ones once its axes are turned {off:.1} \
             degrees more ({:.2} degrees a frame off instead of {:.2}): [imu] rotation_rpy_deg \
             = [{:.1}, {:.1}, {:.1}] fits them",
            per_frame(after),
            per_frame(before),
            deg.x,
            deg.y,
            deg.z,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Frames a tenth of a second apart turning about changing axes; the gyro sees each turn
    /// through `mount` (its axes' error) and `scale`.
    fn check(mount: UnitQuaternion<f64>, scale: f64) -> Verdict {
        // Configured as turned 90 degrees about z.
        let configured = UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::FRAC_PI_2);
        let mut c = CalibrationCheck::new(configured);
        for k in 0..200 {
            let a = k as f64 * 0.3;
            let r = Vector3::new(a.sin(), a.cos(), 0.5 * (2.0 * a).sin()) * 0.05;
            let g = (mount * r) * scale;
            let t = k as f64 * 0.1;
            let verdict = c.add(
                t,
                &UnitQuaternion::from_scaled_axis(g),
                &UnitQuaternion::from_scaled_axis(r),
            );
            if let Some(v) = verdict {
                return v;
            }
        }
        panic!("no verdict within the window")
    }

    #[test]
    fn a_turned_imu_is_named_with_its_turn() {
        let v = check(UnitQuaternion::from_euler_angles(0.0, 0.0, 0.2), 1.0);
        // The gyro's axes turned by +0.2 rad in yaw: turning them back takes -11.5 degrees,
        // from the 90 configured.
        assert!(v.wrong, "{v:?}");
        assert!(v.text.contains("turned 11.5 degrees"), "{v:?}");
        assert!(v.text.contains("= [0.0, 0.0, 78.5]"), "{v:?}");
        let right = check(UnitQuaternion::identity(), 1.0);
        assert!(
            !right.wrong && right.text.starts_with("consistent"),
            "{right:?}"
        );
        // Large turns wrap past half a turn: the ratio is near 57.3, not at it.
        let degrees = check(UnitQuaternion::identity(), 180.0 / std::f64::consts::PI);
        assert!(
            degrees.wrong && degrees.text.contains("degrees per second"),
            "{degrees:?}"
        );
    }

    #[test]
    fn too_little_turning_is_not_judged_and_a_verdict_is_given_once() {
        let mut c = CalibrationCheck::default();
        let q = UnitQuaternion::from_scaled_axis(Vector3::new(0.0, 0.0, 0.001));
        assert_eq!(c.add(0.0, &q, &q), None);
        assert!(c.open());
        let v = c.take().unwrap();
        assert!(!v.wrong && v.text.starts_with("not checked"), "{v:?}");
        assert!(!c.open());
        assert_eq!(c.take(), None);
        assert_eq!(c.add(20.0, &q, &q), None);
    }
}
