//! The navigation map as a stage of a run ([`crate::stage::RunStage`]): during the run it keeps
//! the floor the scans' points saw ([`Hits`], unless a window or a memory cap bounds the run)
//! and writes it beside every map saved ([`floor_file`]); at the end it makes the navigation
//! files from the whole map's mesh ([`super::make`]) and gives the mesh files its layers on
//! their vertices ([`OnMesh`]).
//!
//! Without the navigation map (no options) it keeps nothing, and a map saved where one was
//! saved with a floor file before loses that file, which went with the old map.

use crate::formats::mesh_records::VertexProperties;
use crate::io::error::FileError;
use crate::navmap::files::{NavMapSummary, FILES};
use crate::navmap::floor_file::{self, FloorFile, MapPath};
use crate::navmap::hits::{Hits, ScanFloor};
use crate::navmap::layers::OnMesh;
use crate::navmap::{Grid, NavMapOptions, Robot};
use crate::outputs::mesh_spool::MeshSpool;
use crate::stage::{End, Note, RunStage, Start, Used};
use slamesh_core::{Capacity, Pose};
use std::path::Path;

/// See the module docs.
#[derive(Default)]
pub struct NavMapStage {
    /// How the map is made; `None`: no navigation map.
    how: Option<NavMapOptions>,
    /// The floor this run's scans saw.
    hits: Option<Hits>,
    /// What the map the run started from kept beside it, read at the start: a save during the
    /// run may replace that file.
    carried: Option<FloorFile>,
    /// The grid made at the end, for the mesh files' layers.
    made: Option<(Grid, Robot)>,
    summary: Option<NavMapSummary>,
}

impl NavMapStage {
    /// The stage of a run with the navigation map made as `how` says (`None`: none).
    pub fn new(how: Option<NavMapOptions>) -> Self {
        Self {
            how,
            ..Self::default()
        }
    }

    /// Writes the scans' floor (the carried one, then this run's) beside the map saved at
    /// `map` with `path`, or removes the floor file there, which went with the map saved
    /// before; says which.
    fn floor_beside(
        &self,
        map: &Path,
        path: &[(f64, Pose)],
        poses: &[(usize, Pose)],
    ) -> Result<Option<String>, FileError> {
        let (Some(how), Some(hits)) = (&self.how, &self.hits) else {
            return Ok(floor_file::remove_beside(map).map(|stale| {
                format!(
                    "removed {}, which went with the map saved before",
                    stale.display()
                )
            }));
        };
        let beside = floor_file::beside(map);
        let floors = |each: &mut dyn FnMut(ScanFloor)| {
            floor_file::each_kept(self.carried.as_ref(), Some(hits), poses, each)
        };
        let n = floor_file::write(&beside, how.resolution_m, MapPath::of(path), &floors)?;
        Ok(Some(format!(
            "the scans' floor beside it, {n} floor cells: {}",
            beside.display()
        )))
    }
}

impl<C: Capacity> RunStage<C> for NavMapStage {
    fn name(&self) -> &'static str {
        "navmap"
    }

    /// The scans' floor grows with the area driven: not in a run whose memory a window
    /// bounds (its grid is the mesh's alone, as from a saved map).
    fn start(&mut self, start: &Start<'_>) -> Result<(), FileError> {
        let Some(how) = &self.how else {
            return Ok(());
        };
        if !start.bounded {
            self.hits = Some(Hits::new(how.resolution_m, &how.up().0));
        }
        self.carried = start
            .map
            .and_then(|(map, path)| floor_file::read_beside(map, path));
        Ok(())
    }

    /// The floor counts the scan's own points.
    fn needs_points(&self) -> bool {
        self.hits.is_some()
    }

    fn used(&mut self, frame: &Used<'_>) -> Option<Note> {
        if let Some(h) = &mut self.hits {
            let (i, points, workers) = (frame.frame, frame.points, frame.workers);
            h.add(i, frame.at_stamp, frame.fused_at, points, workers);
        }
        None
    }

    /// The map is saved either way: a floor file that could not be written is said (one left
    /// from before does not go with the new map: passed over).
    fn beside_map(
        &self,
        map: &Path,
        path: &[(f64, Pose)],
        poses: &[(usize, Pose)],
    ) -> Result<Option<String>, FileError> {
        Ok(Some(match self.floor_beside(map, path, poses) {
            Ok(said) => return Ok(said),
            Err(e) => {
                log::warn!("{e}");
                format!("the scans' floor not beside it: {e}")
            }
        }))
    }

    /// Makes the navigation files (none when no frame was used), up as `end.up` says unless
    /// the options say; the scans' floor goes beside the map saved at the end.
    fn finish(&mut self, mesh: &mut MeshSpool, end: &End<'_>) -> Result<(), FileError> {
        let Some(mut how) = self.how.clone().filter(|_| !end.poses.is_empty()) else {
            if let (Some((map, _)), None) = (end.saved_map, &self.hits) {
                if let Some(stale) = floor_file::remove_beside(map) {
                    log::info!(
                        "removed {}: it went with the map saved before",
                        stale.display()
                    );
                }
            }
            return Ok(());
        };
        if how.up.is_none() {
            how.up = end.up.clone();
        }
        if let Some(h) = &self.hits {
            log::debug!("navigation map: the scans' floor took {} bytes", h.bytes());
        }
        let path: Vec<_> = (end.poses.iter())
            .map(|(_, p)| p.translation.vector)
            .collect();
        let floors = |each: &mut dyn FnMut(ScanFloor)| {
            floor_file::each_kept(self.carried.as_ref(), self.hits.as_ref(), end.poses, each)
        };
        let (summary, grid) = super::make(mesh, &floors, &path, &how, end.out)?;
        if let Some((map, saved_path)) = end.saved_map {
            if let Some(said) = self.floor_beside(map, saved_path, end.poses)? {
                log::info!("{said}");
            }
        }
        (self.hits, self.carried) = (None, None);
        self.made = summary.is_some().then_some((grid, how.robot));
        self.summary = summary;
        Ok(())
    }

    fn vertex_properties(&self) -> Option<Box<dyn VertexProperties + '_>> {
        let (grid, robot) = self.made.as_ref()?;
        Some(Box::new(OnMesh::new(grid, *robot)))
    }

    fn summary(&self) -> Option<serde_json::Value> {
        serde_json::to_value(self.summary.as_ref()?).ok()
    }

    fn outputs(&self) -> &'static [&'static str] {
        &FILES
    }
}
