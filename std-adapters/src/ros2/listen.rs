//! The node's way in: a thread of its own takes what comes on `points` (and `imu`,
//! `initialpose`, `/clock`, the `~/save_map` service) and hands scans to the run through a
//! bounded queue ([`crate::sources::feed`]), so that the run reads the node as any other live
//! source ([`Ros2Source`], a [`FrameSource`]).
//!
//! What it guarantees:
//! - the DDS reader is drained as messages come; the thread never waits for the run: a scan
//!   that finds the queue full is dropped whole, named in the log and counted
//!   ([`Counts::dropped`]);
//! - a message that is not a scan is skipped with its topic, stamp and reason, counted
//!   ([`Counts::refused`]), never a crash;
//! - requests (a pose to relocalize at, a map to save) reach the run between frames, also
//!   while it waits for a scan ([`Request`]);
//! - IMU readings reach the run with the first frame whose stamp, plus the time since the
//!   frame before (its sweep, when scans are stamped at the sweep's start), reaches theirs
//!   ([`FrameSource::samples`]), at most [`IMU_KEPT`] waiting;
//! - once an IMU has been heard, a scan is handed to the run when a reading at or past the end
//!   of its sweep has come, or when the wait the node was given (`imu_wait`) has passed since
//!   the scan came; then it runs with the readings it has, said once and counted
//!   ([`Counts::imu_late`]). The queue holds a scan more for each 50 ms of that wait, so that
//!   waiting drops no scan of a sensor at up to 20 Hz;
//! - the stream ends when the stop flag is set (the command sets it on SIGINT and SIGTERM);
//!   the run then writes its outputs as a finished one does.

use crate::io::error::FileError;
use crate::ros2::clouds::{FrameCheck, RawAdapter, RawMessage};
pub use crate::ros2::counts::Counts;
use crate::ros2::messages::{
    Clock, Imu, PoseWithCovarianceStamped, TfMessage, TriggerRequest, TriggerResponse,
};
use crate::ros2::transforms::StaticTransforms;
use crate::sources::feed::{Feed, FeedSender, Offered};
use crate::sources::imu_readings::frame_period;
use crate::sources::{FrameSource, ImuReading, Request, Sample, Waited};
use ros2_client::{RmwRequestId, Server, Subscription};
use rustdds::mio1::{Events, Interest, Poll, Token};
use rustdds::no_key::SimpleDataReader;
use slamesh_core::Point;
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// The DDS endpoints the listening thread reads.
pub struct Endpoints {
    /// `points`, as raw CDR.
    pub points: SimpleDataReader<RawMessage, RawAdapter>,
    /// `initialpose`.
    pub initialpose: Subscription<PoseWithCovarianceStamped>,
    /// `imu`.
    pub imu: Subscription<Imu>,
    /// `/clock`, when `use_sim_time` is set.
    pub clock: Option<Subscription<Clock>>,
    /// `/tf_static`.
    pub tf_static: Subscription<TfMessage>,
    /// `~/save_map`.
    pub save_map: Server<TriggerRequest, TriggerResponse>,
}

/// The topic names, for messages.
#[derive(Debug, Clone)]
pub struct Names {
    /// `points`.
    pub points: String,
    /// `initialpose`.
    pub initialpose: String,
}

/// IMU readings waiting for their frame, at most (ten seconds at 400 Hz): the oldest go
/// first.
pub const IMU_KEPT: usize = 4000;

/// IMU readings waiting for the frame whose stamp follows theirs.
type ImuQueue = Arc<Mutex<ImuWaiting>>;

/// The IMU's readings not yet handed to a frame, and the newest stamp heard.
#[derive(Debug, Default)]
struct ImuWaiting {
    readings: VecDeque<Sample>,
    /// The newest reading's stamp, handed or not (`None`: no IMU heard yet).
    newest: Option<f64>,
}

/// How often a scan waiting for the IMU looks again.
const IMU_LOOK: Duration = Duration::from_millis(1);

/// The queue's room for scans that wait for the IMU: one more scan for each this long of
/// `imu_wait` (a sensor at up to 20 Hz).
pub const WAIT_PER_SCAN: Duration = Duration::from_millis(50);

/// The node's inputs as frames.
pub struct Ros2Source {
    feed: Feed,
    imu: ImuQueue,
    requests: Receiver<Request>,
    counts: Arc<Mutex<Counts>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    /// What `/tf_static` said.
    transforms: StaticTransforms,
    /// The stamp of the last frame the readings went with.
    last_stamp: Option<f64>,
    /// How long after it came a scan waits for the IMU's readings over its sweep (zero: never).
    imu_wait: Duration,
    /// The last frame handed over before the IMU covered it (counted once, said once).
    late: Option<usize>,
}

impl std::fmt::Debug for Ros2Source {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ros2Source")
            .field("feed", &self.feed)
            .finish()
    }
}

impl Ros2Source {
    /// Starts the listening thread on `endpoints`; at most `queue` scans wait for the run (and
    /// one more for each [`WAIT_PER_SCAN`] of `imu_wait`, the longest a scan waits for the
    /// IMU's readings over its sweep); scans not in `lidar_frame` (the first scan's, if
    /// `None`) are refused.
    pub fn start(
        endpoints: Endpoints,
        names: Names,
        (queue, imu_wait): (usize, Duration),
        lidar_frame: Option<String>,
        stop: Arc<AtomicBool>,
    ) -> Result<Self, crate::ros2::node_error::NodeError> {
        let depth = queue + imu_wait.as_micros().div_ceil(WAIT_PER_SCAN.as_micros()) as usize;
        let (tx, feed) = crate::sources::feed::channel(names.points.clone(), "scan", depth);
        let (request_tx, requests) = mpsc::channel();
        let counts = Arc::new(Mutex::new(Counts::default()));
        let imu = ImuQueue::default();
        let transforms = StaticTransforms::default();
        let listener = Listener {
            imu: imu.clone(),
            endpoints,
            names,
            check: FrameCheck {
                expected: lidar_frame,
            },
            tx,
            requests: request_tx,
            counts: counts.clone(),
            stop: stop.clone(),
            transforms: transforms.clone(),
            pending: Vec::new(),
        };
        let thread = std::thread::Builder::new()
            .name("slamesh-ros2".into())
            .spawn(move || listener.run())
            .map_err(|e| crate::ros2::node_error::NodeError::Start {
                doing: "start the listening thread".into(),
                why: e.to_string(),
            })?;
        Ok(Ros2Source {
            feed,
            imu,
            requests,
            counts,
            stop,
            thread: Some(thread),
            transforms,
            last_stamp: None,
            imu_wait,
            late: None,
        })
    }

    /// The end of frame `i`'s sweep: its stamp plus the time since the frame before (the
    /// readings up to it go with the frame, [`FrameSource::samples`]).
    fn sweep_end(&self, i: usize) -> f64 {
        let stamp = self.feed.stamp(i);
        stamp + frame_period(stamp, self.last_stamp, None)
    }

    /// Whether frame `i` (come) may be handed over as far as the IMU goes: no wait set, no
    /// IMU heard, a reading at or past its sweep's end come, or the wait passed.
    fn imu_ready(&mut self, i: usize) -> bool {
        if self.imu_wait.is_zero() {
            return true;
        }
        let newest = match self.imu.lock() {
            Ok(q) => q.newest,
            Err(_) => return true,
        };
        let Some(newest) = newest else {
            return true;
        };
        if newest >= self.sweep_end(i) {
            return true;
        }
        let came = self.feed.arrival(i).unwrap_or_else(Instant::now);
        if came.elapsed() < self.imu_wait {
            return false;
        }
        if self.late == Some(i) {
            return true;
        }
        if let Ok(mut c) = self.counts.lock() {
            c.imu_late += 1;
        }
        if self.late.replace(i).is_none() {
            log::warn!(
                "{}: the IMU's readings did not cover its sweep (to {:.3} s; the newest is at \
                 {newest:.3} s) within imu_wait = {:.3} s: it runs with what came (said once; \
                 counted as imu_late in /diagnostics and report.json)",
                self.feed.label(i),
                self.sweep_end(i),
                self.imu_wait.as_secs_f64()
            );
        }
        true
    }

    /// Waits until frame `i` (come) is [`imu_ready`](Self::imu_ready).
    fn wait_for_imu(&mut self, i: usize) {
        while !self.imu_ready(i) {
            std::thread::sleep(IMU_LOOK);
        }
    }

    /// What the inputs counted so far.
    pub fn counts(&self) -> Arc<Mutex<Counts>> {
        self.counts.clone()
    }

    /// The scans' frame, once a scan came (or `lidar_frame` named it).
    pub fn scans_frame(&self) -> Option<String> {
        self.counts.lock().ok()?.scans_frame.clone()
    }

    /// The IMU readings' frame, once one came with a frame.
    pub fn imu_frame(&self) -> Option<String> {
        self.counts.lock().ok()?.imu_frame.clone()
    }

    /// The static transforms heard so far.
    pub fn transforms(&self) -> &StaticTransforms {
        &self.transforms
    }

    /// `child` in `parent` as `/tf_static` said so far.
    pub fn static_transform(&self, parent: &str, child: &str) -> Option<slamesh_core::Pose> {
        self.transforms.lookup(parent, child)
    }
}

impl Drop for Ros2Source {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        self.feed.drain();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl FrameSource for Ros2Source {
    fn frames(&self) -> usize {
        self.feed.frames()
    }
    fn label(&self, i: usize) -> String {
        self.feed.label(i)
    }
    fn stamp(&self, i: usize) -> f64 {
        self.feed.stamp(i)
    }
    fn stamp_ns(&self, i: usize) -> Option<i64> {
        self.feed.stamp_ns(i)
    }
    fn read(&mut self, i: usize) -> Result<Vec<Point>, FileError> {
        self.feed.read_timed(i).map(|(p, _)| p)
    }
    fn read_timed(&mut self, i: usize) -> Result<(Vec<Point>, Option<Vec<f32>>), FileError> {
        self.feed.read_timed(i)
    }
    fn has(&mut self, i: usize) -> bool {
        let has = self.feed.has(i);
        if has {
            self.wait_for_imu(i);
        }
        has
    }
    fn wait(&mut self, i: usize) -> Waited {
        let waited = self.feed.wait(i);
        if waited == Waited::Frame {
            self.wait_for_imu(i);
        }
        waited
    }
    fn would_wait(&mut self, i: usize) -> bool {
        self.feed.would_wait(i) || !self.imu_ready(i)
    }
    fn arrival(&self, i: usize) -> Option<Instant> {
        self.feed.arrival(i)
    }
    fn samples(&mut self, i: usize) -> Vec<Sample> {
        let stamp = self.feed.stamp(i);
        let before = self.last_stamp.replace(stamp);
        let up_to = stamp + frame_period(stamp, before, None);
        let Ok(mut q) = self.imu.lock() else {
            return Vec::new();
        };
        let mut out: Vec<Sample> = Vec::new();
        while q.readings.front().is_some_and(|s| s.stamp() <= up_to) {
            out.extend(q.readings.pop_front());
        }
        out.sort_by(|a, b| a.stamp().total_cmp(&b.stamp()));
        out
    }
    fn requests(&mut self) -> Vec<Request> {
        self.requests.try_iter().collect()
    }
    fn input_report(&self) -> Option<serde_json::Value> {
        self.counts
            .lock()
            .ok()
            .and_then(|c| serde_json::to_value(&*c).ok())
    }
}

/// How long the thread waits for DDS before looking at the stop flag.
const TICK: Duration = Duration::from_millis(100);

const POINTS: Token = Token(0);
const INITIALPOSE: Token = Token(1);
const CLOCK: Token = Token(2);
const SAVE_MAP: Token = Token(3);
const IMU: Token = Token(4);
const TF_STATIC: Token = Token(5);

/// A `~/save_map` call waiting for the run's answer: its id, the answer's way back, when it
/// came.
type PendingSave = (RmwRequestId, Receiver<Result<String, String>>, Instant);

/// The listening thread's state.
struct Listener {
    endpoints: Endpoints,
    imu: ImuQueue,
    names: Names,
    check: FrameCheck,
    tx: FeedSender,
    requests: Sender<Request>,
    counts: Arc<Mutex<Counts>>,
    stop: Arc<AtomicBool>,
    transforms: StaticTransforms,
    /// `~/save_map` calls the run has not answered yet.
    pending: Vec<PendingSave>,
}

impl Listener {
    fn run(mut self) {
        let poll = match self.register() {
            Ok(p) => Some(p),
            Err(e) => {
                log::error!("ROS 2: cannot wait for messages ({e}); looking every 10 ms");
                None
            }
        };
        let mut poll = poll;
        let mut events = Events::with_capacity(16);
        while !self.stop.load(Ordering::Relaxed) {
            match &mut poll {
                Some(p) => {
                    if let Err(e) = p.poll(&mut events, Some(TICK)) {
                        if e.kind() != std::io::ErrorKind::Interrupted {
                            log::error!("ROS 2: waiting for messages failed: {e}");
                            break;
                        }
                    }
                }
                None => std::thread::sleep(Duration::from_millis(10)),
            }
            if !self.take_points() {
                break;
            }
            self.take_initial_poses();
            self.take_imu();
            self.take_clock();
            self.take_save_requests();
            while let Ok(Some((m, _))) = self.endpoints.tf_static.take() {
                self.transforms.keep(&m);
            }
        }
        self.tx.end();
    }

    fn register(&mut self) -> std::io::Result<Poll> {
        let poll = Poll::new()?;
        let r = poll.registry();
        let e = &mut self.endpoints;
        r.register(&mut e.points, POINTS, Interest::READABLE)?;
        r.register(&mut e.initialpose, INITIALPOSE, Interest::READABLE)?;
        r.register(&mut e.imu, IMU, Interest::READABLE)?;
        if let Some(c) = &mut e.clock {
            r.register(c, CLOCK, Interest::READABLE)?;
        }
        r.register(&mut e.save_map, SAVE_MAP, Interest::READABLE)?;
        r.register(&mut e.tf_static, TF_STATIC, Interest::READABLE)?;
        Ok(poll)
    }

    fn count(&self, f: impl FnOnce(&mut Counts)) {
        if let Ok(mut c) = self.counts.lock() {
            f(&mut c);
        }
    }

    /// Every message waiting on `points`; false when the run has gone.
    fn take_points(&mut self) -> bool {
        loop {
            let sample = match self.endpoints.points.try_take_one() {
                Ok(Some(s)) => s,
                Ok(None) => return true,
                Err(e) => {
                    // Looked at again on the next wake-up, not in a loop here.
                    self.refuse(None, format!("cannot read the message: {e}"));
                    return true;
                }
            };
            let arrived = Instant::now();
            self.count(|c| c.received += 1);
            let scan = match self.check.scan(&sample.into_value(), arrived) {
                Ok(s) => s,
                Err(r) => {
                    self.refuse(r.stamp, r.reason);
                    continue;
                }
            };
            let stamp = scan.stamp;
            if let Some(frame) = &self.check.expected {
                self.count(|c| {
                    if c.scans_frame.is_none() {
                        c.scans_frame = Some(frame.clone());
                    }
                });
            }
            match self.tx.offer(scan) {
                Offered::Queued => self.count(|c| c.queued += 1),
                Offered::Dropped => {
                    let mut n = 0;
                    self.count(|c| {
                        c.dropped += 1;
                        n = c.dropped;
                    });
                    if worth_saying(n) {
                        log::warn!(
                            "{}: scan at {stamp:.3} s dropped: the pipeline is behind ({n} dropped \
                             so far)",
                            self.names.points
                        );
                    }
                }
                Offered::Closed => return false,
            }
        }
    }

    fn refuse(&self, stamp: Option<f64>, reason: String) {
        let at = stamp.map_or(String::new(), |s| format!(" at {s:.3} s"));
        let line = format!("{}: message{at} skipped: {reason}", self.names.points);
        let mut n = 0;
        self.count(|c| {
            c.refused += 1;
            n = c.refused;
            c.last_refused = Some(line.clone());
        });
        if worth_saying(n) {
            log::warn!("{line} ({n} skipped so far)");
        }
    }

    fn take_initial_poses(&mut self) {
        while let Ok(Some((msg, _))) = self.endpoints.initialpose.take() {
            match msg.pose.pose.to_pose() {
                Some(pose) => {
                    log::info!(
                        "{}: relocalizing near ({:.2}, {:.2}, {:.2}) in {:?}",
                        self.names.initialpose,
                        pose.translation.vector.x,
                        pose.translation.vector.y,
                        pose.translation.vector.z,
                        msg.header.frame_id
                    );
                    self.count(|c| c.initial_poses += 1);
                    self.ask(Request::Relocalize(pose));
                }
                None => log::warn!(
                    "{}: pose skipped: a number is not finite or the quaternion is zero",
                    self.names.initialpose
                ),
            }
        }
    }

    /// Every IMU reading waiting; a reading with a number that is not finite is refused.
    fn take_imu(&mut self) {
        let (mut taken, mut dropped) = (0, 0);
        let mut frame = None;
        while let Ok(Some((m, _))) = self.endpoints.imu.take() {
            if frame.is_none() {
                frame = Some(m.header.frame_id.clone());
            }
            let (w, a) = (m.angular_velocity, m.linear_acceleration);
            let reading = ImuReading {
                stamp: m.header.stamp.seconds(),
                gyro: [w.x, w.y, w.z],
                accel: [a.x, a.y, a.z],
            };
            let finite = reading
                .gyro
                .iter()
                .chain(&reading.accel)
                .all(|v| v.is_finite());
            let Ok(mut q) = self.imu.lock() else { return };
            if !finite {
                dropped += 1;
                continue;
            }
            if q.readings.len() == IMU_KEPT {
                q.readings.pop_front();
                dropped += 1;
            }
            q.newest = Some(q.newest.map_or(reading.stamp, |t| t.max(reading.stamp)));
            q.readings.push_back(Sample::Imu(reading));
            taken += 1;
        }
        if taken + dropped > 0 {
            self.count(|c| {
                c.imu_readings += taken;
                c.imu_dropped += dropped;
                if c.imu_frame.is_none() {
                    c.imu_frame = frame.filter(|f| !f.is_empty());
                }
            });
        }
    }

    fn take_clock(&mut self) {
        let Some(clock) = &self.endpoints.clock else {
            return;
        };
        let mut last = None;
        while let Ok(Some((msg, _))) = clock.take() {
            last = Some(msg.clock.seconds());
        }
        if let Some(t) = last {
            self.count(|c| c.clock_s = Some(t));
        }
    }

    fn take_save_requests(&mut self) {
        while let Ok(Some((id, _))) = self.endpoints.save_map.receive_request() {
            self.count(|c| c.save_requests += 1);
            let (reply_tx, reply_rx) = mpsc::channel();
            self.ask(Request::SaveMap(reply_tx));
            self.pending.push((id, reply_rx, Instant::now()));
        }
        // The run answers between frames; the answer goes out from here.
        let mut waiting = Vec::new();
        for (id, rx, asked) in std::mem::take(&mut self.pending) {
            let answer = match rx.try_recv() {
                Ok(a) => a,
                Err(mpsc::TryRecvError::Empty) if asked.elapsed() < SAVE_TIMEOUT => {
                    waiting.push((id, rx, asked));
                    continue;
                }
                Err(mpsc::TryRecvError::Empty) => Err("the pipeline did not answer in time".into()),
                Err(mpsc::TryRecvError::Disconnected) => Err("the run has ended".into()),
            };
            let (success, message) = match answer {
                Ok(m) => (true, m),
                Err(m) => (false, m),
            };
            let response = TriggerResponse { success, message };
            if let Err(e) = self.endpoints.save_map.send_response(id, response) {
                log::warn!("ROS 2: cannot answer save_map: {e:?}");
            }
        }
        self.pending = waiting;
    }

    fn ask(&self, r: Request) {
        if self.requests.send(r).is_ok() {
            self.tx.wake();
        }
    }
}

/// Whether the `n`th refusal or drop is logged: the first ten, then the 16th, 32nd, ... (all
/// are counted).
fn worth_saying(n: u64) -> bool {
    n <= 10 || n.is_power_of_two()
}

/// How long a `~/save_map` call waits for the run's answer.
const SAVE_TIMEOUT: Duration = Duration::from_secs(60);
