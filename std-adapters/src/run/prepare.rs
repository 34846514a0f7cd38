//! A frame's scan on its way to the pipeline ([`Frame`]): as read (or filtered ahead), deskewed
//! (by a stage, the IMU's, or with the last motion), checked against the capacity class, with
//! its given pose when meshing at given poses, or the prior a stage gives.

use crate::io::error::FileError;
use crate::run::capacity;
use crate::run::frame_error::FrameFault;
use crate::run::lookahead::{Ahead, Scan as ReadScan};
use crate::run::options::Deskew;
use crate::run::report::FrameRecord;
use crate::run::session::Run;
use crate::stage::{PriorAt, Sweep};
use slamesh_core::deskew;
use slamesh_core::{Capacity, Point, Pose};
use std::time::Instant;

/// A frame's scan on its way to the pipeline.
#[derive(Debug, Default)]
pub(super) struct Frame {
    /// Its points as read (none when filtered ahead, unless the look-ahead keeps them),
    /// deskewed once prepared.
    pub(super) points: Vec<Point>,
    /// Their times relative to the stamp, when the source records them.
    pub(super) times: Option<Vec<f32>>,
    /// The scan filtered ahead on the pool, instead of `points`.
    pub(super) ahead: Option<Ahead>,
    /// The motion, interval and reference time a deskewed scan was moved with: its pose is
    /// the reference time's, and the trajectory takes it back to the stamp.
    pub(super) to_stamp: Option<(Pose, f64, f64)>,
    /// The pose to mesh it at (meshing at given poses), at the scan's time.
    pub(super) given: Option<Pose>,
    /// The time its pose is at (the LiDAR's clock): the stamp, or a deskewed sweep's middle.
    pub(super) reference: f64,
    /// Where a stage puts it, to register from (the IMU's).
    pub(super) prior: Option<Pose>,
}

impl Frame {
    /// The frame as read, counting its points into `rec`.
    pub(super) fn of(
        scan: Result<ReadScan, FileError>,
        rec: &mut FrameRecord,
    ) -> (Self, Result<(), FrameFault>) {
        match scan {
            Ok(ReadScan::Raw { points, times }) => {
                rec.points = points.len();
                let frame = Frame {
                    points,
                    times,
                    ..Frame::default()
                };
                (frame, Ok(()))
            }
            Ok(ReadScan::Filtered { points, mut ahead }) => {
                rec.points = points;
                (
                    Frame {
                        // The scan's own points when the look-ahead kept them.
                        points: std::mem::take(&mut ahead.raw),
                        ahead: Some(ahead),
                        ..Frame::default()
                    },
                    Ok(()),
                )
            }
            Err(e) => (Frame::default(), Err(FrameFault::Unreadable(e))),
        }
    }
}

impl<C: Capacity> Run<'_, C> {
    /// Deskews the scan (with the IMU's rotations, or the last motion), checks it fits the
    /// capacity, takes its given pose, if the run meshes at given poses, and the IMU's prior.
    pub(super) fn prepare(
        &mut self,
        frame: &mut Frame,
        motion: Option<(Pose, f64)>,
        i: usize,
        rec: &mut FrameRecord,
    ) -> Result<(), FrameFault> {
        frame.reference = rec.stamp;
        if let Some(times) = frame
            .times
            .as_deref()
            .filter(|_| self.opts.deskew != Deskew::Off)
        {
            let t = Instant::now();
            let d = self.deskew(&mut frame.points, times, rec.stamp, motion)?;
            if let Some(d) = d.filter(|d| d.moved > 0) {
                rec.deskewed_points = d.moved;
                frame.reference = rec.stamp + d.reference_s;
                // The points now sit in the sensor frame at `reference_s`.
                frame.to_stamp = motion.map(|(m, dt)| (m, dt, d.reference_s));
            }
            rec.ms.deskew = t.elapsed().as_secs_f64() * 1e3;
        }
        fits_capacity::<C>(&frame.points, &self.opts.config.filter)?;
        frame.given = self.given_pose(i, rec.stamp, frame.to_stamp)?;
        if frame.given.is_none() && self.stages.search().is_none() {
            let history = self.pipeline.motion().history();
            frame.prior = self.stages.prior(&PriorAt {
                frame: i,
                file: &rec.file,
                reference: frame.reference,
                history,
                // The map's first scan: the prior places the map (levels it).
                first: history.1.is_none() && self.pipeline.map().is_empty(),
            });
        }
        Ok(())
    }

    /// Deskews `points` (times after `stamp`) as `--deskew` says: by a stage when one can (the
    /// IMU's rotations, when they cover the sweep), otherwise with the last `motion`; `None`
    /// when neither can.
    fn deskew(
        &mut self,
        points: &mut [Point],
        times: &[f32],
        stamp: f64,
        motion: Option<(Pose, f64)>,
    ) -> Result<Option<deskew::Deskewed>, FrameFault> {
        if self.opts.deskew != Deskew::Motion {
            let history = self.pipeline.motion().history();
            let mut sweep = Sweep {
                points: &mut *points,
                times,
                stamp,
                history,
            };
            match self.stages.deskew(&mut sweep) {
                Some(Ok(d)) => return Ok(Some(d)),
                Some(Err(e)) => return Err(FrameFault::CannotDeskew(e)),
                None => {}
            }
        }
        motion
            .map(|(m, dt)| deskew::deskew(points, times, &m, dt))
            .transpose()
            .map_err(FrameFault::CannotDeskew)
    }

    /// The pose given for frame `i` (stamp `stamp`), moved to a deskewed scan's reference time.
    fn given_pose(
        &self,
        i: usize,
        stamp: f64,
        to_stamp: Option<(Pose, f64, f64)>,
    ) -> Result<Option<Pose>, FrameFault> {
        let Some(p) = &self.opts.given_poses else {
            return Ok(None);
        };
        let g = p.pose_at(i, stamp).ok_or(FrameFault::NoGivenPose {
            by_time: p.stamps.as_ref().map(|_| (p.tolerance_s(), stamp)),
            line: i + 1,
        })?;
        // A given pose is the stamp's; a deskewed scan is fused at its reference time.
        Ok(Some(match to_stamp {
            Some((m, dt, reference)) => deskew::pose_at(&g, &m, dt, reference),
            None => g,
        }))
    }
}

/// Refuses a scan with more points within range than the capacity `C` holds, naming the
/// class that would hold them, rather than cut it silently.
fn fits_capacity<C: Capacity>(
    points: &[Point],
    filter: &slamesh_core::config::FilterConfig,
) -> Result<(), FrameFault> {
    if points.len() <= C::POINTS {
        return Ok(());
    }
    let n = capacity::points_in_range(points, filter);
    if n <= C::POINTS {
        return Ok(());
    }
    Err(FrameFault::OverCapacity {
        points: n,
        class: C::NAME,
        holds: C::POINTS,
        larger: capacity::class_holding(n),
    })
}
