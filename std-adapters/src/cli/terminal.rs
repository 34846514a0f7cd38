//! What a run says on the terminal, for `run`, `mesh`, `localize`, `demo` and `ros2`: each
//! frame's messages (warnings rate-limited by [`FrameNotices`]) and the closing summary.

use crate::cli::notices::FrameNotices;
use crate::loop_closure::{stage, LoopReport};
use crate::run::{FrameRecord, Summary};
use crate::say;
use indicatif::ProgressBar;
use std::path::Path;

/// What the terminal says about one frame: a rate-limited warning when it was skipped or not
/// registered normally, and with `-v` its outcome.
pub fn frame_messages(rec: &FrameRecord, bar: &ProgressBar, notices: &mut FrameNotices) {
    if let Some(e) = &rec.error {
        notices.warn(bar, &format!("skipped: {e}"));
    } else if let Some(reason) = &rec.reason {
        notices.warn(
            bar,
            &format!(
                "frame {} ({}): {}: {reason}",
                rec.frame, rec.file, rec.status
            ),
        );
    }
    if log::log_enabled!(log::Level::Debug) {
        bar.suspend(|| {
            log::debug!(
                "frame {}: {}, {} of {} points kept, {} layers, {:.1} ms",
                rec.frame,
                rec.status,
                rec.points_kept,
                rec.points,
                rec.scan_layers,
                rec.ms.total
            )
        });
    }
}

/// The closing lines of a run: frames, speed, mesh, memory, files.
pub fn print_summary(s: &Summary, out: &Path) {
    let median = |name: &str| {
        s.stage_ms
            .iter()
            .find(|(n, _)| n == name)
            .map_or(0.0, |(_, m)| m.median)
    };
    say!(
        "slamesh: {} frames ({} used, {} skipped) in {:.1} s, {:.1} Hz, median {:.1} ms a frame on {} thread(s)",
        s.frames,
        s.used,
        s.skipped.len(),
        s.seconds,
        s.hz,
        median("total"),
        s.threads
    );
    say!(
        "slamesh: capacity {}; mesh {} triangles, {} vertices; map {} cells, {} evicted; peak memory {}",
        s.capacity,
        s.mesh_triangles,
        s.mesh_vertices,
        s.map_cells,
        s.evicted_cells,
        s.peak_rss_mb
            .map_or("unknown".into(), |m| format!("{m:.0} MB"))
    );
    say!("slamesh: frames by status: {}", s.health.counts_line());
    if let Some(l) = &s.stage::<LoopReport>(stage::NAME) {
        if !l.closures.is_empty() {
            say!(
                "slamesh: loop closure: {} closure(s), {} correction(s), {} map rebuild(s)",
                l.closures.len(),
                l.corrections,
                l.rebuilds
            );
        }
        if let Some(why) = &l.stopped {
            say!("slamesh: loop closure stopped early: {why}");
        }
    }
    let bad = s.health.not_registered.len();
    if bad > 0 {
        say!(
            "slamesh: {bad} frame(s) not registered normally: listed in report.json (summary.health); \
             --strict makes this an error"
        );
    }
    if s.used == 0 {
        say!(
            "slamesh: wrote {}/report.json only (every frame's reason): no frame was used, so \
             there is no trajectory or mesh",
            out.display()
        );
        return;
    }
    let wrote: Vec<String> = (s.files.iter())
        .map(|f| out.join(f).display().to_string())
        .collect();
    say!("slamesh: wrote {}", wrote.join(", "));
}
