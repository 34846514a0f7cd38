//! The IMU in a run, a room of its own below `run` (docs/design.md §1.19): the readings a
//! source gives with each frame go into the core's [`ImuTrack`]; a frame whose time they
//! cover is deskewed with the gyro's rotation at each point's time and registered from the
//! gyro's rotation since the last used frame; the registered rotations correct the gyro bias.
//!
//! It owns the track, the reference times of the last two used frames (where their poses
//! are) and the counts for the report. It guarantees that a frame the readings do not cover
//! (a gap, no readings yet) is run exactly as without an IMU, and named; that a reading it
//! refuses is named (the first ten of each frame's, then counted); that an IMU whose
//! rotations keep missing the registered ones is set aside, named, and comes back when they
//! agree again, and readings that are no IMU's (too slow, too still) are ignored, named
//! ([`trust`]); and that without readings nothing it does changes a run's bytes.

pub mod calibration;
pub mod moving_up;
pub mod report;
pub mod stage;
pub mod state;
pub mod trust;

use crate::sources::Sample;
use calibration::{CalibrationCheck, Verdict};
use moving_up::FirstSeconds;
use nalgebra::{UnitQuaternion, Vector3};
use report::{gap_words, not_level};
pub use report::{GravityReport, ImuCountsReport, ImuFrame, ImuSummary};
use slamesh_core::deskew::{self, DeskewError, Deskewed};
use slamesh_core::gravity::Gravity;
use slamesh_core::imu::{ForceMean, ImuCalibration, ImuGap, ImuTrack, GRAVITY_M_S2};
use slamesh_core::{Capacity, Point, Pose, RegistrationStatus};
use trust::{Trust, DISTRUST_AFTER};

/// What the run does with an IMU's readings (`--imu`, `--deskew`, the configuration's `imu`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuOptions {
    /// Whether readings are used at all (`--imu off`: no).
    pub enabled: bool,
    /// Where the IMU sits on the LiDAR and its clock.
    pub calibration: ImuCalibration,
    /// Whether the IMU's place on the LiDAR was given (`[imu] translation_m` or
    /// `rotation_rpy_deg`); the ROS 2 node otherwise takes it from `/tf_static`.
    pub placed: bool,
    /// Share of the registration's disagreement with the gyro taken into the bias each frame.
    pub bias_gain: f64,
    /// A disagreement above this (degrees over a frame) is not taken into the bias.
    pub bias_max_deg: f64,
    /// The accelerometer's unit (`[imu] accel_unit`); `calibration.accel_unit_m_s2` is set
    /// from it when the run starts.
    pub accel_unit: AccelUnit,
}

impl Default for ImuOptions {
    fn default() -> Self {
        Self {
            enabled: true,
            calibration: ImuCalibration::default(),
            placed: false,
            bias_gain: 0.2,
            bias_max_deg: 1.0,
            accel_unit: AccelUnit::Auto,
        }
    }
}

/// The unit an accelerometer reads in. `sensor_msgs/Imu` and EuRoC's CSV say m/s², but some
/// sensors' drivers give g (Livox's built-in IMU does): read in m/s², gravity would be 1.0
/// and the map would never be levelled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AccelUnit {
    /// Told from the first readings' mean ([`slamesh_core::gravity::reads_in_g`]).
    Auto,
    /// Metres per second squared.
    MetresPerSecondSquared,
    /// Standard gravities.
    G,
}

impl AccelUnit {
    /// The unit's size in m/s², when it is not to be told from the readings.
    pub fn m_s2(self) -> Option<f64> {
        match self {
            AccelUnit::Auto => None,
            AccelUnit::MetresPerSecondSquared => Some(1.0),
            AccelUnit::G => Some(GRAVITY_M_S2),
        }
    }
}

/// The velocity (m/s) at the last of `history`'s two poses (taken at `t_before` and `t_last`),
/// in that pose's frame: the world's step between them, over their time. A body that shakes
/// keeps moving where the world says, whatever its attitude at the one before. Zero while
/// either pose is unknown.
fn body_velocity(
    history: (Option<Pose>, Option<Pose>),
    t_before: Option<f64>,
    t_last: f64,
) -> Vector3<f64> {
    match (history, t_before) {
        ((Some(b), Some(l)), Some(t_b)) if t_last > t_b => {
            l.rotation.inverse() * (l.translation.vector - b.translation.vector) / (t_last - t_b)
        }
        _ => Vector3::zeros(),
    }
}

/// The IMU's part of a run.
#[derive(Debug)]
pub struct Inertial {
    options: ImuOptions,
    track: ImuTrack,
    /// Reference times (the LiDAR's clock) of the poses the motion model holds: the one
    /// before the last, and the last.
    refs: (Option<f64>, Option<f64>),
    /// Whether any reading came: until one does, the run is as without an IMU.
    seen: bool,
    /// Frames deskewed with the gyro, registered from its prior, and not covered.
    frames: (usize, usize, usize),
    /// Whether the readings are trusted now ([`trust`]).
    trust: Trust,
    /// The gyro's and the registered rotations of the current run of misses.
    misses: CalibrationCheck,
    /// What the accelerometer said of up at the map's first scan.
    gravity: Option<GravityReport>,
    /// The gyro's rotations against the registered ones over the first seconds.
    check: CalibrationCheck,
    /// Up over the first seconds of motion (a map not levelled); its answer goes into
    /// `gravity`.
    moving: FirstSeconds,
    /// The calibration check's verdict, once given.
    checked: Option<Verdict>,
    /// The accelerometer's unit, once configured or told ([`Inertial::tell_unit`]), in words.
    unit: Option<String>,
    /// After a resume ([`Inertial::restore`]): the newest reading the checkpoint held. A
    /// source resumed mid-way may hand the readings before it again; they were dealt with.
    resumed_at: Option<f64>,
}

impl Inertial {
    /// Ready for readings, holding at most the capacity's [`Capacity::IMU_SAMPLES`].
    pub fn new<C: Capacity>(options: ImuOptions) -> Self {
        let mut calibration = options.calibration;
        if let Some(unit) = options.accel_unit.m_s2() {
            calibration.accel_unit_m_s2 = unit;
        }
        Self {
            track: ImuTrack::new(C::IMU_SAMPLES, calibration),
            options,
            refs: (None, None),
            seen: false,
            frames: (0, 0, 0),
            trust: Trust::new(),
            misses: CalibrationCheck::new(options.calibration.lidar_from_imu.rotation),
            gravity: None,
            check: CalibrationCheck::new(options.calibration.lidar_from_imu.rotation),
            moving: FirstSeconds::default(),
            checked: None,
            unit: match options.accel_unit {
                AccelUnit::Auto => None,
                AccelUnit::MetresPerSecondSquared => Some("m/s² (configured)".into()),
                AccelUnit::G => Some("g (configured)".into()),
            },
            resumed_at: None,
        }
    }

    /// Counts a frame's dealings into the run's.
    pub fn count(&mut self, f: &ImuFrame) {
        self.frames.0 += usize::from(f.deskewed);
        self.frames.1 += usize::from(f.prior);
        self.frames.2 += usize::from(f.gap.is_some());
    }

    /// The run's summary, if readings came.
    pub fn summary(&self) -> Option<ImuSummary> {
        let c = self.track.counts();
        self.seen.then(|| ImuSummary {
            readings: ImuCountsReport {
                taken: c.taken,
                not_finite: c.not_finite,
                out_of_order: c.out_of_order,
                duplicate: c.duplicate,
                saturated: c.saturated,
                forgotten_early: c.forgotten_early,
            },
            deskewed_frames: self.frames.0,
            prior_frames: self.frames.1,
            gap_frames: self.frames.2,
            gyro_bias: self.track.bias().into(),
            set_aside: self.trust.set_aside().map(String::from),
            returned: self.trust.returned(),
            registrations_doubted: self.trust.doubted(),
            ignored: self.trust.ignored().map(String::from),
            gravity: self.gravity.clone(),
            calibration_check: (self.checked.clone())
                .or_else(|| self.check.pending())
                .map(|v| v.text),
            accelerometer_unit: self.unit.clone(),
        })
    }

    /// Whether the run uses readings now: enabled, some came, at an IMU's rate, and trusted
    /// ([`Trust::trusted`]).
    pub fn active(&self) -> bool {
        self.options.enabled && self.seen && self.trust.trusted()
    }

    /// Takes the readings that came with frame `frame` of `file`; names the refused (the first
    /// ten a frame) and the saturated (the first ten of the run).
    pub fn take(&mut self, samples: &[Sample], file: &str, frame: usize) {
        if !self.options.enabled {
            return;
        }
        let mut named = 0;
        let offset = self.track.calibration().time_offset_s;
        for r in samples.iter().filter_map(Sample::imu) {
            if self.resumed_at.is_some_and(|t| r.stamp + offset <= t) {
                continue;
            }
            self.resumed_at = None;
            self.seen = true;
            let saturated = self.track.counts().saturated;
            let mutated;
            let r = if crate::mutants::on("gyro-scale") {
                mutated = crate::sources::ImuReading {
                    gyro: r.gyro.map(|g| g * 1.1),
                    ..*r
                };
                &mutated
            } else {
                r
            };
            if let Err(e) = self.track.push(r) {
                named += 1;
                if named <= 10 {
                    log::warn!(
                        "{file}: frame {frame}: IMU reading at {} s refused: {e:?}",
                        r.stamp
                    );
                }
            } else if self.track.counts().saturated > saturated && saturated < 10 {
                log::warn!(
                    "{file}: frame {frame}: IMU reading at {} s at the sensor's limit \
                     (gyro {:?} rad/s, accelerometer {:?} m/s²): saturated, kept",
                    r.stamp,
                    r.gyro,
                    r.accel
                );
            }
        }
        let held = self.track.held().iter().map(|r| r.parts().0);
        self.trust.check_rate(held);
    }

    /// Deskews `points` (times `times` after `stamp`) with the gyro's rotation at each point's
    /// time and the motion model's last velocity (`history`: its last two poses), turned into
    /// the sweep's middle by the gyro: the IMU's deskew.
    pub fn deskew(
        &self,
        points: &mut [Point],
        times: &[f32],
        stamp: f64,
        history: (Option<Pose>, Option<Pose>),
    ) -> Result<Deskewed, DeskewError> {
        let velocity = self.refs.1.map(|t_last| {
            let v = body_velocity(history, self.refs.0, t_last);
            move |mid: f64| -> Result<Vector3<f64>, ImuGap> {
                Ok(self.track.rotation(t_last, mid)?.inverse() * v)
            }
        });
        let mut at_mid = None;
        deskew::deskew_by(points, times, |t, mid| {
            let v = match (&velocity, at_mid) {
                (_, Some(v)) => v,
                (Some(turned), None) => {
                    *at_mid.insert(turned(stamp + mid).map_err(DeskewError::Imu)?)
                }
                (None, None) => *at_mid.insert(Vector3::zeros()),
            };
            self.relative(stamp + mid, stamp + t, &v)
                .map_err(DeskewError::Imu)
        })
    }

    /// The sensor's pose at `t` in its frame at `from` (the LiDAR's clock): the gyro's
    /// rotation, and `velocity` (m/s, in the frame at `from`) for the translation.
    fn relative(&self, from: f64, t: f64, velocity: &Vector3<f64>) -> Result<Pose, ImuGap> {
        let turn = self.track.rotation(from, t)?;
        Ok(Pose::from_parts((velocity * (t - from)).into(), turn))
    }

    /// `pose`, the pose at `from`, moved to `to` (a deskewed sweep's pose to its stamp's): the
    /// gyro's rotation, and the velocity of the motion model's last step, which ends at `from`
    /// (`history`: the poses before and at `from`). `None` where the readings do not cover it.
    pub fn moved(
        &self,
        pose: &Pose,
        from: f64,
        to: f64,
        history: (Option<Pose>, Option<Pose>),
    ) -> Option<Pose> {
        let velocity = body_velocity(history, self.refs.1, from);
        Some(pose * self.relative(from, to, &velocity).ok()?)
    }

    /// Where the map's first scan goes, its pose at `t` (its clock): level, its z axis turned
    /// up, when the readings held say which way is up ([`Gravity`]); `None` otherwise (the map's
    /// z is the first scan's). Named in the log either way, and in the summary.
    pub fn level(&mut self, t: f64, file: &str, frame: usize) -> Option<Pose> {
        if let (None, Ok(f)) = (&self.unit, self.force_at_start(t)) {
            self.tell_unit(&f, &format!("{file}: frame {frame}: "));
        }
        let judged = match self.force_at_start(t) {
            Ok(f) => Gravity::judge(&f).map_err(|e| (Some(f), not_level(e))),
            Err(gap) => Err((None, gap_words(gap))),
        };
        let level = judged.as_ref().ok().map(Gravity::level);
        let report = GravityReport::of(judged);
        match &report.why_not {
            None => log::info!(
                "{file}: frame {frame}: IMU: up from {} readings over {:.2} s (spread {:.3} \
                 m/s²): the map is levelled, the first scan tilted {:.2} degrees",
                report.readings,
                report.seconds,
                report.spread_m_s2,
                report.tilt_deg.unwrap_or(0.0)
            ),
            Some(why) => log::warn!(
                "{file}: frame {frame}: IMU: the map is not levelled ({why}); up is the first \
                 scan's z axis"
            ),
        }
        self.gravity = Some(report);
        level.map(|q| Pose::from_parts(Vector3::zeros().into(), q))
    }

    /// The mean force at the map's first scan (stamp `t`): over the readings before it, or,
    /// when they span less than gravity needs ([`slamesh_core::gravity::MIN_SECONDS`]: the
    /// IMU started with the scan), over every reading held, those after the stamp too.
    fn force_at_start(&self, t: f64) -> Result<ForceMean, ImuGap> {
        let before = self.track.mean_force(f64::NEG_INFINITY, t);
        match before {
            Ok(f) if f.seconds >= slamesh_core::gravity::MIN_SECONDS => Ok(f),
            _ => (self.track)
                .mean_force_over(f64::NEG_INFINITY, f64::INFINITY, t)
                .or(before),
        }
    }

    /// Up for a navigation map and what gave it, when the IMU gave it
    /// ([`GravityReport::navmap_up`]).
    pub fn navmap_up(&self) -> Option<(Vector3<f64>, String)> {
        self.gravity.as_ref()?.navmap_up()
    }

    /// Where the sensor is at `t` (its clock): the last pose turned by the gyro's rotation
    /// since, moved at the last step's velocity (the world's last step in the last pose's
    /// frame; none while only one pose is known). `None` before any pose.
    pub fn prior(
        &self,
        history: (Option<Pose>, Option<Pose>),
        t: f64,
    ) -> Option<Result<Pose, ImuGap>> {
        let (before, last) = history;
        let (last, t_last) = (last?, self.refs.1?);
        let turn = match self.track.rotation(t_last, t) {
            Ok(q) => q,
            Err(e) => return Some(Err(e)),
        };
        let step = body_velocity((before, Some(last)), self.refs.0, t_last) * (t - t_last);
        Some(Ok(last * Pose::from_parts(step.into(), turn)))
    }

    /// A frame's pose was taken at time `t` (the motion model now ends with it; `from_prior`:
    /// registered from the gyro's prior): its registered rotation since the last corrects the
    /// bias when it is close, and judges the gyro ([`trust`]); readings no rotation needs are
    /// forgotten.
    pub fn used(
        &mut self,
        t: f64,
        status: RegistrationStatus,
        history: (Option<Pose>, Option<Pose>),
        from_prior: bool,
    ) {
        use RegistrationStatus::{Converged, NotConverged, Recovered};
        let converged = matches!(status, Converged | Recovered);
        let counts = self.trust.counts(converged);
        if let ((Some(before), Some(last)), Some(t_before)) = (history, self.refs.1) {
            let registered = (before.inverse() * last).rotation;
            self.read_up((&before, t_before), (&last, t), converged);
            // The gyro's rotation since the last frame, once, for the check (also once the IMU
            // is set aside: the motion model's frames tell why) and the bias (a frame the
            // readings do not cover teaches neither).
            let gyro = (converged && self.seen)
                .then(|| self.track.rotation(t_before, t).ok())
                .flatten();
            if let Some(gyro) = gyro.filter(|_| self.check.open()) {
                let verdict = self.check.add(t, &gyro, &registered);
                self.note_check(verdict);
            }
            self.judge_gyro(gyro, &registered, (t_before, t), counts);
            if status == NotConverged && from_prior {
                self.lost_from_prior(t_before, t);
            }
            if converged {
                self.trust.stepped(Some(registered));
            }
        }
        self.refs = (self.refs.1, Some(t));
        self.track.forget_before(t);
    }

    /// A converged frame's `gyro` rotation against its `registered` one over `(from, to)`:
    /// the still check; then, trusted, the bias and (a counted frame) the judge; set aside,
    /// whether it matches again.
    fn judge_gyro(
        &mut self,
        gyro: Option<UnitQuaternion<f64>>,
        registered: &UnitQuaternion<f64>,
        (from, to): (f64, f64),
        counts: bool,
    ) {
        let Some(gyro) = gyro else { return };
        if self.options.enabled {
            let deg = |q: &UnitQuaternion<f64>| q.angle().to_degrees();
            self.trust.check_turning(deg(registered), deg(&gyro));
        }
        let limit = self.options.bias_max_deg;
        if self.active() {
            let o = &self.options;
            let (gain, max) = (o.bias_gain, o.bias_max_deg.to_radians());
            let off = (self.track).correct_bias(&gyro, to - from, registered, gain, max);
            if counts {
                self.judge(off.to_degrees(), to - from, Some((to, gyro, *registered)));
            }
        } else if counts && self.options.enabled {
            let off = registered.angle_to(&gyro).to_degrees();
            self.trust.watch(off, limit, "");
        }
    }

    /// A registration lost from the gyro's prior over `(from, to)`: the gyro's fault, counted
    /// as a miss, only when its rotation was far from the last registered step's.
    fn lost_from_prior(&mut self, from: f64, to: f64) {
        let limit = self.options.bias_max_deg;
        let surprised =
            (self.track.rotation(from, to).ok()).is_some_and(|g| self.trust.surprised(&g, limit));
        if surprised && self.active() {
            self.judge(f64::INFINITY, to - from, None);
        }
    }

    /// Takes the interval between two registered frames into the moving body's up, when the
    /// map was not levelled; logs the answer when it comes.
    fn read_up(&mut self, from: (&Pose, f64), to: (&Pose, f64), registered: bool) {
        let not_levelled = self.gravity.as_ref().is_some_and(|g| !g.levelled);
        if !(self.active() && not_levelled && self.moving.open()) {
            return;
        }
        // Up from motion weighs the force against the registered positions' acceleration:
        // not before the readings' unit is known (a gap is named below).
        if let (None, Ok(f)) = (&self.unit, self.track.mean_force(from.1, to.1)) {
            if !self.tell_unit(&f, "") {
                return;
            }
        }
        let force = (self.track.mean_force(from.1, to.1)).map_err(gap_words);
        let Some(m) = self.moving.add(from, to, registered, force) else {
            return;
        };
        match (&m.up, &m.why_not) {
            (Some(_), _) => log::info!(
                "IMU: up from the first {:.1} s of motion: the map's z axis is {:.2} degrees \
                 from it",
                m.seconds,
                m.z_off_deg.unwrap_or(0.0)
            ),
            (None, why) => log::warn!(
                "IMU: no up from the first seconds of motion either ({}); up is the map's z",
                why.as_deref().unwrap_or("")
            ),
        }
        if let Some(g) = &mut self.gravity {
            g.moving = Some(m);
        }
    }

    /// Tells the accelerometer's unit from `force`, the readings' mean over a stretch, while
    /// it is not known ([`AccelUnit::Auto`]): in g, the readings held and to come are taken as
    /// such, named in the log (`at` begins its line) and the summary. False while the
    /// stretch is too short to tell.
    fn tell_unit(&mut self, force: &ForceMean, at: &str) -> bool {
        let Some(in_g) = slamesh_core::gravity::reads_in_g(force) else {
            return false;
        };
        let size = force.mean.norm();
        if in_g {
            self.track.set_accel_unit(GRAVITY_M_S2);
            log::warn!(
                "{at}IMU: the accelerometer's mean over {:.2} s is {size:.2} long: its readings \
                 are in g, not m/s², and are taken as such ([imu] accel_unit = \"g\" says so)",
                force.seconds
            );
        }
        self.unit = Some(match in_g {
            true => format!("g (told from the readings: their mean {size:.2} long)"),
            false => "m/s²".into(),
        });
        true
    }

    /// Keeps and logs the calibration check's verdict, when one came.
    fn note_check(&mut self, verdict: Option<Verdict>) {
        let Some(v) = verdict else { return };
        if v.wrong {
            log::warn!("IMU calibration: {}", v.text);
        } else {
            log::info!("IMU calibration: {}", v.text);
        }
        self.checked = Some(v);
    }

    /// A counted frame whose rotation the gyro missed by `off_deg` (over `dt` s; `pair`, its
    /// end's time, the gyro's and the registered rotation), or a frame lost from its prior
    /// (infinitely, no pair): [`DISTRUST_AFTER`] in a row, and the misses the gyro's
    /// ([`trust`]), and the IMU is set aside, named: its axes, clock or units are not the
    /// LiDAR's (a wrong `[imu]`, degrees for radians).
    fn judge(
        &mut self,
        off_deg: f64,
        dt: f64,
        pair: Option<(f64, UnitQuaternion<f64>, UnitQuaternion<f64>)>,
    ) {
        let configured = self.options.calibration.lidar_from_imu.rotation;
        if off_deg > self.options.bias_max_deg {
            if let Some((t, gyro, registered)) = pair {
                self.misses.add(t, &gyro, &registered);
            }
        } else {
            self.misses = CalibrationCheck::new(configured);
        }
        if !self.trust.judge(off_deg, self.options.bias_max_deg) {
            return;
        }
        let blamed =
            std::mem::replace(&mut self.misses, CalibrationCheck::new(configured)).blames();
        if blamed.is_none() && !self.trust.lost_in_run() {
            self.trust
                .doubt("the misses' scale within 0.5 to 2 times the registered", "");
            return;
        }
        let verdict = self.check.take();
        self.note_check(verdict);
        let why = format!(
            "the gyro's rotation missed the registered one by more than {:.1} degrees on {} \
             frames in a row ({off_deg:.1} degrees over {dt:.3} s, the last): its place or \
             clock in [imu] (rotation_rpy_deg, time_offset_s) or its units (gyro_unit) are \
             not right; the IMU is set aside, the motion model carries on until the gyro \
             matches the registrations again",
            self.options.bias_max_deg, DISTRUST_AFTER
        );
        let why = match (blamed, &self.checked) {
            (Some(b), _) => format!("{why} ({b})"),
            (None, Some(v)) if v.wrong => format!("{why} ({})", v.text),
            _ => why,
        };
        self.trust.set_aside_for(why);
    }
}
