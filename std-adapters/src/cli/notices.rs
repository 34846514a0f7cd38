//! [`FrameNotices`]: the warnings about single frames (skipped, not registered normally), rate
//! limited so that a stretch of bad frames cannot flood the terminal.

use indicatif::ProgressBar;
use std::time::Instant;

/// Warnings shown at once before the rate limit applies.
const BURST: f64 = 10.0;
/// Warnings a second after that.
const PER_SECOND: f64 = 1.0;

/// Frame warnings through `log::warn!`: up to [`BURST`] at once, then [`PER_SECOND`] a second;
/// the ones held back are counted and said with the next one shown, and at the end.
#[derive(Debug)]
pub struct FrameNotices {
    tokens: f64,
    last: Instant,
    held: usize,
}

impl Default for FrameNotices {
    fn default() -> Self {
        FrameNotices {
            tokens: BURST,
            last: Instant::now(),
            held: 0,
        }
    }
}

impl FrameNotices {
    /// Shows `line` as a warning (above the progress `bar`) unless the limit holds it back.
    pub fn warn(&mut self, bar: &ProgressBar, line: &str) {
        let now = Instant::now();
        self.tokens =
            (self.tokens + now.duration_since(self.last).as_secs_f64() * PER_SECOND).min(BURST);
        self.last = now;
        if self.tokens < 1.0 {
            self.held += 1;
            return;
        }
        self.tokens -= 1.0;
        let held = std::mem::take(&mut self.held);
        bar.suspend(|| match held {
            0 => log::warn!("{line}"),
            n => log::warn!("{line} ({n} more frame warnings held back before this one)"),
        });
    }

    /// Says how many warnings were held back since the last one shown, if any.
    pub fn finish(&mut self) {
        let held = std::mem::take(&mut self.held);
        if held > 0 {
            log::warn!("{held} more frame warnings held back; report.json lists every frame");
        }
    }
}
