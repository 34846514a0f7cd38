//! The end of a run ([`Run::finish`]): the stages' last corrections (loop closure's), the map file, the
//! stages' end-of-run files from the whole map (the navigation files), the mesh files and the
//! picture, the summary with the report's health and the files written, then the trajectories
//! and `report.json`; the spools and the checkpoint removed. A run stopped early (Ctrl-C)
//! ends the same way, saying where it stopped.

use crate::formats::mesh_records::VertexProperties;
use crate::outputs::mesh_spool::{MeshCounts, MeshFormat, MeshSpool};
use crate::run::budget::MemoryBudget;
use crate::run::checkpoint::Progress;
use crate::run::files::Trajectories;
use crate::run::memory;
use crate::run::options::RunError;
use crate::run::report::{spreads, write_topview, Summary};
use crate::run::saved_map;
use crate::run::session::Run;
use crate::run::RunOptions;
use crate::sources::FrameSource;
use crate::stage::lent::{Between, RunOutputs};
use crate::stage::{End, Stages};
use slamesh_core::{Capacity, Pose};
use std::path::PathBuf;

impl<C: Capacity> Run<'_, C> {
    /// Writes the trajectories, the mesh files and `report.json`, removes the spools and the
    /// checkpoint, and sums the run up.
    pub fn finish(self, source: &impl FrameSource) -> Result<Summary, RunError> {
        self.finish_as(source, None)
    }

    /// [`finish`](Self::finish) for a run stopped before frame `before` (Ctrl-C): it writes
    /// what it has, and says it was interrupted ([`Summary::interrupted`]).
    pub fn finish_interrupted(
        self,
        source: &impl FrameSource,
        before: usize,
    ) -> Result<Summary, RunError> {
        log::warn!(
            "interrupted before frame {before} of {}: writing what the run has",
            source.frames()
        );
        self.finish_as(source, Some(before))
    }

    /// The stages' last corrections (loop closure's), waited for.
    fn wind_up(&mut self, source: &impl FrameSource) {
        let mut run = Between {
            pipeline: &mut self.pipeline,
            poses: &mut self.progress.poses,
            next_frame: source.frames(),
            outputs: RunOutputs {
                spool: &mut self.files.spool,
                saved_map: &mut self.files.saved_map,
            },
        };
        self.stages.wind_up(&mut run);
    }

    fn finish_as(
        mut self,
        source: &impl FrameSource,
        interrupted: Option<usize>,
    ) -> Result<Summary, RunError> {
        self.wind_up(source);
        self.progress.seconds = self.clock.seconds();
        let Progress {
            poses,
            skipped,
            evicted_cells,
            used_ms,
            seconds,
            ..
        } = self.progress;
        let (health, cost_by_outcome) = self.files.report.health()?;
        // The scan buffers go before the mesh is welded: writing needs no more than the run.
        drop(std::mem::take(&mut self.ahead));
        let frames_seen = self.pipeline.frames();
        let map = self.pipeline.into_map();
        let out = &self.opts.out;
        // A run that used no frame writes its report (with every frame's reason) and no empty
        // trajectory, mesh or picture.
        let stamps: Vec<f64> = poses.iter().map(|(i, _)| source.stamp(*i)).collect();
        // The saved map's path: the start map's, then this run's.
        let mut path = std::mem::take(&mut self.files.start_path);
        path.extend(poses.iter().zip(&stamps).map(|((_, p), t)| (*t, *p)));
        let saving = self.files.saved_map.take();
        saved_map::finish(saving, &path, &map, frames_seen, &self.opts)?;
        let end = End {
            poses: &poses,
            out,
            saved_map: self.opts.save_map.as_deref().map(|m| (m, &path[..])),
            up: self.stages.up(),
        };
        let counts = write_mesh(self.files.spool, &map, &end, &self.opts, &mut self.stages)?;
        let summary = Summary {
            frames: source.frames(),
            used: poses.len(),
            skipped,
            seconds,
            hz: poses.len() as f64 / seconds.max(1e-9),
            threads: self.workers.threads(),
            capacity: C::NAME.to_string(),
            stage_ms: spreads(&used_ms),
            cost_by_outcome,
            mesh_vertices: counts.vertices,
            mesh_triangles: counts.triangles,
            map_cells: map.cell_count(),
            map_layers: map.layer_count(),
            evicted_cells,
            max_layers: self.budget.as_ref().map(|b| b.layers),
            memory_budget: self.budget.map(|b| MemoryBudget {
                peak_mb: memory::peak_rss_bytes().map(memory::mb),
                ..b
            }),
            peak_rss_mb: memory::peak_rss_bytes().map(memory::mb),
            health,
            input: source.input_report(),
            stages: self.stages.summaries(),
            files: written(&self.opts, !poses.is_empty(), &self.stages),
            interrupted,
            poses,
            stamps,
        };
        Trajectories::new(out).write(&summary)?;
        self.files.report.write(&summary)?;
        // The run is complete: nothing is left to resume.
        let _ = std::fs::remove_file(&self.files.checkpoint);
        Ok(summary)
    }
}

/// The files a run with `opts` writes into its output folder (`used`: it used a frame): its
/// trajectories, mesh files and picture, then those of the stages' outputs that are there, then
/// `report.json`.
fn written<C: Capacity>(opts: &RunOptions, used: bool, stages: &Stages<C>) -> Vec<String> {
    let own = ["poses_kitti.txt", "poses_tum.txt"]
        .into_iter()
        .chain(opts.mesh_formats.iter().map(|f| f.file_name()))
        .chain(opts.picture.then_some("topview.png"))
        .filter(|_| used);
    let theirs = stages.outputs().into_iter();
    let theirs = theirs.filter(|f| opts.out.join(f).is_file());
    (own.chain(theirs).chain(["report.json"]))
        .map(str::to_string)
        .collect()
}

/// Writes the mesh files, the picture and the stages' end-of-run files from `spool` with
/// `map`'s cells added; none when no frame was used (`end.poses` empty). A stage's vertex
/// properties (the navigation map's layers) go on the mesh files' vertices.
fn write_mesh<C: Capacity>(
    mut spool: MeshSpool,
    map: &slamesh_core::map::MeshMap,
    end: &End<'_>,
    opts: &RunOptions,
    stages: &mut Stages<C>,
) -> Result<MeshCounts, RunError> {
    let used = !end.poses.is_empty();
    spool.add_map(map)?;
    spool.colour_by(opts.mesh_colour);
    if opts.picture && used {
        let path: Vec<Pose> = end.poses.iter().map(|(_, p)| *p).collect();
        write_topview(&mut spool, &path, &end.out.join("topview.png"))?;
    }
    stages.finish(&mut spool, end)?;
    let outputs: Vec<(PathBuf, MeshFormat)> = opts
        .mesh_formats
        .iter()
        .filter(|_| used)
        .map(|&f| (end.out.join(f.file_name()), f))
        .collect();
    let mut layers = stages.vertex_properties();
    let extra = layers
        .as_mut()
        .map(|l| &mut **l as &mut dyn VertexProperties);
    Ok(spool.finish_with(&outputs, extra)?)
}
