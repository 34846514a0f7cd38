//! Whether decoded points can be a LiDAR's scan: their median range within
//! [`MAX_MEDIAN_RANGE_M`]. Fields read at the wrong type or offset (float64 data read as
//! float32, a text file read as a `.bin`) give coordinates of 10^3 to 10^38 m; taken as a
//! scan, such a cloud fixed the node's scale and capacity and put garbage into the map. A
//! scan is refused with its reason before anything reads it; world-frame clouds (maps, ground
//! truth) are not scans and are not checked.
//!
//! The median is taken over at most [`SAMPLE`] points spread through the scan: a fixed cost.

use slamesh_core::Point;
use std::fmt;

/// No LiDAR's scan has most of its points farther than this (metres): the longest-ranged
/// sensors reach 250 to 500 m, and most points of any scan lie far closer.
pub const MAX_MEDIAN_RANGE_M: f32 = 1000.0;

/// Points the median is read from, at most.
pub const SAMPLE: usize = 1024;

/// A cloud whose points lie too far to be a scan.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AbsurdRanges {
    /// The median range of its finite points (m).
    pub median_m: f32,
}

impl fmt::Display for AbsurdRanges {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "its points' median range is {:.3e} m, beyond any LiDAR's ({MAX_MEDIAN_RANGE_M} m): \
             not read as a scan (fields of another type or place than the data's?)",
            self.median_m
        )
    }
}

impl std::error::Error for AbsurdRanges {}

/// Refuses `points` whose finite points' median range exceeds [`MAX_MEDIAN_RANGE_M`] (points
/// that are not finite are left to the pipeline's filter; none finite passes).
pub fn check(points: &[Point]) -> Result<(), AbsurdRanges> {
    let step = points.len().div_ceil(SAMPLE).max(1);
    let mut ranges: Vec<f32> = (points.iter().step_by(step))
        .map(|p| p.iter().map(|c| c * c).sum::<f32>().sqrt())
        .filter(|r| r.is_finite() || *r == f32::INFINITY)
        .collect();
    if ranges.is_empty() {
        return Ok(());
    }
    let mid = ranges.len() / 2;
    let (_, median, _) = ranges.select_nth_unstable_by(mid, f32::total_cmp);
    match *median > MAX_MEDIAN_RANGE_M {
        true => Err(AbsurdRanges { median_m: *median }),
        false => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scan_passes_and_garbage_coordinates_are_refused() {
        let scan: Vec<Point> = (0..5000).map(|k| [k as f32 * 0.01, 2.0, -1.7]).collect();
        assert_eq!(check(&scan), Ok(()));
        // Float64 data read as float32: huge values in most points.
        let garbage: Vec<Point> = (0..100).map(|k| [2004.0 + k as f32, 1.0, 1.0]).collect();
        let e = check(&garbage).unwrap_err();
        assert!(
            e.median_m > 2000.0 && e.to_string().contains("beyond any LiDAR's"),
            "{e}"
        );
        // A few far returns among many near ones are a scan's.
        let mut mixed = scan.clone();
        mixed.extend((0..1000).map(|_| [1e30, 0.0, 0.0]));
        assert_eq!(check(&mixed), Ok(()));
        // Overflowing squares are infinitely far, not skipped.
        assert!(check(&[[3e38, 3e38, 0.0]; 3]).is_err());
        assert_eq!(check(&[]), Ok(()));
        assert_eq!(check(&[[f32::NAN, 0.0, 0.0]]), Ok(()));
    }
}
