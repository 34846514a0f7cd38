//! The `slamesh` command: one file per subcommand, the settings they share resolved in one
//! place ([`settings`]), and failures as a typed [`CliError`].

// The arguments' doc comments are the command's help text, written for a terminal (`[window]`,
// `<INPUT>`), not rustdoc's markup.
#![allow(
    rustdoc::broken_intra_doc_links,
    rustdoc::invalid_html_tags,
    rustdoc::private_intra_doc_links
)]

pub mod bench;
pub mod config;
#[cfg(feature = "sim")]
pub mod demo;
pub mod error;
pub mod eval;
pub mod input;
pub mod interrupt;
pub mod merge;
pub mod navmap;
pub mod notices;
pub mod render;
#[cfg(feature = "ros2")]
pub mod ros2;
pub mod run;
pub mod settings;
pub mod sweep_trial;
pub mod terminal;

use clap::{ArgAction, Parser, Subcommand};
pub use error::CliError;
use indicatif::{ProgressBar, ProgressStyle};
use std::ffi::OsString;
use std::io::Write as _;

/// Prints a line to stdout; a closed pipe (`slamesh ... | head`) is not an error.
#[macro_export]
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout().lock(), $($arg)*);
    }};
}

/// The `slamesh` command: its arguments parsed, the logger set up, the subcommand run; a
/// failure is logged and ends with a failing exit code.
pub fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    cli.init_logger();
    interrupt::install();
    match cli.run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e @ CliError::Interrupted { .. }) => {
            log::error!("{e}");
            std::process::ExitCode::from(interrupt::INTERRUPTED_STATUS)
        }
        Err(e) => {
            log::error!("{e}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// A subcommand run as the command runs it, from its arguments without the program's name
/// (`["run", "scans/", "--out", "out/"]`), for a program that embeds the command (the Python
/// module's `slamesh.run`). A parse failure is `Err` with clap's message (or the help text);
/// the logger is the command's, set up once per process.
pub fn run_args<I, T>(args: I) -> Result<(), String>
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let argv = std::iter::once(OsString::from("slamesh")).chain(args.into_iter().map(Into::into));
    let cli = Cli::try_parse_from(argv).map_err(|e| e.to_string())?;
    cli.init_logger();
    cli.run().map_err(|e| e.to_string())
}

/// Parses a command line as `slamesh` would (its arguments without the program's name),
/// without running it: `Err` with clap's message. The examples in the README and the docs are
/// checked with it (`tests/docs_examples.rs`).
pub fn parse_args<I, T>(args: I) -> Result<(), String>
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let argv = std::iter::once(OsString::from("slamesh")).chain(args.into_iter().map(Into::into));
    Cli::try_parse_from(argv)
        .map(|_| ())
        .map_err(|e| e.to_string())
}

/// The command line.
#[derive(Parser)]
#[command(
    name = "slamesh",
    version,
    about = "Real-time LiDAR localization and meshing"
)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
    /// More messages: -v adds the details (for the commands that run frames: each frame's
    /// outcome), -vv everything (RUST_LOG, when set, overrides both this and -q, e.g.
    /// RUST_LOG=slamesh=debug).
    #[arg(short, long, global = true, action = ArgAction::Count)]
    verbose: u8,
    /// No progress bar, and only warnings and errors.
    #[arg(short, long, global = true)]
    quiet: bool,
}

#[derive(Subcommand)]
enum Command {
    /// Estimate the sensor's poses and build the mesh map. Writes poses_kitti.txt,
    /// poses_tum.txt, mesh.ply and report.json into --out.
    Run(run::RunArgs),
    /// Build the mesh at given poses (meshing only; default preset: meshing).
    #[command(
        mut_arg("loop_closure", |a| a.hide(true)),
        mut_arg("initial_pose", |a| a.hide(true)),
        mut_arg("map", |a| a.hide(true))
    )]
    Mesh(run::MeshArgs),
    /// Localize in a saved map (--map, written by `run --save-map`): from --initial-pose or,
    /// without it, by searching the map; the map stays as it is unless --update. Writes what
    /// `run` writes.
    #[command(mut_arg("map", |a| a.required(true)))]
    Localize(run::LocalizeArgs),
    /// Compare a trajectory with reference poses (consecutive-frame errors, end-point drift,
    /// ATE, segment errors), score a mesh against a point cloud, or build such a cloud.
    Eval(eval::EvalArgs),
    /// Time the pipeline stage by stage: a warm-up pass over the scans, then --repeat timed
    /// passes (median and 95th percentile per stage, scans per second, peak memory).
    Bench(bench::BenchArgs),
    /// Simulate a drive through a procedural town, run SLAM on it and print its accuracy
    /// against the truth. Writes the outputs of `run`, the true trajectory and topview.png.
    #[cfg(feature = "sim")]
    Demo(demo::DemoArgs),
    /// Print a configuration file with every parameter and its documentation.
    Config(config::ConfigArgs),
    /// Draw a picture of a PLY mesh: from above (hill-shaded, with a scale bar) or obliquely.
    Render(render::RenderArgs),
    /// Merge two saved maps of one site (two robots, or sessions that started apart): B is
    /// found in A by searching A for places along B's path, fused into A, and written with
    /// both paths in A's frame; refused, saying why, when B is not found.
    Merge(merge::MergeArgs),
    /// Make a navigation map from a saved map or a PLY mesh: Nav2's map.yaml + map.pgm (an
    /// occupancy grid for --robot), the ground's elevation grids and traversability
    /// (navmesh.ply; from a saved map, its mesh.ply with the layers on its vertices).
    Navmap(navmap::NavMapArgs),
    /// Run as a ROS 2 node (no ROS installation needed): scans on `points`
    /// (sensor_msgs/PointCloud2), poses on `odom` and `/tf`, the path, the mesh as markers
    /// and diagnostics; `~/save_map` saves the map. Until SIGINT or SIGTERM, then writes what
    /// `run` writes into --out. ROS arguments follow --ros-args.
    #[cfg(feature = "ros2")]
    Ros2(ros2::Ros2Args),
}

/// The terminal's logger, each line it shows also handed to the log's tap
/// ([`crate::io::log_tap`]: the ROS 2 node's `/rosout`).
struct Tee(env_logger::Logger);

impl log::Log for Tee {
    fn enabled(&self, metadata: &log::Metadata) -> bool {
        self.0.enabled(metadata)
    }

    fn log(&self, record: &log::Record) {
        if self.0.matches(record) {
            self.0.log(record);
            crate::io::log_tap::forward(record);
        }
    }

    fn flush(&self) {
        self.0.flush();
    }
}

impl Cli {
    /// Sets up the logger for `-v`, `-q` and `RUST_LOG`: messages go to standard error as
    /// `slamesh: warning: ...`; standard output holds only results.
    pub fn init_logger(&self) {
        let level = match (self.quiet, self.verbose) {
            (true, _) => log::LevelFilter::Warn,
            (false, 0) => log::LevelFilter::Info,
            (false, 1) => log::LevelFilter::Debug,
            (false, _) => log::LevelFilter::Trace,
        };
        // The DDS stack's own log (the ROS 2 node's) is for its maintainers: off, warnings
        // with -v, more with -vv (its repair traffic logs errors by the hundred that are
        // not the node's); RUST_LOG=rustdds=debug shows it all.
        let dds = match self.verbose {
            0 => log::LevelFilter::Off,
            1 => log::LevelFilter::Warn,
            _ => log::LevelFilter::Debug,
        };
        let terminal = env_logger::Builder::new()
            .filter_level(level)
            .filter_module("rustdds", dds.min(level))
            .filter_module("ros2_client", dds.min(level))
            .parse_env("RUST_LOG")
            .format(|buf, record| {
                let level = match record.level() {
                    log::Level::Error => "error: ",
                    log::Level::Warn => "warning: ",
                    log::Level::Info => "",
                    log::Level::Debug => "debug: ",
                    log::Level::Trace => "trace: ",
                };
                writeln!(buf, "slamesh: {level}{}", record.args())
            })
            .build();
        let max = terminal.filter();
        if log::set_boxed_logger(Box::new(Tee(terminal))).is_ok() {
            log::set_max_level(max);
        }
    }

    /// Runs the subcommand.
    pub fn run(&self) -> Result<(), CliError> {
        let quiet = self.quiet;
        match &self.command {
            Command::Run(a) => run::run_command(a, quiet),
            Command::Mesh(a) => run::mesh(a, quiet),
            Command::Localize(a) => run::localize(a, quiet),
            Command::Eval(a) => eval::eval(a),
            Command::Bench(a) => bench::bench(a),
            Command::Render(a) => render::render(a),
            Command::Navmap(a) => navmap::navmap(a),
            Command::Merge(a) => merge::merge(a),
            #[cfg(feature = "ros2")]
            Command::Ros2(a) => ros2::ros2(a, quiet),
            #[cfg(feature = "sim")]
            Command::Demo(a) => demo::demo(a, quiet),
            Command::Config(a) => {
                config::config(a);
                Ok(())
            }
        }
    }
}

/// A progress counter for a run whose frames are not known ahead (a live input; hidden with
/// `--quiet` or off a terminal).
pub fn progress_open(quiet: bool) -> ProgressBar {
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new_spinner()
    };
    bar.set_style(
        ProgressStyle::with_template("{spinner} {pos} frames  {per_sec}  {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    bar
}

/// A progress bar for `frames` frames (hidden with `--quiet` or off a terminal).
pub fn progress(frames: usize, quiet: bool) -> ProgressBar {
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(frames as u64)
    };
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} frames  {per_sec}  eta {eta}  {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar
}
