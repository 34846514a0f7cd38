//! A run that starts from a saved map ([`crate::formats::map_file`]): loading it into the
//! pipeline, the places to search for the first pose when none is given, and what a map file
//! written at the end says about itself.
//!
//! The search's candidates lie on the map's own path: every `spacing` metres along the poses
//! its sensor had, and a cell to either side of each (a robot localizing in a map drives
//! where the mapping one drove, in another lane perhaps); each is tried at every heading
//! ([`slamesh_core::relocalize`]).

use crate::formats::map_file::{MapFile, MapInfo};
use crate::io::error::FileError;
use crate::run::config_file;
use crate::run::options::InitialPose;
use slamesh_core::map::MeshMap;
use slamesh_core::pipeline::Relocalized;
use slamesh_core::relocalize::{along_path, Search};
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

/// Candidate poses for the search along a saved map's path
/// ([`slamesh_core::relocalize::along_path`]).
pub fn candidates(path: &[(f64, Pose)], spacing_m: f64) -> Vec<Pose> {
    let mut out = Vec::new();
    along_path(path.iter().map(|(_, p)| p), spacing_m, |c| out.push(c));
    out
}

/// The candidates of a run from a saved map whose path is `path`: the given pose first (when
/// near one is given), then the path's ([`candidates`]); `None` when the run continues from
/// the path's end (no search).
pub fn search_from(
    path: &[(f64, Pose)],
    initial: Option<InitialPose>,
    config: &Config,
) -> Option<Vec<Pose>> {
    let hint = match initial {
        Some(InitialPose::MapEnd) => return None,
        Some(InitialPose::Near(p)) => Some(p),
        None => None,
    };
    let along = candidates(path, config.grid.cell_size_m);
    Some(hint.into_iter().chain(along).collect())
}

/// What the report says of the frame whose search found the pose.
pub fn found(r: &Relocalized) -> String {
    let p = r.outcome.t_world_sensor.translation.vector;
    format!(
        "found in the map at ({:.2}, {:.2}, {:.2}) with no pose given: {:.0} % of the scan on \
         the map's surfaces ({:.0} % on walls), the best elsewhere {:.0} % ({} hypotheses, {} \
         registered)",
        p.x,
        p.y,
        p.z,
        100.0 * r.hit_share,
        100.0 * r.wall_share,
        100.0 * r.runner_up_share,
        r.hypotheses,
        r.registered
    )
}

/// Why a frame whose search found no convincing pose has none.
pub fn not_found(r: &Relocalized) -> String {
    format!(
        "not localized in the map: its best pose puts {:.0} % of the scan on the map's surfaces \
         (at least {:.0} % needed) and {:.0} % on its walls (at least {:.0} %){}, the best elsewhere {:.0} % ({} hypotheses, {} registered); \
         the next frame searches again",
        100.0 * r.hit_share,
        100.0 * Search::default().min_hit_share,
        100.0 * r.wall_share,
        100.0 * Search::default().min_wall_share,
        if r.settled {
            ""
        } else {
            " and its registration did not settle"
        },
        100.0 * r.runner_up_share,
        r.hypotheses,
        r.registered
    )
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

/// The saved map a run started from (`--map`), as the run goes: its path (a map the run saves
/// keeps it first), the search for the run's pose in it until a frame finds it, and its pager
/// under a memory cap (localizing only). Empty for a run that did not start from a map.
#[derive(Default)]
pub(crate) struct FromMap {
    /// The map's path of stamped poses.
    pub(crate) path: Vec<(f64, Pose)>,
    /// Where to search for the pose, until a frame finds it ([`candidates`]); also after a
    /// request to relocalize.
    pub(crate) search: Option<Vec<Pose>>,
    /// The map paged in by tile under the memory cap.
    pub(crate) pager: Option<crate::run::map_pager::MapPager>,
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

    #[test]
    fn candidates_follow_the_path_and_its_sides() {
        let path: Vec<(f64, Pose)> = (0..10)
            .map(|i| (i as f64, Pose::translation(0.5 * i as f64, 0.0, 1.7)))
            .collect();
        let c = candidates(&path, 1.6);
        // Poses at x = 0, 2 and 4 (each 1.6 m or more on), three to a place.
        assert_eq!(c.len(), 9);
        let at: Vec<[f64; 3]> = c.iter().map(|p| p.translation.vector.into()).collect();
        assert_eq!(at[0], [0.0, 0.0, 1.7]);
        assert_eq!(at[1], [0.0, 1.6, 1.7]);
        assert_eq!(at[2], [0.0, -1.6, 1.7]);
        assert_eq!(at[3], [2.0, 0.0, 1.7]);
    }
}
