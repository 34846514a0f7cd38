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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::run::checkpoint::{self, Progress};
    use crate::sources::{ImuReading, Sample};
    use crate::stage::{Stages, Used};
    use slamesh_core::cell::{Axis, CellKey};
    use slamesh_core::layer::Layer;
    use slamesh_core::map::MeshMap;
    use slamesh_core::{KittiCapacity, RegistrationStatus};

    /// An IMU stage that took half a second of still readings at 200 Hz, levelled the map's
    /// first scan and learned from it: a run's stages with it, and their checkpoint state.
    fn stages_after_a_frame() -> (Stages<KittiCapacity>, Vec<u8>) {
        let mut stages = Stages::<KittiCapacity>::new();
        stages.push(Box::new(ImuStage::new::<KittiCapacity>(
            ImuOptions::default(),
        )));
        let samples: Vec<Sample> = (0..100)
            .map(|k| {
                Sample::Imu(ImuReading {
                    stamp: k as f64 * 0.005,
                    gyro: [0.001, 0.0, 0.002],
                    accel: [0.1, 0.0, 9.8],
                })
            })
            .collect();
        let (file, reference) = ("seed", 0.5);
        (stages).read(&crate::stage::Read {
            frame: 0,
            file,
            samples: &samples,
        });
        let level = stages.prior(&crate::stage::PriorAt {
            frame: 0,
            file,
            reference,
            history: (None, None),
            first: true,
        });
        assert!(level.is_some(), "levelled by the still readings");
        let workers = crate::parallel::Workers::new(1).unwrap();
        let mut notes = crate::stage::Notes::default();
        let used = Used {
            frame: 0,
            status: RegistrationStatus::FirstScan,
            reference,
            history: (None, Some(Pose::identity())),
            at_stamp: &Pose::identity(),
            fused_at: &Pose::identity(),
            information: &Default::default(),
            counter: 1,
            fused_points: &[],
            points: &[],
            workers: &workers,
        };
        stages.used(&used, &mut notes);
        let mut state = Vec::new();
        stages.save(&mut state);
        (stages, state)
    }

    #[test]
    fn the_imu_s_state_goes_through_a_checkpoint_and_back() {
        let (stages, state) = stages_after_a_frame();
        assert!(!state.is_empty());
        let (mut back, _) = stages_after_a_frame();
        back.restore(&state).unwrap();
        let mut again = Vec::new();
        back.save(&mut again);
        assert_eq!(again, state);
        assert_eq!(back.summaries(), stages.summaries());
        assert!(stages.up().is_some(), "up from gravity");
    }

    /// Writes the fuzz target `checkpoint`'s seed (fuzz/corpus/checkpoint/imu): a checkpoint
    /// of two frames, one cell and the stages' state above, in the format this build writes.
    /// `cargo test -p slamesh --lib write_the_checkpoint_fuzz_seed -- --ignored`
    #[test]
    #[ignore = "writes the fuzz seed into fuzz/corpus"]
    fn write_the_checkpoint_fuzz_seed() {
        let (_, state) = stages_after_a_frame();
        let lattice = slamesh_core::lattice::Lattice {
            cell_size: 1.6,
            full_cover: true,
        };
        let mut map = MeshMap::with_capacity(4, 4, lattice);
        let ground = Layer {
            pred: [0.4; slamesh_core::lattice::VERTICES],
            var: [0.05; slamesh_core::lattice::VERTICES],
            ..Layer::UNKNOWN
        };
        map.insert_layer(CellKey::new(0, 0, -1), Axis::Z, ground, 1)
            .unwrap();
        let progress = Progress {
            fingerprint: "input \"seed\", 3 frames".into(),
            next_frame: 2,
            pipeline_frames: 2,
            poses: vec![(0, Pose::identity()), (1, Pose::identity())],
            seconds: 0.2,
            stages: state,
            ..Progress::new(String::new())
        };
        let file = concat!(env!("CARGO_MANIFEST_DIR"), "/../fuzz/corpus/checkpoint/imu");
        checkpoint::write(std::path::Path::new(file), &progress, &map).unwrap();
    }
}
