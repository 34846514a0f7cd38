//! The loop-closure thread (docs/design.md §1.14): spools each frame's scan, keeps the
//! keyframe graph, checks keyframes for revisits, optimises the graph when a closure is
//! accepted, rebuilds the map at the corrected poses, and hands the correction to the run.
//!
//! It never waits for the run except for the acknowledgement of a correction it sent: one
//! correction is in flight at a time, so that each is computed against the poses the run
//! reports.

use crate::io::error::FileError;
use crate::loop_closure::graph::{local_covariance, Edge, PoseGraph};
use crate::loop_closure::saved::SavedMap;
use crate::loop_closure::settings::LoopSettings;
use crate::loop_closure::spool::ScanSpool;
use crate::loop_closure::streaming::{self, RebuiltOutputs};
use crate::loop_closure::{Closure, Corrected, ToWorker};
use crate::parallel::Workers;
use crate::stage::lent::Windowed;
use nalgebra::Matrix6;
use slamesh_core::map::MeshMap;
use slamesh_core::math::{rotation_angle, se3_exp, se3_log};
use slamesh_core::{Capacity, Config, Pipeline, Pose};
use std::sync::mpsc::{Receiver, Sender};

mod rebuild;
mod revisits;
use rebuild::Rebuild;
use revisits::Found;

/// Layers the local map of a check may hold (a few dozen scans' worth).
const SUBMAP_LAYERS: usize = 60_000;

/// One frame the run used.
struct Frame {
    /// The run's frame index.
    frame: usize,
    /// The pose as the odometry made it, before any correction.
    raw: Pose,
    /// Metres travelled from the start.
    travelled_m: f64,
    /// The graph node at or before it.
    node: usize,
    /// The correction the run's map holds it at (`map pose = in_map · raw`).
    in_map: Pose,
    /// The correction the run's trajectory has it at (`run's pose = shown · raw`).
    shown: Pose,
}

/// The thread's state.
pub(crate) struct Worker<C: Capacity> {
    config: Config,
    s: LoopSettings,
    spool: ScanSpool,
    frames: Vec<Frame>,
    graph: PoseGraph,
    /// The frame index (into `frames`) of each node.
    node_frame: Vec<usize>,
    /// Each frame's correction ([`Worker::corrections`]), kept between optimisations: a
    /// frame after the newest node takes that node's.
    correction: Vec<Pose>,
    /// The run reports `applied · raw`.
    applied: Pose,
    /// Travel when a keyframe was last checked.
    checked_at_m: f64,
    /// A checked revisit waiting for another to agree: its node and correction.
    pending: Option<(usize, Pose, Closure)>,
    /// The graph changed since the last correction sent.
    dirty: bool,
    /// A correction was sent and not yet acknowledged.
    in_flight: bool,
    /// Frames the correction in flight names; later ones get its `last`.
    sent_upto: usize,
    finishing: bool,
    /// The run pipeline's frame count after the newest frame.
    counter: u32,
    /// The registrations' covariances (each in its frame) summed since the last keyframe.
    since_key: Matrix6<f64>,
    new_closures: Vec<Closure>,
    /// The pipeline that builds a check's local map and searches it; in a windowed run also
    /// the one that rebuilds (`None` meanwhile: no check runs then).
    submap: Option<Box<Pipeline<C>>>,
    /// A pipeline for the next rebuild (its map the one the run handed back).
    rebuild: Option<Box<Pipeline<C>>>,
    rebuilding: Option<Rebuild<C>>,
    /// The pipeline whose rebuilt map is with the run, until the run hands back its old one.
    awaiting: Option<Box<Pipeline<C>>>,
    /// A windowed run's rules and outputs ([`streaming`]); `None`: the run keeps its map whole.
    streaming: Option<Windowed>,
    /// Rebuilds started (each windowed one has outputs of its own).
    rebuilds: usize,
    /// The run's thread count (0: one per core), and a pool of as many for a rebuild after
    /// the run's last frame ([`Worker::take_the_run_s_threads`]).
    threads: usize,
    pool: Option<Workers>,
    to_run: Sender<Corrected>,
    /// The saved map the run started from, if it did: revisits of its path are looked for
    /// too, and a rebuild starts from its cells.
    saved: Option<SavedMap>,
}

impl<C: Capacity> Worker<C> {
    pub(crate) fn new(
        config: Config,
        s: LoopSettings,
        spool: ScanSpool,
        to_run: Sender<Corrected>,
        saved: Option<SavedMap>,
        streaming: Option<Windowed>,
        threads: usize,
    ) -> Result<Self, FileError> {
        let submap = match &streaming {
            None => Pipeline::<C>::with_map_layers(config, SUBMAP_LAYERS),
            Some(w) => {
                Pipeline::<C>::with_limits(config, streaming::engine_limits::<C>(), w.map_layers)
            }
        }
        .map_err(config_error)?;
        Ok(Self {
            config,
            s,
            spool,
            frames: Vec::new(),
            graph: PoseGraph::default(),
            node_frame: Vec::new(),
            correction: Vec::new(),
            applied: Pose::identity(),
            checked_at_m: f64::NEG_INFINITY,
            pending: None,
            dirty: false,
            in_flight: false,
            sent_upto: 0,
            finishing: false,
            counter: 0,
            since_key: Matrix6::zeros(),
            new_closures: Vec::new(),
            submap: Some(Box::new(submap)),
            rebuild: None,
            rebuilding: None,
            awaiting: None,
            streaming,
            rebuilds: 0,
            threads,
            pool: None,
            to_run,
            saved,
        })
    }

    /// Runs until the run says it is finishing and nothing is left to do.
    pub(crate) fn run(mut self, rx: Receiver<ToWorker>) -> Result<(), FileError> {
        loop {
            // Idle: wait for the run. Rebuilding: only look.
            if self.rebuilding.is_none() {
                let Ok(first) = rx.recv() else { return Ok(()) };
                self.take(first)?;
                self.check()?;
            }
            // Every keyframe due is checked, in order, however far behind the run the
            // thread is (so which places are checked does not depend on timing), until a
            // closure asks for a correction: that starts first.
            while !self.correction_due() {
                let Ok(m) = rx.try_recv() else { break };
                self.take(m)?;
                self.check()?;
            }
            if self.finishing && self.dirty {
                self.drop_stale_rebuild();
            }
            if self.rebuilding.is_some() {
                self.rebuild_slice()?;
            } else if self.correction_due() {
                self.start_correction()?;
            }
            if self.finishing && !self.in_flight && !self.dirty && self.rebuilding.is_none() {
                let _ = self.to_run.send(Corrected::done(self.spool.bytes()));
                return Ok(());
            }
        }
    }

    /// The graph changed and a correction can start: none is with the run or being built.
    fn correction_due(&self) -> bool {
        self.dirty && !self.in_flight && self.rebuilding.is_none()
    }

    fn take(&mut self, m: ToWorker) -> Result<(), FileError> {
        match m {
            ToWorker::Frame {
                frame,
                counter,
                pose,
                information,
                points,
            } => {
                self.counter = counter;
                self.since_key += local_covariance(&information, &pose);
                self.add_frame(frame, &pose, &points)?
            }
            ToWorker::Applied {
                correction,
                returned,
            } => {
                // Frames the correction did not name were moved by its `last`.
                for f in &mut self.frames[self.sent_upto..] {
                    f.shown = correction * f.shown;
                }
                self.applied = correction * self.applied;
                self.in_flight = false;
                if let Some(mut p) = self.awaiting.take() {
                    if let Some(old) = returned {
                        *p.map_mut() = *old;
                    }
                    p.map_mut().clear();
                    match self.streaming {
                        Some(_) => self.submap = Some(p),
                        None => self.rebuild = Some(p),
                    }
                }
            }
            ToWorker::Finish => self.finishing = true,
        }
        Ok(())
    }

    /// Spools a frame and adds a keyframe when it has moved or turned enough.
    fn add_frame(
        &mut self,
        frame: usize,
        reported: &Pose,
        points: &[slamesh_core::Point],
    ) -> Result<(), FileError> {
        self.spool.push(points)?;
        let raw = self.applied.inverse() * reported;
        let (travelled_m, key) = match (self.frames.last(), self.node_frame.last()) {
            (Some(prev), Some(&k)) => {
                let step = (raw.translation.vector - prev.raw.translation.vector).norm();
                let since = self.frames[k].raw.inverse() * raw;
                let key = since.translation.vector.norm() >= self.s.keyframe_m
                    || rotation_angle(&since).to_degrees() >= self.s.keyframe_deg;
                (prev.travelled_m + step, key)
            }
            _ => (0.0, true),
        };
        let index = self.frames.len();
        let correction = self.correction_of_last_node();
        if key {
            if let Some(&k) = self.node_frame.last() {
                let from = &self.frames[k];
                let z = from.raw.inverse() * raw;
                let walk = self.s.odometry_covariance(travelled_m - from.travelled_m);
                let info = (walk + self.since_key)
                    .try_inverse()
                    .unwrap_or_else(|| walk.try_inverse().unwrap_or_else(Matrix6::zeros));
                let a = self.graph.nodes.len() - 1;
                self.graph.edges.push(Edge {
                    a,
                    b: a + 1,
                    z,
                    info,
                });
            }
            self.graph.nodes.push(correction * raw);
            self.node_frame.push(index);
            self.since_key = Matrix6::zeros();
        }
        self.correction.push(correction);
        self.frames.push(Frame {
            frame,
            raw,
            travelled_m,
            node: self.graph.nodes.len() - 1,
            in_map: self.applied,
            shown: self.applied,
        });
        Ok(())
    }

    /// The run pipeline's frame count before its first frame: the saved map's.
    fn first_counter(&self) -> u32 {
        self.saved.as_ref().map_or(0, |m| m.frames)
    }

    /// `corrected · raw⁻¹` of the newest node (identity before any).
    fn correction_of_last_node(&self) -> Pose {
        match (self.graph.nodes.last(), self.node_frame.last()) {
            (Some(x), Some(&f)) => x * self.frames[f].raw.inverse(),
            _ => Pose::identity(),
        }
    }

    /// Each frame's correction (`corrected = c · raw`), interpolated between its nodes by
    /// travel.
    fn corrections(&self) -> Vec<Pose> {
        let of_node =
            |n: usize| self.graph.nodes[n] * self.frames[self.node_frame[n]].raw.inverse();
        self.frames
            .iter()
            .map(|f| {
                let a = of_node(f.node);
                let Some(&next) = self.node_frame.get(f.node + 1) else {
                    return a;
                };
                let (sa, sb) = (
                    self.frames[self.node_frame[f.node]].travelled_m,
                    self.frames[next].travelled_m,
                );
                let t = ((f.travelled_m - sa) / (sb - sa).max(1e-9)).clamp(0.0, 1.0);
                let b = of_node(f.node + 1);
                a * se3_exp(&(se3_log(&(a.inverse() * b)) * t))
            })
            .collect()
    }

    /// Checks the newest keyframe for a revisit (once per `check_every_m` of travel, five
    /// times that while a rebuild runs): of this run's path first, else of the saved map's
    /// the run started from. A verified one that agrees with the one before closes the loop.
    fn check(&mut self) -> Result<(), FileError> {
        let Some(&kf) = self.node_frame.last() else {
            return Ok(());
        };
        if self.submap.is_none() {
            // A windowed run's rebuild has the pipeline.
            return Ok(());
        }
        let here = &self.frames[kf];
        // While a rebuild runs, checks come five times less often: the map reaches the run
        // sooner, and the closure being applied already holds the place.
        let every = match self.rebuilding {
            Some(_) => 5.0 * self.s.check_every_m,
            None => self.s.check_every_m,
        };
        if here.travelled_m - self.checked_at_m < every {
            return Ok(());
        }
        self.checked_at_m = here.travelled_m;
        let (pose, travelled) = (self.correction[kf] * here.raw, here.travelled_m);
        let found = match self.revisit_in_run(kf, &pose, travelled)? {
            Some(f) => Some(f),
            None => self.revisit_in_saved(kf, &pose, travelled)?,
        };
        if let Some(found) = found {
            self.take_closure(kf, &pose, found);
        }
        Ok(())
    }

    /// Takes a verified revisit by keyframe `kf` (at `pose`): its edge waits, weightless, for
    /// the next to agree with it; two that agree go into the graph, which is optimised.
    fn take_closure(&mut self, kf: usize, pose: &Pose, f: Found) {
        let Found {
            v,
            node: old,
            with_frame,
            in_saved_map,
        } = f;
        let node = self.graph.nodes.len() - 1;
        let delta = v.pose * pose.inverse();
        let closure = Closure {
            frame: self.frames[kf].frame,
            with_frame,
            in_saved_map,
            hit_share: v.found.hit_share,
            wall_share: v.found.wall_share,
            runner_up_share: v.found.runner_up_share,
            correction_m: (v.pose.translation.vector - pose.translation.vector).norm(),
            correction_deg: rotation_angle(&(pose.inverse() * v.pose)).to_degrees(),
            position: v.pose.translation.vector.into(),
            applied_at_frame: None,
        };
        let sigma = self.s.loop_covariance()
            + local_covariance(&v.found.outcome.stats.information, &v.pose);
        let edge = Edge {
            a: old,
            b: node,
            z: self.graph.nodes[old].inverse() * v.pose,
            info: sigma.try_inverse().unwrap_or_else(Matrix6::zeros),
        };
        // Two checked revisits in a row must agree on the correction.
        let agrees = self.pending.as_ref().is_some_and(|(_, d, _)| {
            let apart = d.inverse() * delta;
            apart.translation.vector.norm() < self.s.agree_m
                && rotation_angle(&apart).to_degrees() < self.s.agree_deg
        });
        if !agrees {
            self.pending = Some((self.graph.edges.len(), delta, closure));
            self.graph.edges.push(Edge {
                info: Matrix6::zeros(),
                ..edge
            });
            return;
        }
        // The earlier one's edge was kept weightless until now.
        if let Some((e, _, c)) = self.pending.take() {
            self.graph.edges[e].info = edge.info;
            self.new_closures.push(c);
        }
        self.graph.edges.push(edge);
        self.new_closures.push(closure);
        self.graph.optimize(10);
        self.correction = self.corrections();
        self.dirty = true;
    }

    /// Sends the run a correction: the trajectory's by `corrections`, the rebuilt map, and
    /// the closures the correction holds.
    fn send(
        &mut self,
        rebuilt: Option<(Box<Pipeline<C>>, Option<RebuiltOutputs>)>,
        corrections: Vec<Pose>,
        closures: Vec<Closure>,
    ) {
        // The rebuilt map goes; its pipeline waits for the run's old one.
        let (rebuilt, outputs) = match rebuilt {
            Some((mut p, outputs)) => {
                let lattice = *p.map().lattice();
                let map = std::mem::replace(p.map_mut(), MeshMap::with_capacity(0, 0, lattice));
                self.awaiting = Some(p);
                (Some(Box::new(map)), outputs)
            }
            None => (None, None),
        };
        let per_frame: Vec<(usize, Pose)> = self
            .frames
            .iter()
            .zip(&corrections)
            .map(|(f, c)| (f.frame, c * f.shown.inverse()))
            .collect();
        let last = corrections
            .last()
            .map_or(Pose::identity(), |c| c * self.applied.inverse());
        for (f, c) in self.frames.iter_mut().zip(&corrections) {
            f.shown = *c;
        }
        self.sent_upto = corrections.len().min(self.frames.len());
        self.in_flight = true;
        let _ = self.to_run.send(Corrected {
            rebuilt,
            outputs,
            per_frame,
            last,
            closures,
            done: false,
            spool_bytes: self.spool.bytes(),
        });
    }
}

/// A pipeline that cannot be made for the run's configuration (checked when the run started).
fn config_error(e: slamesh_core::ConfigError) -> FileError {
    FileError::at(std::path::Path::new("loop closure"), e.to_string())
}
