//! Reading and filtering ahead: while the pipeline registers frame `i`, frame `i + 1` is read
//! (on the run's thread: a source need not be `Send`) and filtered on a thread of its own by
//! the core's [`ScanFilter`]. The filter runs on one core; ahead, it runs while the pipeline's
//! serial stages (bucketing, the solve, the update) leave the other core idle.
//!
//! What it guarantees:
//! - the same filtered points as the pipeline's own filter (the same function at the same
//!   capacity), so the same poses and mesh;
//! - a frame it cannot filter ahead is handed back raw, to be filtered in line: one to deskew
//!   (its motion is known only once frame `i` is registered) and one with more raw points
//!   than the capacity (whose refusal the step words);
//! - at most one frame ahead, its buffers counted by [`LookAhead::bytes`];
//! - off ([`LookAhead::off`]) with one thread: nothing ahead, no thread.

use crate::io::error::FileError;
use crate::run::source::FrameSource;
use slamesh_core::filter::{FilterStats, Filtered, ScanFilter};
use slamesh_core::{Capacity, Config, Point, Serial};
use std::sync::mpsc;
use std::thread;
use std::time::Instant;

/// A frame's points as the step gets them.
#[derive(Debug)]
pub enum Scan {
    /// As read, with each point's time when the source records them.
    Raw {
        /// Sensor-frame points.
        points: Vec<Point>,
        /// Their times relative to the frame's stamp (seconds).
        times: Option<Vec<f32>>,
    },
    /// Being filtered ahead: [`LookAhead::filtered`] waits for the result.
    Ahead {
        /// How many raw points were read.
        points: usize,
    },
}

/// One frame read.
#[derive(Debug)]
pub struct Read {
    /// Its index.
    pub frame: usize,
    /// Its points, or why they could not be read.
    pub scan: Result<Scan, FileError>,
    /// Time spent reading (ms).
    pub ms: f64,
    /// Points the reader dropped ([`FrameSource::dropped_by_reader`] right after the read).
    pub dropped_by_reader: usize,
}

/// A frame filtered ahead.
#[derive(Debug)]
pub struct Ahead {
    /// The down-sampled points.
    pub points: Vec<Point>,
    /// What the filter did.
    pub stats: FilterStats,
    /// Time the filter thread spent on it (ms).
    pub filter_ms: f64,
    /// Time the run waited for it (ms).
    pub wait_ms: f64,
}

impl Ahead {
    /// The core's view of it.
    pub fn filtered(&self) -> Filtered<'_> {
        Filtered {
            points: &self.points,
            stats: self.stats,
        }
    }
}

/// The filter thread and the frame read ahead.
#[derive(Debug, Default)]
pub struct LookAhead {
    worker: Option<Worker>,
    next: Option<Read>,
}

/// The filter thread: raw scans in, filtered ones out, in order.
#[derive(Debug)]
struct Worker {
    /// `None` once dropped: closing the queue ends the thread's loop.
    jobs: Option<mpsc::Sender<Vec<Point>>>,
    done: mpsc::Receiver<(Vec<Point>, FilterStats, f64)>,
    thread: Option<thread::JoinHandle<()>>,
}

impl LookAhead {
    /// No look-ahead: every frame is read when its step comes, and filtered in line.
    pub fn off() -> Self {
        Self::default()
    }

    /// A look-ahead with a filter thread for a pipeline of capacity `C` and `config`.
    pub fn new<C: Capacity>(config: Config) -> Self {
        let (jobs, inbox) = mpsc::channel::<Vec<Point>>();
        let (outbox, done) = mpsc::channel();
        let thread = thread::Builder::new()
            .name("slamesh-filter".into())
            .spawn(move || {
                run_when_idle();
                let mut filter = ScanFilter::new::<C>();
                for raw in inbox {
                    let t = Instant::now();
                    let f = filter.filter(&raw, &config, &Serial);
                    let ms = t.elapsed().as_secs_f64() * 1e3;
                    if outbox.send((f.points.to_vec(), f.stats, ms)).is_err() {
                        break;
                    }
                }
            });
        match thread {
            Ok(thread) => Self {
                worker: Some(Worker {
                    jobs: Some(jobs),
                    done,
                    thread: Some(thread),
                }),
                next: None,
            },
            // No thread to be had: the run filters in line, as with one thread.
            Err(_) => Self::off(),
        }
    }

    /// Bytes a look-ahead adds for capacity `C`: its filter's buffers and one filtered scan.
    pub fn bytes<C: Capacity>() -> usize {
        C::filter_bytes() + C::POINTS * size_of::<Point>()
    }

    /// Frame `i`: the one read ahead if it is `i`, otherwise read now (raw).
    pub fn take(&mut self, source: &mut impl FrameSource, i: usize) -> Read {
        match self.next.take() {
            Some(read) if read.frame == i => read,
            stale => {
                if let Some(Read {
                    scan: Ok(Scan::Ahead { .. }),
                    ..
                }) = stale
                {
                    let _ = self.filtered();
                }
                read(source, i)
            }
        }
    }

    /// Reads frame `i` now, and starts filtering it when `can_filter` says its points may be.
    /// Does nothing when off or past the last frame.
    pub fn read_ahead(
        &mut self,
        source: &mut impl FrameSource,
        i: usize,
        can_filter: impl Fn(&[Point], &Option<Vec<f32>>) -> bool,
    ) {
        let Some(worker) = &self.worker else { return };
        if i >= source.frames() {
            return;
        }
        let mut r = read(source, i);
        if let Ok(Scan::Raw { points, times }) = &mut r.scan {
            if can_filter(points, times) {
                let n = points.len();
                let sent = worker.jobs.as_ref().map(|j| j.send(std::mem::take(points)));
                if matches!(sent, Some(Ok(()))) {
                    r.scan = Ok(Scan::Ahead { points: n });
                }
            }
        }
        self.next = Some(r);
    }

    /// Waits for the frame being filtered ahead.
    pub fn filtered(&mut self) -> Result<Ahead, String> {
        let t = Instant::now();
        let received = self.worker.as_ref().map(|w| w.done.recv());
        match received {
            Some(Ok((points, stats, filter_ms))) => Ok(Ahead {
                points,
                stats,
                filter_ms,
                wait_ms: t.elapsed().as_secs_f64() * 1e3,
            }),
            _ => Err("the filter thread stopped".into()),
        }
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        self.jobs = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Puts the calling thread in Linux's idle scheduling class, so that it runs on a core only
/// when nothing else would: the filter fills the gaps the pipeline's serial stages leave
/// instead of slowing its parallel ones. Elsewhere, or if refused, the thread runs as any.
/// The crate's one `unsafe`: a libc call with no pointer but to a local.
#[allow(unsafe_code)]
fn run_when_idle() {
    #[cfg(target_os = "linux")]
    {
        let param = libc::sched_param { sched_priority: 0 };
        // SAFETY: pid 0 is the calling thread; `param` is a valid `sched_param` for the call.
        let _ = unsafe { libc::sched_setscheduler(0, libc::SCHED_IDLE, &param) };
    }
}

/// Reads frame `i` raw, timed.
fn read(source: &mut impl FrameSource, i: usize) -> Read {
    let t = Instant::now();
    let scan = source
        .read_timed(i)
        .map(|(points, times)| Scan::Raw { points, times });
    Read {
        frame: i,
        scan,
        ms: t.elapsed().as_secs_f64() * 1e3,
        dropped_by_reader: source.dropped_by_reader(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slamesh_core::KittiCapacity;

    /// Frame `i` is a row of `10 + i` points 2 m ahead; frame 2 cannot be read.
    struct Rows;

    impl FrameSource for Rows {
        fn frames(&self) -> usize {
            6
        }
        fn label(&self, i: usize) -> String {
            format!("row {i}")
        }
        fn stamp(&self, i: usize) -> f64 {
            i as f64
        }
        fn read(&mut self, i: usize) -> Result<Vec<Point>, FileError> {
            if i == 2 {
                return Err(FileError::at(std::path::Path::new("row 2"), "unreadable"));
            }
            Ok((0..10 + i).map(|k| [2.0, k as f32 * 0.5, 0.0]).collect())
        }
    }

    fn raw_len(r: &Read) -> Option<usize> {
        match &r.scan {
            Ok(Scan::Raw { points, .. }) => Some(points.len()),
            _ => None,
        }
    }

    #[test]
    fn frames_come_back_in_order_filtered_ahead_raw_or_failed() {
        let config = Config::default();
        let mut ahead = LookAhead::new::<KittiCapacity>(config);
        let mut source = Rows;
        let yes = |_: &[Point], _: &Option<Vec<f32>>| true;
        // Nothing ahead: read now, raw.
        let first = ahead.take(&mut source, 0);
        assert_eq!((first.frame, raw_len(&first)), (0, Some(10)));
        // Ahead: the filter thread's result is the core filter's.
        ahead.read_ahead(&mut source, 1, yes);
        let second = ahead.take(&mut source, 1);
        assert!(matches!(second.scan, Ok(Scan::Ahead { points: 11 })));
        let got = ahead.filtered().unwrap();
        let raw = Rows.read(1).unwrap();
        let mut own = ScanFilter::new::<KittiCapacity>();
        let want = own.filter(&raw, &config, &Serial);
        assert_eq!(
            (got.points.as_slice(), got.stats),
            (want.points, want.stats)
        );
        // A frame that cannot be read is handed over as its error.
        ahead.read_ahead(&mut source, 2, yes);
        assert!(ahead.take(&mut source, 2).scan.is_err());
        // A frame read ahead but not asked for is dropped, its filtering too: the next one
        // filtered ahead is the next one received.
        ahead.read_ahead(&mut source, 3, yes);
        let fourth = ahead.take(&mut source, 4);
        assert_eq!(raw_len(&fourth), Some(14));
        ahead.read_ahead(&mut source, 5, yes);
        assert!(matches!(
            ahead.take(&mut source, 5).scan,
            Ok(Scan::Ahead { points: 15 })
        ));
        assert_eq!(ahead.filtered().unwrap().stats.input, 15);
        // A frame the step must filter itself, and past the end: nothing ahead.
        ahead.read_ahead(&mut source, 4, |_, _| false);
        assert_eq!(raw_len(&ahead.take(&mut source, 4)), Some(14));
        ahead.read_ahead(&mut source, 6, yes);
        assert!(ahead.next.is_none());
    }

    #[test]
    fn off_reads_each_frame_when_asked() {
        let mut ahead = LookAhead::off();
        ahead.read_ahead(&mut Rows, 1, |_, _| true);
        assert!(ahead.next.is_none());
        assert_eq!(raw_len(&ahead.take(&mut Rows, 1)), Some(11));
        assert!(ahead.filtered().is_err());
    }
}
