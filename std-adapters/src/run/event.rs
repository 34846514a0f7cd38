//! What a frame's event carries beside its record ([`Run::event`]): the samples that came with
//! the frame, how well its registration pinned the pose down, and, for sinks that want the
//! map, the frame's own points. The run keeps them here from the frame's step to its event.

use crate::run::report::FrameRecord;
use crate::run::session::Run;
use crate::run::sink::{FrameEvent, MapUpdate};
use crate::sources::Sample;
use slamesh_core::lm::PoseInformation;
use slamesh_core::{Capacity, Point};

/// See the module docs.
#[derive(Debug, Default)]
pub(super) struct EventParts {
    /// The samples that are not scans that came with the last frame.
    pub(super) samples: Vec<Sample>,
    /// How well the last used frame's registration pinned its pose down (for a sink's
    /// covariance).
    pub(super) information: Option<PoseInformation>,
    /// The last used frame's own points, for its event's map update
    /// ([`Run::hand_own_points`]); `None`: not kept.
    pub(super) own_points: Option<Vec<Point>>,
}

impl<C: Capacity> Run<'_, C> {
    /// From now on a used frame's own points go to its event's map update
    /// ([`MapUpdate::own_points`]; moved, not copied), and a frame filtered ahead keeps them.
    pub fn hand_own_points(&mut self) {
        self.event.own_points = Some(Vec::new());
        self.ahead.keep_points();
    }

    /// What the sinks are told of the frame `record` describes: its pose at its stamp when it
    /// was used, the samples that came with it, and with `want_map` the map as it changed it
    /// (with the layers the stages changed elsewhere; the whole map and the corrected path
    /// when loops were closed with it).
    pub fn event(&mut self, record: FrameRecord, want_map: bool) -> FrameEvent {
        let samples = std::mem::take(&mut self.event.samples);
        let information = self.event.information.take();
        let poses = &self.progress.poses;
        let pose = (record.error.is_none())
            .then(|| {
                poses
                    .last()
                    .filter(|(j, _)| *j == record.frame)
                    .map(|(_, p)| *p)
            })
            .flatten();
        let map = match (
            want_map && record.error.is_none(),
            record.notes.moved.is_empty(),
        ) {
            (false, _) => None,
            (true, true) => MapUpdate::of(&self.pipeline, record.frame, record.stamp)
                .map(|u| u.with_changed(self.pipeline.map(), self.stages.changed())),
            (true, false) => MapUpdate::after_closure(
                &self.pipeline,
                record.frame,
                record.stamp,
                poses.iter().map(|(_, p)| *p).collect(),
                record.notes.moved.clone(),
            ),
        };
        let own = self.event.own_points.as_mut().map(std::mem::take);
        let map = map.map(|u| MapUpdate {
            own_points: own.unwrap_or_default(),
            ..u
        });
        FrameEvent {
            record,
            pose,
            map,
            samples,
            information: pose.and(information),
        }
    }
}
