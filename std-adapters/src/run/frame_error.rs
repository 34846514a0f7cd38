//! Why one frame was skipped ([`FrameError`]): the run records it with the frame's file and
//! index and goes on. An error that stops the run is a [`RunError`](crate::run::RunError).

use crate::io::error::FileError;
use crate::run::capacity::Class;
use slamesh_core::deskew::DeskewError;
use slamesh_core::pipeline::Relocalized;
use slamesh_core::relocalize::Search;
use slamesh_core::ScanError;
use std::fmt;

/// A frame the run could not use, and why.
#[derive(Debug, Clone)]
pub struct FrameError {
    /// The frame's file (or recording and message) as the source names it.
    pub label: String,
    /// Its index.
    pub frame: usize,
    /// What went wrong.
    pub fault: FrameFault,
}

/// What went wrong with a frame.
#[derive(Debug, Clone)]
pub enum FrameFault {
    /// It could not be read (the reader's error names the file and the place).
    Unreadable(FileError),
    /// Its points' times do not fit its points.
    CannotDeskew(DeskewError),
    /// More points within range than the capacity class holds.
    OverCapacity {
        /// Points within range.
        points: usize,
        /// The run's class's name.
        class: &'static str,
        /// What it holds.
        holds: usize,
        /// The smallest class that holds them, if any does.
        larger: Option<Class>,
    },
    /// Meshing at given poses, and none is given for this frame.
    NoGivenPose {
        /// The given trajectory's tolerance in time and this frame's stamp (s), when poses
        /// are matched by time; `None` when matched by line.
        by_time: Option<(f64, f64)>,
        /// The line of the given trajectory that would hold it.
        line: usize,
    },
    /// The pipeline refused the scan.
    Refused(ScanError),
    /// A search for the pose in a saved map found no convincing one (what it saw).
    NotLocalized(Box<Relocalized>),
}

impl FrameError {
    /// `fault` of frame `frame`, whose file is `label`.
    pub fn new(label: &str, frame: usize, fault: FrameFault) -> Self {
        FrameError {
            label: label.to_string(),
            frame,
            fault,
        }
    }
}

impl fmt::Display for FrameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let FrameFault::Unreadable(e) = &self.fault {
            return write!(f, "{e}");
        }
        write!(f, "{}: frame {}: {}", self.label, self.frame, self.fault)
    }
}

impl fmt::Display for FrameFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FrameFault::Unreadable(e) => write!(f, "{e}"),
            FrameFault::CannotDeskew(e) => write!(f, "cannot deskew: {e:?}"),
            FrameFault::OverCapacity {
                points,
                class,
                holds,
                larger,
            } => {
                write!(
                    f,
                    "{points} points within range, more than the {class} capacity holds \
                     ({holds}): "
                )?;
                match larger {
                    Some(c) => write!(f, "run with --capacity {}", c.flag),
                    None => write!(
                        f,
                        "no class holds it: thin the scan, or narrow filter.range_min_m and \
                         filter.range_max_m"
                    ),
                }
            }
            FrameFault::NoGivenPose {
                by_time: Some((tolerance, stamp)),
                ..
            } => write!(
                f,
                "no given pose within {tolerance:.3} s of its time {stamp:.6}"
            ),
            FrameFault::NoGivenPose {
                by_time: None,
                line,
            } => write!(f, "no given pose (line {line})"),
            FrameFault::Refused(e) => write!(f, "{e}"),
            FrameFault::NotLocalized(r) => write!(f, "{}", not_found(r)),
        }
    }
}

impl std::error::Error for FrameError {}

/// Why a frame whose search found no convincing pose has none.
pub fn not_found(r: &Relocalized) -> String {
    format!(
        "not localized in the map: its best pose puts {:.0} % of the scan on the map's surfaces \
         (at least {:.0} % needed) and {:.0} % on its walls (at least {:.0} %){}, the best elsewhere {:.0} % ({} hypotheses, {} registered); \
         the next frame searches again",
        100.0 * r.hit_share,
        100.0 * Search::default().min_hit_share,
        100.0 * r.wall_share,
        100.0 * Search::default().min_wall_share,
        if r.settled {
            ""
        } else {
            " and its registration did not settle"
        },
        100.0 * r.runner_up_share,
        r.hypotheses,
        r.registered
    )
}
