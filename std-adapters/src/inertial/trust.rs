//! Whether the run trusts the IMU's readings: judged fairly, against registrations that can be
//! believed, and given back when they agree again (docs/design.md §1.19).
//!
//! - **Not an IMU**: readings that come slower than [`MIN_RATE_HZ`] (a 10 Hz topic of one
//!   reading a scan), or whose gyro stays still while the registrations turn
//!   ([`STILL_AFTER_DEG`]), are ignored for the whole run, said once: the run is then exactly
//!   as without them. Until the rate is known (two readings), the readings are not used.
//! - **Set aside**: [`DISTRUST_AFTER`] frames in a row whose registered rotation the gyro
//!   missed, when the misses are the gyro's. A frame counts only when it and the frame before
//!   it converged (a registration right after a lost one is the least sure); a registration
//!   lost from the gyro's start counts only when the gyro turned far from what the motion
//!   model expected ([`SURPRISE_DEG`]): lost while the gyro was steady is the registration's
//!   fault. A run of converged misses is the gyro's only when their pairs show a wrong
//!   scale ([`CalibrationCheck::blames`](crate::inertial::calibration::CalibrationCheck::blames):
//!   a unit, a clock); otherwise the registrations are doubted (an untimed sweep bent by a
//!   shaking road registers a part of each turn, and five frames of it fit a turn of the
//!   axes as well), said, and the IMU kept. Axes turned from `[imu]` are named by the check
//!   over the first seconds ([`crate::inertial::calibration`]).
//! - **Back**: set aside, it comes back after [`TRUST_AGAIN_AFTER`] such frames in a row
//!   whose rotation it matched, said.

use crate::io::le::{put_f64, put_opt_str, put_u64, Damaged, Decoder};
use nalgebra::UnitQuaternion;

/// Frames in a row whose rotation the gyro misses before the IMU is set aside.
pub const DISTRUST_AFTER: usize = 5;

/// Frames in a row whose rotation the gyro matches before an IMU set aside comes back.
pub const TRUST_AGAIN_AFTER: usize = 10;

/// Readings slower than this (Hz) are not an IMU to deskew or predict a sweep with.
pub const MIN_RATE_HZ: f64 = 50.0;

/// Once the registrations turned this far (degrees, summed over converged frames), a gyro
/// that turned less than [`STILL_SHARE`] of it is not this sensor's.
pub const STILL_AFTER_DEG: f64 = 15.0;

/// See [`STILL_AFTER_DEG`].
pub const STILL_SHARE: f64 = 0.2;

/// A registration lost from the gyro's start blames the gyro only when the gyro turned this
/// much further (degrees) than the last registered step over the frame, or more than twice
/// what the bias may take, whichever is larger: a rough road shakes a sensor by a few
/// degrees a frame, a gyro read in the wrong unit turns tens.
pub const SURPRISE_DEG: f64 = 10.0;

/// What the run holds of its trust in the IMU.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Trust {
    /// Frames in a row whose rotation the gyro missed.
    disagreeing: usize,
    /// Frames in a row whose rotation the gyro matched while set aside.
    agreeing: usize,
    /// Why the IMU is set aside now, if it is.
    set_aside: Option<String>,
    /// The last reason it was set aside, and how many times it came back.
    history: (Option<String>, usize),
    /// Why the readings are not an IMU's, if they are not: for the whole run.
    ignored: Option<String>,
    /// The readings' rate is known to be an IMU's.
    rate_ok: bool,
    /// The registered and the gyro's turn summed (degrees) until the still check is decided
    /// (`None` then).
    turned: Option<(f64, f64)>,
    /// Whether the last frame's registration converged.
    last_converged: bool,
    /// Whether the current run of misses has a registration lost from a surprising gyro.
    lost_in_run: bool,
    /// Runs of misses put down to the registrations.
    doubted: usize,
    /// The last registered step's rotation: what the motion model expects of the next.
    last_step: Option<UnitQuaternion<f64>>,
}

impl Trust {
    /// Nothing judged yet.
    pub fn new() -> Self {
        Trust {
            turned: Some((0.0, 0.0)),
            ..Trust::default()
        }
    }

    /// Whether the readings may be used now.
    pub fn trusted(&self) -> bool {
        self.rate_ok && self.set_aside.is_none() && self.ignored.is_none()
    }

    /// Why the IMU is set aside now, or was last.
    pub fn set_aside(&self) -> Option<&str> {
        self.set_aside.as_deref().or(self.history.0.as_deref())
    }

    /// Times it came back.
    pub fn returned(&self) -> usize {
        self.history.1
    }

    /// Runs of misses put down to the registrations, not the gyro.
    pub fn doubted(&self) -> usize {
        self.doubted
    }

    /// Why the readings are ignored, if they are.
    pub fn ignored(&self) -> Option<&str> {
        self.ignored.as_deref()
    }

    /// Judges the readings' rate from their times (`times`, the readings held, in order),
    /// once two came; a rate below [`MIN_RATE_HZ`] ignores them, said.
    pub fn check_rate(&mut self, times: impl Iterator<Item = f64>) {
        if self.rate_ok || self.ignored.is_some() {
            return;
        }
        let times: Vec<f64> = times.collect();
        let mut gaps: Vec<f64> = (times.windows(2))
            .map(|w| w[1] - w[0])
            .filter(|g| *g > 0.0)
            .collect();
        if gaps.is_empty() {
            return;
        }
        gaps.sort_by(f64::total_cmp);
        let hz = 1.0 / gaps[gaps.len() / 2];
        if hz >= MIN_RATE_HZ {
            self.rate_ok = true;
        } else {
            self.ignore(format!(
                "its readings come at {hz:.1} Hz, below the {MIN_RATE_HZ} Hz an IMU gives: not \
                 an IMU to deskew or predict a sweep with"
            ));
        }
    }

    fn ignore(&mut self, why: String) {
        log::warn!("IMU: ignored: {why}; the run goes on as without it");
        self.ignored = Some(why);
    }

    /// Takes a converged frame's registered turn and the gyro's over the same time into the
    /// still check; a gyro that stays still while the registrations turn is ignored, said.
    pub fn check_turning(&mut self, registered_deg: f64, gyro_deg: f64) {
        let Some((r, g)) = &mut self.turned else {
            return;
        };
        (*r, *g) = (*r + registered_deg, *g + gyro_deg);
        if *r < STILL_AFTER_DEG {
            return;
        }
        let (r, g) = (*r, *g);
        self.turned = None;
        if g < STILL_SHARE * r {
            self.ignore(format!(
                "its gyro turned {g:.1} degrees while the registrations turned {r:.1}: not an \
                 IMU on this sensor"
            ));
        }
    }

    /// Whether a frame's comparison with the gyro counts: it converged (`converged`) and so
    /// did the frame before. Call once a frame, before [`judge`](Self::judge).
    pub fn counts(&mut self, converged: bool) -> bool {
        let counts = converged && self.last_converged;
        self.last_converged = converged;
        counts
    }

    /// Whether a registration lost from the gyro's start is the gyro's fault: its turn over
    /// the frame (`gyro`) is far from the last registered step's (none before the first: a
    /// body starting from rest; `max_deg` the bias's limit).
    pub fn surprised(&self, gyro: &UnitQuaternion<f64>, max_deg: f64) -> bool {
        let step = self.last_step.unwrap_or_else(UnitQuaternion::identity);
        gyro.angle_to(&step).to_degrees() > SURPRISE_DEG.max(2.0 * max_deg)
    }

    /// Keeps the registered step's rotation for the next frame's [`surprised`](Self::surprised).
    pub fn stepped(&mut self, registered: Option<UnitQuaternion<f64>>) {
        self.last_step = registered;
    }

    /// A counted frame whose rotation the gyro missed by `off_deg` (over `dt` seconds; `limit`
    /// the most it may miss by): [`DISTRUST_AFTER`] in a row set it aside with `why`'s words.
    /// Returns true when it did.
    pub fn judge(&mut self, off_deg: f64, limit_deg: f64) -> bool {
        if off_deg <= limit_deg {
            (self.disagreeing, self.lost_in_run) = (0, false);
            return false;
        }
        self.lost_in_run |= off_deg == f64::INFINITY;
        self.disagreeing += 1;
        self.disagreeing == DISTRUST_AFTER
    }

    /// Whether the run of misses that reached [`DISTRUST_AFTER`] had a registration lost from a
    /// surprising gyro in it (the gyro's fault whatever the pairs say).
    pub fn lost_in_run(&self) -> bool {
        self.lost_in_run
    }

    /// Puts a run of misses down to the registrations: the count starts again, said the first
    /// time (`why`: what the pairs showed).
    pub fn doubt(&mut self, why: &str, at: &str) {
        if self.doubted == 0 {
            log::warn!(
                "{at}IMU: the registered rotations missed the gyro's on {DISTRUST_AFTER} frames \
                 in a row, but its scale and axes agree with theirs ({why}): the registrations \
                 are doubted, not the IMU, which is kept"
            );
        }
        (self.disagreeing, self.lost_in_run, self.doubted) = (0, false, self.doubted + 1);
    }

    /// Sets the IMU aside for `why`.
    pub fn set_aside_for(&mut self, why: String) {
        log::warn!("IMU: {why}");
        (self.set_aside, self.agreeing) = (Some(why), 0);
    }

    /// While set aside: a counted frame the gyro matched (`off_deg` within `limit_deg`) or
    /// missed; [`TRUST_AGAIN_AFTER`] matches in a row bring it back, said.
    pub fn watch(&mut self, off_deg: f64, limit_deg: f64, at: &str) {
        if self.set_aside.is_none() {
            return;
        }
        self.agreeing = if off_deg <= limit_deg {
            self.agreeing + 1
        } else {
            0
        };
        if self.agreeing == TRUST_AGAIN_AFTER {
            log::info!(
                "{at}IMU: back: the gyro matched the registered rotation on {TRUST_AGAIN_AFTER} \
                 frames in a row"
            );
            self.history = (self.set_aside.take(), self.history.1 + 1);
            (self.agreeing, self.disagreeing) = (0, 0);
        }
    }

    /// Appends it to a checkpoint's record.
    pub fn put(&self, e: &mut Vec<u8>) {
        for n in [
            self.disagreeing,
            self.agreeing,
            self.history.1,
            self.doubted,
        ] {
            put_u64(e, n as u64);
        }
        put_opt_str(e, self.set_aside.as_deref());
        put_opt_str(e, self.history.0.as_deref());
        put_opt_str(e, self.ignored.as_deref());
        e.push(u8::from(self.rate_ok));
        e.push(u8::from(self.last_converged));
        e.push(u8::from(self.lost_in_run));
        e.push(u8::from(self.turned.is_some()));
        let (r, g) = self.turned.unwrap_or_default();
        put_f64(e, r);
        put_f64(e, g);
        e.push(u8::from(self.last_step.is_some()));
        let q = self.last_step.unwrap_or_default();
        for v in [q.w, q.i, q.j, q.k] {
            put_f64(e, v);
        }
    }

    /// Reads back what [`put`](Self::put) wrote.
    pub fn read(d: &mut Decoder) -> Result<Self, Damaged> {
        let (disagreeing, agreeing, returned) = (d.usize()?, d.usize()?, d.usize()?);
        let doubted = d.usize()?;
        let (set_aside, last, ignored) = (d.opt_string()?, d.opt_string()?, d.opt_string()?);
        let (rate_ok, last_converged, lost_in_run) = (d.flag()?, d.flag()?, d.flag()?);
        let turning = d.flag()?;
        let turned = (d.f64()?, d.f64()?);
        let stepped = d.flag()?;
        let q = nalgebra::Quaternion::new(d.f64()?, d.f64()?, d.f64()?, d.f64()?);
        // Taken as written (normalising again could move its last bit, and a resumed run
        // would then differ from one never stopped); a rotation that is not one is damage.
        let unit = (q.norm() - 1.0).abs() < 1e-9;
        if stepped && !unit {
            return Err("the last step's rotation is not a unit quaternion".into());
        }
        Ok(Trust {
            disagreeing,
            agreeing,
            set_aside,
            history: (last, returned),
            ignored,
            rate_ok,
            turned: turning.then_some(turned),
            last_converged,
            lost_in_run,
            doubted,
            last_step: stepped.then(|| UnitQuaternion::new_unchecked(q)),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slow_readings_are_ignored_and_fast_ones_trusted_once_two_came() {
        let mut t = Trust::new();
        t.check_rate([0.0].into_iter());
        assert!(!t.trusted(), "one reading tells no rate");
        t.check_rate([0.0, 0.1, 0.2].into_iter());
        assert!(!t.trusted());
        assert!(t.ignored().unwrap().contains("10.0 Hz"));
        let mut t = Trust::new();
        t.check_rate([0.0, 0.005, 0.010, 0.5].into_iter());
        assert!(t.trusted());
    }

    #[test]
    fn a_gyro_still_while_the_registrations_turn_is_ignored() {
        let mut t = Trust::new();
        t.check_rate([0.0, 0.01].into_iter());
        for _ in 0..20 {
            t.check_turning(1.0, 0.01);
        }
        assert!(t.ignored().unwrap().contains("turned 0.1 degrees"));
        let mut t = Trust::new();
        t.check_turning(20.0, 19.0);
        t.check_turning(0.0, 0.0);
        assert!(t.ignored().is_none());
    }

    #[test]
    fn set_aside_after_misses_in_a_row_and_back_after_matches_in_a_row() {
        let mut t = Trust::new();
        t.check_rate([0.0, 0.01].into_iter());
        for k in 1..=DISTRUST_AFTER {
            assert_eq!(t.judge(5.0, 1.0), k == DISTRUST_AFTER);
        }
        t.set_aside_for("missed".into());
        assert!(!t.trusted());
        for _ in 1..TRUST_AGAIN_AFTER {
            t.watch(0.5, 1.0, "");
        }
        t.watch(3.0, 1.0, "");
        assert!(!t.trusted(), "a miss starts the count again");
        for _ in 0..TRUST_AGAIN_AFTER {
            t.watch(0.5, 1.0, "");
        }
        assert!(t.trusted());
        assert_eq!((t.set_aside(), t.returned()), (Some("missed"), 1));
    }

    #[test]
    fn only_frames_after_a_converged_one_count_and_a_steady_gyro_is_not_blamed() {
        let mut t = Trust::new();
        assert!(!t.counts(true), "the first frame has none before it");
        assert!(t.counts(true));
        assert!(!t.counts(false));
        assert!(!t.counts(true));
        let step = UnitQuaternion::from_euler_angles(0.0, 0.0, 0.01);
        assert!(!t.surprised(&step, 1.0), "from rest, a small turn");
        assert!(t.surprised(&UnitQuaternion::from_euler_angles(0.0, 0.0, 0.3), 1.0));
        t.stepped(Some(step));
        assert!(!t.surprised(&UnitQuaternion::from_euler_angles(0.0, 0.0, 0.02), 1.0));
        assert!(!t.surprised(&UnitQuaternion::from_euler_angles(0.0, 0.0, 0.1), 1.0));
        assert!(t.surprised(&UnitQuaternion::from_euler_angles(0.0, 0.0, 0.3), 1.0));
    }

    #[test]
    fn it_reads_back_as_it_was() {
        let mut t = Trust::new();
        t.check_rate([0.0, 0.01].into_iter());
        t.check_turning(3.0, 2.5);
        t.counts(true);
        t.stepped(Some(UnitQuaternion::from_euler_angles(0.1, 0.0, 0.2)));
        t.set_aside_for("why".into());
        let mut e = Vec::new();
        t.put(&mut e);
        let back = Trust::read(&mut Decoder { bytes: &e }).unwrap();
        assert_eq!(back.set_aside, t.set_aside);
        assert_eq!(
            (back.turned, back.rate_ok, back.last_converged),
            (t.turned, true, true)
        );
        assert_eq!(back.last_step, t.last_step, "exactly, to the bit");
        let mut again = Vec::new();
        back.put(&mut again);
        assert_eq!(again, e);
    }

    /// A last step that is no rotation (what the checkpoint fuzz target found: infinities
    /// there, normalised to not-a-number on reading, so the state read did not write back
    /// as read) is damage.
    #[test]
    fn a_last_step_that_is_no_rotation_is_damage() {
        let mut t = Trust::new();
        t.stepped(Some(UnitQuaternion::identity()));
        let mut e = Vec::new();
        t.put(&mut e);
        let w = e.len() - 32;
        for bad in [f64::INFINITY, f64::NAN, 2.0, 0.0] {
            e[w..w + 8].copy_from_slice(&bad.to_le_bytes());
            let read = Trust::read(&mut Decoder { bytes: &e });
            assert!(read.is_err(), "{bad} as the rotation's w was read");
        }
    }
}
