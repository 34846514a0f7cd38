//! One way out: what a run produces, handed to every sink it is given ([`Sinks`]).
//!
//! After each frame the run makes one [`FrameEvent`] (the frame's record: status, reason,
//! counts and timings; its pose; and, when a sink asks for it, the map as the frame changed
//! it, [`MapUpdate`]) and offers it to each sink in turn; at the end, once its own files are
//! written, it tells each sink the run is over, with its [`Summary`]. A sink is anything that
//! takes these: the progress line on the terminal, the live view, the run's own report and
//! trajectories ([`crate::run::files`]), and later a ROS 2 publisher or a navigation map.
//!
//! A sink runs on the run's thread, so a slow one would stall the run: wrap it in
//! [`Queued`], which hands events to a thread of its own through a bounded queue with a named
//! policy for a full queue ([`WhenFull`]): drop the new event and count it, or wait.
//!
//! Guarantees: events reach a sink in frame order; [`Sink::finish`] is called once, after the
//! last event, and a queued sink has been given every event it did not drop by then.

use crate::io::FileError;
use crate::run::report::{FrameRecord, Summary};
use crate::sources::Sample;
use slamesh_core::cell::{Axis, CellKey};
use slamesh_core::layer::Layer;
use slamesh_core::lm::PoseInformation;
use slamesh_core::{Capacity, Pipeline, Point, Pose};
use std::fmt;
use std::sync::mpsc::{sync_channel, SyncSender, TrySendError};
use std::sync::Arc;
use std::thread::JoinHandle;

/// What a run tells its sinks about one frame.
#[derive(Debug, Clone)]
pub struct FrameEvent {
    /// The frame's record, as `report.json` holds it.
    pub record: FrameRecord,
    /// Its pose at its stamp, when it was used.
    pub pose: Option<Pose>,
    /// The map as the frame changed it, when a sink wants it ([`Sink::wants_map`]) and the
    /// frame was used.
    pub map: Option<MapUpdate>,
    /// The samples that are not scans (an IMU's readings) that came with the frame, in time
    /// order.
    pub samples: Vec<Sample>,
    /// How well the registration pinned the frame's pose down, when it was registered (the
    /// inverse of its covariance, [`PoseInformation`]).
    pub information: Option<PoseInformation>,
}

/// The map as one frame changed it: copied out of the pipeline by the run, only when a sink
/// asks for it.
#[derive(Debug, Clone)]
pub struct MapUpdate {
    /// Frame index.
    pub frame: usize,
    /// The frame's time (seconds).
    pub stamp_s: f64,
    /// The estimated sensor pose.
    pub pose: Pose,
    /// The scan's points as registered, sensor frame.
    pub points: Vec<Point>,
    /// The scan's own points, before down-sampling (sensor frame, deskewed as registered):
    /// what the live grid's floor counts ([`crate::navmap::hits`]). Empty from
    /// [`of`](Self::of); [`run_to`](crate::run::run_to) hands them over when a sink wants
    /// the map.
    pub own_points: Vec<Point>,
    /// The map layers the frame changed, as they are after it (every layer after a loop
    /// closure).
    pub layers: Vec<(CellKey, Axis, Layer)>,
    /// After a loop closure: the whole corrected trajectory and what was closed.
    pub closed: Option<(Vec<Pose>, Vec<String>)>,
}

impl MapUpdate {
    /// The last frame `pipeline` took (frame `frame`, at `stamp_s`); `None` before the first.
    pub fn of<C: Capacity>(pipeline: &Pipeline<C>, frame: usize, stamp_s: f64) -> Option<Self> {
        let pose = pipeline.pose()?;
        let map = pipeline.map();
        let layers = pipeline
            .last_scan()
            .iter()
            .filter_map(|s| map.layer(&s.key, s.axis).map(|l| (s.key, s.axis, *l)))
            .collect();
        Some(MapUpdate {
            frame,
            stamp_s,
            pose,
            points: pipeline.last_points().to_vec(),
            own_points: Vec::new(),
            layers,
            closed: None,
        })
    }

    /// With `changed`'s layers of `map` too (the layers a stage changed beyond the frame's
    /// own: what clearing made forget a vertex), each once; a layer no longer in the map is
    /// passed over.
    pub fn with_changed(
        mut self,
        map: &slamesh_core::map::MeshMap,
        changed: impl Iterator<Item = (CellKey, Axis)>,
    ) -> Self {
        let mut changed = changed.peekable();
        if changed.peek().is_none() {
            return self;
        }
        let mut have: std::collections::HashSet<(CellKey, Axis)> =
            self.layers.iter().map(|(k, a, _)| (*k, *a)).collect();
        for (key, axis) in changed {
            if let Some(l) = map.layer(&key, axis).filter(|_| have.insert((key, axis))) {
                self.layers.push((key, axis, *l));
            }
        }
        self
    }

    /// [`of`](Self::of) after a loop closure: every layer of the map, the corrected `path`
    /// and what was closed.
    pub fn after_closure<C: Capacity>(
        pipeline: &Pipeline<C>,
        frame: usize,
        stamp_s: f64,
        path: Vec<Pose>,
        notes: Vec<String>,
    ) -> Option<Self> {
        let mut update = Self::of(pipeline, frame, stamp_s)?;
        update.layers = pipeline
            .map()
            .layers()
            .map(|l| (l.key, l.axis, *l.layer))
            .collect();
        update.closed = Some((path, notes));
        Some(update)
    }
}

/// Why a sink failed: its name and the reason. The run goes on without it and says so at the
/// end.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SinkError {
    /// The sink's name.
    pub sink: String,
    /// What went wrong.
    pub reason: SinkFault,
}

/// What went wrong in a sink.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum SinkFault {
    /// A file it writes could not be written.
    File(FileError),
    /// Its thread stopped before the run's end (it ended early or panicked): why.
    Stopped(String),
    /// Its own reason (a viewer's server, a topic's writer): in words.
    Failed(String),
}

impl fmt::Display for SinkFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SinkFault::File(e) => e.fmt(f),
            SinkFault::Stopped(why) | SinkFault::Failed(why) => f.write_str(why),
        }
    }
}

impl std::error::Error for SinkFault {}

impl From<FileError> for SinkFault {
    fn from(e: FileError) -> Self {
        SinkFault::File(e)
    }
}

impl From<String> for SinkFault {
    fn from(why: String) -> Self {
        SinkFault::Failed(why)
    }
}

impl From<&str> for SinkFault {
    fn from(why: &str) -> Self {
        SinkFault::Failed(why.to_string())
    }
}

impl fmt::Display for SinkError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.sink, self.reason)
    }
}

impl std::error::Error for SinkError {}

/// Something a run's results go to.
pub trait Sink {
    /// Its name in messages.
    fn name(&self) -> String;

    /// Whether it wants the map each frame changed ([`FrameEvent::map`]); copying it costs
    /// the run a little, so only when some sink does.
    fn wants_map(&self) -> bool {
        false
    }

    /// One frame, in frame order.
    fn frame(&mut self, event: Arc<FrameEvent>) -> Result<(), SinkFault>;

    /// The run is over (with its summary when it finished; `None` when the sink is closed
    /// without one): write what is left. Returns a line saying what it did, if any.
    fn finish(&mut self, summary: Option<&Summary>) -> Result<Option<String>, SinkFault> {
        let _ = summary;
        Ok(None)
    }
}

/// A sink made of a function of each event (the terminal's progress line, say).
pub struct FnSink<F> {
    name: &'static str,
    f: F,
}

impl<F: FnMut(&FrameEvent)> FnSink<F> {
    /// `f` for each event, named `name` in messages.
    pub fn new(name: &'static str, f: F) -> Self {
        FnSink { name, f }
    }
}

impl<F: FnMut(&FrameEvent)> Sink for FnSink<F> {
    fn name(&self) -> String {
        self.name.to_string()
    }
    fn frame(&mut self, event: Arc<FrameEvent>) -> Result<(), SinkFault> {
        (self.f)(&event);
        Ok(())
    }
}

/// What a [`Queued`] sink does with an event that finds its queue full.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum WhenFull {
    /// Drop the new event and count it: the run never waits (a live view, a live topic).
    DropNewest,
    /// Wait for room: every event arrives, and a slow sink slows the run (a file that must
    /// hold every frame).
    Wait,
}

/// What a [`Queued`] sink did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct QueueStats {
    /// Events handed to the sink.
    pub delivered: usize,
    /// Events dropped because the queue was full ([`WhenFull::DropNewest`]).
    pub dropped: usize,
}

type Finished = (usize, Result<Option<String>, SinkFault>);

/// What goes through a [`Queued`] sink's queue.
enum Message {
    Frame(Arc<FrameEvent>),
    End(Arc<Summary>),
}

/// A sink on a thread of its own behind a bounded queue, so that it cannot stall the run
/// beyond its [`WhenFull`] policy. Dropped without [`Sink::finish`], it still closes the queue
/// and waits for the sink's thread.
pub struct Queued {
    name: String,
    wants_map: bool,
    when_full: WhenFull,
    tx: Option<SyncSender<Message>>,
    thread: Option<JoinHandle<Finished>>,
    dropped: usize,
    /// The first error the sink returned: it gets no more events after it.
    failed: Option<SinkFault>,
}

impl Queued {
    /// `sink` on a thread of its own, behind a queue of `capacity` events (at least one).
    pub fn new(
        mut sink: impl Sink + Send + 'static,
        capacity: usize,
        when_full: WhenFull,
    ) -> std::io::Result<Self> {
        let (name, wants_map) = (sink.name(), sink.wants_map());
        let (tx, rx) = sync_channel::<Message>(capacity.max(1));
        let thread = std::thread::Builder::new()
            .name(format!("slamesh-sink-{name}"))
            .spawn(move || {
                let mut delivered = 0;
                for message in rx {
                    let event = match message {
                        Message::Frame(event) => event,
                        Message::End(summary) => return (delivered, sink.finish(Some(&summary))),
                    };
                    if let Err(e) = sink.frame(event) {
                        // The queue's other end sees the error when it sends next or finishes.
                        return (delivered, Err(e));
                    }
                    delivered += 1;
                }
                (delivered, sink.finish(None))
            })?;
        Ok(Queued {
            name,
            wants_map,
            when_full,
            tx: Some(tx),
            thread: Some(thread),
            dropped: 0,
            failed: None,
        })
    }

    /// Closes the queue, waits for the sink to take what is in it and finish, and says what
    /// it did.
    pub fn end(mut self) -> (QueueStats, Result<Option<String>, SinkFault>) {
        let failed = self.failed.take();
        let (stats, result) = self.close();
        (stats, failed.map_or(result, Err))
    }

    /// Closes the queue and waits for the sink to take what is in it and finish.
    fn close(&mut self) -> (QueueStats, Result<Option<String>, SinkFault>) {
        self.tx = None;
        let (delivered, result) = match self.thread.take().map(JoinHandle::join) {
            Some(Ok(done)) => done,
            Some(Err(_)) => (0, Err(SinkFault::Stopped("its thread panicked".into()))),
            None => (0, Ok(None)),
        };
        let stats = QueueStats {
            delivered,
            dropped: self.dropped,
        };
        (stats, self.failed.take().map_or(result, Err))
    }
}

impl Sink for Queued {
    fn name(&self) -> String {
        self.name.clone()
    }
    fn wants_map(&self) -> bool {
        self.wants_map
    }
    fn frame(&mut self, event: Arc<FrameEvent>) -> Result<(), SinkFault> {
        let Some(tx) = &self.tx else {
            return Ok(());
        };
        let event = Message::Frame(event);
        let sent = match self.when_full {
            WhenFull::Wait => tx.send(event).map_err(|_| ()),
            WhenFull::DropNewest => match tx.try_send(event) {
                Ok(()) => Ok(()),
                Err(TrySendError::Full(_)) => {
                    self.dropped += 1;
                    Ok(())
                }
                Err(TrySendError::Disconnected(_)) => Err(()),
            },
        };
        if sent.is_err() {
            // The sink's thread ended early: its error comes with `finish`.
            let (_, result) = self.close();
            let reason = (result.err()).unwrap_or_else(|| SinkFault::Stopped("it stopped".into()));
            self.failed = Some(reason.clone());
            return Err(reason);
        }
        Ok(())
    }
    fn finish(&mut self, summary: Option<&Summary>) -> Result<Option<String>, SinkFault> {
        if let Some(e) = self.failed.take() {
            return Err(e);
        }
        if let (Some(tx), Some(s)) = (&self.tx, summary) {
            // Waits for room whatever the policy: the end is never dropped. A sink that
            // stopped says why below.
            let _ = tx.send(Message::End(Arc::new(s.clone())));
        }
        let (stats, result) = self.close();
        let said = result?;
        let queue = format!(
            "{} frames delivered, {} dropped (the sink was behind)",
            stats.delivered, stats.dropped
        );
        Ok(Some(match said {
            Some(s) => format!("{s}; {queue}"),
            None => queue,
        }))
    }
}

impl Drop for Queued {
    fn drop(&mut self) {
        if self.thread.is_some() {
            let _ = self.close();
        }
    }
}

/// The sinks a run fans out to, in the order given. A sink that fails is named, dropped and
/// reported at the end; the run and the other sinks go on.
#[derive(Default)]
pub struct Sinks<'a> {
    sinks: Vec<Box<dyn Sink + 'a>>,
    errors: Vec<SinkError>,
}

impl<'a> Sinks<'a> {
    /// No sink.
    pub fn new() -> Self {
        Sinks::default()
    }

    /// Adds `sink` (after those added before).
    pub fn add(&mut self, sink: impl Sink + 'a) -> &mut Self {
        self.sinks.push(Box::new(sink));
        self
    }

    /// Whether any sink wants the map each frame changed.
    pub fn want_map(&self) -> bool {
        self.sinks.iter().any(|s| s.wants_map())
    }

    /// Offers `event` to every sink.
    pub fn frame(&mut self, event: FrameEvent) {
        let event = Arc::new(event);
        let errors = &mut self.errors;
        self.sinks
            .retain_mut(|s| match s.frame(Arc::clone(&event)) {
                Ok(()) => true,
                Err(reason) => {
                    log::warn!("{}: {reason}; it gets no more frames", s.name());
                    errors.push(SinkError {
                        sink: s.name(),
                        reason,
                    });
                    false
                }
            });
    }

    /// Tells every sink the run is over, with its summary; says what each did. The first sink
    /// that failed, during the run or now, is the error.
    pub fn finish(mut self, summary: &Summary) -> Result<(), SinkError> {
        for s in &mut self.sinks {
            match s.finish(Some(summary)) {
                Ok(Some(line)) => log::info!("{}: {line}", s.name()),
                Ok(None) => {}
                Err(reason) => self.errors.push(SinkError {
                    sink: s.name(),
                    reason,
                }),
            }
        }
        match self.errors.into_iter().next() {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;
    use std::time::{Duration, Instant};

    fn event(frame: usize) -> FrameEvent {
        FrameEvent {
            record: FrameRecord::skipped(frame, format!("{frame}.bin")),
            pose: None,
            map: None,
            samples: Vec::new(),
            information: None,
        }
    }

    /// Takes `ms` for each frame and keeps the frames it saw.
    struct Sleepy {
        ms: u64,
        seen: Arc<Mutex<Vec<usize>>>,
    }

    impl Sink for Sleepy {
        fn name(&self) -> String {
            "sleepy".into()
        }
        fn frame(&mut self, event: Arc<FrameEvent>) -> Result<(), SinkFault> {
            std::thread::sleep(Duration::from_millis(self.ms));
            self.seen.lock().unwrap().push(event.record.frame);
            Ok(())
        }
        fn finish(&mut self, _: Option<&Summary>) -> Result<Option<String>, SinkFault> {
            Ok(Some(format!("saw {}", self.seen.lock().unwrap().len())))
        }
    }

    #[test]
    fn a_slow_sink_behind_a_dropping_queue_does_not_stall_the_run() {
        let seen = Arc::new(Mutex::new(Vec::new()));
        let sleepy = Sleepy {
            ms: 50,
            seen: Arc::clone(&seen),
        };
        let mut q = Queued::new(sleepy, 2, WhenFull::DropNewest).unwrap();
        let t = Instant::now();
        for i in 0..40 {
            q.frame(Arc::new(event(i))).unwrap();
        }
        // 40 frames offered to a sink that takes 50 ms each: offering them took no sleep.
        let offered = t.elapsed();
        assert!(offered < Duration::from_millis(500), "{offered:?}");
        let said = q.finish(None).unwrap().unwrap();
        let seen = seen.lock().unwrap().clone();
        assert!(seen.len() >= 2 && seen.len() < 40, "{seen:?}");
        assert!(
            seen.windows(2).all(|w| w[0] < w[1]),
            "in frame order: {seen:?}"
        );
        assert_eq!(seen[0], 0, "the first frame finds room");
        let dropped = 40 - seen.len();
        assert!(
            said.contains(&format!(
                "{} frames delivered, {dropped} dropped",
                seen.len()
            )),
            "{said}"
        );
    }

    #[test]
    fn a_waiting_queue_delivers_every_frame_in_order() {
        let seen = Arc::new(Mutex::new(Vec::new()));
        let sleepy = Sleepy {
            ms: 2,
            seen: Arc::clone(&seen),
        };
        let mut sinks = Sinks::new();
        sinks.add(Queued::new(sleepy, 1, WhenFull::Wait).unwrap());
        for i in 0..20 {
            sinks.frame(event(i));
        }
        sinks.finish(&Summary::default()).unwrap();
        assert_eq!(*seen.lock().unwrap(), (0..20).collect::<Vec<_>>());
    }

    /// Fails on its third frame.
    struct Failing(usize);

    impl Sink for Failing {
        fn name(&self) -> String {
            "failing".into()
        }
        fn frame(&mut self, _: Arc<FrameEvent>) -> Result<(), SinkFault> {
            self.0 += 1;
            if self.0 == 3 {
                return Err("disk full".into());
            }
            Ok(())
        }
    }

    #[test]
    fn a_failing_sink_is_dropped_and_named_and_the_others_go_on() {
        let mut counted = 0;
        {
            let mut sinks = Sinks::new();
            sinks.add(Failing(0));
            sinks.add(FnSink::new("count", |_: &FrameEvent| counted += 1));
            sinks.add(Queued::new(Failing(0), 4, WhenFull::Wait).unwrap());
            for i in 0..10 {
                sinks.frame(event(i));
            }
            let e = sinks.finish(&Summary::default()).unwrap_err();
            assert_eq!(
                e,
                SinkError {
                    sink: "failing".into(),
                    reason: "disk full".into()
                }
            );
        }
        assert_eq!(counted, 10);
    }
}
