//! `slamesh`: LiDAR odometry and meshing from the command line (`slamesh --help`); each
//! subcommand lives in its own file under `cli/`.

mod cli;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    let cli = cli::Cli::parse();
    cli.init_logger();
    match cli.run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            log::error!("{e}");
            ExitCode::FAILURE
        }
    }
}
