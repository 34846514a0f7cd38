//! What works inside a run beside registration, plugged in: a [`RunStage`] (not the core's
//! `Stage`, which names the pipeline's own steps for timing) is told the run's start and each
//! frame as read; may deskew its scan and give the pose it registers from; sees the scan
//! fused (and may change the map) and the pose kept; notes what it did in the frame's record
//! (and why it doubts the frame); keeps its state in a checkpoint; writes what goes beside a
//! map saved during or at the end of the run; and has the whole map, read-only, at the end,
//! for its files and its part of the run's summary. Between frames a stage may move the run
//! as a whole (a loop closed: the trajectory, the motion model, a rebuilt map), with what the
//! run lends it for that ([`lent`]).
//!
//! A run holds its stages as a list ([`Stages`]) and names none of them: each lives in its
//! own room (the IMU in [`crate::inertial::stage`], clearing what moves in [`crate::dynamic`],
//! the navigation map in [`crate::navmap::stage`], loop closure in
//! [`crate::loop_closure::stage`]) and `run/wiring.rs` is the one list that
//! wires them from the options; a caller adds its own ([`crate::run::run_with`]). A run's
//! stages are called in the list's order, on the run's thread, between the core's steps: what
//! they do is the same on any thread count. Where one answer is wanted (a deskew, a prior, up)
//! the first stage that gives one gives it.

pub mod lent;

use crate::formats::mesh_records::VertexProperties;
use crate::io::error::FileError;
use crate::io::le::{put_str, put_u64, Damaged, Decoder};
use crate::outputs::mesh_spool::MeshSpool;
use crate::parallel::Workers;
use crate::sources::Sample;
use lent::{Between, Windowed};
use nalgebra::Vector3;
use slamesh_core::cell::{Axis, CellKey};
use slamesh_core::deskew::{DeskewError, Deskewed};
use slamesh_core::lm::PoseInformation;
use slamesh_core::pipeline::Relocalized;
use slamesh_core::relocalize::Paging;
use slamesh_core::{Capacity, Config, Pipeline, Point, Pose, RegistrationStatus};
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

/// A capability that works inside a run. Every hook has a default that does nothing.
pub trait RunStage<C: Capacity>: Send {
    /// Its name: the key of its part of the run's summary.
    fn name(&self) -> &'static str;

    /// The bytes it takes at most, counted with the rest of the process under a memory cap.
    fn bytes(&self) -> usize {
        0
    }

    /// The run starts (anew or resumed), before its first frame: an error stops the run
    /// before it begins.
    fn start(&mut self, _start: &Start<'_>) -> Result<(), FileError> {
        Ok(())
    }

    /// Whether it needs each used frame's own points ([`Used::points`]; asked after
    /// [`start`](Self::start)).
    fn needs_points(&self) -> bool {
        false
    }

    /// Between frames, before frame `run.next_frame` is read: may change the map (a paged
    /// map's tiles around the predicted pose) or move the run as a whole (every pose of the
    /// trajectory, the motion model, the map: a loop closed). Returns a note for that frame's
    /// record, which says what moved ([`Note::moved`]).
    fn between(&mut self, _run: &mut Between<'_, C>) -> Option<Note> {
        None
    }

    /// The run's last frame has run: the last of what [`between`](Self::between) does, waited
    /// for, before the map is written.
    fn wind_up(&mut self, _run: &mut Between<'_, C>) {}

    /// Where the frame's pose is searched for, when this stage has it searched (the first
    /// that does): the pose is then neither predicted nor given a prior.
    fn search(&mut self) -> Option<Searching<'_>> {
        None
    }

    /// A search ran ([`search`](Self::search)), with what it found. Returns a note for the
    /// frame's record ([`Note::jumped`] when the pose was found).
    fn searched(&mut self, _frame: usize, _found: &Relocalized) -> Option<Note> {
        None
    }

    /// The next frames are to search for their pose near `near` (a user's request): true when
    /// this stage will.
    fn relocalize(&mut self, _near: Pose) -> bool {
        false
    }

    /// What failed in what it reads or writes beside the frames (a paged map's file), once: the
    /// run stops with it after the frame.
    fn failed(&mut self) -> Option<FileError> {
        None
    }

    /// A frame was read, with the samples that are not scans that came with it (an IMU's).
    fn read(&mut self, _frame: &Read<'_>) {}

    /// Deskews the frame's scan when it can (the first stage that does deskews it; without
    /// one, the run deskews with the last motion): `None` when it does not.
    fn deskew(&mut self, _sweep: &mut Sweep<'_>) -> Option<Result<Deskewed, DeskewError>> {
        None
    }

    /// Where the frame's sensor is at its reference time, to register from (the first stage
    /// that knows gives it; asked only when the pose is neither given nor searched for).
    fn prior(&mut self, _at: &PriorAt<'_>) -> Option<Pose> {
        None
    }

    /// The pose at the frame's stamp of a scan this stage deskewed, fused at `fused_at`
    /// (its pose at `reference`); `None` to leave it to the run's motion model.
    fn at_stamp(
        &self,
        _fused_at: &Pose,
        _reference: f64,
        _stamp: f64,
        _history: History,
    ) -> Option<Pose> {
        None
    }

    /// The frame's scan was fused into `pipeline`'s map at `pose`: it may change the map.
    /// Returns a note for the frame's record.
    fn fused(&mut self, _pipeline: &mut Pipeline<C>, _pose: &Pose) -> Option<Note> {
        None
    }

    /// The map's layers it changed in its last [`fused`](Self::fused), beyond the frame's own
    /// (what clearing made forget a vertex): the frame's map update carries them too, so that
    /// a sink that keeps the map sends them again.
    fn changed(&self) -> &[(CellKey, Axis)] {
        &[]
    }

    /// A used frame's pose was kept. Returns a note for the frame's record.
    fn used(&mut self, _frame: &Used<'_>) -> Option<Note> {
        None
    }

    /// Appends what a checkpoint keeps of it, for [`restore`](Self::restore); nothing by
    /// default (a resumed run starts it anew).
    fn save(&self, _state: &mut Vec<u8>) {}

    /// Takes back what [`save`](Self::save) wrote, in place of what it holds.
    fn restore(&mut self, _state: &[u8]) -> Result<(), Damaged> {
        Ok(())
    }

    /// Which way is up in the map frame, and what said so, when it knows.
    fn up(&self) -> Option<(Vector3<f64>, String)> {
        None
    }

    /// A map file was saved at `map`, during the run or at its end, with `path` (the stamped
    /// poses it holds, the map it started from first); `poses` are this run's (frame, pose).
    /// Writes what goes with it beside it (or removes what went with the map saved there
    /// before); returns what to add to the message that says the map was saved.
    fn beside_map(
        &self,
        _map: &Path,
        _path: &[(f64, Pose)],
        _poses: &[(usize, Pose)],
    ) -> Result<Option<String>, FileError> {
        Ok(None)
    }

    /// The run's end, once the map is whole and before the mesh files are written: writes its
    /// files from the whole map, read through `mesh` (what the window evicted, then the cells
    /// still in memory).
    fn finish(&mut self, _mesh: &mut MeshSpool, _end: &End<'_>) -> Result<(), FileError> {
        Ok(())
    }

    /// Properties it gives each vertex of the mesh files (after [`finish`](Self::finish)).
    fn vertex_properties(&self) -> Option<Box<dyn VertexProperties + '_>> {
        None
    }

    /// Its part of the run's summary (`report.json`), under its name.
    fn summary(&self) -> Option<serde_json::Value> {
        None
    }

    /// The files it may write into the output folder. A new run removes those a run before
    /// left there, so that what the folder holds after the run is this run's; the summary
    /// lists those that are there at its end.
    fn outputs(&self) -> &'static [&'static str] {
        &[]
    }
}

/// Where a frame's pose is searched for ([`RunStage::search`]).
pub struct Searching<'a> {
    /// Where to look first.
    pub candidates: &'a [Pose],
    /// What makes the map hold what lies around each place searched.
    pub paging: &'a mut (dyn Paging + Send),
}

/// What a stage knows when the run starts.
#[derive(Clone, Copy)]
pub struct Start<'a> {
    /// A window or a memory cap bounds the run's memory: what grows with the area driven is
    /// not kept.
    pub bounded: bool,
    /// The saved map the run starts from, with its path (stamped poses).
    pub map: Option<(&'a Path, &'a [(f64, Pose)])>,
    /// The run's configuration.
    pub config: &'a Config,
    /// The output folder (a stage's scratch files go there, dot-named).
    pub out: &'a Path,
    /// The run's thread count (0: one a core).
    pub threads: usize,
    /// A run whose map is a window: the window, for a stage that rebuilds the map as the run
    /// keeps it (made anew at each call). `None` for a run that keeps its whole map.
    pub windowed: Option<&'a dyn Fn() -> Windowed>,
}

/// The motion model's last two poses, older first (the core's
/// [`slamesh_core::motion::ConstantVelocity::history`]).
pub type History = (Option<Pose>, Option<Pose>);

/// A frame as read ([`RunStage::read`]).
#[derive(Clone, Copy)]
pub struct Read<'a> {
    /// Its index.
    pub frame: usize,
    /// What to call it in messages (its file).
    pub file: &'a str,
    /// The samples that are not scans that came with it, in time order.
    pub samples: &'a [Sample],
}

/// A frame's scan to deskew ([`RunStage::deskew`]).
pub struct Sweep<'a> {
    /// Its points, in the sensor frame.
    pub points: &'a mut [Point],
    /// Each point's time after the stamp (s).
    pub times: &'a [f32],
    /// The frame's stamp (s).
    pub stamp: f64,
    /// The motion model's last two poses.
    pub history: History,
}

/// Where a frame's prior is asked for ([`RunStage::prior`]).
#[derive(Clone, Copy)]
pub struct PriorAt<'a> {
    /// Its index.
    pub frame: usize,
    /// What to call it in messages (its file).
    pub file: &'a str,
    /// The time its pose is at (the stamp, or a deskewed sweep's reference time).
    pub reference: f64,
    /// The motion model's last two poses.
    pub history: History,
    /// It is the map's first scan: the prior places the map (levels it, say).
    pub first: bool,
}

/// What a stage notes in a frame's record.
#[derive(Debug, Clone, PartialEq)]
pub struct Note {
    /// Its key in the record (e.g. `cleared_vertices`, `imu`).
    pub key: &'static str,
    /// Its value there.
    pub value: serde_json::Value,
    /// Why the frame is doubted, when it is: a status and its reason, which the run's health
    /// lists beside the frames not registered normally (e.g. `ImuGap`).
    pub doubt: Option<(&'static str, String)>,
    /// What moved the run as a whole before the frame, each said in a line (a loop closed):
    /// the sinks that keep the map and the path are sent the whole of both again.
    pub moved: Vec<String>,
    /// The frame's pose does not follow from the last one's (found by a search, or the run
    /// moved): what follows the motion (the ROS 2 node's `odom`) is told.
    pub jumped: bool,
}

impl Note {
    /// `value` under `key`, the frame not doubted.
    pub fn of(key: &'static str, value: impl serde::Serialize) -> Self {
        Self {
            key,
            value: serde_json::to_value(value).unwrap_or_default(),
            doubt: None,
            moved: Vec::new(),
            jumped: false,
        }
    }
}

/// What a frame's record keeps of the stages' notes.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Notes {
    /// Each note's value under its key.
    #[serde(flatten)]
    pub values: BTreeMap<String, serde_json::Value>,
    /// Why the frame is doubted: (status, reason), one a note that doubts it.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub doubts: Vec<(String, String)>,
    /// What moved the run as a whole before the frame ([`Note::moved`]; in its note's value
    /// in `report.json`).
    #[serde(skip)]
    pub moved: Vec<String>,
    /// Some note said the pose jumped ([`Note::jumped`]).
    #[serde(skip)]
    pub jumped: bool,
}

impl Notes {
    /// Keeps `note`.
    pub fn add(&mut self, note: Note) {
        if let Some((status, why)) = note.doubt {
            self.doubts.push((status.to_string(), why));
        }
        self.jumped |= note.jumped || !note.moved.is_empty();
        self.moved.extend(note.moved);
        self.values.insert(note.key.to_string(), note.value);
    }
}

/// A used frame, as its pose was kept.
#[derive(Clone, Copy)]
pub struct Used<'a> {
    /// Its index.
    pub frame: usize,
    /// How its registration ended.
    pub status: RegistrationStatus,
    /// The time its fused pose is at (the stamp, or a deskewed sweep's reference time).
    pub reference: f64,
    /// The motion model's last two poses, the frame's last.
    pub history: History,
    /// Its pose at its stamp (the trajectory's).
    pub at_stamp: &'a Pose,
    /// The pose its scan was fused at (a deskewed scan's reference time).
    pub fused_at: &'a Pose,
    /// How well registration pinned that pose down.
    pub information: &'a PoseInformation,
    /// The pipeline's frame count after it ([`Pipeline::frames`]).
    pub counter: u32,
    /// The filtered scan it fused, in the sensor frame.
    pub fused_points: &'a [Point],
    /// Its own points in the sensor frame, when a stage [needs them](RunStage::needs_points).
    pub points: &'a [Point],
    /// The run's pool.
    pub workers: &'a Workers,
}

/// The run's end, as the stages see it.
pub struct End<'a> {
    /// This run's used frames and their poses (at their stamps); empty when none was used.
    pub poses: &'a [(usize, Pose)],
    /// The output folder.
    pub out: &'a Path,
    /// The map file saved at the end (`--save-map`), and its path.
    pub saved_map: Option<(&'a Path, &'a [(f64, Pose)])>,
    /// Which way is up in the map frame, and what said so, when something did (the IMU).
    pub up: Option<(Vector3<f64>, String)>,
}

/// A run's stages, in the order they are called.
pub struct Stages<C: Capacity>(Vec<Box<dyn RunStage<C>>>);

impl<C: Capacity> Default for Stages<C> {
    fn default() -> Self {
        Self(Vec::new())
    }
}

impl<C: Capacity> Stages<C> {
    /// No stage.
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds `stage` at the end of the list.
    pub fn push(&mut self, stage: Box<dyn RunStage<C>>) {
        self.0.push(stage);
    }

    /// Puts `stage` before the others.
    pub fn push_first(&mut self, stage: Box<dyn RunStage<C>>) {
        self.0.insert(0, stage);
    }

    /// Adds `more`'s stages at the end of the list.
    pub fn extend(&mut self, more: Stages<C>) {
        self.0.extend(more.0);
    }

    /// The bytes they take at most, together.
    pub fn bytes(&self) -> usize {
        self.0.iter().map(|s| s.bytes()).sum()
    }

    /// Tells each the run starts.
    pub fn start(&mut self, start: &Start<'_>) -> Result<(), FileError> {
        self.0.iter_mut().try_for_each(|s| s.start(start))
    }

    /// [`RunStage::between`] in turn, each note into `notes`.
    pub fn between(&mut self, run: &mut Between<'_, C>, notes: &mut Notes) {
        for s in &mut self.0 {
            if let Some(note) = s.between(run) {
                notes.add(note);
            }
        }
    }

    /// The first stage's search ([`RunStage::search`]).
    pub fn search(&mut self) -> Option<Searching<'_>> {
        self.0.iter_mut().find_map(|s| s.search())
    }

    /// Tells each a search ran; their notes go into `notes`.
    pub fn searched(&mut self, frame: usize, found: &Relocalized, notes: &mut Notes) {
        for s in &mut self.0 {
            if let Some(note) = s.searched(frame, found) {
                notes.add(note);
            }
        }
    }

    /// Asks each to search near `near` from the next frame; true when one will.
    pub fn relocalize(&mut self, near: Pose) -> bool {
        let mut any = false;
        for s in &mut self.0 {
            any |= s.relocalize(near);
        }
        any
    }

    /// The first failure a stage reports ([`RunStage::failed`]).
    pub fn failed(&mut self) -> Option<FileError> {
        self.0.iter_mut().find_map(|s| s.failed())
    }

    /// [`RunStage::wind_up`] in turn.
    pub fn wind_up(&mut self, run: &mut Between<'_, C>) {
        self.0.iter_mut().for_each(|s| s.wind_up(run));
    }

    /// Whether any needs each used frame's own points.
    pub fn need_points(&self) -> bool {
        self.0.iter().any(|s| s.needs_points())
    }

    /// Tells each the frame was read.
    pub fn read(&mut self, frame: &Read<'_>) {
        self.0.iter_mut().for_each(|s| s.read(frame));
    }

    /// The first stage's deskew that deskews the scan, if one does.
    pub fn deskew(&mut self, sweep: &mut Sweep<'_>) -> Option<Result<Deskewed, DeskewError>> {
        self.0.iter_mut().find_map(|s| s.deskew(sweep))
    }

    /// The first prior a stage gives, asking each in turn until one does.
    pub fn prior(&mut self, at: &PriorAt<'_>) -> Option<Pose> {
        self.0.iter_mut().find_map(|s| s.prior(at))
    }

    /// The first pose at the stamp a stage gives for a scan it deskewed.
    pub fn at_stamp(
        &self,
        fused_at: &Pose,
        reference: f64,
        stamp: f64,
        history: History,
    ) -> Option<Pose> {
        (self.0.iter()).find_map(|s| s.at_stamp(fused_at, reference, stamp, history))
    }

    /// Tells each the frame's scan was fused at `pose`; their notes go into `notes` and the
    /// milliseconds they took together are returned.
    pub fn fused(&mut self, pipeline: &mut Pipeline<C>, pose: &Pose, notes: &mut Notes) -> f64 {
        let t = Instant::now();
        for s in &mut self.0 {
            if let Some(note) = s.fused(pipeline, pose) {
                notes.add(note);
            }
        }
        t.elapsed().as_secs_f64() * 1e3
    }

    /// The layers they changed in their last [`fused`](Self::fused), beyond the frame's own.
    pub fn changed(&self) -> impl Iterator<Item = (CellKey, Axis)> + '_ {
        self.0.iter().flat_map(|s| s.changed().iter().copied())
    }

    /// Tells each a used frame's pose was kept; their notes go into `notes`.
    pub fn used(&mut self, frame: &Used<'_>, notes: &mut Notes) {
        for s in &mut self.0 {
            if let Some(note) = s.used(frame) {
                notes.add(note);
            }
        }
    }

    /// What a checkpoint keeps of them: each stage's state that is not empty, after its name.
    pub fn save(&self, state: &mut Vec<u8>) {
        let mut part = Vec::new();
        for s in &self.0 {
            part.clear();
            s.save(&mut part);
            if !part.is_empty() {
                put_str(state, s.name());
                put_u64(state, part.len() as u64);
                state.extend_from_slice(&part);
            }
        }
    }

    /// Takes back what [`save`](Self::save) wrote: each part to the stage of its name (to
    /// stages of one name in their order).
    pub fn restore(&mut self, state: &[u8]) -> Result<(), Damaged> {
        let mut d = Decoder { bytes: state };
        let mut restored = vec![false; self.0.len()];
        while !d.bytes.is_empty() {
            let name = d.string()?;
            let n = d.count(1)?;
            let part = d.take(n)?;
            let k = (0..self.0.len())
                .find(|&k| !restored[k] && self.0[k].name() == name)
                .ok_or_else(|| {
                    Damaged(format!(
                        "the state of a stage this run does not have ({name})"
                    ))
                })?;
            restored[k] = true;
            (self.0[k])
                .restore(part)
                .map_err(|e| Damaged(format!("{name}'s state: {e}")))?;
        }
        Ok(())
    }

    /// Which way is up, from the first stage that knows.
    pub fn up(&self) -> Option<(Vector3<f64>, String)> {
        self.0.iter().find_map(|s| s.up())
    }

    /// What each writes beside the map saved at `map` ([`RunStage::beside_map`]), joined for the
    /// message that says the map was saved; a stage that could not write is said there and
    /// logged (the map is saved either way).
    pub fn beside_map(&self, map: &Path, path: &[(f64, Pose)], poses: &[(usize, Pose)]) -> String {
        let mut said = String::new();
        for s in &self.0 {
            match s.beside_map(map, path, poses) {
                Ok(Some(m)) => said.push_str(&format!("; {m}")),
                Ok(None) => {}
                Err(e) => {
                    log::warn!("{e}");
                    said.push_str(&format!("; {}: not beside it: {e}", s.name()));
                }
            }
        }
        said
    }

    /// Each stage's end ([`RunStage::finish`]), in order; the first that fails is the error.
    pub fn finish(&mut self, mesh: &mut MeshSpool, end: &End<'_>) -> Result<(), FileError> {
        self.0.iter_mut().try_for_each(|s| s.finish(mesh, end))
    }

    /// The vertex properties the first stage that gives any gives the mesh files.
    pub fn vertex_properties(&self) -> Option<Box<dyn VertexProperties + '_>> {
        self.0.iter().find_map(|s| s.vertex_properties())
    }

    /// Their parts of the run's summary, by name.
    pub fn summaries(&self) -> BTreeMap<String, serde_json::Value> {
        (self.0.iter())
            .filter_map(|s| Some((s.name().to_string(), s.summary()?)))
            .collect()
    }

    /// The files they may write into the output folder.
    pub fn outputs(&self) -> Vec<&'static str> {
        self.0
            .iter()
            .flat_map(|s| s.outputs().iter().copied())
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slamesh_core::SmallCapacity as Small;

    /// Counts what it is told, and writes a file at the end.
    #[derive(Default)]
    struct Counting {
        started: bool,
        fused: u64,
        used: Vec<usize>,
    }

    impl RunStage<Small> for Counting {
        fn name(&self) -> &'static str {
            "counting"
        }
        fn bytes(&self) -> usize {
            100
        }
        fn start(&mut self, start: &Start<'_>) -> Result<(), FileError> {
            self.started = !start.bounded;
            Ok(())
        }
        fn fused(&mut self, _: &mut Pipeline<Small>, _: &Pose) -> Option<Note> {
            self.fused += 1;
            Some(Note::of("fused_so_far", self.fused))
        }
        fn used(&mut self, frame: &Used<'_>) -> Option<Note> {
            self.used.push(frame.frame);
            (frame.frame == 7).then(|| Note {
                doubt: Some(("Odd", "frame 7".into())),
                ..Note::of("odd", true)
            })
        }
        fn save(&self, state: &mut Vec<u8>) {
            put_u64(state, self.fused);
        }
        fn restore(&mut self, state: &[u8]) -> Result<(), Damaged> {
            self.fused = Decoder { bytes: state }.u64()?;
            Ok(())
        }
        fn summary(&self) -> Option<serde_json::Value> {
            Some(serde_json::json!({ "used": self.used }))
        }
        fn outputs(&self) -> &'static [&'static str] {
            &["counted.txt"]
        }
    }

    #[test]
    fn a_stage_is_told_each_step_and_reports_under_its_name() {
        let mut stages = Stages::<Small>::new();
        stages.push(Box::new(Counting::default()));
        stages.push(Box::new(Counting::default()));
        assert_eq!(stages.bytes(), 200);
        let config = Default::default();
        let start = Start {
            bounded: false,
            map: None,
            config: &config,
            out: Path::new("."),
            threads: 1,
            windowed: None,
        };
        stages.start(&start).unwrap();
        let mut pipeline = Pipeline::<Small>::new(Default::default()).unwrap();
        let mut notes = Notes::default();
        for _ in 0..3 {
            stages.fused(&mut pipeline, &Pose::identity(), &mut notes);
        }
        assert_eq!(notes.values["fused_so_far"], 3);
        let workers = Workers::new(1).unwrap();
        let mut doubts = Vec::new();
        for frame in [4, 7] {
            let mut notes = Notes::default();
            let used = Used {
                frame,
                status: RegistrationStatus::Converged,
                reference: 0.0,
                history: (None, None),
                at_stamp: &Pose::identity(),
                fused_at: &Pose::identity(),
                information: &Default::default(),
                counter: 1,
                fused_points: &[],
                points: &[],
                workers: &workers,
            };
            stages.used(&used, &mut notes);
            doubts.extend(notes.doubts);
        }
        assert_eq!(doubts, vec![("Odd".to_string(), "frame 7".to_string()); 2]);
        // A checkpoint's state, back into stages started anew.
        let mut state = Vec::new();
        stages.save(&mut state);
        let mut again = Stages::<Small>::new();
        again.push(Box::new(Counting::default()));
        again.push(Box::new(Counting::default()));
        again.restore(&state).unwrap();
        let mut more = Notes::default();
        again.fused(&mut pipeline, &Pose::identity(), &mut more);
        assert_eq!(
            more.values["fused_so_far"], 4,
            "counting on from the checkpoint"
        );
        assert!(
            Stages::<Small>::new().restore(&state).is_err(),
            "no stage of that name"
        );
        let summaries = stages.summaries();
        assert_eq!(summaries.len(), 1, "one key for the two stages of one name");
        assert_eq!(summaries["counting"], serde_json::json!({ "used": [4, 7] }));
        assert_eq!(stages.outputs(), ["counted.txt", "counted.txt"]);
        assert!(!stages.need_points());
        assert!(stages.vertex_properties().is_none());
    }
}
