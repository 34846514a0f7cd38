//! The `slamesh` command: one file per subcommand, the settings they share resolved in one
//! place ([`settings`]), and failures as a typed [`CliError`].

pub mod bench;
pub mod config;
#[cfg(feature = "sim")]
pub mod demo;
pub mod error;
pub mod eval;
pub mod run;
pub mod settings;

use clap::{Parser, Subcommand};
pub use error::CliError;
use indicatif::{ProgressBar, ProgressStyle};

/// Prints a line to stdout; a closed pipe (`slamesh ... | head`) is not an error.
#[macro_export]
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout().lock(), $($arg)*);
    }};
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
}

#[derive(Subcommand)]
enum Command {
    /// Estimate the sensor's poses and build the mesh map. Writes poses_kitti.txt,
    /// poses_tum.txt, mesh.ply and report.json into --out.
    Run(run::RunArgs),
    /// Build the mesh at given poses (meshing only; default preset: meshing).
    Mesh(run::MeshArgs),
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
}

impl Cli {
    /// Runs the subcommand.
    pub fn run(&self) -> Result<(), CliError> {
        match &self.command {
            Command::Run(a) => run::run_command(a),
            Command::Mesh(a) => run::mesh(a),
            Command::Eval(a) => eval::eval(a),
            Command::Bench(a) => bench::bench(a),
            #[cfg(feature = "sim")]
            Command::Demo(a) => demo::demo(a),
            Command::Config(a) => {
                config::config(a);
                Ok(())
            }
        }
    }
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
