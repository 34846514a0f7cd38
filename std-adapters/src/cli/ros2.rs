//! `slamesh ros2`: the pipeline as a ROS 2 node ([`crate::ros2`]), until SIGINT or SIGTERM,
//! then the outputs `run --out DIR` writes.
//!
//! The run's settings come from the flags, or from ROS parameters of the same names
//! (`-p preset:=kitti`, `-p threads:=4`, `-p out:=DIR`, `-p map:=FILE`, `-p save_map:=FILE`,
//! `-p localize:=true`, `-p loop_closure:=false`), which win when both are given.

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
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// `slamesh ros2`'s arguments.
#[derive(Args, Debug)]
pub struct Ros2Args {
    /// Output folder, written when the node stops (SIGINT, SIGTERM) as `run --out` writes
    /// it (ROS parameter `out`).
    #[arg(long, default_value = "slamesh-ros2")]
    pub out: PathBuf,
    /// Where the parameters come from (ROS parameters `preset`, `config`).
    #[command(flatten)]
    pub profile: Profile,
    /// Reconstruction threads (1: serial; 0: one per core; ROS parameter `threads`).
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
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

fn node_error(reason: String) -> CliError {
    CliError::BadFlag {
        flag: "ros2",
        reason,
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

/// The flags with the ROS parameters of the same names put over them.
fn with_parameters(args: &Ros2Args, node: &mut NodeSettings) -> Result<Ros2Args, CliError> {
    let p = &mut node.params;
    let mut take_text = |k: &str| p.remove(k).map(|v| v.as_text());
    let profile = Profile {
        preset: take_text("preset").or(args.profile.preset.clone()),
        config: take_text("config")
            .map(PathBuf::from)
            .or(args.profile.config.clone()),
    };
    let out = take_text("out").map_or(args.out.clone(), PathBuf::from);
    let map = take_text("map").map(PathBuf::from).or(args.map.clone());
    let save_map = take_text("save_map")
        .map(PathBuf::from)
        .or(args.save_map.clone());
    let threads = match p.remove("threads") {
        None => args.threads,
        Some(ParamValue::Int(n)) if (0..=1024).contains(&n) => n as usize,
        Some(v) => {
            return Err(node_error(format!(
                "parameter threads: {} is not 0 to 1024",
                v.as_text()
            )))
        }
    };
    let localize = flag(p, "localize")?.unwrap_or(args.localize);
    let loop_closure = flag(p, "loop_closure")?
        .map(|on| if on { OnOff::On } else { OnOff::Off })
        .or(args.loop_closure);
    let navmap = flag(p, "navmap")?.unwrap_or(args.navmap);
    let robot = crate::cli::navmap::RobotArgs {
        robot: parsed(p, "robot", crate::cli::navmap::robot)?.unwrap_or(args.robot.robot),
        navmap_resolution: parsed(p, "navmap_resolution", crate::cli::navmap::resolution)?
            .unwrap_or(args.robot.navmap_resolution),
    };
    if localize && map.is_none() {
        return Err(node_error(
            "localize needs a map (--map or -p map:=FILE)".into(),
        ));
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
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    if let Err(e) = ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed)) {
        log::warn!("SIGINT and SIGTERM will not end the node cleanly: {e}");
    }
    let mut node = RosNode::start(node_settings).map_err(node_error)?;
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
        args.out.display()
    );
    if args.map.is_none() {
        crate::run::scale::fit_to_scene(&mut s, &mut source);
    }
    let mut opts = run_options(&args, &s, node.settings.use_imu);
    if !args.localize {
        choose_loop_closure(args.loop_closure, &mut opts)?;
    }
    let sink = advertised.sink(&opts.config, &source, args.robot.options());
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
    print_summary(&summary, &args.out);
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

fn run_options(args: &Ros2Args, s: &Settings, use_imu: bool) -> RunOptions {
    RunOptions {
        out: args.out.clone(),
        config: s.config,
        preset: s.preset.to_string(),
        window: s.window,
        threads: args.threads,
        mesh_formats: vec![MeshFormat::Ply],
        mesh_colour: MeshColour::None,
        input: "ROS 2".into(),
        picture: !args.no_picture,
        map: args.map.clone(),
        localize_only: args.localize,
        save_map: args.save_map.clone(),
        navmap: args.navmap.then(|| args.robot.options()),
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
    fn loop_closure_comes_from_the_flag_or_the_parameter_which_wins() {
        assert_eq!(resolved(&[], "").unwrap().loop_closure, None);
        let flag = resolved(&["--loop-closure", "off"], "").unwrap();
        assert_eq!(flag.loop_closure, Some(OnOff::Off));
        let param = resolved(
            &["--loop-closure", "off"],
            "--ros-args -p loop_closure:=true",
        );
        assert_eq!(param.unwrap().loop_closure, Some(OnOff::On));
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
            &["--navmap"],
            "--ros-args -p navmap:=false -p robot:=legged -p navmap_resolution:=0.05",
        )
        .unwrap();
        assert!(!params.navmap && params.robot.robot == Robot::LEGGED);
        assert_eq!(params.robot.options().resolution_m, 0.05);
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
}
