//! The capacity classes the command offers, and how to choose one for a sensor.
//!
//! A class is one of the core's [`Capacity`] types: its numbers are fixed at compile time,
//! and the command is built for each (so four copies of the pipeline's code are in the
//! binary). A scan with more points within range than its class holds is refused with the
//! class to use, rather than cut silently ([`Run::step`](crate::run::Run::step)).

use crate::run::memory;
use crate::run::options::RunOptions;
use crate::run::window::Window;
use crate::sources::FrameSource;
use slamesh_core::config::FilterConfig;
use slamesh_core::filter::Preparation;
use slamesh_core::{Capacity, Point};
#[cfg(doc)]
use slamesh_core::{KittiCapacity, Lidar16Capacity, Lidar32Capacity, SmallCapacity};

/// The compiled-in capacity classes, smallest first.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ClassId {
    /// [`SmallCapacity`].
    Tiny,
    /// [`Lidar16Capacity`].
    L16,
    /// [`Lidar32Capacity`].
    L32,
    /// [`KittiCapacity`].
    L64,
}

/// Runs `$body` with `$C` standing for the capacity type of the [`ClassId`] `$class`: the one
/// place a class chosen at run time becomes a type (the command, the demo and the Python
/// module all dispatch through it).
///
/// ```
/// use slamesh::run::capacity::ClassId;
/// use slamesh::core::Capacity;
/// let points = slamesh::with_capacity!(ClassId::L16, C => C::POINTS);
/// assert_eq!(points, 36_000);
/// ```
#[macro_export]
macro_rules! with_capacity {
    ($class:expr, $C:ident => $body:expr) => {
        match $class {
            $crate::run::capacity::ClassId::Tiny => {
                type $C = $crate::core::SmallCapacity;
                $body
            }
            $crate::run::capacity::ClassId::L16 => {
                type $C = $crate::core::Lidar16Capacity;
                $body
            }
            $crate::run::capacity::ClassId::L32 => {
                type $C = $crate::core::Lidar32Capacity;
                $body
            }
            $crate::run::capacity::ClassId::L64 => {
                type $C = $crate::core::KittiCapacity;
                $body
            }
        }
    };
}

impl ClassId {
    /// Every class, smallest first.
    pub const ALL: [ClassId; 4] = [ClassId::Tiny, ClassId::L16, ClassId::L32, ClassId::L64];

    /// Its value of `--capacity` (and of the Python module's `capacity`).
    pub const fn flag(self) -> &'static str {
        match self {
            ClassId::Tiny => "tiny",
            ClassId::L16 => "16",
            ClassId::L32 => "32",
            ClassId::L64 => "64",
        }
    }

    /// The class whose flag is `flag`.
    pub fn from_flag(flag: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|c| c.flag() == flag)
    }

    /// Its numbers.
    pub fn class(self) -> Class {
        crate::with_capacity!(self, C => Class::of::<C>(self))
    }
}

/// One compiled-in capacity.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Class {
    /// Which it is.
    pub id: ClassId,
    /// Its name in messages ([`Capacity::NAME`]).
    pub name: &'static str,
    /// Its value of `--capacity`.
    pub flag: &'static str,
    /// Points a scan may keep within range ([`Capacity::POINTS`]).
    pub points: usize,
    /// Its memory bound ([`Capacity::memory_bytes`]).
    pub bytes: usize,
    /// What it needs under a memory cap, before the rest of the process, with the next frame
    /// read ahead but filtered in line ([`Window::least_cap_bytes`]).
    pub least_cap_bytes: usize,
    /// The same with loop closure's thread ([`Window::least_cap_bytes_closing`]).
    pub least_cap_closing_bytes: usize,
}

impl Class {
    fn of<C: Capacity>(id: ClassId) -> Self {
        Class {
            id,
            name: C::NAME,
            flag: id.flag(),
            points: C::POINTS,
            bytes: C::memory_bytes(),
            least_cap_bytes: Window::least_cap_bytes::<C>(0, false),
            least_cap_closing_bytes: Window::least_cap_bytes_closing::<C>(0),
        }
    }
}

/// The classes, smallest first.
pub fn classes() -> [Class; 4] {
    ClassId::ALL.map(ClassId::class)
}

/// Room kept above the first scan's points when choosing a class: later scans may see more.
pub const HEADROOM: f64 = 1.25;

/// The smallest class that holds `points` within range with [`HEADROOM`] to spare; the
/// largest when none does.
pub fn class_for(points: usize) -> Class {
    let all = classes();
    let need = (points as f64 * HEADROOM).ceil() as usize;
    all.into_iter()
        .find(|c| c.points >= need)
        .unwrap_or(all[all.len() - 1])
}

/// [`class_for`] under a memory cap of `cap_bytes` with `other_bytes` for the rest of the
/// process: when that class needs more than the cap and a smaller one holds `points` (with no
/// headroom) and fits, the smaller one. Later scans with more points than it holds are then
/// refused, each with the class to use: a tight cap is worth more than the spare room. With
/// loop closure asked for (`closing`), a class that fits with it first, then one without.
pub fn class_under_cap(
    points: usize,
    cap_bytes: usize,
    other_bytes: usize,
    closing: bool,
) -> Class {
    let fits = |c: &Class, closing: bool| {
        let least = match closing {
            true => c.least_cap_closing_bytes,
            false => c.least_cap_bytes,
        };
        least + other_bytes <= cap_bytes
    };
    let preferred = class_for(points);
    let holding = class_holding(points);
    for closing in [closing, false] {
        if fits(&preferred, closing) {
            return preferred;
        }
        if let Some(c) = holding.filter(|c| fits(c, closing)) {
            return c;
        }
    }
    preferred
}

/// The class that holds a scan of `points` within range (no headroom), if any does.
pub fn class_holding(points: usize) -> Option<Class> {
    classes().into_iter().find(|c| c.points >= points)
}

/// Points of `scan` the filter would keep before down-sampling: those the core's
/// [`Preparation`] accepts (finite, within range).
pub fn points_in_range(scan: &[Point], filter: &FilterConfig) -> usize {
    // The voxel size only sets the keys, which this count does not use.
    let prep = Preparation::new(filter, 1.0);
    scan.iter().filter(|p| prep.point(p).is_ok()).count()
}

/// A scan with fewer than one in this many of its neighbours' points is worth a warning: a
/// cut-off file or a partial sweep ([`choose`], and the run's step).
pub const SMALL_SCAN_RATIO: usize = 4;

/// Frames whose point counts a scan is compared with ([`RecentScans`]).
pub const RECENT_SCANS: usize = 9;

/// The point counts of the last [`RECENT_SCANS`] frames a run read: a scan far smaller than
/// their median ([`SMALL_SCAN_RATIO`]) is named, a cut-off file or a partial sweep; it is
/// used all the same.
#[derive(Debug, Default)]
pub struct RecentScans(std::collections::VecDeque<usize>);

impl RecentScans {
    /// Counts the frame `rec` describes, saying first when its scan is far smaller than the
    /// frames read before it.
    pub fn note(&mut self, rec: &crate::run::report::FrameRecord) {
        let n = rec.points;
        if n == 0 {
            return;
        }
        // Their median, sorted in place of a copy: no allocation on the frame's path.
        let mut recent = [0usize; RECENT_SCANS];
        let k = self.0.len();
        for (r, &n) in recent.iter_mut().zip(&self.0) {
            *r = n;
        }
        recent[..k].sort_unstable();
        if let Some(&typical) = recent[..k].get(k / 2) {
            if n * SMALL_SCAN_RATIO < typical {
                log::warn!(
                    "{}: frame {}: {n} points, far fewer than the {typical} of the frames before \
                     it: a cut-off file or a partial sweep?",
                    rec.file,
                    rec.frame
                );
            }
        }
        if self.0.len() == RECENT_SCANS {
            self.0.pop_front();
        }
        self.0.push_back(n);
    }
}

/// Readable scans among the first frames that `auto` looks at ([`choose`]).
pub const CHOICE_SCANS: usize = 5;

/// The class `auto` chooses: the smallest for the largest of the first [`CHOICE_SCANS`]
/// readable scans of `source` (of the first ten; a live source's that have come), counting
/// their points within the configuration's range limits, so that one odd small first scan (a
/// partial sweep, a cut-off file) does not choose a class too small for the sensor's whole
/// sweeps; under the memory cap when there is one ([`class_under_cap`]); the largest when no
/// scan is readable. Says what it chose.
pub fn choose(source: &mut impl FrameSource, opts: &RunOptions) -> Class {
    let mut seen: Vec<(usize, usize)> = Vec::new();
    for i in 0..source.frames().min(10) {
        if seen.len() == CHOICE_SCANS || (!seen.is_empty() && source.would_wait(i)) {
            break;
        }
        if let Ok(scan) = source.read(i) {
            seen.push((i, points_in_range(&scan, &opts.config.filter)));
        }
    }
    // The first of the largest.
    let Some((i, n)) = seen
        .iter()
        .copied()
        .reduce(|a, b| if b.1 > a.1 { b } else { a })
    else {
        let all = classes();
        return all[all.len() - 1];
    };
    for &(j, m) in seen.iter().filter(|&&(_, m)| m * SMALL_SCAN_RATIO < n) {
        log::warn!(
            "{}: frame {j}: {m} points within range, far fewer than frame {i}'s {n}: a cut-off \
             file or a partial sweep? (it does not choose the capacity class)",
            source.label(j)
        );
    }
    let class = match opts.window.memory_cap_mb {
        Some(cap) => {
            let other = memory::other_bytes();
            let closing = opts.loop_closure.is_some();
            let class = class_under_cap(n, (cap * 1e6) as usize, other, closing);
            let least = |c: &Class| (c.least_cap_bytes + other) as f64 / 1e6;
            match class_holding(n) {
                Some(h) if least(&class) > cap => log::warn!(
                    "a memory cap of {cap} MB is too tight for frame {i}'s {n} points within \
                     range: the smallest class that holds them, {} (--capacity {}), needs {:.0} MB",
                    h.name,
                    h.flag,
                    least(&h)
                ),
                _ => {}
            }
            class
        }
        None => class_for(n),
    };
    log::info!(
        "capacity {} (--capacity {}): frame {i} has {n} points within range, the most of the \
         first {} readable scans",
        class.name,
        class.flag,
        seen.len()
    );
    class
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_class_is_its_capacity_type() {
        for id in ClassId::ALL {
            let c = id.class();
            assert_eq!(ClassId::from_flag(c.flag), Some(id));
            let (name, points) = crate::with_capacity!(id, C => (C::NAME, C::POINTS));
            assert_eq!((c.name, c.points), (name, points));
        }
        let points: Vec<usize> = classes().iter().map(|c| c.points).collect();
        assert!(points.windows(2).all(|w| w[0] < w[1]), "smallest first");
    }

    #[test]
    fn the_smallest_class_with_headroom_is_chosen() {
        assert_eq!(class_for(1_000).flag, "tiny");
        assert_eq!(class_for(1_700).flag, "16", "1 700 x 1.25 > 2 048");
        assert_eq!(class_for(28_000).flag, "16");
        assert_eq!(class_for(30_000).flag, "32");
        assert_eq!(class_for(121_000).flag, "64");
        assert_eq!(
            class_for(500_000).flag,
            "64",
            "the largest when none holds it"
        );
        assert_eq!(class_holding(36_000).map(|c| c.flag), Some("16"));
        assert_eq!(class_holding(200_000), None);
    }

    #[test]
    fn a_tight_cap_takes_the_smallest_class_that_holds_the_scan() {
        let [_, l16, l32, l64] = classes();
        // 60 000 points: the 64-beam class with a quarter to spare, the 32-beam without.
        assert_eq!(class_for(60_000), l64);
        let other = 10_000_000;
        let roomy = l64.least_cap_bytes + other;
        assert_eq!(class_under_cap(60_000, roomy, other, false), l64);
        assert_eq!(class_under_cap(60_000, roomy - 1, other, false), l32);
        // With loop closure asked for: the class that keeps it within the cap before the one
        // with room to spare, and without it only when none keeps it.
        let closing = l32.least_cap_closing_bytes + other;
        assert!(l32.least_cap_closing_bytes < l64.least_cap_closing_bytes);
        assert!(l64.least_cap_closing_bytes > l64.least_cap_bytes);
        assert_eq!(class_under_cap(60_000, closing, other, true), l32);
        let big = l64.least_cap_closing_bytes + other;
        assert_eq!(class_under_cap(60_000, big, other, true), l64);
        assert_eq!(
            class_under_cap(60_000, closing - 1, other, true),
            class_under_cap(60_000, closing - 1, other, false)
        );
        assert!(l32.least_cap_bytes < l64.least_cap_bytes);
        // Too tight for any class that holds the scan: the preferred one (refused later).
        assert_eq!(
            class_under_cap(60_000, l16.least_cap_bytes + other, other, false),
            l64
        );
    }

    #[test]
    fn points_in_range_counts_what_the_filter_keeps() {
        let f = FilterConfig {
            range_min_m: 1.0,
            range_max_m: 10.0,
            vertical_correction_deg: 0.0,
        };
        let scan = [
            [0.5, 0.0, 0.0],
            [2.0, 0.0, 0.0],
            [0.0, 9.0, 0.0],
            [20.0, 0.0, 0.0],
            [f32::NAN, 0.0, 0.0],
        ];
        assert_eq!(points_in_range(&scan, &f), 2);
    }
}
