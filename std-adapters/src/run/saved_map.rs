//! A run that starts from a saved map ([`crate::formats::map_file`]): loading it into the
//! pipeline (the search for the first pose when none is given, and paging the map under a
//! cap, are a stage: [`crate::localize`]), and what a map file written
//! at the end says about itself.

use crate::formats::map_file::{MapFile, MapInfo};
use crate::io::error::FileError;
use crate::run::config_file;
use slamesh_core::map::MeshMap;
use slamesh_core::{Config, Pose};
use std::path::Path;
use std::time::Instant;

/// What loading a saved map gave a run.
#[derive(Debug, Clone)]
pub struct MapStart {
    /// Scans fused into the map before this run.
    pub frames: u32,
    /// The map's path: stamped sensor poses.
    pub path: Vec<(f64, Pose)>,
    /// Layers loaded.
    pub layers: usize,
    /// Bytes of the file.
    pub bytes: u64,
    /// Seconds the load took.
    pub load_s: f64,
}

/// Loads the whole map file `path` into `map` (which must be empty).
pub fn load(path: &Path, map: &mut MeshMap) -> Result<MapStart, FileError> {
    let t = Instant::now();
    let mut file = MapFile::open(path)?;
    let layers = file.load_all(map)?;
    Ok(MapStart {
        frames: file.info.frames,
        path: std::mem::take(&mut file.poses),
        layers,
        bytes: file.bytes,
        load_s: t.elapsed().as_secs_f64(),
    })
}

/// The configuration a map file was made with, for a run that names none.
pub fn config_of(path: &Path) -> Result<config_file::Settings, FileError> {
    let file = MapFile::open(path)?;
    let mut settings = config_file::parse(&file.info.config_toml).map_err(|e| {
        FileError::at(
            path,
            format!("not a usable map file: its configuration does not read: {e}"),
        )
    })?;
    // A map written before [`info`] left the rule out may carry it.
    settings.config = without_stale_rule(&settings.config);
    Ok(settings)
}

/// `config` without the rule that leaves cells unseen for a while out of registration
/// (`map.stale_after_frames` 0), for a saved map's configuration: loop closure sets the rule
/// for the run that made the map ([`crate::loop_closure::settings::LoopSettings::configure`]),
/// but a run that loads the map starts with every cell unseen since that run, and with the
/// rule it would register against none of the older ones.
fn without_stale_rule(config: &Config) -> Config {
    let mut config = *config;
    config.map.stale_after_frames = 0;
    config
}

/// What a map file written by a run with `config` (from preset `preset`) after `frames`
/// scans says about its map.
pub fn info(config: &Config, preset: &str, frames: u32) -> MapInfo {
    // A library run names no preset (`RunOptions::default()`): its file still has to read
    // back, and it lists every parameter, so the preset it names fills nothing it left out.
    let preset = if preset.is_empty() { "default" } else { preset };
    MapInfo {
        lattice: config.lattice(),
        frames,
        frame_id: "map".to_string(),
        config_toml: config_file::documented_toml(&without_stale_rule(config), preset),
    }
}

/// Finishes the map file being written (`saved`, from `opts.save_map`): the cells still in
/// `map`, and `path`: the path of the map the run started from followed by this run's stamped
/// poses.
pub(super) fn finish(
    saved: Option<crate::formats::map_file::MapWriter>,
    path: &[(f64, Pose)],
    map: &slamesh_core::map::MeshMap,
    frames_seen: u32,
    opts: &crate::run::RunOptions,
) -> Result<(), crate::run::RunError> {
    let shown_as = opts.save_map.as_deref().unwrap_or(&opts.out);
    let Some(mut saved) = saved else {
        return Ok(());
    };
    saved.add_map(map)?;
    saved.set_frames(frames_seen);
    let stats = saved.finish(path)?;
    log::info!(
        "map saved to {}: {} cells, {} layers, {:.1} MB",
        shown_as.display(),
        stats.cells,
        stats.layers,
        stats.bytes as f64 / 1e6
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_map_saved_by_a_run_that_names_no_preset_reads_back_with_its_configuration() {
        let mut config = Config::default();
        config.grid.cell_size_m = 0.5;
        let toml = info(&config, "", 0).config_toml;
        let read = config_file::parse(&toml).expect("the configuration reads");
        assert_eq!(read.config.grid.cell_size_m, 0.5);
    }
}
