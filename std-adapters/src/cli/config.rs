//! `slamesh config`: print a configuration file with every parameter and its documentation.

use crate::run::config_file::{self, PRESETS};
use crate::say;
use clap::Args;

/// `slamesh config`'s arguments.
#[derive(Args, Debug)]
pub struct ConfigArgs {
    /// The preset to print.
    #[arg(long, default_value = "default", value_parser = PRESETS)]
    pub preset: String,
}

/// Prints the preset as a documented TOML file.
pub fn config(args: &ConfigArgs) {
    let c = config_file::preset(&args.preset).unwrap_or_default();
    let text = config_file::documented_toml(&c, &args.preset) + &config_file::documented_imu_toml();
    say!("{}", text.trim_end());
}
