//! `slamesh eval`'s plots, as evo draws them: the estimated trajectory, rigidly aligned, over
//! the reference from above, and the absolute error of each pose over the distance travelled.

use super::TopView;
use slamesh_core::Pose;

/// The reference's colour.
const REFERENCE: [u8; 3] = [235, 235, 235];
/// The estimate's colour.
const ESTIMATE: [u8; 3] = [230, 40, 40];
/// The axes' colour.
const AXES: [u8; 3] = [150, 150, 150];

/// The margin around a plot's box: a tenth of its long side.
fn margin(lo: [f64; 2], hi: [f64; 2]) -> f64 {
    0.1 * (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1e-3)
}

/// Metres to add above a box `[lo, hi]` drawn `pixels` on its long side (with its
/// [`margin`]) for a legend of `lines` lines.
fn legend_room(lo: [f64; 2], hi: [f64; 2], pixels: usize, lines: usize) -> f64 {
    let span = (hi[0] - lo[0]).max(hi[1] - lo[1]) + 2.0 * margin(lo, hi);
    let metres_a_pixel = span / pixels.max(16) as f64;
    (22 * lines + 16) as f64 * metres_a_pixel
}

/// The trajectories from above: the reference in white, the aligned estimate in red, the
/// start (green) and end marked, a scale bar and a legend with the ATE.
pub fn trajectories(estimate: &[Pose], reference: &[Pose], ate_m: f64, pixels: usize) -> TopView {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in estimate.iter().chain(reference) {
        let t = p.translation.vector;
        lo = [lo[0].min(t.x), lo[1].min(t.y)];
        hi = [hi[0].max(t.x), hi[1].max(t.y)];
    }
    if !lo[0].is_finite() {
        (lo, hi) = ([0.0; 2], [1.0; 2]);
    }
    // Room above the paths for the legend's three lines.
    hi[1] += legend_room(lo, hi, pixels, 3);
    let mut view = TopView::with_margin(lo, hi, pixels, margin(lo, hi));
    view.path(reference, REFERENCE);
    view.path(estimate, ESTIMATE);
    if let (Some(a), Some(b)) = (reference.first(), reference.last()) {
        let (a, b) = (a.translation.vector, b.translation.vector);
        view.marker(a.x, a.y, [60, 220, 60]);
        view.marker(b.x, b.y, REFERENCE);
    }
    view.scale_bar();
    view.legend(&[
        "white: reference, green: start".to_string(),
        "red: estimate, aligned".to_string(),
        format!("ate {ate_m:.3} m rmse"),
    ]);
    view
}

/// The error over distance: `error_m[k]` at `distance_m[k]`, as a line, with the axes' ends
/// and the largest error written.
pub fn error_over_distance(distance_m: &[f64], error_m: &[f64], pixels: usize) -> TopView {
    let n = distance_m.len().min(error_m.len());
    let length = distance_m[..n].iter().copied().fold(0.0, f64::max).max(1.0);
    let top = error_m[..n].iter().copied().fold(0.0, f64::max).max(1e-3);
    // The chart's box in its own units: distance along x, error scaled to half the length.
    let height = length / 2.0;
    let y = |e: f64| e / top * height * 0.9;
    let room = legend_room([0.0, 0.0], [length, height], pixels, 2);
    let (lo, hi) = ([0.0, 0.0], [length, height + room]);
    let mut view = TopView::with_margin(lo, hi, pixels, margin(lo, hi));
    let line = |points: &[(f64, f64)]| -> Vec<Pose> {
        points
            .iter()
            .map(|&(x, y)| Pose::translation(x, y, 0.0))
            .collect()
    };
    view.path(&line(&[(0.0, 0.0), (length, 0.0)]), AXES);
    view.path(&line(&[(0.0, 0.0), (0.0, height)]), AXES);
    let curve: Vec<(f64, f64)> = (0..n).map(|k| (distance_m[k], y(error_m[k]))).collect();
    view.path(&line(&curve), ESTIMATE);
    let scale = length / pixels as f64;
    view.label_at(-4.0 * scale, -4.0 * scale, "0");
    view.label_at(
        length - 60.0 * scale,
        -4.0 * scale,
        &format!("{length:.0} m"),
    );
    view.label_at(4.0 * scale, y(top) + 20.0 * scale, &format!("{top:.3} m"));
    view.legend(&[
        "error of each pose, aligned".to_string(),
        "over the distance travelled".to_string(),
    ]);
    view
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_plots_draw_both_paths_and_the_error_line() {
        let reference: Vec<Pose> = (0..50)
            .map(|k| Pose::translation(f64::from(k), 0.1 * f64::from(k), 0.0))
            .collect();
        let estimate: Vec<Pose> = reference
            .iter()
            .map(|p| Pose::translation(p.translation.x, p.translation.y + 1.0, 0.0))
            .collect();
        let mut t = trajectories(&estimate, &reference, 0.5, 800);
        let (w, h) = t.size();
        assert!(w.max(h) >= 800);
        let red = t.rgb.iter().filter(|c| **c == ESTIMATE).count();
        let white = t.rgb.iter().filter(|c| **c == REFERENCE).count();
        assert!(red > 100 && white > 100, "{red} red, {white} white");
        let distance: Vec<f64> = (0..50).map(f64::from).collect();
        let error: Vec<f64> = (0..50).map(|k| 0.01 * f64::from(k)).collect();
        let e = error_over_distance(&distance, &error, 800);
        assert!(e.rgb.iter().filter(|c| **c == ESTIMATE).count() > 100);
        let dir = crate::test_support::scratch_dir("plots");
        t.write_png(&dir.join("t.png")).unwrap();
    }
}
