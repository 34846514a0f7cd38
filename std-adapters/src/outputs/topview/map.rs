//! A run's picture: its map from above with its path, read at a glance.
//!
//! What it guarantees:
//! - a map with a roof over its path (a hall, an office, a tunnel) is shown without it: where
//!   the level surfaces near the path more than [`ROOF_ABOVE_M`] above the sensor cover at
//!   least [`ROOFED_SHARE`] of the area its floor covers ([`Roofs`]), everything more than
//!   [`KEEP_ABOVE_M`] above the sensor nearby is left out ([`Cut`]), so the floor, the walls
//!   and what stands on the floor show, and the legend says so; a map open to the sky is drawn
//!   whole;
//! - the path is drawn with its start (green) and end (white) marked, with a scale bar, the
//!   colour scale of heights, and a legend of what is drawn.
//!
//! The triangles are read twice (once to find roofs, once to draw), so a spooled mesh is
//! never held in memory.

use super::TopView;
use slamesh_core::{Point, Pose};
use std::collections::{HashMap, HashSet};

/// A flat surface this far above the sensor over the path is a roof (metres).
pub const ROOF_ABOVE_M: f32 = 1.0;
/// The roofed area, as a share of the floor's near the path, from which the picture leaves
/// roofs out.
pub const ROOFED_SHARE: f64 = 0.25;
/// How much of the map above the sensor a cut picture keeps (metres).
pub const KEEP_ABOVE_M: f32 = 0.5;
/// Cells of the path for finding roofs (metres).
pub const ROOF_CELL_M: f64 = 2.0;
/// Cells of the path for the sensor's height near a triangle (metres).
pub const HEIGHT_CELL_M: f64 = 8.0;

fn cell(x: f64, y: f64, size: f64) -> (i64, i64) {
    ((x / size).floor() as i64, (y / size).floor() as i64)
}

fn centroid(t: &[Point; 3]) -> [f64; 3] {
    core::array::from_fn(|k| (f64::from(t[0][k]) + f64::from(t[1][k]) + f64::from(t[2][k])) / 3.0)
}

/// Whether a triangle is near level (its normal within 45 degrees of vertical).
fn level(t: &[Point; 3]) -> bool {
    let u: [f32; 3] = core::array::from_fn(|k| t[1][k] - t[0][k]);
    let v: [f32; 3] = core::array::from_fn(|k| t[2][k] - t[0][k]);
    let n = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    len > 0.0 && n[2].abs() > 0.7 * len
}

/// The sensor's highest height in each cell of [`HEIGHT_CELL_M`] the path crosses.
#[derive(Debug, Clone, Default)]
struct PathHeights(HashMap<(i64, i64), f32>);

impl PathHeights {
    fn new(path: &[Pose]) -> Self {
        let mut cells = HashMap::new();
        for p in path {
            let t = p.translation.vector;
            let z = cells
                .entry(cell(t.x, t.y, HEIGHT_CELL_M))
                .or_insert(f32::MIN);
            *z = z.max(t.z as f32);
        }
        Self(cells)
    }

    /// The sensor's highest height in the cells within `reach` cells of world `(x, y)`.
    fn near(&self, x: f64, y: f64, reach: i64) -> Option<f32> {
        let (cx, cy) = cell(x, y, HEIGHT_CELL_M);
        (-reach..=reach)
            .flat_map(|dx| (-reach..=reach).map(move |dy| (cx + dx, cy + dy)))
            .filter_map(|k| self.0.get(&k).copied())
            .reduce(f32::max)
    }
}

/// Finds roofs over a path, from the map's triangles seen one by one: the level surfaces
/// near the path (within [`ROOF_REACH_CELLS`] cells of [`HEIGHT_CELL_M`]) above the sensor
/// by more than [`ROOF_ABOVE_M`] (roofs, ceilings) against those below it (floors, ground),
/// counted in cells of [`ROOF_CELL_M`]. A sensor with a narrow field of view sees no ceiling
/// right above it, only farther off, so the whole neighbourhood is weighed, not the path alone.
#[derive(Debug, Clone)]
pub struct Roofs {
    heights: PathHeights,
    roofed: HashSet<(i64, i64)>,
    floored: HashSet<(i64, i64)>,
}

/// How far from the path roofs and floors are counted (cells of [`HEIGHT_CELL_M`]).
pub const ROOF_REACH_CELLS: i64 = 2;

impl Roofs {
    /// Roofs over `path` (sensor poses, world frame).
    pub fn new(path: &[Pose]) -> Self {
        Self {
            heights: PathHeights::new(path),
            roofed: HashSet::new(),
            floored: HashSet::new(),
        }
    }

    /// Looks at one triangle of the map.
    pub fn see(&mut self, t: &[Point; 3]) {
        if !level(t) {
            return;
        }
        let c = centroid(t);
        let Some(z) = self.heights.near(c[0], c[1], ROOF_REACH_CELLS) else {
            return;
        };
        let key = cell(c[0], c[1], ROOF_CELL_M);
        if c[2] as f32 > z + ROOF_ABOVE_M {
            self.roofed.insert(key);
        } else if (c[2] as f32) < z - KEEP_ABOVE_M {
            self.floored.insert(key);
        }
    }

    /// The roofed area near the path as a share of the floor's.
    pub fn share(&self) -> f64 {
        self.roofed.len() as f64 / self.floored.len().max(1) as f64
    }
}

/// What a picture leaves out: the map above a height.
#[derive(Debug, Clone)]
pub struct Cut {
    /// Near the path: the sensor's heights.
    local: PathHeights,
    /// Elsewhere (or with no path): this height.
    fallback: f32,
    /// Kept above those heights (metres).
    above: f32,
}

impl Cut {
    /// Above the sensor along the path (by [`KEEP_ABOVE_M`]), when `roofs` found its
    /// neighbourhood roofed; `None` for a map open to the sky.
    pub fn over_path(roofs: &Roofs) -> Option<Self> {
        if roofs.share() < ROOFED_SHARE || roofs.heights.0.is_empty() {
            return None;
        }
        let fallback = roofs.heights.0.values().copied().fold(f32::MIN, f32::max);
        Some(Self {
            local: roofs.heights.clone(),
            fallback,
            above: KEEP_ABOVE_M,
        })
    }

    /// Above a fixed height (`render --clip-above`).
    pub fn above(z: f32) -> Self {
        Self {
            local: PathHeights::default(),
            fallback: z,
            above: 0.0,
        }
    }

    /// The highest height kept at world `(x, y)`: the sensor's highest in the cells around
    /// it, and the margin.
    pub fn limit(&self, x: f64, y: f64) -> f32 {
        self.local.near(x, y, 1).unwrap_or(self.fallback) + self.above
    }

    /// The highest height kept anywhere.
    pub fn top(&self) -> f32 {
        self.fallback + self.above
    }

    /// Whether a triangle is left out.
    pub fn hides(&self, t: &[Point; 3]) -> bool {
        let c = centroid(t);
        c[2] as f32 > self.limit(c[0], c[1])
    }

    /// What the legend says of it.
    pub fn describe(&self) -> String {
        if self.local.0.is_empty() {
            format!("cut above {:.1} m", self.fallback + self.above)
        } else {
            format!("roof cut: {:.1} m above the path", self.above)
        }
    }
}

/// How a run's picture is drawn.
#[derive(Debug, Clone, Copy)]
pub struct MapPicture {
    /// Pixels on the long side.
    pub pixels: usize,
    /// Metres of map around the path.
    pub margin_m: f64,
    /// The colour scale's lowest height (metres).
    pub z_lo: f32,
    /// The colour scale's highest height (metres), or the cut's top if lower.
    pub z_top: f32,
}

/// Draws a run's picture: the triangles that `triangles` hands to the function it is given
/// (called twice: roofs, then drawing), the path, its start and end, a scale bar, the colour
/// scale and a legend; with `truth` (the demo's), the true path in white under the estimate.
/// Returns the picture (to write) and the cut it made, if any.
pub fn draw<E>(
    mut triangles: impl FnMut(&mut dyn FnMut([Point; 3])) -> Result<(), E>,
    path: &[Pose],
    truth: Option<&[Pose]>,
    how: MapPicture,
) -> Result<(TopView, Option<Cut>), E> {
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for p in path.iter().chain(truth.into_iter().flatten()) {
        let t = p.translation.vector;
        lo = [lo[0].min(t.x - how.margin_m), lo[1].min(t.y - how.margin_m)];
        hi = [hi[0].max(t.x + how.margin_m), hi[1].max(t.y + how.margin_m)];
    }
    if path.is_empty() {
        (lo, hi) = ([-how.margin_m; 2], [how.margin_m; 2]);
    }
    let mut roofs = Roofs::new(path);
    triangles(&mut |t| roofs.see(&t))?;
    let cut = Cut::over_path(&roofs);
    let z_hi = match &cut {
        Some(c) => how.z_top.min(c.top()),
        None => how.z_top,
    }
    .max(how.z_lo + 1.0);
    let mut view = TopView::new(lo, hi, how.pixels);
    triangles(&mut |t| {
        if !cut.as_ref().is_some_and(|c| c.hides(&t)) {
            view.triangles(std::iter::once(t), how.z_lo, z_hi);
        }
    })?;
    if let Some(truth) = truth {
        view.path(truth, TRUTH);
    }
    view.path(path, PATH);
    if let (Some(first), Some(last)) = (path.first(), path.last()) {
        let (a, b) = (first.translation.vector, last.translation.vector);
        view.marker(a.x, a.y, START);
        view.marker(b.x, b.y, END);
    }
    view.scale_bar();
    view.colour_scale(how.z_lo, z_hi);
    let mut legend = vec![
        "red: path".to_string(),
        "green: start, white: end".to_string(),
    ];
    if truth.is_some() {
        legend.insert(1, "white: true path".to_string());
    }
    legend.extend(cut.as_ref().map(Cut::describe));
    view.legend(&legend);
    Ok((view, cut))
}

/// The path's colour.
const PATH: [u8; 3] = [230, 40, 40];
/// The true path's colour (the demo's).
const TRUTH: [u8; 3] = [255, 255, 255];
/// The start's marker.
const START: [u8; 3] = [60, 220, 60];
/// The end's marker.
const END: [u8; 3] = [245, 245, 245];

#[cfg(test)]
mod tests {
    use super::*;

    /// A 20 x 10 m floor at z = 0 in 1 m squares, with a ceiling at 3 m if `roof`, and walls.
    fn hall(roof: bool) -> Vec<[Point; 3]> {
        let mut t = Vec::new();
        for x in 0..20 {
            for y in 0..10 {
                let (x, y) = (x as f32, y as f32);
                let mut square = |z: f32| {
                    t.push([[x, y, z], [x + 1.0, y, z], [x + 1.0, y + 1.0, z]]);
                    t.push([[x, y, z], [x + 1.0, y + 1.0, z], [x, y + 1.0, z]]);
                };
                square(0.0);
                if roof {
                    square(3.0);
                }
            }
        }
        for x in 0..20 {
            for z in 0..3 {
                let (x, z) = (x as f32, z as f32);
                t.push([[x, 0.0, z], [x + 1.0, 0.0, z], [x + 1.0, 0.0, z + 1.0]]);
            }
        }
        t
    }

    fn walk() -> Vec<Pose> {
        (0..30)
            .map(|k| Pose::translation(2.0 + 0.5 * f64::from(k), 5.0, 1.5))
            .collect()
    }

    fn picture(t: &[[Point; 3]], path: &[Pose]) -> (TopView, Option<Cut>) {
        let how = MapPicture {
            pixels: 300,
            margin_m: 5.0,
            z_lo: -1.0,
            z_top: 3.0,
        };
        draw::<()>(
            |f| {
                t.iter().for_each(|t| f(*t));
                Ok(())
            },
            path,
            None,
            how,
        )
        .unwrap()
    }

    #[test]
    fn a_roofed_hall_is_drawn_without_its_roof_and_an_open_one_whole() {
        let path = walk();
        let (view, cut) = picture(&hall(true), &path);
        let cut = cut.expect("the hall's roof is cut away");
        assert!((cut.limit(5.0, 5.0) - 2.0).abs() < 1e-6);
        assert!(cut.describe().contains("roof cut"));
        for p in &path {
            let t = p.translation.vector;
            // Under the path: the floor, not the roof (3 m).
            assert_eq!(view.height_at(t.x, t.y + 1.0), Some(0.0), "{t:?}");
        }
        // The wall's lower part is kept.
        let (open, none) = picture(&hall(false), &path);
        assert!(none.is_none(), "no roof, no cut");
        assert_eq!(open.height_at(5.0, 6.0), Some(0.0));
    }

    #[test]
    fn a_fixed_cut_hides_what_is_above_it() {
        let c = Cut::above(2.0);
        assert!(c.hides(&[[0.0, 0.0, 3.0], [1.0, 0.0, 3.0], [0.0, 1.0, 3.0]]));
        assert!(!c.hides(&[[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]]));
        assert_eq!(c.describe(), "cut above 2.0 m");
    }
}
