//! The IMU as a stage of a run ([`crate::stage::RunStage`]): it takes the readings that come
//! with each frame, deskews a scan whose sweep they cover, gives the prior a frame registers
//! from (levelling the map's first scan), moves a deskewed scan's pose to its stamp, learns
//! from each registered frame, and keeps its state in a checkpoint. Each used frame's record
//! notes what it did (`imu`), a frame the readings did not cover is doubted (`ImuGap`), and
//! the run's summary has its totals (`imu`).

use crate::inertial::{ImuFrame, ImuOptions, Inertial};
use crate::io::le::Damaged;
use crate::stage::{History, Note, PriorAt, Read, RunStage, Sweep, Used};
use nalgebra::Vector3;
use slamesh_core::deskew::{DeskewError, Deskewed};
use slamesh_core::{Capacity, Pose};

/// See the module docs.
pub struct ImuStage {
    inertial: Inertial,
    /// What it did for the frame in progress.
    frame: ImuFrame,
}

impl ImuStage {
    /// The stage of a run whose IMU is used as `options` say, holding at most the capacity's
    /// readings.
    pub fn new<C: Capacity>(options: ImuOptions) -> Self {
        Self {
            inertial: Inertial::new::<C>(options),
            frame: ImuFrame::default(),
        }
    }
}

impl<C: Capacity> RunStage<C> for ImuStage {
    fn name(&self) -> &'static str {
        "imu"
    }

    fn read(&mut self, frame: &Read<'_>) {
        self.frame = ImuFrame::default();
        self.inertial.take(frame.samples, frame.file, frame.frame);
    }

    /// With the gyro's rotations when the readings cover the sweep; a gap is noted, and the
    /// run deskews with the last motion instead.
    fn deskew(&mut self, sweep: &mut Sweep<'_>) -> Option<Result<Deskewed, DeskewError>> {
        if !self.inertial.active() {
            return None;
        }
        let (stamp, history) = (sweep.stamp, sweep.history);
        match self
            .inertial
            .deskew(sweep.points, sweep.times, stamp, history)
        {
            Ok(d) => {
                self.frame.deskewed = true;
                Some(Ok(d))
            }
            Err(DeskewError::Imu(gap)) => {
                self.frame.missed(gap);
                None
            }
            Err(e) => Some(Err(e)),
        }
    }

    /// The map's first scan levelled when the accelerometer says which way is up; later ones
    /// where the gyro turned the last pose.
    fn prior(&mut self, at: &PriorAt<'_>) -> Option<Pose> {
        if !self.inertial.active() {
            return None;
        }
        if at.first {
            return self.inertial.level(at.reference, at.file, at.frame);
        }
        match self.inertial.prior(at.history, at.reference) {
            Some(Ok(p)) => {
                self.frame.prior = true;
                Some(p)
            }
            Some(Err(gap)) if self.frame.gap.is_none() => {
                self.frame.missed(gap);
                None
            }
            _ => None,
        }
    }

    fn at_stamp(
        &self,
        fused_at: &Pose,
        reference: f64,
        stamp: f64,
        history: History,
    ) -> Option<Pose> {
        (self.frame.deskewed)
            .then(|| self.inertial.moved(fused_at, reference, stamp, history))
            .flatten()
    }

    fn used(&mut self, frame: &Used<'_>) -> Option<Note> {
        let (status, history) = (frame.status, frame.history);
        (self.inertial).used(frame.reference, status, history, self.frame.prior);
        if !self.inertial.active() {
            return None;
        }
        self.inertial.count(&self.frame);
        Some(Note {
            doubt: self.frame.gap.clone().map(|gap| ("ImuGap", gap)),
            ..Note::of("imu", &self.frame)
        })
    }

    fn save(&self, state: &mut Vec<u8>) {
        self.inertial.save(state);
    }

    fn restore(&mut self, state: &[u8]) -> Result<(), Damaged> {
        self.inertial.restore(state)
    }

    /// Up from gravity, when the map was levelled.
    fn up(&self) -> Option<(Vector3<f64>, String)> {
        self.inertial.navmap_up()
    }

    fn summary(&self) -> Option<serde_json::Value> {
        serde_json::to_value(self.inertial.summary()?).ok()
    }
}
