//! A live source's frames: scans that a thread of the source's own hands over through a
//! bounded queue, read by the run in order ([`Feed`]). The UDP listener ([`crate::sources::live`])
//! and the ROS 2 node's subscription both feed one.
//!
//! What it guarantees:
//! - the producer never waits: [`FeedSender::offer`] drops a scan that finds the queue full,
//!   whole, and says so (the producer counts it);
//! - frames are the scans the run took, in order, each with its stamp and the instant it came
//!   (for the latency from arrival to pose);
//! - the last [`KEPT`] frames read can be read again (the command looks at the first frames
//!   before the run reads them); a frame further back is an error naming the feed.

use crate::io::error::FileError;
use crate::sources::Waited;
use slamesh_core::Point;
use std::path::Path;
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::time::Instant;

/// Frames kept for a second reading.
pub const KEPT: usize = 2;

/// One scan as it came.
#[derive(Debug, Clone)]
pub struct TimedScan {
    /// Its stamp (seconds).
    pub stamp: f64,
    /// Its stamp exactly, in nanoseconds, when the sensor's message gives it in whole numbers
    /// (a ROS header): what the run's replies carry back ([`Feed::stamp_ns`]).
    pub stamp_ns: Option<i64>,
    /// Its points, sensor frame.
    pub points: Vec<Point>,
    /// Each point's time relative to the stamp (seconds), when the sensor gives them.
    pub times: Option<Vec<f32>>,
    /// When it came.
    pub arrived: Instant,
    /// What came with it (an IMU's readings up to it), for [`Feed::samples`].
    pub samples: Vec<crate::sources::Sample>,
}

/// A frame read, kept for a second reading.
#[derive(Debug)]
struct Kept {
    frame: usize,
    points: Vec<Point>,
    times: Option<Vec<f32>>,
    /// Not handed yet.
    samples: Vec<crate::sources::Sample>,
}

enum Message {
    Scan(TimedScan),
    /// A request came for the run ([`Feed::wait`] returns).
    Wake,
    End,
}

/// What the producer's [`FeedSender::offer`] did with a scan.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Offered {
    /// Queued for the run.
    Queued,
    /// Dropped whole: the run is behind and the queue is full.
    Dropped,
    /// The run has gone: stop producing.
    Closed,
}

/// The producer's end of a feed.
#[derive(Debug, Clone)]
pub struct FeedSender {
    tx: SyncSender<Message>,
}

impl FeedSender {
    /// Hands `scan` to the run without waiting.
    pub fn offer(&self, scan: TimedScan) -> Offered {
        match self.tx.try_send(Message::Scan(scan)) {
            Ok(()) => Offered::Queued,
            Err(TrySendError::Full(_)) => Offered::Dropped,
            Err(TrySendError::Disconnected(_)) => Offered::Closed,
        }
    }

    /// Wakes a run waiting in [`Feed::wait`] (a request came). Not waiting: a full queue
    /// means the run is not waiting for a scan.
    pub fn wake(&self) {
        let _ = self.tx.try_send(Message::Wake);
    }

    /// Ends the stream (not waiting: a full queue ends with the sender's drop, which the
    /// reader sees too).
    pub fn end(self) {
        let _ = self.tx.try_send(Message::End);
    }
}

/// The run's end of a feed: frames in order, waiting for the next while the stream is open.
pub struct Feed {
    label: String,
    unit: &'static str,
    rx: Receiver<Message>,
    /// Each frame's stamp (and its exact one) and arrival.
    frames: Vec<(f64, Option<i64>, Instant)>,
    /// The next scan, taken from the queue ahead of its read.
    next: Option<TimedScan>,
    /// The last frames read (at most [`KEPT`]).
    kept: Vec<Kept>,
    ended: bool,
}

impl std::fmt::Debug for Feed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Feed")
            .field("label", &self.label)
            .field("frames", &self.frames.len())
            .finish()
    }
}

/// A feed holding at most `depth` scans (at least one) for the run; frames are called
/// "`label` `unit` `i`" in messages.
pub fn channel(label: String, unit: &'static str, depth: usize) -> (FeedSender, Feed) {
    let (tx, rx) = mpsc::sync_channel(depth.max(1));
    let feed = Feed {
        label,
        unit,
        rx,
        frames: Vec::new(),
        next: None,
        kept: Vec::new(),
        ended: false,
    };
    (FeedSender { tx }, feed)
}

impl Feed {
    /// Frames taken so far, and one more while the stream is open.
    pub fn frames(&self) -> usize {
        self.frames.len() + usize::from(!self.ended || self.next.is_some())
    }

    /// Takes one message; true when it was a wake-up.
    fn take(&mut self, message: Result<Message, ()>) -> bool {
        match message {
            Ok(Message::Scan(s)) => self.next = Some(s),
            Ok(Message::Wake) => return true,
            Ok(Message::End) | Err(()) => self.ended = true,
        }
        false
    }

    /// Whether frame `i` is there: waits for it while the stream is open.
    pub fn has(&mut self, i: usize) -> bool {
        loop {
            match self.wait(i) {
                Waited::Frame => return true,
                Waited::End => return false,
                Waited::Request => {}
            }
        }
    }

    /// Waits for frame `i` while the stream is open, or for a wake-up ([`FeedSender::wake`]).
    pub fn wait(&mut self, i: usize) -> Waited {
        if i < self.frames.len() || self.next.is_some() && i == self.frames.len() {
            return Waited::Frame;
        }
        if i > self.frames.len() || self.ended {
            return Waited::End;
        }
        let m = self.rx.recv().map_err(|_| ());
        if self.take(m) {
            return Waited::Request;
        }
        match self.next {
            Some(_) => Waited::Frame,
            None => Waited::End,
        }
    }

    /// Whether reading frame `i` would wait: it has not come yet (taken from the queue if it
    /// has).
    pub fn would_wait(&mut self, i: usize) -> bool {
        if i < self.frames.len() || self.ended || self.next.is_some() {
            return false;
        }
        loop {
            let woken = match self.rx.try_recv() {
                Ok(m) => self.take(Ok(m)),
                Err(mpsc::TryRecvError::Disconnected) => self.take(Err(())),
                Err(mpsc::TryRecvError::Empty) => return true,
            };
            if !woken {
                return false;
            }
        }
    }

    /// Frame `i`'s label.
    pub fn label(&self, i: usize) -> String {
        format!("{} {} {i}", self.label, self.unit)
    }

    /// Frame `i`'s stamp (0 when it has not come).
    pub fn stamp(&self, i: usize) -> f64 {
        match (self.frames.get(i), &self.next) {
            (Some((t, _, _)), _) => *t,
            (None, Some(s)) if i == self.frames.len() => s.stamp,
            _ => 0.0,
        }
    }

    /// Frame `i`'s exact stamp in nanoseconds, when its message gave one
    /// ([`TimedScan::stamp_ns`]).
    pub fn stamp_ns(&self, i: usize) -> Option<i64> {
        match (self.frames.get(i), &self.next) {
            (Some((_, t, _)), _) => *t,
            (None, Some(s)) if i == self.frames.len() => s.stamp_ns,
            _ => None,
        }
    }

    /// When frame `i` came (also the next one, come but not read yet).
    pub fn arrival(&self, i: usize) -> Option<Instant> {
        match (self.frames.get(i), &self.next) {
            (Some(f), _) => Some(f.2),
            (None, Some(s)) if i == self.frames.len() => Some(s.arrived),
            _ => None,
        }
    }

    /// Frame `i`, waiting for it: the next one, or one of the last [`KEPT`] read (a live
    /// stream cannot go further back).
    pub fn read_timed(&mut self, i: usize) -> Result<(Vec<Point>, Option<Vec<f32>>), FileError> {
        if let Some(k) = self.kept.iter().find(|k| k.frame == i) {
            return Ok((k.points.clone(), k.times.clone()));
        }
        let label = self.label.clone();
        let err = |why: String| FileError::at(Path::new(&label), why);
        if i != self.frames.len() {
            return Err(err(format!(
                "frame {i}: a live stream is read in order (next: {})",
                self.frames.len()
            )));
        }
        if !self.has(i) {
            return Err(err("the stream has ended".into()));
        }
        let Some(scan) = self.next.take() else {
            return Err(err("the stream has ended".into()));
        };
        self.frames.push((scan.stamp, scan.stamp_ns, scan.arrived));
        if self.kept.len() == KEPT {
            self.kept.remove(0);
        }
        self.kept.push(Kept {
            frame: i,
            points: scan.points.clone(),
            times: scan.times.clone(),
            samples: scan.samples,
        });
        Ok((scan.points, scan.times))
    }

    /// What came with frame `i`, once it was read: handed once.
    pub fn samples(&mut self, i: usize) -> Vec<crate::sources::Sample> {
        (self.kept.iter_mut().find(|k| k.frame == i))
            .map_or_else(Vec::new, |k| std::mem::take(&mut k.samples))
    }

    /// Empties the queue, for a source that is closing.
    pub fn drain(&mut self) {
        while self.rx.try_recv().is_ok() {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scan(stamp: f64) -> TimedScan {
        TimedScan {
            samples: Vec::new(),
            stamp,
            stamp_ns: None,
            points: vec![[stamp as f32, 0.0, 0.0]],
            times: None,
            arrived: Instant::now(),
        }
    }

    #[test]
    fn frames_come_in_order_and_a_full_queue_drops_the_new_scan() {
        let (tx, mut feed) = channel("test".into(), "scan", 2);
        assert_eq!(tx.offer(scan(1.0)), Offered::Queued);
        assert_eq!(tx.offer(scan(2.0)), Offered::Queued);
        assert_eq!(tx.offer(scan(3.0)), Offered::Dropped);
        assert!(feed.has(0));
        assert_eq!(feed.stamp(0), 1.0);
        assert_eq!(feed.read_timed(0).unwrap().0, vec![[1.0, 0.0, 0.0]]);
        assert!(!feed.would_wait(1));
        assert_eq!(feed.read_timed(1).unwrap().0, vec![[2.0, 0.0, 0.0]]);
        // Read again: kept.
        assert_eq!(feed.read_timed(0).unwrap().0, vec![[1.0, 0.0, 0.0]]);
        assert!(feed.would_wait(2));
        tx.end();
        assert!(!feed.has(2));
        assert!(feed.read_timed(2).is_err());
        assert_eq!(feed.frames(), 2);
        assert!(feed.label(5).ends_with("scan 5"));
    }

    #[test]
    fn a_dropped_sender_ends_the_stream() {
        let (tx, mut feed) = channel("test".into(), "scan", 1);
        drop(tx);
        assert!(!feed.has(0));
        let (tx, feed) = channel("test".into(), "scan", 1);
        drop(feed);
        assert_eq!(tx.offer(scan(1.0)), Offered::Closed);
    }
}
