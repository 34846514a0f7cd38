//! Reading and filtering ahead: while the pipeline registers frame `i`, frame `i + 1` is read
//! (on the run's thread: a source need not be `Send`) and filtered by the core's
//! [`ScanFilter`] as one task on the run's rayon pool. The pipeline runs on the pool too
//! ([`Workers::install_beside`]), so no thread of the run waits beside the pool's and the
//! scheduler has no more threads than cores to share out. On two threads the filter runs with
//! the [`Yielding`] executor: between pieces of its work it runs the pipeline's waiting
//! parallel tasks first, so its own work lands where the pipeline runs serially (bucketing,
//! the solve, the update). On more ([`SPREAD_FROM`]) its own loops are spread over
//! the pool too ([`OnThisPool`]): run serially it took longer than the whole of the rest of a
//! frame on 8 and 16 threads, and the pipeline waited for it (docs/journal.md, "All the
//! cores").
//!
//! What it guarantees:
//! - the same filtered points as the pipeline's own filter (the same function at the same
//!   capacity), so the same poses and mesh;
//! - a frame it cannot filter ahead is handed back raw, to be filtered in line: one to deskew
//!   (its motion is known only once frame `i` is registered) and one with more raw points
//!   than the capacity (whose refusal the step words);
//! - at most one frame ahead, its buffers counted by [`LookAhead::bytes`];
//! - [`LookAhead::reading_only`]: the next frame read ahead, but filtered in line (no buffers
//!   of its own, for a tight memory cap);
//! - off ([`LookAhead::off`]) or with one thread (no pool): nothing ahead;
//! - a live source's frame is read ahead only if it is already there
//!   ([`FrameSource::would_wait`]).

use crate::io::error::FileError;
use crate::parallel::{OnThisPool, Workers, Yielding, SPREAD_FROM};
use crate::sources::FrameSource;
use slamesh_core::filter::{FilterStats, Filtered, ScanFilter};
use slamesh_core::{Capacity, Config, Point};
use std::path::Path;
use std::sync::mpsc;
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
    /// Filtered ahead.
    Filtered {
        /// How many raw points were read.
        points: usize,
        /// The filtered scan.
        ahead: Ahead,
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
    /// Time the filter job took (ms).
    pub filter_ms: f64,
    /// Time the run waited for it (ms).
    pub wait_ms: f64,
    /// The scan's own points, when the look-ahead keeps them ([`LookAhead::keep_points`]);
    /// none otherwise.
    pub raw: Vec<Point>,
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

/// The filter run ahead on the pool, and the frame read ahead.
#[derive(Debug, Default)]
pub struct LookAhead {
    /// The filter's buffers while no frame is being filtered; `None` when off, or while
    /// a job holds them.
    filter: Option<ScanFilter>,
    /// Where a job sends its result and hands the filter back.
    done: Option<(mpsc::Sender<Job>, mpsc::Receiver<Job>)>,
    /// The frame read ahead; while a job filters it, its raw points are the job's and
    /// `filtering` holds how many there were.
    next: Option<Read>,
    filtering: Option<usize>,
    /// Whether a frame filtered ahead keeps its own points too ([`Ahead::raw`]).
    keep_points: bool,
}

/// What a filter job hands back: the filter, the down-sampled points, what it did, the time
/// it took (ms) and the scan's own points when they are kept.
type Job = (ScanFilter, Vec<Point>, FilterStats, f64, Vec<Point>);

impl LookAhead {
    /// No look-ahead: every frame is read when its step comes, and filtered in line.
    pub fn off() -> Self {
        Self::default()
    }

    /// A look-ahead that reads the next frame while the pipeline registers this one, but
    /// leaves its filtering to the pipeline: for a memory cap too tight for the filter's
    /// buffers twice ([`bytes`](Self::bytes) of none).
    pub fn reading_only() -> Self {
        Self {
            done: Some(mpsc::channel()),
            ..Self::default()
        }
    }

    /// A look-ahead for a pipeline of capacity `C`, filtering on the pool of the run's
    /// workers ([`read_ahead`](Self::read_ahead)).
    pub fn new<C: Capacity>() -> Self {
        Self {
            filter: Some(ScanFilter::new::<C>()),
            done: Some(mpsc::channel()),
            ..Self::default()
        }
    }

    /// Frames filtered ahead keep their own points too ([`Ahead::raw`]: the navigation
    /// map's floor counts them), held one frame longer.
    pub fn keep_points(&mut self) {
        self.keep_points = true;
    }

    /// Bytes a look-ahead adds for capacity `C`: its filter's buffers and one filtered scan.
    pub fn bytes<C: Capacity>() -> usize {
        C::filter_bytes() + C::POINTS * size_of::<Point>()
    }

    /// Frame `i`: the one read ahead if it is `i` (waiting for its filter job), otherwise
    /// read now (raw).
    pub fn take(&mut self, source: &mut impl FrameSource, i: usize) -> Read {
        let filtering = self.filtering.take();
        match self.next.take() {
            Some(mut read) if read.frame == i => {
                if let Some(points) = filtering {
                    read.scan = match self.filtered() {
                        Ok(ahead) => Ok(Scan::Filtered { points, ahead }),
                        Err(e) => Err(FileError::at(
                            Path::new(&source.label(i)),
                            format!("frame {i}: {e}"),
                        )),
                    };
                }
                read
            }
            _ => {
                // A stale frame's job still hands the filter back.
                if filtering.is_some() {
                    let _ = self.filtered();
                }
                read(source, i)
            }
        }
    }

    /// Reads frame `i` now, and starts filtering it on `workers`' pool with `config` when
    /// `can_filter` says its points may be. Does nothing when off or past the last frame.
    pub fn read_ahead(
        &mut self,
        source: &mut impl FrameSource,
        i: usize,
        workers: &Workers,
        config: &Config,
        can_filter: impl Fn(&[Point], &Option<Vec<f32>>) -> bool,
    ) {
        let (Some((outbox, _)), Workers::Pool(pool)) = (&self.done, workers) else {
            return;
        };
        // A live source's next frame that has not come yet is not waited for: the frame being
        // registered would wait with it, a whole sweep's time added to its latency.
        if i >= source.frames() || source.would_wait(i) {
            return;
        }
        let mut r = read(source, i);
        if let Ok(Scan::Raw { points, times }) = &mut r.scan {
            if can_filter(points, times) {
                if let Some(mut filter) = self.filter.take() {
                    let n = points.len();
                    let (raw, outbox, config) = (std::mem::take(points), outbox.clone(), *config);
                    let spread = pool.threads() >= SPREAD_FROM;
                    let keep = self.keep_points;
                    pool.spawn(move || {
                        let t = Instant::now();
                        let f = if spread {
                            filter.filter(&raw, &config, &OnThisPool)
                        } else {
                            filter.filter(&raw, &config, &Yielding)
                        };
                        let (points, stats) = (f.points.to_vec(), f.stats);
                        let ms = t.elapsed().as_secs_f64() * 1e3;
                        let raw = if keep { raw } else { Vec::new() };
                        let _ = outbox.send((filter, points, stats, ms, raw));
                    });
                    self.filtering = Some(n);
                }
            }
        }
        self.next = Some(r);
    }

    /// Waits for the frame being filtered ahead, and takes the filter back.
    fn filtered(&mut self) -> Result<Ahead, String> {
        let t = Instant::now();
        let received = self.done.as_ref().map(|(_, inbox)| inbox.recv());
        match received {
            Some(Ok((filter, points, stats, filter_ms, raw))) => {
                self.filter = Some(filter);
                Ok(Ahead {
                    points,
                    stats,
                    filter_ms,
                    wait_ms: t.elapsed().as_secs_f64() * 1e3,
                    raw,
                })
            }
            _ => Err("the filter job stopped".into()),
        }
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
    use slamesh_core::{KittiCapacity, Serial};

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

    /// The frame's points filtered ahead, or why not.
    fn filtered(r: Read) -> Ahead {
        match r.scan {
            Ok(Scan::Filtered { ahead, .. }) => ahead,
            other => panic!("not filtered ahead: {other:?}"),
        }
    }

    #[test]
    fn frames_come_back_in_order_filtered_ahead_raw_or_failed() {
        // Two threads: the filter yields; four: it spreads over the pool.
        for threads in [2, 4] {
            in_order_filtered_ahead_raw_or_failed(threads);
        }
    }

    fn in_order_filtered_ahead_raw_or_failed(threads: usize) {
        let config = Config::default();
        let workers = Workers::new(threads).unwrap();
        let mut ahead = LookAhead::new::<KittiCapacity>();
        let mut source = Rows;
        let yes = |_: &[Point], _: &Option<Vec<f32>>| true;
        // Nothing ahead: read now, raw.
        let first = ahead.take(&mut source, 0);
        assert_eq!((first.frame, raw_len(&first)), (0, Some(10)));
        // Ahead: the filter job's result is the core filter's.
        ahead.read_ahead(&mut source, 1, &workers, &config, yes);
        let second = ahead.take(&mut source, 1);
        assert!(matches!(second.scan, Ok(Scan::Filtered { points: 11, .. })));
        let got = filtered(second);
        let raw = Rows.read(1).unwrap();
        let mut own = ScanFilter::new::<KittiCapacity>();
        let want = own.filter(&raw, &config, &Serial);
        assert_eq!(
            (got.points.as_slice(), got.stats),
            (want.points, want.stats)
        );
        // A frame that cannot be read is handed over as its error.
        ahead.read_ahead(&mut source, 2, &workers, &config, yes);
        assert!(ahead.take(&mut source, 2).scan.is_err());
        // A frame read ahead but not asked for is dropped once its filtering is done: the
        // filter is back for the next one.
        ahead.read_ahead(&mut source, 3, &workers, &config, yes);
        let fourth = ahead.take(&mut source, 4);
        assert_eq!(raw_len(&fourth), Some(14));
        ahead.read_ahead(&mut source, 5, &workers, &config, yes);
        assert_eq!(filtered(ahead.take(&mut source, 5)).stats.input, 15);
        // A frame the step must filter itself, and past the end: nothing ahead.
        ahead.read_ahead(&mut source, 4, &workers, &config, |_, _| false);
        assert_eq!(raw_len(&ahead.take(&mut source, 4)), Some(14));
        ahead.read_ahead(&mut source, 6, &workers, &config, yes);
        assert!(ahead.next.is_none());
    }

    #[test]
    fn a_look_ahead_keeping_points_hands_the_frame_as_read_with_its_filtered_points() {
        let (config, yes) = (Config::default(), |_: &[Point], _: &Option<Vec<f32>>| true);
        let workers = Workers::new(2).unwrap();
        let mut ahead = LookAhead::new::<KittiCapacity>();
        ahead.read_ahead(&mut Rows, 1, &workers, &config, yes);
        assert!(
            filtered(ahead.take(&mut Rows, 1)).raw.is_empty(),
            "not kept"
        );
        ahead.keep_points();
        ahead.read_ahead(&mut Rows, 3, &workers, &config, yes);
        let got = filtered(ahead.take(&mut Rows, 3));
        assert_eq!(got.raw, Rows.read(3).unwrap());
        assert_eq!(got.stats.input, 13);
    }

    #[test]
    fn off_or_on_one_thread_reads_each_frame_when_asked() {
        let (config, yes) = (Config::default(), |_: &[Point], _: &Option<Vec<f32>>| true);
        for (mut ahead, threads) in [
            (LookAhead::off(), 2),
            (LookAhead::new::<KittiCapacity>(), 1),
        ] {
            let workers = Workers::new(threads).unwrap();
            ahead.read_ahead(&mut Rows, 1, &workers, &config, yes);
            assert!(ahead.next.is_none());
            assert_eq!(raw_len(&ahead.take(&mut Rows, 1)), Some(11));
        }
    }
}
