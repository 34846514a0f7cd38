//! Wall-clock time per pipeline stage, through the core's [`Probe`].

use slamesh_core::{Probe, Stage};
use std::time::{Duration, Instant};

/// Milliseconds per stage of one scan, plus the std-side stages.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct StageMs {
    /// Reading the scan file.
    pub read: f64,
    /// Deskewing (0 for scans without point times).
    pub deskew: f64,
    /// Range filter and down-sampling.
    pub filter: f64,
    /// Bucketing (all rounds).
    pub bucket: f64,
    /// GP reconstruction (all rounds).
    pub reconstruct: f64,
    /// Association (all rounds).
    pub associate: f64,
    /// Levenberg-Marquardt (all rounds).
    pub solve: f64,
    /// Map fusion, and clearing what the scan sees through (`--dynamic`).
    pub update: f64,
    /// Mesh extraction of the cells this scan updated.
    pub mesh: f64,
    /// Sliding-window eviction.
    pub evict: f64,
    /// Everything above but reading; a filter run ahead on its own thread
    /// ([`crate::run::lookahead`]) counts only for the time the run waited for it.
    pub total: f64,
}

impl StageMs {
    /// The field names, in [`values`](Self::values) order.
    pub const NAMES: [&'static str; 11] = [
        "read",
        "deskew",
        "filter",
        "bucket",
        "reconstruct",
        "associate",
        "solve",
        "update",
        "mesh",
        "evict",
        "total",
    ];

    /// The fields in [`NAMES`](Self::NAMES) order.
    pub fn values(&self) -> [f64; 11] {
        [
            self.read,
            self.deskew,
            self.filter,
            self.bucket,
            self.reconstruct,
            self.associate,
            self.solve,
            self.update,
            self.mesh,
            self.evict,
            self.total,
        ]
    }

    /// The times from their [`values`](Self::values).
    pub fn from_values(v: [f64; 11]) -> Self {
        let [read, deskew, filter, bucket, reconstruct, associate, solve, update, mesh, evict, total] =
            v;
        StageMs {
            read,
            deskew,
            filter,
            bucket,
            reconstruct,
            associate,
            solve,
            update,
            mesh,
            evict,
            total,
        }
    }

    /// The per-scan pipeline time: deskew to mesh (no reading, no eviction).
    pub fn pipeline(&self) -> f64 {
        self.deskew
            + self.filter
            + self.bucket
            + self.reconstruct
            + self.associate
            + self.solve
            + self.update
            + self.mesh
    }
}

/// A run's clock: the core stages' times ([`StageTimer`]) and the frame loop's wall time,
/// counting what a resumed run's process before it took.
#[derive(Debug)]
pub(crate) struct RunClock {
    /// The core stages' times of the frame in progress.
    pub(crate) stages: StageTimer,
    started: Instant,
    /// Loop seconds before this process (from the checkpoint when resuming).
    before: f64,
}

impl RunClock {
    /// A clock started now, `before` seconds of the loop already run.
    pub(crate) fn new(before: f64) -> Self {
        Self {
            stages: StageTimer::new(),
            started: Instant::now(),
            before,
        }
    }

    /// The frame loop's seconds so far.
    pub(crate) fn seconds(&self) -> f64 {
        self.before + self.started.elapsed().as_secs_f64()
    }
}

/// A [`Probe`] that adds up the time spent in each core stage.
#[derive(Debug, Default)]
pub struct StageTimer {
    current: Option<(Stage, Instant)>,
    spent: [Duration; 6],
}

impl StageTimer {
    /// A timer with nothing recorded.
    pub fn new() -> Self {
        Self::default()
    }

    /// The time recorded so far, then cleared.
    pub fn take(&mut self) -> StageMs {
        let ms = |s: Stage| {
            let i = Stage::WORKING.iter().position(|&w| w == s).unwrap_or(0);
            self.spent[i].as_secs_f64() * 1e3
        };
        let out = StageMs {
            filter: ms(Stage::Filter),
            bucket: ms(Stage::Bucket),
            reconstruct: ms(Stage::Reconstruct),
            associate: ms(Stage::Associate),
            solve: ms(Stage::Solve),
            update: ms(Stage::Update),
            ..StageMs::default()
        };
        self.spent = Default::default();
        self.current = None;
        out
    }
}

impl Probe for StageTimer {
    fn enter(&mut self, stage: Stage) {
        let now = Instant::now();
        if let Some((s, since)) = self.current.take() {
            if let Some(i) = Stage::WORKING.iter().position(|&w| w == s) {
                self.spent[i] += now - since;
            }
        }
        if stage != Stage::Done {
            self.current = Some((stage, now));
        }
    }
}
