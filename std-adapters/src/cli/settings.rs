//! The one place a subcommand's settings are resolved: a preset or a configuration file
//! ([`Profile`]), then the sliding-window flags on top ([`WindowFlags`]), then the fit to the
//! scene's scale ([`crate::run::scale::fit_to_scene`]).

use crate::cli::error::CliError;
use crate::run::config_file::{self, Settings, WindowSettings, PRESETS};
use clap::Args;
use std::path::PathBuf;

/// Where the pipeline's parameters come from.
#[derive(Args, Debug, Clone)]
pub struct Profile {
    /// Parameter preset (when not given: `meshing` for `mesh`, `town` for `demo`, `default`
    /// otherwise).
    #[arg(long, value_parser = PRESETS, conflicts_with = "config")]
    pub preset: Option<String>,
    /// A TOML configuration file instead of a preset (print one with `slamesh config`).
    #[arg(long)]
    pub config: Option<PathBuf>,
}

impl Profile {
    /// The settings of the configuration file, or of the preset given, or of `default_preset`.
    pub fn resolve(&self, default_preset: &str) -> Result<Settings, CliError> {
        if let Some(path) = &self.config {
            return Ok(config_file::read(path)?);
        }
        let name = self.preset.as_deref().unwrap_or(default_preset);
        config_file::preset_settings(name).map_err(|reason| CliError::BadFlag {
            flag: "--preset",
            reason: reason.to_string(),
        })
    }
}

/// Sliding-window eviction from the command line (on top of a configuration file's `[window]`).
#[derive(Args, Debug, Clone)]
pub struct WindowFlags {
    /// Evict map cells not seen for more than N frames.
    #[arg(long, value_name = "N")]
    pub evict_after: Option<u32>,
    /// Evict map cells farther than R metres from the sensor.
    #[arg(long, value_name = "R")]
    pub evict_radius: Option<f64>,
    /// Keep the process under this many MB by evicting the oldest cells.
    #[arg(long, value_name = "MB")]
    pub memory_cap: Option<f64>,
    /// Append evicted cells to the output mesh, so nothing is lost.
    #[arg(long)]
    pub save_evicted: bool,
}

impl WindowFlags {
    /// Sets the rules given on the command line in `w`; refuses a radius or cap that is not a
    /// positive number.
    pub fn apply(&self, w: &mut WindowSettings) -> Result<(), CliError> {
        if let Some(n) = self.evict_after {
            w.max_age_frames = Some(n);
        }
        for (flag, value, slot) in [
            ("--evict-radius", self.evict_radius, &mut w.radius_m),
            ("--memory-cap", self.memory_cap, &mut w.memory_cap_mb),
        ] {
            if let Some(v) = value {
                if !(v > 0.0 && v.is_finite()) {
                    return Err(CliError::BadFlag {
                        flag,
                        reason: format!("must be a positive number, found {v}"),
                    });
                }
                *slot = Some(v);
            }
        }
        w.save_evicted |= self.save_evicted;
        Ok(())
    }
}
