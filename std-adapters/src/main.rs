//! `slamesh`: LiDAR odometry and meshing from the command line (`slamesh --help`); each
//! subcommand lives in its own file under `cli/`.

mod cli;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    match cli::Cli::parse().run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("slamesh: error: {e}");
            ExitCode::FAILURE
        }
    }
}
