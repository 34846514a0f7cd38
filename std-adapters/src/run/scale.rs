//! The scene's scale, taken from the first whole scan, and the configuration fitted to it
//! (docs/design.md §1.7): the cell, the GP kernel's reach and the nearest range kept shrink in
//! small spaces, so that a 16-beam scan of an office at 1 to 15 m and a KITTI street both
//! work with no options. Decided once, at the start of a run, from a whole scan ([`scale_scan`]),
//! and kept.
//!
//! The rule, from the ranges of the scan's finite, non-zero points:
//! - cell edge: the median range / [`RANGES_PER_CELL`], at most the configuration's own and at
//!   least [`MIN_CELL_M`]. The town and KITTI (medians 7 to 13 m) keep 1.4 m;
//! - the GP kernel's `kappa` grows as the cell shrinks, so the kernel spans the same share of
//!   a cell;
//! - the nearest range kept: a quarter of the 10th percentile of the ranges, at most the
//!   configuration's own and at least [`MIN_RANGE_M`] (KITTI's 10th percentiles are 5 m: it
//!   keeps 1.2 m).

use crate::run::capacity::{CHOICE_SCANS, SMALL_SCAN_RATIO};
use crate::run::config_file::Settings;
use crate::sources::FrameSource;
use slamesh_core::{Config, Point};

/// Median range over cell edge that the fitted cell keeps.
pub const RANGES_PER_CELL: f64 = 5.0;
/// The smallest fitted cell edge (metres).
pub const MIN_CELL_M: f64 = 0.5;
/// The smallest fitted nearest range (metres).
pub const MIN_RANGE_M: f64 = 0.3;

/// What the fit found and chose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fitted {
    /// Median range of the scan's points (metres).
    pub median_range_m: f64,
    /// The 10th percentile of their ranges (metres).
    pub near_range_m: f64,
    /// The configuration fitted to them.
    pub config: Config,
}

/// `config` fitted to the scale of `scan` (sensor frame); `None` when the scan has fewer than
/// 100 finite, non-zero points to judge by.
pub fn fit(config: &Config, scan: &[Point]) -> Option<Fitted> {
    let mut ranges: Vec<f64> = scan
        .iter()
        .filter(|p| p.iter().all(|c| c.is_finite()))
        .map(|p| {
            p.iter()
                .map(|&c| f64::from(c) * f64::from(c))
                .sum::<f64>()
                .sqrt()
        })
        .filter(|&r| r > 0.0)
        .collect();
    if ranges.len() < 100 {
        return None;
    }
    ranges.sort_by(f64::total_cmp);
    let at = |q: f64| ranges[((ranges.len() - 1) as f64 * q) as usize];
    let (near, median) = (at(0.1), at(0.5));
    // Only ever smaller than the configuration's own, and no smaller than the floors.
    let shrink = |v: f64, base: f64, floor: f64| {
        if base > floor {
            v.clamp(floor, base)
        } else {
            base
        }
    };
    let mut c = *config;
    // Whole centimetres, for configurations and messages that read well.
    let cm = |v: f64| (v * 100.0).floor() / 100.0;
    c.grid.cell_size_m = shrink(
        cm(median / RANGES_PER_CELL),
        config.grid.cell_size_m,
        MIN_CELL_M,
    );
    c.gp.kappa_per_m = config.gp.kappa_per_m * config.grid.cell_size_m / c.grid.cell_size_m;
    c.filter.range_min_m = shrink(cm(near / 4.0), config.filter.range_min_m, MIN_RANGE_M);
    Some(Fitted {
        median_range_m: median,
        near_range_m: near,
        config: c,
    })
}

/// Fits `s`'s configuration to the scale of `source`'s first scan when `s.scale_to_scene`,
/// and says what it chose (the command's, the node's and the Python module's start). The scan
/// is the first of the readable scans that the capacity's choice looks at
/// ([`scale_scan`]) that is not far smaller than the largest of them: a cut-off file or a
/// partial sweep first decides nothing.
pub fn fit_to_scene(s: &mut Settings, source: &mut impl FrameSource) {
    if !s.scale_to_scene {
        return;
    }
    let Some((i, fitted)) =
        scale_scan(source).and_then(|(i, scan)| Some((i, fit(&s.config, &scan)?)))
    else {
        return;
    };
    let c = &fitted.config;
    log::info!(
        "scale from frame {i}: median range {:.1} m: cells of {:.2} m, gp.kappa_per_m {:.2}, \
         filter.range_min_m {:.2} (preset {}; setting any of these, or another preset, keeps \
         its own)",
        fitted.median_range_m,
        c.grid.cell_size_m,
        c.gp.kappa_per_m,
        c.filter.range_min_m,
        s.preset
    );
    s.config = fitted.config;
}

/// The scan the scene's scale is taken from, with its frame: among the first
/// [`CHOICE_SCANS`] readable scans of the first ten frames (a live source's that have come,
/// once one has), the first that holds at least a [`SMALL_SCAN_RATIO`]th of the points of the
/// largest; those before it are named. `None` when none is readable.
pub fn scale_scan(source: &mut impl FrameSource) -> Option<(usize, Vec<Point>)> {
    let mut seen: Vec<(usize, usize)> = Vec::new();
    for i in 0..source.frames().min(10) {
        if seen.len() == CHOICE_SCANS || (!seen.is_empty() && source.would_wait(i)) {
            break;
        }
        if let Ok(scan) = source.read(i) {
            seen.push((i, usable(&scan)));
        }
    }
    let largest = seen.iter().map(|s| s.1).max()?;
    let &(i, n) = seen.iter().find(|s| s.1 * SMALL_SCAN_RATIO >= largest)?;
    for &(j, m) in seen.iter().take_while(|s| s.0 < i) {
        log::warn!(
            "{}: frame {j}: {m} usable points, far fewer than frame {i}'s {n} or the largest's \
             {largest}: a cut-off file or a partial sweep? (it does not choose the scale)",
            source.label(j)
        );
    }
    Some((i, source.read(i).ok()?))
}

/// The points of `scan` a fit reads: finite and not at the sensor.
fn usable(scan: &[Point]) -> usize {
    let fine = |p: &&Point| p.iter().all(|c| c.is_finite()) && p.iter().any(|&c| c != 0.0);
    scan.iter().filter(fine).count()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points on a sphere of radius `r` around the sensor, `n` of them.
    fn shell(r: f32, n: usize) -> Vec<Point> {
        (0..n)
            .map(|i| {
                let a = i as f32 * 0.37;
                let e = (i as f32 * 0.11).sin() * 0.5;
                [r * e.cos() * a.cos(), r * e.cos() * a.sin(), r * e.sin()]
            })
            .collect()
    }

    #[test]
    fn a_street_keeps_the_configuration_and_a_room_shrinks_it() {
        let base = crate::run::config_file::preset("town").unwrap();
        let street = fit(&base, &shell(10.0, 1000)).unwrap();
        assert_eq!(street.config, base);
        assert!((street.median_range_m - 10.0).abs() < 1e-3);

        let room = fit(&base, &shell(3.0, 1000)).unwrap();
        assert!((room.config.grid.cell_size_m - 0.6).abs() < 0.011);
        let kappa = base.gp.kappa_per_m * base.grid.cell_size_m / room.config.grid.cell_size_m;
        assert!((room.config.gp.kappa_per_m - kappa).abs() < 1e-9);
        assert!((room.config.filter.range_min_m - 0.75).abs() < 0.011);
        room.config.validate().unwrap();

        // A desk-scale scan: the smallest cell and nearest range.
        let desk = fit(&base, &shell(0.6, 1000)).unwrap();
        assert_eq!(desk.config.grid.cell_size_m, MIN_CELL_M);
        assert_eq!(desk.config.filter.range_min_m, MIN_RANGE_M);
    }

    /// Frames of `sizes[i]` points on a sphere of radius `radii[i]`; frame 1 unreadable.
    struct Shells(Vec<(f32, usize)>);

    impl FrameSource for Shells {
        fn frames(&self) -> usize {
            self.0.len()
        }
        fn label(&self, i: usize) -> String {
            format!("shell {i}")
        }
        fn stamp(&self, i: usize) -> f64 {
            i as f64
        }
        fn read(&mut self, i: usize) -> Result<Vec<Point>, crate::io::error::FileError> {
            match i {
                1 => Err(crate::io::error::FileError::at(
                    std::path::Path::new("shell 1"),
                    "unreadable",
                )),
                _ => Ok(shell(self.0[i].0, self.0[i].1)),
            }
        }
    }

    #[test]
    fn a_far_smaller_first_scan_does_not_decide_the_scale() {
        let street = (10.0, 1000);
        let mut s = crate::run::config_file::preset_settings("default").unwrap();
        let base = s.config;
        // A cut-off first scan of 200 points 3 m away would shrink the cells to 0.6 m.
        let mut source = Shells(vec![(3.0, 200), street, street, street, street]);
        assert_eq!(
            scale_scan(&mut source).unwrap().0,
            2,
            "the first whole scan"
        );
        fit_to_scene(&mut s, &mut source);
        assert_eq!(s.config, base, "the street's scale");
        // A first scan a third of the largest still decides, as before.
        let mut source = Shells(vec![(3.0, 400), street, street]);
        assert_eq!(scale_scan(&mut source).unwrap().0, 0);
        assert!(scale_scan(&mut Shells(vec![])).is_none());
    }

    #[test]
    fn too_few_points_or_only_bad_ones_give_no_fit() {
        let base = Config::default();
        assert!(fit(&base, &shell(3.0, 99)).is_none());
        let mut bad = vec![[f32::NAN, 0.0, 0.0]; 500];
        bad.extend(vec![[0.0, 0.0, 0.0]; 500]);
        assert!(fit(&base, &bad).is_none());
    }
}
