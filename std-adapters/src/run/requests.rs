//! What a live source's user asks of a run, served between frames ([`Request`]: a ROS 2
//! node's `initialpose` and `~/save_map`).
//!
//! - **Save the map now**: the map as it is in memory, with the path so far (the saved map's
//!   first, when the run started from one), to `--save-map`'s file or `map.slamesh` in the
//!   output folder, written to a temporary file and renamed. Cells a window has evicted are in
//!   the final map file (`--save-map`), not in one saved during the run. With the navigation
//!   map on, the scans' floor so far goes beside it ([`floor_file`]), as at the run's end, so
//!   that `slamesh navmap` on a map the ROS 2 node saved finds the kerbs the run found; a
//!   floor file there from an earlier save is removed otherwise.
//! - **Relocalize**: the next frames search for their pose near the one given (then along the
//!   saved map's path) instead of following the motion, until one is found, as a run from a
//!   saved map searches for its first pose (the stage that searches:
//!   [`crate::stage::RunStage::relocalize`]).

use crate::formats::map_file::MapWriter;
use crate::run::saved_map;
use crate::run::session::Run;
use crate::sources::{FrameSource, Request};
use slamesh_core::{Capacity, Pose};
use std::path::PathBuf;

impl<C: Capacity> Run<'_, C> {
    /// Serves `request` (from `source`, whose stamps date the path).
    pub fn serve(&mut self, source: &impl FrameSource, request: Request) {
        match request {
            Request::SaveMap(reply) => {
                let answer = self.save_map_now(source);
                match &answer {
                    Ok(m) => log::info!("{m}"),
                    Err(e) => log::warn!("cannot save the map: {e}"),
                }
                // The asker may have gone; the log says what happened.
                let _ = reply.send(answer);
            }
            Request::Relocalize(pose) => self.relocalize_near(pose),
        }
    }

    /// Where a map saved during the run goes: `--save-map`'s file, or `map.slamesh` in the
    /// output folder.
    pub fn map_file(&self) -> PathBuf {
        self.opts
            .save_map
            .clone()
            .unwrap_or_else(|| self.opts.out.join("map.slamesh"))
    }

    fn save_map_now(&mut self, source: &impl FrameSource) -> Result<String, String> {
        let target = self.map_file();
        // Its own temporary name: the final map file (`--save-map`) is being written beside.
        let name = target
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let staging = target.with_file_name(format!(".{name}.saving"));
        std::fs::create_dir_all(&self.opts.out)
            .map_err(|e| format!("{}: cannot create the folder: {e}", self.opts.out.display()))?;
        let info = saved_map::info(&self.opts.config, &self.opts.preset, 0);
        let mut w = MapWriter::create(&staging, &info).map_err(|e| e.to_string())?;
        w.add_map(self.pipeline.map()).map_err(|e| e.to_string())?;
        w.set_frames(self.pipeline.frames());
        let path: Vec<(f64, Pose)> = (self.files.start_path)
            .iter()
            .copied()
            .chain(
                self.progress
                    .poses
                    .iter()
                    .map(|(i, p)| (source.stamp(*i), *p)),
            )
            .collect();
        let stats = w.finish(&path).map_err(|e| e.to_string())?;
        std::fs::rename(&staging, &target).map_err(|e| {
            let _ = std::fs::remove_file(&staging);
            format!("{}: cannot rename the map file: {e}", target.display())
        })?;
        let beside = (self.stages).beside_map(&target, &path, &self.progress.poses);
        Ok(format!(
            "map saved to {}: {} cells, {} layers, {} poses, {:.1} MB{beside}",
            target.display(),
            stats.cells,
            stats.layers,
            path.len(),
            stats.bytes as f64 / 1e6
        ))
    }

    fn relocalize_near(&mut self, pose: Pose) {
        if !self.stages.relocalize(pose) {
            log::warn!("cannot relocalize: no stage of this run searches for the pose");
        }
    }
}
