//! `slamesh ros2`: the pipeline as a ROS 2 node ([`crate::ros2`]), until SIGINT or SIGTERM,
//! then the outputs `run --out DIR` writes.
//!
//! The run's settings come from the flags, or from ROS parameters of the same names
//! (`-p preset:=kitti`, `-p threads:=4`, `-p out:=DIR`, `-p map:=FILE`, `-p save_map:=FILE`,
//! `-p localize:=true`, `-p loop_closure:=false`, or a `--params-file`'s): a flag given on the
//! command line wins, and the node says which parameter it set aside. A flag left at its
//! default (`--robot wheeled`, `--navmap-resolution 0.1`) counts as not given.

use crate::cli::error::CliError;
use crate::cli::notices::FrameNotices;
use crate::cli::run::{choose_loop_closure, CapacityFlag, OnOff};
use crate::cli::settings::{Profile, WindowFlags};
use crate::cli::terminal::{frame_messages, print_summary};
use crate::formats::ros_args::{ParamValue, RosArgs};
use crate::outputs::mesh_spool::{MeshColour, MeshFormat};
use crate::ros2::{NodeSettings, RosNode};
use crate::run::config_file::Settings;
use crate::run::sink::{FnSink, Queued, WhenFull};
use crate::run::{FrameEvent, RunOptions, Sinks};
use crate::say;
use clap::Args;
use ros2_client::parameters::ParameterValue as RosParameterValue;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// `slamesh ros2`'s arguments.
#[derive(Args, Debug)]
pub struct Ros2Args {
    /// Output folder, written when the node stops (SIGINT, SIGTERM) as `run --out` writes
    /// it (ROS parameter `out`; default `slamesh-ros2`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Where the parameters come from (ROS parameters `preset`, `config`).
    #[command(flatten)]
    pub profile: Profile,
    /// Reconstruction threads (1: serial; 0, the default: one per core; ROS parameter
    /// `threads`).
    #[arg(long)]
    pub threads: Option<usize>,
    /// The sliding window's flags.
    #[command(flatten)]
    pub window: WindowFlags,
    /// The capacity class (as `run --capacity`).
    #[arg(long, value_enum, default_value_t = CapacityFlag::Auto)]
    pub capacity: CapacityFlag,
    /// Start from a saved map (ROS parameter `map`): map on from it, in its frame; with
    /// --localize only localize in it. An `initialpose` relocalizes in it.
    #[arg(long, value_name = "FILE")]
    pub map: Option<PathBuf>,
    /// Only localize in --map (the map stays as it is; ROS parameter `localize`).
    #[arg(long, requires = "map")]
    pub localize: bool,
    /// The map file `~/save_map` writes, and the whole map at the end (ROS parameter
    /// `save_map`; default for the service: map.slamesh in the output folder).
    #[arg(long, value_name = "FILE")]
    pub save_map: Option<PathBuf>,
    /// Close loops (as `run --loop-closure`; ROS parameter `loop_closure`, true or false): on
    /// by default where the run can; a correction moves `map -> odom` and the path, and the
    /// rebuilt map goes out on `mesh` and `map`.
    #[arg(long, value_enum)]
    pub loop_closure: Option<OnOff>,
    /// Do not draw topview.png at the end.
    #[arg(long)]
    pub no_picture: bool,
    /// Also write the navigation map when the node stops (as `run --navmap`; ROS parameter
    /// `navmap`, true or false), and the scans' floor beside each map `~/save_map` saves,
    /// which `slamesh navmap FILE` reads.
    #[arg(long)]
    pub navmap: bool,
    /// Clear from the map what the scans see through, as `run --dynamic on` does (ROS
    /// parameter `dynamic`, true or false): cars and people that moved on leave the map, and
    /// the `mesh` topic sends the cells clearing changed again.
    #[arg(long)]
    pub dynamic: bool,
    /// The robot and cell size of the `map` topic's grid and of --navmap (ROS parameters
    /// `robot`: a profile or a TOML file; `navmap_resolution`, m).
    #[command(flatten)]
    pub robot: crate::cli::navmap::RobotArgs,
    /// The ROS arguments: `--ros-args -r points:=/velodyne_points -p preset:=kitti
    /// --params-file FILE.yaml -r __ns:=/robot1`.
    #[arg(
        trailing_var_arg = true,
        allow_hyphen_values = true,
        value_name = "ROS_ARGS"
    )]
    pub ros_args: Vec<String>,
}

/// The output folder when neither `--out` nor the parameter `out` names one.
pub const DEFAULT_OUT: &str = "slamesh-ros2";

impl Ros2Args {
    /// The output folder.
    pub fn out_dir(&self) -> PathBuf {
        self.out
            .clone()
            .unwrap_or_else(|| PathBuf::from(DEFAULT_OUT))
    }
}

fn node_error(reason: impl std::fmt::Display) -> CliError {
    CliError::BadFlag {
        flag: "ros2",
        reason: reason.to_string(),
    }
}

/// The true-or-false ROS parameter `key` of `params` (taken out), if given.
fn flag(params: &mut BTreeMap<String, ParamValue>, key: &str) -> Result<Option<bool>, CliError> {
    match params.remove(key) {
        None => Ok(None),
        Some(ParamValue::Bool(b)) => Ok(Some(b)),
        Some(v) => Err(node_error(format!(
            "parameter {key}: {} is not true or false",
            v.as_text()
        ))),
    }
}

/// The ROS parameter `key` of `params` (taken out), read from its text by `parse` (the
/// flag's own reader), if given.
fn parsed<T>(
    params: &mut BTreeMap<String, ParamValue>,
    key: &str,
    parse: fn(&str) -> Result<T, String>,
) -> Result<Option<T>, CliError> {
    let value = params.remove(key).map(|v| parse(&v.as_text()));
    value
        .transpose()
        .map_err(|e| node_error(format!("parameter {key}: {e}")))
}

/// `flag` when given, else `param`: a flag on the command line wins over the ROS parameter
/// `name`, and the node says when it set the parameter aside.
fn either<T: PartialEq + std::fmt::Debug>(
    name: &str,
    flag: Option<T>,
    param: Option<T>,
) -> Option<T> {
    match (flag, param) {
        (Some(f), Some(p)) => {
            if f != p {
                log::info!(
                    "--{} {f:?} given: the ROS parameter {name} ({p:?}) is set aside",
                    name.replace('_', "-")
                );
            }
            Some(f)
        }
        (f, p) => f.or(p),
    }
}

/// The `threads` parameter, when given: 0 to 1024.
fn threads_parameter(p: &mut BTreeMap<String, ParamValue>) -> Result<Option<usize>, CliError> {
    match p.remove("threads") {
        None => Ok(None),
        Some(ParamValue::Int(n)) if (0..=1024).contains(&n) => Ok(Some(n as usize)),
        Some(v) => Err(node_error(format!(
            "parameter threads: {} is not 0 to 1024",
            v.as_text()
        ))),
    }
}

/// The robot and the navigation map's cell size: the flags', or the parameters `robot` and
/// `navmap_resolution` where a flag is at its default.
fn robot_with_parameters(
    given: &crate::cli::navmap::RobotArgs,
    p: &mut BTreeMap<String, ParamValue>,
) -> Result<crate::cli::navmap::RobotArgs, CliError> {
    let (robot, resolution) = (&given.robot, given.navmap_resolution);
    let default = crate::cli::navmap::RobotArgs::default();
    Ok(crate::cli::navmap::RobotArgs {
        robot: either(
            "robot",
            (*robot != default.robot).then_some(*robot),
            parsed(p, "robot", crate::cli::navmap::robot)?,
        )
        .unwrap_or(default.robot),
        navmap_resolution: either(
            "navmap_resolution",
            (resolution != default.navmap_resolution).then_some(resolution),
            parsed(p, "navmap_resolution", crate::cli::navmap::resolution)?,
        )
        .unwrap_or(default.navmap_resolution),
    })
}

/// The flags, with the ROS parameters of the same names where a flag was not given
/// ([`either`]).
fn with_parameters(args: &Ros2Args, node: &mut NodeSettings) -> Result<Ros2Args, CliError> {
    let p = &mut node.params;
    let mut take_text = |k: &str| p.remove(k).map(|v| v.as_text());
    let (preset, config) = (take_text("preset"), take_text("config").map(PathBuf::from));
    // The profile is one choice: `--preset` or `--config` sets both parameters aside.
    let profile = match &args.profile {
        Profile {
            preset: None,
            config: None,
        } => Profile { preset, config },
        given => {
            either("preset", given.preset.clone(), preset);
            either("config", given.config.clone(), config);
            given.clone()
        }
    };
    let out = either("out", args.out.clone(), take_text("out").map(PathBuf::from));
    let map = either("map", args.map.clone(), take_text("map").map(PathBuf::from));
    let save_map = take_text("save_map").map(PathBuf::from);
    let save_map = either("save_map", args.save_map.clone(), save_map);
    let threads = threads_parameter(p)?;
    let threads = either("threads", args.threads, threads);
    let localize = either(
        "localize",
        args.localize.then_some(true),
        flag(p, "localize")?,
    );
    let loop_closure = flag(p, "loop_closure")?.map(|on| if on { OnOff::On } else { OnOff::Off });
    let loop_closure = either("loop_closure", args.loop_closure, loop_closure);
    let navmap = either("navmap", args.navmap.then_some(true), flag(p, "navmap")?);
    let dynamic = either("dynamic", args.dynamic.then_some(true), flag(p, "dynamic")?);
    let robot = robot_with_parameters(&args.robot, p)?;
    let (localize, navmap) = (localize.unwrap_or(false), navmap.unwrap_or(false));
    if localize && map.is_none() {
        return Err(node_error("localize needs a map (--map or -p map:=FILE)"));
    }
    for k in p.keys() {
        log::warn!("ROS parameter {k} is not one of slamesh's: ignored");
    }
    Ok(Ros2Args {
        out,
        profile,
        threads,
        window: args.window.clone(),
        capacity: args.capacity,
        map,
        localize,
        save_map,
        loop_closure,
        no_picture: args.no_picture,
        navmap,
        dynamic: dynamic.unwrap_or(false),
        robot,
        ros_args: Vec::new(),
    })
}

/// Runs the node until it is stopped.
pub fn ros2(args: &Ros2Args, quiet: bool) -> Result<(), CliError> {
    let ros = RosArgs::parse(&args.ros_args).map_err(node_error)?;
    let mut node_settings = NodeSettings::from_process(&ros).map_err(node_error)?;
    let args = with_parameters(args, &mut node_settings)?;
    let mut s = match &args.map {
        Some(map) if args.profile.preset.is_none() && args.profile.config.is_none() => {
            crate::run::saved_map::config_of(map)?
        }
        _ => args.profile.resolve("default")?,
    };
    args.window.apply(&mut s.window)?;
    let stop = crate::cli::interrupt::listen().unwrap_or_default();
    let values = declared(&args, &node_settings, &s);
    let mut node = RosNode::start(node_settings, values).map_err(node_error)?;
    let mut source = node.listen(stop).map_err(node_error)?;
    let advertised = node.advertise().map_err(node_error)?;
    log::info!(
        "ROS 2 node {} in domain {}{}: scans on {}, poses on {} (preset {}), output in {}",
        node.settings.fqn(),
        node.settings.domain_id,
        if node.settings.localhost_only {
            " (this machine only)"
        } else {
            ""
        },
        node.settings.topics.points,
        node.settings.topics.odom,
        s.preset,
        args.out_dir().display()
    );
    if args.map.is_none() {
        crate::run::scale::fit_to_scene(&mut s, &mut source);
    }
    let mut opts = run_options(&args, &s, node.settings.use_imu);
    if !args.localize {
        choose_loop_closure(args.loop_closure, &mut opts)?;
    }
    let lidar_in_base = advertised.lidar_in_base(&mut source);
    // The IMU's place from the robot's transforms, unless the configuration gives it.
    if opts.imu.enabled && !opts.imu.placed {
        if let Some(p) = advertised.lidar_from_imu(&mut source, &lidar_in_base) {
            opts.imu.calibration.lidar_from_imu = p;
        }
    }
    let sink = advertised.sink(&opts.config, &source, args.robot.options(), lidar_in_base);
    let sink = Queued::new(sink, 8, WhenFull::Wait)
        .map_err(|e| node_error(format!("cannot start the publishing thread: {e}")))?;
    let bar = crate::cli::progress_open(quiet);
    let mut notices = FrameNotices::default();
    let mut sinks = Sinks::new();
    sinks.add(sink);
    sinks.add(FnSink::new("progress", |e: &FrameEvent| {
        frame_messages(&e.record, &bar, &mut notices);
        bar.inc(1);
    }));
    let summary = args.capacity.run(&mut source, &opts, sinks)?;
    bar.finish_and_clear();
    notices.finish();
    print_summary(&summary, &args.out_dir());
    if let Ok(counts) = source.counts().lock() {
        let topic = &node.settings.topics.points;
        let skipped = summary.skipped.len();
        say!(
            "slamesh: {}",
            counts.closing_line(topic, summary.used, skipped)
        );
    }
    Ok(())
}

/// The node's parameters as `ros2 param` lists them, with the values the node runs with.
fn declared(args: &Ros2Args, n: &NodeSettings, s: &Settings) -> Vec<(String, RosParameterValue)> {
    use RosParameterValue as V;
    let text = |v: &str| V::String(v.to_string());
    let path = |p: &Option<PathBuf>| {
        V::String(
            p.as_ref()
                .map_or(String::new(), |p| p.display().to_string()),
        )
    };
    let mut values = vec![
        ("preset", text(s.preset)),
        ("out", text(&args.out_dir().display().to_string())),
        ("threads", V::Integer(args.threads.unwrap_or(0) as i64)),
        ("map", path(&args.map)),
        ("save_map", path(&args.save_map)),
        ("localize", V::Boolean(args.localize)),
        ("navmap", V::Boolean(args.navmap)),
        ("dynamic", V::Boolean(args.dynamic)),
        ("map_frame", text(&n.frames.map)),
        ("odom_frame", text(&n.frames.odom)),
        ("base_frame", text(&n.frames.base)),
        ("queue", V::Integer(n.queue as i64)),
        ("publish_tf", V::Boolean(n.publish_tf)),
        ("publish_mesh", V::Boolean(n.publish_mesh)),
        ("publish_map", V::Boolean(n.map_every.is_some())),
        ("use_sim_time", V::Boolean(n.use_sim_time)),
        ("use_imu", V::Boolean(n.use_imu)),
        ("imu_wait", V::Double(n.imu_wait.as_secs_f64())),
    ];
    if let Some(every) = n.map_every {
        values.push(("map_every", V::Integer(every as i64)));
    }
    if let Some(frame) = &n.lidar_frame {
        values.push(("lidar_frame", text(frame)));
    }
    values
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect()
}

fn run_options(args: &Ros2Args, s: &Settings, use_imu: bool) -> RunOptions {
    RunOptions {
        out: args.out_dir(),
        config: s.config,
        preset: s.preset.to_string(),
        window: s.window,
        threads: args.threads.unwrap_or(0),
        mesh_formats: vec![MeshFormat::Ply],
        mesh_colour: MeshColour::None,
        input: "ROS 2".into(),
        picture: !args.no_picture,
        map: args.map.clone(),
        localize_only: args.localize,
        save_map: args.save_map.clone(),
        navmap: args.navmap.then(|| args.robot.options()),
        dynamic: args
            .dynamic
            .then(slamesh_core::clearing::ClearingConfig::default),
        imu: crate::inertial::ImuOptions {
            enabled: use_imu,
            ..s.imu
        },
        ..RunOptions::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::navmap::Robot;
    use clap::Parser;

    #[derive(Parser)]
    struct Command {
        #[command(flatten)]
        args: Ros2Args,
    }

    /// The node's flags `flags` with the ROS parameters of `ros_args` put over them.
    fn resolved(flags: &[&str], ros_args: &str) -> Result<Ros2Args, CliError> {
        let command =
            Command::try_parse_from(std::iter::once("ros2").chain(flags.iter().copied())).unwrap();
        let words: Vec<String> = ros_args.split_whitespace().map(String::from).collect();
        let mut node = NodeSettings::new(&RosArgs::parse(&words).unwrap(), &|_| None).unwrap();
        with_parameters(&command.args, &mut node)
    }

    #[test]
    fn loop_closure_comes_from_the_flag_which_wins_or_the_parameter() {
        assert_eq!(resolved(&[], "").unwrap().loop_closure, None);
        let flag = resolved(&["--loop-closure", "off"], "").unwrap();
        assert_eq!(flag.loop_closure, Some(OnOff::Off));
        let both = resolved(
            &["--loop-closure", "off"],
            "--ros-args -p loop_closure:=true",
        );
        assert_eq!(both.unwrap().loop_closure, Some(OnOff::Off));
        let off = resolved(&[], "--ros-args -p loop_closure:=false").unwrap();
        assert_eq!(off.loop_closure, Some(OnOff::Off));
        let bad = resolved(&[], "--ros-args -p loop_closure:=3")
            .err()
            .unwrap();
        assert!(bad
            .to_string()
            .contains("loop_closure: 3 is not true or false"));
    }

    #[test]
    fn the_navigation_map_and_its_robot_come_from_the_flags_or_the_parameters() {
        let plain = resolved(&[], "").unwrap();
        assert!(!plain.navmap);
        assert_eq!(plain.robot.options().robot, Robot::WHEELED);
        let flags = resolved(&["--navmap", "--robot", "legged"], "").unwrap();
        assert!(flags.navmap && flags.robot.robot == Robot::LEGGED);
        let params = resolved(
            &[],
            "--ros-args -p navmap:=true -p robot:=legged -p navmap_resolution:=0.05",
        )
        .unwrap();
        assert!(params.navmap && params.robot.robot == Robot::LEGGED);
        assert_eq!(params.robot.options().resolution_m, 0.05);
        // The flags win; a flag at its default (wheeled) counts as not given.
        let both = resolved(
            &["--navmap", "--navmap-resolution", "0.08"],
            "--ros-args -p navmap:=false -p robot:=legged -p navmap_resolution:=0.05",
        )
        .unwrap();
        assert!(both.navmap && both.robot.robot == Robot::LEGGED);
        assert_eq!(both.robot.options().resolution_m, 0.08);
        // Clearing what moves: off, by the flag, by the parameter.
        assert!(!plain.dynamic);
        assert!(resolved(&["--dynamic"], "").unwrap().dynamic);
        let by_param = resolved(&[], "--ros-args -p dynamic:=true").unwrap();
        assert!(by_param.dynamic);
        let s = crate::run::config_file::preset_settings("default").unwrap();
        assert!(run_options(&by_param, &s, false).dynamic.is_some());
        for (bad, says) in [
            ("navmap:=3", "navmap: 3 is not true or false"),
            ("robot:=tracked", "parameter robot:"),
            ("navmap_resolution:=5.0", "not a cell size"),
        ] {
            let e = resolved(&[], &format!("--ros-args -p {bad}"))
                .err()
                .unwrap();
            assert!(e.to_string().contains(says), "{bad}: {e}");
        }
    }

    #[test]
    fn flags_win_over_the_example_parameter_file() {
        let file = concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/ros2/params.yaml");
        let ros_args = format!("--ros-args --params-file {file}");
        // The file alone: its own out, preset and threads.
        let file_only = resolved(&[], &ros_args).unwrap();
        assert_eq!(file_only.out_dir(), PathBuf::from("slamesh-ros2"));
        assert_eq!(file_only.profile.preset.as_deref(), Some("kitti"));
        let given = resolved(
            &["--out", "run1", "--preset", "fast", "--threads", "2"],
            &ros_args,
        )
        .unwrap();
        assert_eq!(given.out_dir(), PathBuf::from("run1"));
        assert_eq!(given.profile.preset.as_deref(), Some("fast"));
        assert_eq!(given.threads, Some(2));
        // --config is the profile too: the file's preset is set aside.
        let config = resolved(&["--config", "my.toml"], &ros_args).unwrap();
        assert_eq!(config.profile.preset, None);
        assert_eq!(config.profile.config, Some(PathBuf::from("my.toml")));
        // Nothing at all: the default folder.
        assert_eq!(
            resolved(&[], "").unwrap().out_dir(),
            PathBuf::from(DEFAULT_OUT)
        );
    }
}
