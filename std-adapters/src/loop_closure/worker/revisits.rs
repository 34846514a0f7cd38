//! Where the loop-closure thread finds a revisit (docs/design.md §1.14): of the run's own
//! path, checked in the local map of the earlier frames' scans, or of the saved map's path
//! the run started from, checked in the saved map's tiles near it.

use super::Worker;
use crate::io::error::FileError;
use crate::loop_closure::detect::{self, Past, Verified};
use slamesh_core::{Capacity, Pose};

/// A verified revisit and what its loop edge joins.
pub(super) struct Found {
    pub(super) v: Verified,
    /// The graph node the edge starts from.
    pub(super) node: usize,
    /// The earlier frame (this run's) or the saved path's pose it was found near.
    pub(super) with_frame: usize,
    pub(super) in_saved_map: bool,
}

impl<C: Capacity> Worker<C> {
    /// A revisit of this run's own path by keyframe `kf` (at `pose`, `travelled` metres
    /// along), checked in the local map of the earlier frames' scans.
    pub(super) fn revisit_in_run(
        &mut self,
        kf: usize,
        pose: &Pose,
        travelled: f64,
    ) -> Result<Option<Found>, FileError> {
        let past = self
            .frames
            .iter()
            .zip(&self.correction)
            .enumerate()
            .map(|(i, (f, c))| Past {
                index: i,
                pose: c * f.raw,
                travelled_m: f.travelled_m,
            });
        let Some(mut revisit) = detect::revisit(&self.s, pose, travelled, past) else {
            return Ok(None);
        };
        let Some(submap) = self.submap.as_deref_mut() else {
            return Ok(None);
        };
        if self.streaming.is_some() {
            // The local map may be smaller than its frames make (a windowed run's): the
            // nearest are fused first, the farthest lose what does not fit.
            let d = |p: &Past| (p.pose.translation.vector - pose.translation.vector).norm();
            revisit.submap.sort_by(|a, b| d(a).total_cmp(&d(b)));
        }
        let points = self.spool.read(kf)?;
        let t = std::time::Instant::now();
        let spool = &mut self.spool;
        let verified = detect::verify(&self.s, submap, &points, pose, travelled, &revisit, |i| {
            spool.read(i)
        })?;
        log::debug!(
            "loop closure: frame {} checked against {} earlier frames ({} in the local map) in {:.0} ms: {}",
            self.frames[kf].frame,
            revisit.near.len(),
            revisit.submap.len(),
            t.elapsed().as_secs_f64() * 1e3,
            if verified.is_some() { "found" } else { "not found" }
        );
        let Some(v) = verified else {
            return Ok(None);
        };
        // The earlier node nearest to the pose found anchors the loop edge.
        let nearest = revisit.near.iter().min_by(|x, y| {
            let d = |p: &Past| {
                let n = self.frames[p.index].node;
                (self.graph.nodes[n].translation.vector - v.pose.translation.vector).norm()
            };
            d(x).total_cmp(&d(y))
        });
        Ok(nearest.map(|p| {
            let node = self.frames[p.index].node;
            Found {
                v,
                node,
                with_frame: self.frames[self.node_frame[node]].frame,
                in_saved_map: false,
            }
        }))
    }

    /// A revisit of the saved map's path (the earlier session's) by keyframe `kf`, checked in
    /// the saved map's cells near it ([`SavedMap::load_near`]). Its edge is to the run's first
    /// keyframe, which the run placed in the saved map when it started and the graph holds.
    pub(super) fn revisit_in_saved(
        &mut self,
        kf: usize,
        pose: &Pose,
        travelled: f64,
    ) -> Result<Option<Found>, FileError> {
        let (Some(saved), Some(submap)) = (&mut self.saved, self.submap.as_deref_mut()) else {
            return Ok(None);
        };
        // The earlier session's poses count as where this run started: the drift allowed is
        // this run's whole travel's.
        let past = (saved.path.iter().enumerate()).map(|(i, p)| Past {
            index: i,
            pose: *p,
            travelled_m: 0.0,
        });
        let Some(revisit) = detect::revisit(&self.s, pose, travelled, past) else {
            return Ok(None);
        };
        let points = self.spool.read(kf)?;
        submap.map_mut().clear();
        let near: Vec<Pose> = revisit.near.iter().map(|p| p.pose).collect();
        if let Err(e) = saved.load_near(&near, self.s.submap_margin_m, submap.map_mut()) {
            // The file was read whole when the run started: what fails here is room.
            log::debug!(
                "loop closure: the saved map near frame {}: {e}",
                self.frames[kf].frame
            );
            return Ok(None);
        }
        let verified = detect::search(&self.s, submap, &points, pose, travelled, &revisit);
        log::debug!(
            "loop closure: frame {} checked against the saved map ({} poses of its path near): {}",
            self.frames[kf].frame,
            revisit.near.len(),
            if verified.is_some() {
                "found"
            } else {
                "not found"
            }
        );
        let Some(v) = verified else {
            return Ok(None);
        };
        let at = v.pose.translation.vector;
        let nearest = (revisit.near.iter())
            .min_by(|x, y| {
                let d = |p: &Past| (p.pose.translation.vector - at).norm();
                d(x).total_cmp(&d(y))
            })
            .map_or(0, |p| p.index);
        Ok(Some(Found {
            v,
            node: 0,
            with_frame: nearest,
            in_saved_map: true,
        }))
    }
}
