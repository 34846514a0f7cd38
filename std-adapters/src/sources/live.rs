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

use crate::io::error::FileError;
use crate::sources::packets::{self, PacketOptions, SensorHint, SensorStream, StreamStats};
use crate::sources::sweep::Sweep;
use serde::Serialize;
use slamesh_core::Point;
use std::net::{SocketAddr, UdpSocket};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
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
    /// Why the stream ended, if it was not asked to.
    pub error: Option<String>,
}

/// Frames kept for a second reading.
const KEPT: usize = 2;

enum Message {
    Sweep(Sweep, Instant),
    End,
}

/// A live stream as frames.
pub struct Live {
    label: String,
    local: SocketAddr,
    rx: Receiver<Message>,
    /// Each frame's stamp and the instant its last packet came.
    frames: Vec<(f64, Instant)>,
    /// The next sweep, taken from the queue ahead of its read.
    next: Option<(Sweep, Instant)>,
    /// The last frames read (at most [`KEPT`]), for a second reading: the command looks at the
    /// first frame before the run reads it.
    kept: Vec<(usize, Vec<Point>, Vec<f32>)>,
    ended: bool,
    stats: Arc<Mutex<LiveStats>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl std::fmt::Debug for Live {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Live")
            .field("local", &self.local)
            .field("frames", &self.frames.len())
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
        let (tx, rx) = mpsc::sync_channel(options.queue.max(1));
        let stats = Arc::new(Mutex::new(LiveStats::default()));
        let listener = Listener {
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
            label,
            local,
            rx,
            frames: Vec::new(),
            next: None,
            kept: Vec::new(),
            ended: false,
            stats,
            stop: packets.stop.clone(),
            thread: Some(thread),
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
        self.frames.len() + usize::from(!self.ended || self.next.is_some())
    }

    /// Whether frame `i` is there: waits for it while the stream is open.
    pub fn has(&mut self, i: usize) -> bool {
        if i < self.frames.len() || self.next.is_some() && i == self.frames.len() {
            return true;
        }
        if i > self.frames.len() || self.ended {
            return false;
        }
        match self.rx.recv() {
            Ok(Message::Sweep(s, at)) => {
                self.next = Some((s, at));
                true
            }
            Ok(Message::End) | Err(_) => {
                self.ended = true;
                false
            }
        }
    }

    /// Whether reading frame `i` would wait: it has not come yet (taken from the queue if it
    /// has).
    pub fn would_wait(&mut self, i: usize) -> bool {
        if i < self.frames.len() || self.ended || self.next.is_some() {
            return false;
        }
        match self.rx.try_recv() {
            Ok(Message::Sweep(s, at)) => {
                self.next = Some((s, at));
                false
            }
            Ok(Message::End) | Err(mpsc::TryRecvError::Disconnected) => {
                self.ended = true;
                false
            }
            Err(mpsc::TryRecvError::Empty) => true,
        }
    }

    /// Frame `i`'s label.
    pub fn label(&self, i: usize) -> String {
        format!("{} sweep {i}", self.label)
    }

    /// Frame `i`'s stamp.
    pub fn stamp(&self, i: usize) -> f64 {
        match (self.frames.get(i), &self.next) {
            (Some((t, _)), _) => *t,
            (None, Some((s, _))) if i == self.frames.len() => s.stamp().unwrap_or(0.0),
            _ => 0.0,
        }
    }

    /// When frame `i`'s last packet came.
    pub fn arrival(&self, i: usize) -> Option<Instant> {
        self.frames.get(i).map(|f| f.1)
    }

    /// Frame `i`, waiting for it: the next one, or one of the last two read (a live stream
    /// cannot go further back).
    pub fn read_timed(&mut self, i: usize) -> Result<(Vec<Point>, Option<Vec<f32>>), FileError> {
        if let Some((_, points, times)) = self.kept.iter().find(|k| k.0 == i) {
            return Ok((points.clone(), Some(times.clone())));
        }
        if i != self.frames.len() {
            return Err(FileError::at(
                Path::new(&self.label),
                format!(
                    "frame {i}: a live stream is read in order (next: {})",
                    self.frames.len()
                ),
            ));
        }
        if !self.has(i) {
            return Err(FileError::at(
                Path::new(&self.label),
                "the stream has ended",
            ));
        }
        let Some((sweep, at)) = self.next.take() else {
            return Err(FileError::at(
                Path::new(&self.label),
                "the stream has ended",
            ));
        };
        self.frames.push((sweep.stamp().unwrap_or(0.0), at));
        let times = sweep.relative_times();
        if self.kept.len() == KEPT {
            self.kept.remove(0);
        }
        self.kept.push((i, sweep.points.clone(), times.clone()));
        Ok((sweep.points, Some(times)))
    }
}

impl Drop for Live {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        // The thread sees the flag within its read timeout.
        while self.rx.try_recv().is_ok() {}
        if let Some(t) = self.thread.take() {
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
    tx: SyncSender<Message>,
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
            let (n, _) = match self.socket.recv_from(&mut buf) {
                Ok(got) => got,
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) =>
                {
                    continue;
                }
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
            let counts = st.stats();
            let completed = done.is_some();
            let mut dropped = false;
            if let Some(sweep) = done {
                match self.tx.try_send(Message::Sweep(sweep, Instant::now())) {
                    Ok(()) => {}
                    Err(TrySendError::Full(_)) => dropped = true,
                    Err(TrySendError::Disconnected(_)) => break None,
                }
            }
            if let Ok(mut s) = self.stats.lock() {
                s.stream = counts;
                s.sweeps += u64::from(completed);
                if dropped {
                    s.sweeps_dropped += 1;
                }
            }
        };
        if let Some(st) = &mut stream {
            // A turn that ended right at the cut is whole; it goes if the queue has room.
            if let Some(sweep) = st.finish() {
                if self
                    .tx
                    .try_send(Message::Sweep(sweep, Instant::now()))
                    .is_ok()
                {
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
        if let Ok(mut s) = self.stats.lock() {
            s.error = error;
        }
        // Not waiting: a full queue ends with the sender's drop, which the reader sees too.
        let _ = self.tx.try_send(Message::End);
    }
}
