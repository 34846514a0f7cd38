//! The IMU as a motion prior (docs/design.md §1.19), through the command's run loop on the
//! simulator, with the IMU 0.3 m from the LiDAR and turned 90 degrees (configured):
//! - a car shaken by a rough road within its rolling sweeps: with its IMU, as accurate as the
//!   calm drive and never lost; without (its first half), frames lost and 30 times the error;
//! - readings with a hole: the frames in it run on the motion model, named `ImuGap`;
//! - readings in the wrong units: the IMU is set aside after five frames, named;
//! - a hand-held rig's fast turns: with the IMU no frame needs recovery, also when the
//!   readings come as a CSV beside a folder of scans (`slamesh run`); `--imu off` ignores them;
//! - a LiDAR mounted tilted: with its IMU the map is levelled, up is up in every pose, and the
//!   navigation map says gravity gave it.

use crate::common::{scratch, slamesh_run_ok, write_folder_with_imu};
use nalgebra::{Translation3, UnitQuaternion};
use slamesh::eval::odometry::consecutive_errors;
use slamesh::formats::trajectory;
use slamesh::inertial::ImuSummary;
use slamesh::inertial::{AccelUnit, GravityReport, ImuOptions};
use slamesh::run::{run, FrameSource, RunOptions, Sample, Summary};
use slamesh_core::{Capacity, KittiCapacity, Lidar32Capacity, Point, Pose};
use slamesh_sim::town::Carried;
use slamesh_sim::{Drive, ImuModel, Vibration};

/// The IMU's place on the LiDAR: 0.3 m off, turned 90 degrees about z.
fn mount() -> Pose {
    Pose::from_parts(
        Translation3::new(0.3, 0.0, 0.0),
        UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::FRAC_PI_2),
    )
}

/// The drive's and the IMU's seed: `SLAMESH_IMU_SEED` if set (to measure a bound's spread over
/// seeds), else `own`.
fn seed_or(own: u64) -> u64 {
    std::env::var("SLAMESH_IMU_SEED")
        .ok()
        .map(|s| s.parse().expect("SLAMESH_IMU_SEED: a whole number"))
        .unwrap_or(own)
}

/// An IMU at `hz` in its [`mount`].
pub(crate) fn imu(hz: f64) -> ImuModel {
    let mut m = ImuModel::mems(hz, seed_or(7));
    m.lidar_from_imu = mount();
    m
}

/// A run into `out` on two threads with the default preset, the IMU used or not, mounted as
/// [`mount`] says.
pub(crate) fn options(out: &std::path::Path, use_imu: bool) -> RunOptions {
    let mut imu = ImuOptions {
        enabled: use_imu,
        ..ImuOptions::default()
    };
    imu.calibration.lidar_from_imu = mount();
    RunOptions {
        out: out.to_path_buf(),
        config: slamesh::run::config_file::preset("default").unwrap(),
        preset: "default".into(),
        threads: 2,
        imu,
        ..RunOptions::default()
    }
}

/// A run's summary, its statuses and its mean frame-to-frame translation error (m).
pub(crate) fn run_drive<C: Capacity>(
    source: &mut impl FrameSource,
    truth: &[Pose],
    use_imu: bool,
    name: &str,
) -> (Summary, Vec<String>, f64) {
    let out = scratch(&format!("imu-{name}"));
    let opts = options(&out, use_imu);
    let mut statuses = Vec::new();
    let summary = run::<C>(source, &opts, |r| statuses.push(r.status.to_string())).unwrap();
    let estimate = trajectory::read_kitti(&out.join("poses_kitti.txt")).unwrap();
    let truth: Vec<Pose> = truth.iter().map(|p| truth[0].inverse() * p).collect();
    let step = consecutive_errors(&estimate, &truth).mean_translation_m;
    (summary, statuses, step)
}

pub(crate) fn count(statuses: &[String], status: &str) -> usize {
    statuses.iter().filter(|s| *s == status).count()
}

/// The car's first `frames` frames with a rolling sweep.
pub(crate) fn car_frames(frames: usize) -> Drive {
    let mut d = Drive::car(frames, seed_or(1));
    d.sweep_s = Some(0.1);
    d
}

/// The car's first `frames` frames with a rolling sweep, shaken by a rough road, with a
/// 200 Hz IMU.
pub(crate) fn shaken_car(frames: usize) -> Drive {
    car_frames(frames)
        .shaken(Vibration::rough_road())
        .with_imu(imu(200.0))
}

/// The car's first 60 frames with a rolling sweep.
fn car() -> Drive {
    car_frames(60)
}

#[test]
fn a_shaken_sweep_with_its_imu_tracks_as_well_as_a_calm_one() {
    let calm = car();
    let (_, _, still) = run_drive::<KittiCapacity>(&mut calm.clone(), &calm.poses, false, "calm");
    let shaken = car().shaken(Vibration::rough_road()).with_imu(imu(200.0));
    let truth = shaken.poses.clone();
    // Without the IMU on the first half only: its lost frames are slow, and half shows it.
    let half = car_frames(30).shaken(Vibration::rough_road());
    let (_, lost, blind) =
        run_drive::<KittiCapacity>(&mut half.clone(), &half.poses, false, "blind");
    let (s, statuses, seeing) =
        run_drive::<KittiCapacity>(&mut shaken.clone(), &truth, true, "imu");
    println!(
        "mean step error: calm {:.3} cm, shaken without the IMU {:.3} cm ({} frames not \
         converged), with it {:.3} cm",
        still * 100.0,
        blind * 100.0,
        count(&lost, "NotConverged"),
        seeing * 100.0
    );
    // With the IMU the shaken drive tracks within 1.10 times the calm one on the test's seeds
    // (0.307 against 0.279 cm); over seeds 2 to 4 (SLAMESH_IMU_SEED) 1.21, 1.01 and 1.00. The
    // bound sits near today's on the test's seeds (1.15), the 1.3 on any other.
    let ratio = match std::env::var("SLAMESH_IMU_SEED") {
        Ok(_) => 1.3,
        Err(_) => 1.15,
    };
    assert!(seeing <= ratio * still, "{seeing} against {still}");
    assert!(
        blind > 3.0 * still,
        "the shake is hard without the IMU: {blind}"
    );
    assert_eq!(count(&statuses, "Converged"), 59, "{statuses:?}");
    let imu = s
        .stage::<ImuSummary>("imu")
        .expect("the summary says what the IMU did");
    assert_eq!(
        (imu.deskewed_frames, imu.prior_frames, imu.gap_frames),
        (60, 59, 0)
    );
    // 200 Hz over the second before the first frame, the 6 s and the last sweep.
    assert_eq!(imu.readings.taken, 1400);
    assert!(s.health.doubted.is_empty());
}

/// A drive whose IMU's readings `alter` changes on their way to the run, its points with
/// their times or (`untimed`) without, as an untimed folder's scans come.
pub(crate) struct Altered {
    drive: Drive,
    alter: fn(&mut Vec<Sample>),
    timed: bool,
}

impl Altered {
    /// `drive` with its readings changed by `alter`.
    pub(crate) fn new(drive: Drive, alter: fn(&mut Vec<Sample>)) -> Self {
        Altered {
            drive,
            alter,
            timed: true,
        }
    }

    /// `drive` as it is, but for its points' times.
    pub(crate) fn untimed(drive: Drive) -> Self {
        Altered {
            timed: false,
            ..Altered::new(drive, |_| {})
        }
    }
}

impl FrameSource for Altered {
    fn frames(&self) -> usize {
        self.drive.frames()
    }
    fn label(&self, i: usize) -> String {
        self.drive.label(i)
    }
    fn stamp(&self, i: usize) -> f64 {
        self.drive.stamp(i)
    }
    fn read(&mut self, i: usize) -> Result<Vec<Point>, slamesh::io::FileError> {
        self.drive.read(i)
    }
    fn read_timed(
        &mut self,
        i: usize,
    ) -> Result<(Vec<Point>, Option<Vec<f32>>), slamesh::io::FileError> {
        let (points, times) = self.drive.read_timed(i)?;
        Ok((points, times.filter(|_| self.timed)))
    }
    fn samples(&mut self, i: usize) -> Vec<Sample> {
        let mut s = self.drive.samples(i);
        (self.alter)(&mut s);
        s
    }
}

/// Nothing from 2.0 s to 2.5 s.
fn holed(s: &mut Vec<Sample>) {
    s.retain(|s| !(2.0..2.5).contains(&s.stamp()));
}

/// Degrees a second where radians are due.
fn in_degrees(s: &mut [Sample]) {
    for r in s.iter_mut().filter_map(Sample::imu_mut) {
        r.gyro = r.gyro.map(f64::to_degrees);
    }
}

#[test]
fn frames_the_readings_miss_run_on_the_motion_model_and_are_named() {
    let calm = car_frames(30).with_imu(imu(200.0));
    let truth = calm.poses.clone();
    let (s, statuses, step) =
        run_drive::<KittiCapacity>(&mut Altered::new(calm, holed), &truth, true, "holed");
    let gaps: Vec<usize> = s.health.doubted.iter().map(|g| g.frame).collect();
    // Frames 20 to 24 sweep through the hole; frame 25's prior reaches back into it.
    assert_eq!(gaps, [20, 21, 22, 23, 24, 25], "{:?}", s.health.doubted);
    assert!(s
        .health
        .doubted
        .iter()
        .all(|g| g.status == "ImuGap" && g.reason.contains("no IMU reading from")));
    assert_eq!(count(&statuses, "Converged"), 29);
    assert!(step < 0.01, "{step}");
}

#[test]
fn an_imu_whose_rotations_keep_missing_is_set_aside_and_named() {
    let d = shaken_car(20);
    let truth = d.poses.clone();
    let (s, statuses, _) = run_drive::<KittiCapacity>(
        &mut Altered::new(d.clone(), |s| in_degrees(s)),
        &truth,
        true,
        "degrees",
    );
    let imu = s.stage::<ImuSummary>("imu").expect("readings came");
    let why = imu.set_aside.expect("set aside");
    assert!(why.contains("units (gyro_unit)"), "{why}");
    // The check over the first frames says why: the gyro's angles are 57.3 times too large.
    // (Judged on the frames after it was set aside: every frame before was lost.)
    let check = imu.calibration_check.expect("judged by the run's end");
    assert!(check.contains("degrees per second"), "{check}");
    // The frames after it ran on the motion model, to the end.
    assert_eq!(statuses.len(), 20);
    assert!(imu.prior_frames < 10, "{}", imu.prior_frames);
    // Told in `[imu]` (`gyro_unit = "deg/s"`), the same readings serve every frame.
    let out = scratch("imu-degrees-told");
    let mut opts = options(&out, true);
    opts.imu.calibration.gyro_unit_rad_s = 1f64.to_radians();
    let s = run::<KittiCapacity>(&mut Altered::new(d, |s| in_degrees(s)), &opts, |_| {}).unwrap();
    let imu = s.stage::<ImuSummary>("imu").expect("readings came");
    assert!(imu.set_aside.is_none(), "{imu:?}");
    assert_eq!(imu.prior_frames, 19);
}

/// The readings of an IMU turned 15 degrees further about its z than `[imu]` says.
fn turned(s: &mut [Sample]) {
    let q = UnitQuaternion::from_euler_angles(0.0, 0.0, 15f64.to_radians());
    for r in s.iter_mut().filter_map(Sample::imu_mut) {
        r.gyro = (q * nalgebra::Vector3::from(r.gyro)).into();
        r.accel = (q * nalgebra::Vector3::from(r.accel)).into();
    }
}

#[test]
fn an_imu_turned_from_its_configured_place_is_named_with_the_turn() {
    let d = shaken_car(30);
    let truth = d.poses.clone();
    let (s, _, _) =
        run_drive::<KittiCapacity>(&mut Altered::new(d, |s| turned(s)), &truth, true, "turned");
    let check = s
        .stage::<ImuSummary>("imu")
        .and_then(|i| i.calibration_check)
        .expect("judged");
    println!("{check}");
    // Configured at 90 degrees of yaw, the IMU sits at 75.
    let yaw: f64 = check
        .split("rotation_rpy_deg = [")
        .nth(1)
        .and_then(|t| t.split(']').next())
        .and_then(|rpy| rpy.split(", ").nth(2))
        .and_then(|y| y.parse().ok())
        .expect("the turn named");
    assert!((yaw - 75.0).abs() < 2.0, "{check}");
}

/// The hand-held rig's first `frames` scans, with its IMU at 400 Hz.
pub(crate) fn hand_held(frames: usize) -> Drive {
    Drive::carried(frames, Carried::HANDHELD, 1).with_imu(imu(400.0))
}

#[test]
fn with_an_imu_fast_turns_need_no_recovery() {
    let d = hand_held(60);
    let truth = d.poses.clone();
    let (_, without, _) = run_drive::<Lidar32Capacity>(&mut d.clone(), &truth, false, "hand");
    let (_, with, step) = run_drive::<Lidar32Capacity>(&mut d.clone(), &truth, true, "hand-imu");
    println!(
        "recovered: {} without the IMU, {} with it; mean step error {:.2} cm",
        count(&without, "Recovered"),
        count(&with, "Recovered"),
        step * 100.0
    );
    assert!(count(&without, "Recovered") > 0);
    assert_eq!(count(&with, "Converged"), 59, "{with:?}");
    assert!(step < 0.02, "{step}");
}

#[test]
fn the_command_reads_an_imu_csv_beside_a_folder_of_scans() {
    let dir = scratch("imu-csv-folder");
    let d = hand_held(16);
    let scans = write_folder_with_imu(&d, &dir);
    std::fs::write(
        dir.join("imu.toml"),
        "[imu]\ntranslation_m = [0.3, 0.0, 0.0]\nrotation_rpy_deg = [0.0, 0.0, 90.0]\n",
    )
    .unwrap();
    let report = |out: &std::path::Path| -> serde_json::Value {
        let text = std::fs::read_to_string(out.join("report.json")).unwrap();
        serde_json::from_str(&text).unwrap()
    };
    let config = dir.join("imu.toml");
    let (with, without) = (dir.join("with"), dir.join("without"));
    slamesh_run_ok(&scans, &with, &["--config", config.to_str().unwrap()]);
    slamesh_run_ok(
        &scans,
        &without,
        &["--config", config.to_str().unwrap(), "--imu", "off"],
    );
    let (with, without) = (report(&with), report(&without));
    let imu = &with["summary"]["imu"];
    assert_eq!(imu["prior_frames"], 15, "{imu}");
    // 400 Hz over the second before the first frame and the 8 s.
    assert_eq!(imu["readings"]["taken"], 400 + 16 * 200, "{imu}");
    assert!(without["summary"].get("imu").is_none());
    let recovered = |r: &serde_json::Value| {
        r["frames"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|f| f["status"] == "Recovered")
            .count()
    };
    assert_eq!(recovered(&with), 0);
    let frames = with["frames"].as_array().unwrap();
    assert!(
        frames[1..].iter().all(|f| f["imu"]["prior"] == true),
        "{}",
        frames[1]
    );
    assert!(without["frames"][1].get("imu").is_none());
}

/// The angle (degrees) between up as the estimate and as the truth see it from the sensor.
fn up_off_deg(estimate: &Pose, truth: &Pose) -> f64 {
    let z = nalgebra::Vector3::z();
    let seen = |p: &Pose| p.rotation.inverse() * z;
    seen(estimate).angle(&seen(truth)).to_degrees()
}

/// A run of `d` with its IMU used or not (mounted as [`mount`]) and a navigation map: its
/// summary, its trajectory and its `navmap.json`.
fn navmap_run<C: Capacity>(d: &Drive, use_imu: bool, name: &str) -> (Summary, Vec<Pose>, String) {
    let out = scratch(&format!("imu-{name}-{use_imu}"));
    let opts = RunOptions {
        navmap: Some(slamesh::navmap::NavMapOptions::default()),
        ..options(&out, use_imu)
    };
    let s = run::<C>(&mut d.clone(), &opts, |_| {}).unwrap();
    let estimate = trajectory::read_kitti(&out.join("poses_kitti.txt")).unwrap();
    let navmap = std::fs::read_to_string(out.join("navmap.json")).unwrap();
    (s, estimate, navmap)
}

/// `frames` of the car with its LiDAR pitched 4 degrees and rolled 2 (its first scan is not
/// level), and its IMU.
fn tilted_car(frames: usize) -> Drive {
    let tilt = Pose::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_euler_angles(2f64.to_radians(), 4f64.to_radians(), 0.0),
    );
    let mut d = Drive::car(frames, 1);
    d.poses.iter_mut().for_each(|p| *p *= tilt);
    d.with_imu(imu(200.0))
}

#[test]
fn a_tilted_lidar_maps_level_with_its_imu() {
    let d = tilted_car(20);
    let mut ups = Vec::new();
    for use_imu in [true, false] {
        let (s, estimate, navmap) = navmap_run::<KittiCapacity>(&d, use_imu, "level");
        let worst = (estimate.iter().zip(&d.poses))
            .map(|(e, t)| up_off_deg(e, t))
            .fold(0.0, f64::max);
        ups.push((
            worst,
            s.stage::<ImuSummary>("imu").and_then(|i| i.gravity),
            navmap,
        ));
    }
    let [(with, Some(g), navmap), (without, None, plain)] = &ups[..] else {
        panic!("{ups:?}");
    };
    println!("up off by at most {with:.3} degrees with the IMU, {without:.3} without; {g:?}");
    assert!(g.levelled && g.why_not.is_none(), "{g:?}");
    // The first scan's true tilt: the mount's and the road's.
    let z = nalgebra::Vector3::z();
    let tilt_deg = (d.poses[0].rotation * z).angle(&z).to_degrees();
    assert!(
        (g.tilt_deg.unwrap() - tilt_deg).abs() < 0.5,
        "{g:?} {tilt_deg}"
    );
    assert!(*with < 0.5, "{with}");
    assert!(*without > tilt_deg - 0.5, "{without}");
    assert!(navmap.contains("gravity: the IMU"), "{navmap}");
    assert!(plain.contains("the map's z axis"), "{plain}");
}

/// The accelerometer in g, as some sensors' drivers give it (Livox's built-in IMU does).
fn in_g(s: &mut [Sample]) {
    for r in s.iter_mut().filter_map(Sample::imu_mut) {
        r.accel = r.accel.map(|a| a / slamesh_core::imu::GRAVITY_M_S2);
    }
}

#[test]
fn an_accelerometer_in_g_is_told_and_levels_the_map_as_one_in_metres_per_second_squared() {
    // The tilted car of the test above, its accelerometer read in g: told from the still
    // start, the map is levelled as with m/s²; configured, the same without telling.
    let d = tilted_car(8);
    let out = scratch("imu-in-g");
    let level = |source: &mut dyn FnMut(&RunOptions) -> Summary, unit: AccelUnit| {
        let mut opts = options(&out, true);
        opts.imu.accel_unit = unit;
        let imu = source(&opts)
            .stage::<ImuSummary>("imu")
            .expect("readings came");
        (
            imu.gravity.expect("up was looked for"),
            imu.accelerometer_unit,
        )
    };
    let mut plain = |o: &RunOptions| run::<KittiCapacity>(&mut d.clone(), o, |_| {}).unwrap();
    let mut altered = |o: &RunOptions| {
        run::<KittiCapacity>(&mut Altered::new(d.clone(), |s| in_g(s)), o, |_| {}).unwrap()
    };
    let (in_ms2, said_ms2) = level(&mut plain, AccelUnit::Auto);
    let (told, said_told) = level(&mut altered, AccelUnit::Auto);
    let (configured, said_configured) = level(&mut altered, AccelUnit::G);
    println!("{said_ms2:?} {said_told:?} {said_configured:?}\n{in_ms2:?}\n{told:?}");
    assert_eq!(said_ms2.as_deref(), Some("m/s²"));
    assert!(said_told
        .as_deref()
        .is_some_and(|u| u.starts_with("g (told")));
    assert_eq!(said_configured.as_deref(), Some("g (configured)"));
    for g in [&in_ms2, &told, &configured] {
        assert!(g.levelled, "{g:?}");
    }
    // The same up to the readings' rounding.
    for g in [&told, &configured] {
        assert!(
            (g.tilt_deg.unwrap() - in_ms2.tilt_deg.unwrap()).abs() < 1e-6,
            "{g:?}"
        );
        assert!(
            (g.magnitude_m_s2 - in_ms2.magnitude_m_s2).abs() < 1e-6,
            "{g:?}"
        );
    }
    // Read as m/s², gravity would be 1.0 long: not levelled, named.
    let (wrong, _) = level(&mut altered, AccelUnit::MetresPerSecondSquared);
    let why = wrong.why_not.clone().unwrap_or_default();
    assert!(
        !wrong.levelled && why.contains("1.01 m/s², not gravity"),
        "{wrong:?}"
    );
    // A start too unsteady to level: up over the first seconds of motion, as in m/s².
    let d = hand_held(12);
    let mut plain = |o: &RunOptions| run::<Lidar32Capacity>(&mut d.clone(), o, |_| {}).unwrap();
    let mut altered = |o: &RunOptions| {
        run::<Lidar32Capacity>(&mut Altered::new(d.clone(), |s| in_g(s)), o, |_| {}).unwrap()
    };
    let up = |g: GravityReport| nalgebra::Vector3::from(g.moving.unwrap().up.unwrap());
    let (moving_ms2, _) = level(&mut plain, AccelUnit::Auto);
    let (moving_g, said) = level(&mut altered, AccelUnit::Auto);
    assert!(said.is_some_and(|u| u.starts_with("g (told")));
    assert!(up(moving_g).angle(&up(moving_ms2)) < 1e-6);
}

#[test]
fn a_moving_start_finds_up_over_its_first_seconds() {
    // The hand-held rig moves and turns from its first scan: too unsteady to level the map,
    // up is read over the first seconds of motion instead, in the map's (the first scan's)
    // frame, and handed to the navigation map.
    let d = hand_held(16);
    let (s, _, navmap) = navmap_run::<Lidar32Capacity>(&d, true, "moving-up");
    let g = s
        .stage::<ImuSummary>("imu")
        .and_then(|i| i.gravity)
        .expect("up was looked for");
    println!("{g:?}");
    assert!(!g.levelled, "{g:?}");
    let moving = g.moving.expect("read over the first seconds");
    let up = nalgebra::Vector3::from(moving.up.expect("found"));
    // The truth's up in the first scan's frame.
    let truth = d.poses[0].rotation.inverse() * nalgebra::Vector3::z();
    let off = up.angle(&truth).to_degrees();
    println!("up from motion {off:.3} degrees from the truth's");
    assert!(off < 1.0, "{off}");
    assert!(navmap.contains("of motion"), "{navmap}");
}
