//! A sensor's packets taken live from a UDP socket (`slamesh run udp://0.0.0.0:2368`),
//! assembled into sweeps on a thread of their own and handed to the run through a bounded
//! queue.
//!
//! What it guarantees:
//! - the socket is read on its own thread and never waits for the run: a sweep that finds the
//!   queue full is dropped whole (counted, [`LiveStats::sweeps_dropped`]), never a part of one;
//! - frames are the sweeps the run took, in order; each keeps its stamp (the middle of its
//!   firings, [`crate::sources::sweep::Sweep::stamp`]) and the instant its last packet came, for
//!   the latency from packet to pose;
//! - the stream ends when [`PacketOptions::stop`] is set (the command sets it on Ctrl-C), after
//!   [`PacketOptions::idle`] without a packet, or on a socket error; a run then writes its
//!   outputs as a finished one does.
//!
//! A Velodyne's packet times are placed in the hour of the host's clock (the sensor's own
//! time of hour is kept within it); an Ouster's are its own clock's, as its packets carry them.

pub mod imu_port;

use crate::io::error::FileError;
use crate::sources::feed::{self, Feed, FeedSender, Offered, TimedScan};
use crate::sources::packets::{self, PacketOptions, SensorHint, SensorStream, StreamStats};
use crate::sources::sweep::Sweep;
use crate::sources::Sample;
use serde::Serialize;
use slamesh_core::imu::ImuSample;
use slamesh_core::Point;
use std::net::{SocketAddr, UdpSocket};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// How to listen.
#[derive(Debug, Clone)]
pub struct LiveOptions {
    /// The sensor, where turns are cut, when to end ([`PacketOptions::idle`],
    /// [`PacketOptions::stop`]).
    pub packets: PacketOptions,
    /// Sweeps waiting for the run, at most.
    pub queue: usize,
}

impl Default for LiveOptions {
    fn default() -> Self {
        Self {
            packets: PacketOptions::default(),
            queue: 2,
        }
    }
}

/// What the listening thread counted.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct LiveStats {
    /// The sensor, once told.
    pub sensor: Option<String>,
    /// Datagrams received.
    pub datagrams: u64,
    /// The sensor's packets.
    pub stream: StreamStats,
    /// Whole sweeps assembled.
    pub sweeps: u64,
    /// Whole sweeps dropped because the run was behind (the queue full).
    pub sweeps_dropped: u64,
    /// An Ouster's IMU packets taken on its own port ([`imu_port`]), and those refused.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub imu_port: Option<ImuPortStats>,
    /// Why the stream ended, if it was not asked to.
    pub error: Option<String>,
}

/// What the IMU port's thread counted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct ImuPortStats {
    /// The port.
    pub port: u16,
    /// IMU packets decoded.
    pub packets: u64,
    /// Datagrams refused (not a legacy IMU packet).
    pub bad_packets: u64,
    /// Readings dropped unread (the run took none for [`imu_port::KEPT`] of them).
    pub dropped: u64,
}

/// A live stream as frames.
pub struct Live {
    local: SocketAddr,
    feed: Feed,
    stats: Arc<Mutex<LiveStats>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    /// The thread on an Ouster's IMU port, when it has one of its own.
    imu_thread: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for Live {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Live")
            .field("local", &self.local)
            .field("feed", &self.feed)
            .finish()
    }
}

/// The address of a `udp://HOST:PORT` input, if it is one.
pub fn address(input: &str) -> Option<&str> {
    input.strip_prefix("udp://")
}

impl Live {
    /// Binds `addr` (`HOST:PORT`) and starts listening.
    pub fn open(addr: &str, options: &LiveOptions) -> Result<Self, FileError> {
        let label = format!("udp://{addr}");
        let err = |why: String| FileError::at(Path::new(&label), why);
        let packets = &options.packets;
        let hint = SensorHint::new(packets, None)?;
        let socket = UdpSocket::bind(addr).map_err(|e| err(format!("cannot listen: {e}")))?;
        let local = socket.local_addr().map_err(|e| err(e.to_string()))?;
        socket
            .set_read_timeout(Some(Duration::from_millis(50)))
            .map_err(|e| err(e.to_string()))?;
        let (tx, feed) = feed::channel(label.clone(), "sweep", options.queue);
        let stats = Arc::new(Mutex::new(LiveStats::default()));
        let imu = hint
            .ouster()
            .and_then(|o| imu_port::listen(o, local, &packets.stop, &stats));
        let (imu_readings, imu_thread) = imu.unzip();
        let listener = Listener {
            imu: imu_readings,
            socket,
            hint,
            cut_deg: packets.cut_azimuth_deg,
            idle: packets.idle,
            stop: packets.stop.clone(),
            stats: stats.clone(),
            tx,
        };
        let thread = std::thread::Builder::new()
            .name("slamesh-udp".into())
            .spawn(move || listener.run())
            .map_err(|e| err(format!("cannot start the listening thread: {e}")))?;
        Ok(Self {
            local,
            feed,
            stats,
            stop: packets.stop.clone(),
            thread: Some(thread),
            imu_thread,
        })
    }

    /// The address listened on (the port the system chose, when 0 was asked).
    pub fn local_addr(&self) -> SocketAddr {
        self.local
    }

    /// What the listening thread counted so far.
    pub fn stats(&self) -> LiveStats {
        self.stats.lock().map(|s| s.clone()).unwrap_or_default()
    }

    /// Frames taken so far, and one more while the stream is open.
    pub fn frames(&self) -> usize {
        self.feed.frames()
    }

    /// Whether frame `i` is there: waits for it while the stream is open.
    pub fn has(&mut self, i: usize) -> bool {
        self.feed.has(i)
    }

    /// Whether reading frame `i` would wait: it has not come yet.
    pub fn would_wait(&mut self, i: usize) -> bool {
        self.feed.would_wait(i)
    }

    /// Frame `i`'s label.
    pub fn label(&self, i: usize) -> String {
        self.feed.label(i)
    }

    /// Frame `i`'s stamp.
    pub fn stamp(&self, i: usize) -> f64 {
        self.feed.stamp(i)
    }

    /// When frame `i`'s last packet came.
    pub fn arrival(&self, i: usize) -> Option<Instant> {
        self.feed.arrival(i)
    }

    /// Frame `i`, waiting for it: the next one, or one of the last two read (a live stream
    /// cannot go further back).
    pub fn read_timed(&mut self, i: usize) -> Result<(Vec<Point>, Option<Vec<f32>>), FileError> {
        self.feed.read_timed(i)
    }

    /// The IMU's readings that came with frame `i` (an Ouster's IMU packets sent to the lidar
    /// port), once it was read.
    pub fn samples(&mut self, i: usize) -> Vec<Sample> {
        self.feed.samples(i)
    }
}

/// A sensor's packets taken live from a UDP socket: an address `udp://HOST:PORT`.
pub struct LiveKind;

impl crate::sources::kinds::InputKind for LiveKind {
    fn name(&self) -> &'static str {
        "a live sensor (udp://)"
    }

    fn open(
        &self,
        path: &Path,
        how: &crate::sources::kinds::OpenOptions,
    ) -> Option<Result<crate::sources::kinds::Opened, FileError>> {
        let addr = path.to_str().and_then(address)?;
        let live = LiveOptions {
            packets: how.packets.clone(),
            ..LiveOptions::default()
        };
        Some(Live::open(addr, &live).map(|l| Box::new(l) as _))
    }
}

impl crate::sources::FrameSource for Live {
    fn frames(&self) -> usize {
        Live::frames(self)
    }
    fn label(&self, i: usize) -> String {
        Live::label(self, i)
    }
    fn stamp(&self, i: usize) -> f64 {
        Live::stamp(self, i)
    }
    fn read(&mut self, i: usize) -> Result<Vec<Point>, FileError> {
        Live::read_timed(self, i).map(|(p, _)| p)
    }
    fn read_timed(&mut self, i: usize) -> Result<(Vec<Point>, Option<Vec<f32>>), FileError> {
        Live::read_timed(self, i)
    }
    fn has(&mut self, i: usize) -> bool {
        Live::has(self, i)
    }
    fn would_wait(&mut self, i: usize) -> bool {
        Live::would_wait(self, i)
    }
    fn arrival(&self, i: usize) -> Option<Instant> {
        Live::arrival(self, i)
    }
    fn samples(&mut self, i: usize) -> Vec<Sample> {
        Live::samples(self, i)
    }
    fn input_report(&self) -> Option<serde_json::Value> {
        serde_json::to_value(self.stats()).ok()
    }
}

impl crate::sources::kinds::OpenedInput for Live {
    fn describe(&self) -> String {
        format!("packets on {}", self.local_addr())
    }
    fn is_live(&self) -> bool {
        true
    }
}

impl Drop for Live {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        // The thread sees the flag within its read timeout.
        self.feed.drain();
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        if let Some(t) = self.imu_thread.take() {
            let _ = t.join();
        }
    }
}

/// The listening thread's state.
struct Listener {
    socket: UdpSocket,
    hint: SensorHint,
    cut_deg: Option<f64>,
    idle: Option<Duration>,
    stop: Arc<AtomicBool>,
    stats: Arc<Mutex<LiveStats>>,
    tx: FeedSender,
    /// Readings from the IMU port's thread, when there is one.
    imu: Option<imu_port::Readings>,
}

impl Listener {
    fn run(self) {
        let mut buf = vec![0u8; 65_536];
        let mut stream: Option<SensorStream> = None;
        let mut last_packet = Instant::now();
        // Every datagram read here was sent to this port.
        let port = self.socket.local_addr().map_or(0, |a| a.port());
        let error = loop {
            if self.stop.load(Ordering::Relaxed) {
                break None;
            }
            if self.idle.is_some_and(|idle| last_packet.elapsed() > idle) {
                break None;
            }
            let n = match receive(&self.socket, &mut buf) {
                Ok(Some(n)) => n,
                Ok(None) => continue,
                Err(e) => break Some(format!("cannot receive: {e}")),
            };
            last_packet = Instant::now();
            let payload = &buf[..n];
            let now = SystemTime::now()
                .duration_since(UNIX_EPOCH)
                .map_or(0.0, |d| d.as_secs_f64());
            if let Ok(mut s) = self.stats.lock() {
                s.datagrams += 1;
            }
            if stream.is_none() {
                match packets::identify(payload, &self.hint) {
                    Ok(Some(sensor)) => {
                        stream = Some(SensorStream::new(&sensor, port, self.cut_deg));
                        if let Ok(mut s) = self.stats.lock() {
                            s.sensor = Some(sensor.name());
                        }
                    }
                    Ok(None) => continue,
                    Err(e) => break Some(e),
                }
            }
            let Some(st) = &mut stream else { continue };
            let done = st.datagram(port, payload, now);
            if !self.hand_over(st, done) {
                break None;
            }
        };
        if let Some(st) = &mut stream {
            self.finish(st);
        }
        if let Ok(mut s) = self.stats.lock() {
            s.error = error;
        }
        self.tx.end();
    }

    /// Offers the sweep a datagram completed (if any) and counts; false when the run has gone.
    fn hand_over(&self, st: &mut SensorStream, done: Option<Sweep>) -> bool {
        let completed = done.is_some();
        let offered = done.map(|sweep| self.tx.offer(timed(sweep, self.imu_readings(st))));
        if let Ok(mut s) = self.stats.lock() {
            s.stream = st.stats();
            s.sweeps += u64::from(completed);
            s.sweeps_dropped += u64::from(offered == Some(Offered::Dropped));
        }
        offered != Some(Offered::Closed)
    }

    /// The IMU's readings since the last sweep: the lidar port's and the IMU port's, in time
    /// order.
    fn imu_readings(&self, st: &mut SensorStream) -> Vec<ImuSample> {
        let mut readings = st.take_imu();
        if let Some(shared) = &self.imu {
            readings.extend(imu_port::take(shared));
            readings.sort_by(|a, b| a.stamp.total_cmp(&b.stamp));
        }
        readings
    }

    /// The stream's end: a turn that ended right at the cut is whole, and goes if the queue
    /// has room.
    fn finish(&self, st: &mut SensorStream) {
        if let Some(sweep) = st.finish() {
            if self.tx.offer(timed(sweep, self.imu_readings(st))) == Offered::Queued {
                if let Ok(mut s) = self.stats.lock() {
                    s.sweeps += 1;
                }
            }
        }
        let counts = st.stats();
        if let Ok(mut s) = self.stats.lock() {
            s.stream = counts;
        }
    }
}

/// A datagram's length, read into `buf`; `None` when the socket's read timeout passed first.
fn receive(socket: &UdpSocket, buf: &mut [u8]) -> std::io::Result<Option<usize>> {
    match socket.recv_from(buf) {
        Ok((n, _)) => Ok(Some(n)),
        Err(e)
            if matches!(
                e.kind(),
                std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
            ) =>
        {
            Ok(None)
        }
        Err(e) => Err(e),
    }
}

/// A sweep as the feed takes it, come now, with the IMU's readings since the last one.
fn timed(sweep: Sweep, imu: Vec<ImuSample>) -> TimedScan {
    TimedScan {
        samples: imu.into_iter().map(Sample::Imu).collect(),
        stamp: sweep.stamp().unwrap_or(0.0),
        stamp_ns: None,
        times: Some(sweep.relative_times()),
        points: sweep.points,
        arrived: Instant::now(),
    }
}
