//! The search for the pose in a saved map, and its paging, as one of a run's stages
//! ([`crate::stage::RunStage`]). A run from a saved map with no pose given searches for its
//! first pose along the map's path, frame after frame until one is found; a user's request to
//! relocalize (the ROS 2 node's `initialpose`) has the next frames search near the pose given,
//! then along the path. Under a memory cap a localizing run's map is paged: between frames
//! the tiles around the predicted pose are made resident (while a search runs, the search
//! pages). The frame whose search found the pose notes how (`relocalization`).
//!
//! Holds the search's candidates until a frame finds the pose, the pager, and the map's path
//! and cell size (a request's candidates). Every run has it: without a map and a request it
//! does nothing.

use crate::io::error::FileError;
use crate::localize::pager::MapPager;
use crate::localize::search::{candidates, found};
use crate::stage::lent::Between;
use crate::stage::{Note, RunStage, Searching, Start};
use slamesh_core::pipeline::Relocalized;
use slamesh_core::relocalize::{AllResident, Paging};
use slamesh_core::{Capacity, Pose, RegistrationStatus};

/// The search for the pose, and the paged map (see the module docs).
#[derive(Default)]
pub struct MapSearch {
    /// Where to search, until a frame finds the pose.
    search: Option<Vec<Pose>>,
    /// The saved map paged in under a memory cap (localizing only).
    pager: Option<MapPager>,
    /// The saved map's path, stamped (a request searches along it after the pose given).
    path: Vec<(f64, Pose)>,
    /// The map's cell edge (the candidates' spacing).
    spacing_m: f64,
    /// What the search pages with when the whole map is resident: nothing.
    resident: AllResident,
}

impl MapSearch {
    /// A search of `search`'s candidates from the first frame (`None`: the pose follows from
    /// the map's end, or there is no map), in a map paged by `pager` when given.
    pub fn new(search: Option<Vec<Pose>>, pager: Option<MapPager>) -> Self {
        Self {
            search,
            pager,
            ..Self::default()
        }
    }
}

impl<C: Capacity> RunStage<C> for MapSearch {
    fn name(&self) -> &'static str {
        "map_search"
    }

    fn start(&mut self, start: &Start<'_>) -> Result<(), FileError> {
        self.path = start.map.map_or_else(Vec::new, |(_, path)| path.to_vec());
        self.spacing_m = start.config.grid.cell_size_m;
        Ok(())
    }

    fn between(&mut self, run: &mut Between<'_, C>) -> Option<Note> {
        if let (Some(pager), None) = (&mut self.pager, &self.search) {
            let predicted = run.pipeline.motion().predict();
            pager.around(run.pipeline.map_mut(), &predicted);
        }
        None
    }

    fn search(&mut self) -> Option<Searching<'_>> {
        let candidates = self.search.as_deref()?;
        let paging: &mut (dyn Paging + Send) = match &mut self.pager {
            Some(pager) => pager,
            None => &mut self.resident,
        };
        Some(Searching { candidates, paging })
    }

    fn searched(&mut self, frame: usize, r: &Relocalized) -> Option<Note> {
        if r.outcome.status != RegistrationStatus::Relocalized {
            return None;
        }
        let said = found(r);
        log::info!("frame {frame}: {said}");
        self.search = None;
        Some(Note {
            jumped: true,
            ..Note::of("relocalization", said)
        })
    }

    fn relocalize(&mut self, near: Pose) -> bool {
        let along = candidates(&self.path, self.spacing_m);
        self.search = Some(std::iter::once(near).chain(along).collect());
        true
    }

    fn failed(&mut self) -> Option<FileError> {
        self.pager.as_mut().and_then(MapPager::take_error)
    }

    fn wind_up(&mut self, _run: &mut Between<'_, C>) {
        if let Some(p) = &self.pager {
            log::info!("map paged: {}", p.stats());
        }
    }
}
