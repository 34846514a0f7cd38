//! `slamesh run` (estimate poses, build the mesh) and `slamesh mesh` (build it at given poses).

use crate::cli::error::CliError;
use crate::cli::input::{InputArgs, SweepArg};
use crate::cli::notices::FrameNotices;
use crate::cli::progress;
use crate::cli::settings::{Profile, WindowFlags};
use crate::cli::sweep_trial;
use crate::cli::terminal::{frame_messages, print_summary};
use crate::formats::kitti;
use crate::formats::trajectory;
use crate::formats::trajectory::Trajectory;
use crate::inertial::ImuOptions;
use crate::io::FileError;
use crate::loop_closure::settings::LoopSettings;
use crate::outputs::mesh_spool::{MeshColour, MeshFormat};
use crate::run::capacity::{self, ClassId};
use crate::run::config_file::Settings;
use crate::run::session::{Deskew, InitialPose};
use crate::run::sink::FnSink;
use crate::run::{run_to, FrameEvent, FrameSource, Input, RunOptions, Sinks, Summary};
use crate::sources::scans::ScanFolder;
use clap::Args;
use slamesh_core::clearing::ClearingConfig;
use std::path::{Path, PathBuf};

/// `slamesh run`'s arguments (and most of `slamesh mesh`'s).
#[derive(Args, Debug)]
pub struct RunArgs {
    /// The input and how to read it.
    #[command(flatten)]
    pub source: InputArgs,
    /// Output folder.
    #[arg(long)]
    pub out: PathBuf,
    /// Where the parameters come from (`--preset`, `--config`).
    #[command(flatten)]
    pub profile: Profile,
    /// Reconstruction threads (1: serial; 0: one per core).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Also write mesh.obj.
    #[arg(long)]
    pub obj: bool,
    /// Colour mesh.ply's vertices (red, green, blue) by height or by variance.
    #[arg(long, value_enum, default_value_t = ColourFlag::None)]
    pub colour: ColourFlag,
    /// The sliding window's flags.
    #[command(flatten)]
    pub window: WindowFlags,
    /// Save a checkpoint (the map and the run so far, `checkpoint.bin` in the output folder)
    /// after every N frames, so that a killed run can be resumed.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..))]
    pub checkpoint_every: Option<u32>,
    /// Continue a killed run from the checkpoint in its output folder (same input and
    /// settings); it loses at most the frames after the last checkpoint.
    #[arg(long)]
    pub resume: bool,
    /// Exit with an error, listing them, when any frame was not registered normally
    /// (skipped, degenerate, too few matches, solver failure); the outputs are written all
    /// the same.
    #[arg(long)]
    pub strict: bool,
    /// Deskew scans whose points carry times (recordings with a `t`, `time`, `timestamp` or
    /// `offset_time` field): auto with the IMU's rotations when its readings cover the sweep,
    /// otherwise with the motion between the last two frames.
    #[arg(long, value_enum, default_value_t = DeskewFlag::Auto)]
    pub deskew: DeskewFlag,
    /// Do not draw topview.png (the mesh from above with the path; 7 MB while it is drawn).
    #[arg(long)]
    pub no_picture: bool,
    /// Also write a navigation map for --robot: Nav2's map.yaml + map.pgm, the elevation
    /// grids (elevation.asc, elevation_variance.asc), the ground's traversability
    /// (navmesh.ply, and on mesh.ply's vertices) and navmap.json; with --view or --record,
    /// the grid near the sensor on /map as the run goes.
    #[arg(long)]
    pub navmap: bool,
    /// The robot and cell size of --navmap.
    #[command(flatten)]
    pub robot: crate::cli::navmap::RobotArgs,
    /// The capacity class: how many points a scan may keep within range, and how large the
    /// map may grow (tiny: 2 048 points, 0.34 MB; 16: 36 000, 36.1 MB; 32: 72 000, 72.2 MB;
    /// 64: 140 000, 139.2 MB). auto takes the smallest that holds the points within range of
    /// the largest of the first five scans with a quarter to spare.
    #[arg(long, value_enum, default_value_t = CapacityFlag::Auto)]
    pub capacity: CapacityFlag,
    /// Start from a saved map (written by --save-map): map on from it, in its frame (with
    /// `localize`: localize in it). Its configuration is used unless --preset or --config
    /// says otherwise (the cell size must be the map's).
    #[arg(long, value_name = "FILE")]
    pub map: Option<PathBuf>,
    /// Where the sensor starts in the map: "x y z yaw_deg" or a TUM line "t x y z qx qy qz
    /// qw" (tried first by the search for the first pose, so a wrong one costs a search), or
    /// "end": where the map's path ended, moving as it last moved (a session continuing the
    /// one that saved the map; no search). Without it, a run from a map searches the map for
    /// the first frame's pose (and, until one is found, for each next frame's).
    #[arg(long, value_name = "POSE", requires = "map", value_parser = parse_initial_pose)]
    pub initial_pose: Option<InitialPose>,
    /// Save the whole map to FILE at the end (cells a window evicted included), to localize
    /// in later or map on from (`--map`); with `--navmap`, the floor the scans saw beside it
    /// (FILE with the extension `.floor`), which `slamesh navmap FILE` reads.
    #[arg(long, value_name = "FILE")]
    pub save_map: Option<PathBuf>,
    /// Close loops: when the sensor comes back to where it has been, correct the trajectory
    /// and rebuild the map so that the revisited place is one surface (a thread of its own;
    /// each scan is kept on disk in the output folder until the end, about 85 KB a frame).
    /// On by default, where a run can close loops (from a saved map, against its path too;
    /// under a memory cap when the cap holds it beside the map): not in a fixed map (localize
    /// without --update) or when resuming (then off, and the log says why).
    #[arg(long, value_enum)]
    pub loop_closure: Option<OnOff>,
    /// Take what moves out of the map as the run goes (cars that drove past, people who
    /// walked by, parked cars that left): map surfaces the scans' rays see through, frame
    /// after frame, are hidden from the mesh and the navigation map.
    #[arg(long, value_enum, value_name = "ON|OFF")]
    pub dynamic: Option<OnOff>,
    /// Serve a live view for the Foxglove app on ADDR (default 127.0.0.1:8765, this machine
    /// only; reach it from a laptop through an SSH tunnel). It only publishes. Needs a build
    /// with the feature `view` (`cargo install --path std-adapters --features view`).
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = VIEW_ADDRESS)]
    pub view: Option<String>,
    /// Record the view's channels to slam.mcap in the output folder (opens in the Foxglove
    /// app). Needs a build with the feature `view`, as `--view` does.
    #[arg(long)]
    pub record: bool,
}

/// The address `--view` serves on when none is given: this machine only.
const VIEW_ADDRESS: &str = "127.0.0.1:8765";

/// A feature turned on or off.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum OnOff {
    /// On.
    On,
    /// Off.
    Off,
}

/// `--deskew`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum DeskewFlag {
    /// Whenever the points carry times: with the IMU when it covers the sweep, otherwise with
    /// the motion.
    Auto,
    /// With the IMU's rotations (the motion where its readings do not cover the sweep).
    Imu,
    /// With the motion between the last two frames, even with an IMU.
    Motion,
    /// Never.
    Off,
}

/// `--colour`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColourFlag {
    /// No colour.
    None,
    /// Blue (lowest) to red (highest).
    Height,
    /// Blue (certain) to red (the variance at which triangles are hidden).
    Variance,
}

/// `--capacity`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum CapacityFlag {
    /// The smallest class for the first scan.
    Auto,
    /// `SmallCapacity`.
    Tiny,
    /// `Lidar16Capacity`.
    #[value(name = "16")]
    L16,
    /// `Lidar32Capacity`.
    #[value(name = "32")]
    L32,
    /// `KittiCapacity`.
    #[value(name = "64")]
    L64,
}

impl CapacityFlag {
    /// Runs `source` to its end in the class named, or (`auto`) the one its first scans need.
    pub fn run(
        self,
        source: &mut impl FrameSource,
        opts: &RunOptions,
        sinks: Sinks<'_>,
    ) -> Result<Summary, CliError> {
        let class = self
            .class()
            .unwrap_or_else(|| capacity::choose(source, opts).id);
        Ok(crate::with_capacity!(class, C => run_to::<C>(source, opts, sinks))?)
    }

    /// The class named, or `None` for `auto`.
    pub fn class(self) -> Option<ClassId> {
        match self {
            CapacityFlag::Auto => None,
            CapacityFlag::Tiny => Some(ClassId::Tiny),
            CapacityFlag::L16 => Some(ClassId::L16),
            CapacityFlag::L32 => Some(ClassId::L32),
            CapacityFlag::L64 => Some(ClassId::L64),
        }
    }
}

/// `slamesh mesh`'s arguments.
#[derive(Args, Debug)]
pub struct MeshArgs {
    /// What `run` takes.
    #[command(flatten)]
    pub run: RunArgs,
    /// LiDAR poses, one per frame (KITTI or TUM format).
    #[arg(long)]
    pub poses: PathBuf,
    /// KITTI calib.txt: the poses are camera poses (KITTI poses.txt); turn them into
    /// LiDAR poses with its Tr.
    #[arg(long)]
    pub calib: Option<PathBuf>,
}

/// `slamesh localize`'s arguments.
#[derive(Args, Debug)]
pub struct LocalizeArgs {
    /// What `run` takes.
    #[command(flatten)]
    pub run: RunArgs,
    /// Keep fusing the scans into the map (mapping on); without it the map is fixed.
    #[arg(long)]
    pub update: bool,
}

/// Localizes in a saved map (`--map`, required): registration against it without updating
/// it (unless `--update`), the same outputs as `run`.
pub fn localize(args: &LocalizeArgs, quiet: bool) -> Result<(), CliError> {
    if args.run.loop_closure == Some(OnOff::On) && !args.update {
        return Err(not_for(
            "--loop-closure",
            "localize without --update",
            "the map is fixed (with --update, or run --map FILE, it maps on and closes loops)",
        ));
    }
    // `--map` is required by the parser (`cli::Command::Localize`).
    run_in_map(&args.run, !args.update, quiet)
}

/// A flag `run` takes that `command` does not, and why.
fn not_for(flag: &'static str, command: &str, why: &str) -> CliError {
    CliError::BadFlag {
        flag,
        reason: format!("not for {command}: {why}"),
    }
}

/// `--initial-pose`: "x y z yaw_deg", a TUM line "t x y z qx qy qz qw", or "end".
fn parse_initial_pose(text: &str) -> Result<InitialPose, String> {
    if text.trim() == "end" {
        return Ok(InitialPose::MapEnd);
    }
    parse_pose(text).map(InitialPose::Near)
}

/// A pose: "x y z yaw_deg" or a TUM line "t x y z qx qy qz qw".
fn parse_pose(text: &str) -> Result<slamesh_core::Pose, String> {
    let v: Vec<f64> = text
        .split(|c: char| c.is_whitespace() || c == ',')
        .filter(|s| !s.is_empty())
        .map(|s| {
            s.parse::<f64>()
                .map_err(|_| format!("{s:?} is not a number"))
        })
        .collect::<Result<_, _>>()?;
    if !v.iter().all(|x| x.is_finite()) {
        return Err("a number is not finite".into());
    }
    let t = nalgebra::Translation3::new;
    match v[..] {
        [x, y, z, yaw] => Ok(slamesh_core::Pose::from_parts(
            t(x, y, z),
            nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, yaw.to_radians()),
        )),
        [_, _, _, _, _, _, _, _] => crate::formats::trajectory::tum_pose(&v)
            .ok_or_else(|| "the quaternion is zero".to_string()),
        _ => Err(format!(
            "{} numbers: give \"x y z yaw_deg\" or a TUM line \"t x y z qx qy qz qw\"",
            v.len()
        )),
    }
}

/// Meshes at the given poses (preset `meshing` unless told otherwise).
pub fn mesh(args: &MeshArgs, quiet: bool) -> Result<(), CliError> {
    let run = &args.run;
    for (flag, given) in [
        ("--loop-closure", run.loop_closure == Some(OnOff::On)),
        ("--initial-pose", run.initial_pose.is_some()),
        ("--map", run.map.is_some()),
    ] {
        if given {
            return Err(not_for(flag, "mesh", "the poses are given"));
        }
    }
    let poses = read_given_poses(&args.poses, args.calib.as_deref())?;
    run_with(&args.run, "meshing", Some(poses), quiet, false)
}

/// Estimates the poses and builds the mesh (preset `default` unless told otherwise).
pub fn run_command(args: &RunArgs, quiet: bool) -> Result<(), CliError> {
    if args.map.is_some() {
        return run_in_map(args, false, quiet);
    }
    run_with(args, "default", None, quiet, false)
}

/// A run from a saved map: mapping on from it, or (`localize_only`) localizing in it.
fn run_in_map(args: &RunArgs, localize_only: bool, quiet: bool) -> Result<(), CliError> {
    run_with(args, "default", None, quiet, localize_only)
}

fn run_with(
    args: &RunArgs,
    default_preset: &str,
    given: Option<Trajectory>,
    quiet: bool,
    localize_only: bool,
) -> Result<(), CliError> {
    let mut s = match &args.map {
        // The map's own configuration, unless one is named.
        Some(map) if args.profile.preset.is_none() && args.profile.config.is_none() => {
            crate::run::saved_map::config_of(map)?
        }
        _ => args.profile.resolve(default_preset)?,
    };
    args.window.apply(&mut s.window)?;
    let mut source = args.source.open()?;
    if given.is_none() && args.map.is_none() {
        crate::run::scale::fit_to_scene(&mut s, &mut source);
    }
    if let Some(p) = &given {
        say_given_poses(p, source.frames());
    }
    let mut opts = run_options(args, &s, given, localize_only);
    // A live input ends on Ctrl-C (the end of its stream); a run over files stops early on it
    // (in the `slamesh` program: Python keeps its own Ctrl-C).
    opts.stop = (!args.source.is_live())
        .then(crate::cli::interrupt::listen_if_installed)
        .flatten();
    if !localize_only {
        choose_loop_closure(args.loop_closure, &mut opts)?;
    }
    if let Some(SweepArg::Auto) = args.source.sweep {
        sweep_by_trial(args, &opts, &mut source)?;
    }
    let bar = match source.is_live() {
        true => crate::cli::progress_open(quiet),
        false => progress(source.frames(), quiet),
    };
    log::info!(
        "{} from {} (preset {}), output in {}",
        source.describe(),
        args.source.input.display(),
        s.preset,
        args.out.display()
    );
    let mut notices = FrameNotices::default();
    let on_frame = |e: &FrameEvent| {
        let rec = &e.record;
        frame_messages(rec, &bar, &mut notices);
        bar.set_message(format!(
            "{} ms, {} MB",
            rec.ms.total.round(),
            rec.rss_mb.unwrap_or(0.0).round()
        ));
        bar.inc(1);
    };
    let mut sinks = view_sinks(args, &opts)?;
    sinks.add(FnSink::new("progress", on_frame));
    let summary = args.capacity.run(&mut source, &opts, sinks)?;
    bar.finish_and_clear();
    notices.finish();
    print_summary(&summary, &args.out);
    judge(&summary, args.strict)
}

/// `--sweep auto`: the sweep the first scans register best with ([`sweep_trial`]), said in the
/// log and the report, and taken for the run.
fn sweep_by_trial(args: &RunArgs, opts: &RunOptions, source: &mut Input) -> Result<(), CliError> {
    let input = &args.source.input;
    if source.downcast_ref::<ScanFolder>().is_none() {
        return Err(FileError::at(input, crate::sources::kinds::NOT_A_FOLDER).into());
    }
    // The candidates' runs say what the run will say again: only their errors are shown.
    let level = log::max_level();
    log::set_max_level(log::LevelFilter::Error);
    let trial = sweep_trial::choose(
        || args.source.open(),
        input,
        opts,
        &args.out.join(".sweep-trial"),
    );
    log::set_max_level(level);
    let trial = trial?;
    log::info!("{}", trial.describe());
    if let Some(spec) = &trial.chosen {
        source.time_from_sweep(input, spec)?;
    }
    source.note_sweep_trial(trial.describe());
    Ok(())
}

/// Loop closure for a run that estimates its poses: on unless `--loop-closure off`, or the
/// run cannot close loops ([`RunOptions::loop_closure_unavailable`]): then an error when
/// `--loop-closure on` asked for it, otherwise off, saying why. Under a memory cap or window it
/// is on too: it takes a share of the cap, and gives way (saying what it would need) when the
/// cap cannot hold it. When on, and when resuming a run that had it on, the configuration gets
/// what loop closure needs of it ([`LoopSettings::configure`]).
pub(crate) fn choose_loop_closure(
    flag: Option<OnOff>,
    opts: &mut RunOptions,
) -> Result<(), CliError> {
    if flag == Some(OnOff::Off) {
        return Ok(());
    }
    let s = LoopSettings::default();
    if opts.loop_closure_unavailable_from_start().is_none() {
        s.configure(&mut opts.config);
    }
    if let Some(why) = opts.loop_closure_unavailable() {
        if flag == Some(OnOff::On) {
            return Err(CliError::BadFlag {
                flag: "--loop-closure",
                reason: why.to_string(),
            });
        }
        log::info!("loop closure is off: {why}");
        return Ok(());
    }
    opts.loop_closure = Some(s);
    Ok(())
}

/// The run's end as an exit status: an error when no frame was used, or (`--strict`) when a
/// frame was not registered normally, each named.
fn judge(summary: &Summary, strict: bool) -> Result<(), CliError> {
    if let Some(before) = summary.interrupted {
        return Err(CliError::Interrupted {
            before,
            of: summary.frames,
        });
    }
    if summary.used == 0 {
        return Err(CliError::NoFrameUsed);
    }
    let bad = &summary.health.not_registered;
    if strict && !bad.is_empty() {
        for b in bad {
            log::error!("frame {} ({}): {}: {}", b.frame, b.file, b.status, b.reason);
        }
        return Err(CliError::NotRegistered { frames: bad.len() });
    }
    Ok(())
}

/// Says how `poses` are matched to the input's `frames`, and warns when some frames have none.
fn say_given_poses(p: &Trajectory, frames: usize) {
    let how = match p.stamps {
        Some(_) => format!(
            "matched to frames by time (within {:.3} s)",
            p.tolerance_s()
        ),
        None => "taken in line order".to_string(),
    };
    if p.poses.len() < frames {
        log::warn!(
            "{} poses for {frames} frames, {how}; frames without a pose are skipped",
            p.poses.len()
        );
    } else {
        log::info!("{} poses, {how}", p.poses.len());
    }
}

/// The run's options from the command line and the resolved settings `s`.
fn run_options(
    args: &RunArgs,
    s: &Settings,
    given: Option<Trajectory>,
    localize_only: bool,
) -> RunOptions {
    let mut mesh_formats = vec![MeshFormat::Ply];
    if args.obj {
        mesh_formats.push(MeshFormat::Obj);
    }
    RunOptions {
        out: args.out.clone(),
        config: s.config,
        preset: s.preset.to_string(),
        window: s.window,
        threads: args.threads,
        mesh_formats,
        mesh_colour: match args.colour {
            ColourFlag::None => MeshColour::None,
            ColourFlag::Height => MeshColour::Height,
            ColourFlag::Variance => MeshColour::Variance,
        },
        given_poses: given,
        input: args.source.input.display().to_string(),
        checkpoint_every: args.checkpoint_every.map(|n| n as usize),
        resume: args.resume,
        picture: !args.no_picture,
        map: args.map.clone(),
        localize_only,
        initial_pose: args.initial_pose,
        save_map: args.save_map.clone(),
        loop_closure: None,
        dynamic: (args.dynamic == Some(OnOff::On)).then(ClearingConfig::default),
        navmap: args.navmap.then(|| args.robot.options()),
        deskew: match args.deskew {
            DeskewFlag::Auto => Deskew::Auto,
            DeskewFlag::Imu => Deskew::Imu,
            DeskewFlag::Motion => Deskew::Motion,
            DeskewFlag::Off => Deskew::Off,
        },
        imu: ImuOptions {
            enabled: args.source.imu.as_deref() != Some("off"),
            ..s.imu
        },
        stop: None,
    }
}

/// The live view and its recording, when asked for (`--view`, `--record`): a sink of the run.
/// In a build without the feature `view`, asking for them is an error that says how to get
/// them.
fn view_sinks<'a>(args: &RunArgs, opts: &RunOptions) -> Result<Sinks<'a>, CliError> {
    #[cfg_attr(not(feature = "view"), allow(unused_mut))]
    let mut sinks = Sinks::new();
    #[cfg(feature = "view")]
    {
        let view = crate::view::ViewOptions {
            serve: args.view.clone(),
            record: args.record,
            grid: opts.navmap.clone(),
        };
        if view.is_on() {
            // The recording goes into the output folder, made before the run makes it.
            std::fs::create_dir_all(&opts.out).map_err(|e| {
                FileError::at(&opts.out, format!("cannot create the output folder: {e}"))
            })?;
        }
        if let Some(v) = crate::view::View::for_run(&view, &opts.out, &opts.config)? {
            sinks.add(v);
        }
    }
    #[cfg(not(feature = "view"))]
    {
        let _ = opts;
        let flag = match (&args.view, args.record) {
            (Some(_), _) => Some("--view"),
            (None, true) => Some("--record"),
            (None, false) => None,
        };
        if let Some(flag) = flag {
            return Err(CliError::BadFlag {
                flag,
                reason: "this slamesh was built without the live view: build it with the \
                         feature view (cargo install --path std-adapters --features view, or \
                         cargo run --release --features slamesh/view -- run ...)"
                    .into(),
            });
        }
    }
    Ok(sinks)
}

/// LiDAR poses from a trajectory file (with its stamps, if TUM); with `calib`, KITTI camera
/// poses turned into LiDAR ones.
pub fn read_given_poses(path: &Path, calib: Option<&Path>) -> Result<Trajectory, FileError> {
    let mut t = trajectory::read(path)?;
    if let Some(c) = calib {
        t.poses = kitti::lidar_poses(&t.poses, &kitti::read_calib_tr(c)?);
    }
    Ok(t)
}
