//! Traversability on a mesh of the ground (`navmesh.ply`): the seen ground of a [`Grid`] as a
//! triangle mesh, a vertex every [`NAVMESH_SPACING_M`], each vertex carrying the layers a mesh
//! planner's cost layers are made of, over the robot's footprint around it:
//! - `slope_deg`: the slope of the plane fitted to the ground's heights (least squares);
//! - `step_m`: the highest step between neighbouring cells;
//! - `roughness_m`: the RMS residual of the heights to that plane;
//! - `border`: 1 where the footprint reaches a cell with nothing known (the seen mesh's edge:
//!   unknown beyond), else 0;
//! - `cost`: 1 (lethal) where the cell is not free or the slope or the step is beyond the
//!   robot's; otherwise the largest of slope over its limit, step over its limit, roughness
//!   over the step limit, and 0.5 at a border; below 1.
//!
//! The same layers go on the SLAM mesh's own vertices ([`OnMesh`]: `mesh.ply` with
//! `--navmap`), with `ground` saying which vertices are ground.
//!
//! Vertices are in the grid's frame (the map's when up is its z). PLY readers that keep extra
//! vertex properties (plyfile, Open3D's tensor API, trimesh's `metadata`) read the layers by
//! name; mesh_navigation's `mesh_map` takes its own layers from a mesh, and these give it
//! (or a planner of one's own) the same quantities precomputed for the robot.

use crate::formats::mesh_records::VertexProperties;
use crate::navmap::grid::{CellIndex, Grid, Occupancy};
use crate::navmap::robot::Robot;
use nalgebra::{Matrix3, Vector3};
use slamesh_core::cell::BuildCellHasher;
use slamesh_core::Point;
use std::collections::HashMap;

/// The spacing (m) of the navigation mesh's vertices (a whole number of cells, at least one).
pub const NAVMESH_SPACING_M: f64 = 0.2;

/// The ground as a mesh with its traversability layers, one value a vertex each.
#[derive(Debug, Default, Clone)]
pub struct NavMesh {
    /// Vertex positions (grid frame).
    pub vertices: Vec<Point>,
    /// Triangles, counter-clockwise seen from above.
    pub triangles: Vec<[u32; 3]>,
    /// See the module's documentation.
    pub slope_deg: Vec<f32>,
    /// See the module's documentation.
    pub step_m: Vec<f32>,
    /// See the module's documentation.
    pub roughness_m: Vec<f32>,
    /// See the module's documentation.
    pub border: Vec<f32>,
    /// See the module's documentation.
    pub cost: Vec<f32>,
}

impl NavMesh {
    /// The navigation mesh of `grid`'s seen ground for `robot`.
    pub fn of(grid: &Grid, robot: &Robot) -> NavMesh {
        let res = grid.resolution();
        let stride = (NAVMESH_SPACING_M / res).round().max(1.0) as i64;
        let footprint = footprint((robot.radius_m / res).ceil().max(1.0) as i64);
        let mut mesh = NavMesh::default();
        let mut index: HashMap<CellIndex, u32> = HashMap::new();
        for (ix, iy) in grid.ground_cells(stride) {
            let Some((h, _)) = grid.elevation(ix, iy) else {
                continue;
            };
            index.insert((ix, iy), mesh.vertices.len() as u32);
            let centre = [(ix as f64 + 0.5) * res, (iy as f64 + 0.5) * res, h];
            mesh.vertices.push(centre.map(|v| v as f32));
            let l = Layers::at(grid, (ix, iy), &footprint, robot);
            mesh.slope_deg.push(l.slope_deg as f32);
            mesh.step_m.push(l.step_m as f32);
            mesh.roughness_m.push(l.roughness_m as f32);
            mesh.border.push(if l.border { 1.0 } else { 0.0 });
            mesh.cost.push(l.cost as f32);
        }
        mesh.triangles = triangles(&index, stride);
        mesh
    }

    /// The layers by name, in the PLY's order.
    pub fn properties(&self) -> [(&'static str, &[f32]); 5] {
        [
            ("slope_deg", &self.slope_deg),
            ("step_m", &self.step_m),
            ("roughness_m", &self.roughness_m),
            ("border", &self.border),
            ("cost", &self.cost),
        ]
    }
}

/// The layers on the SLAM mesh's own vertices (`mesh.ply` with `--navmap`): a vertex on the
/// ground (within a step of its cell's ground height) carries its cell's layers, as
/// `navmesh.ply`'s vertices do, and `ground` 1; any other (a wall, a car's roof, a ceiling)
/// `ground` 0, `cost` 1 (lethal: nothing to drive on) and no slope, step or roughness (NaN).
/// Each cell's layers are worked out once.
pub struct OnMesh<'a> {
    grid: &'a Grid,
    robot: Robot,
    footprint: Vec<(i64, i64)>,
    done: HashMap<CellIndex, [f32; 5], BuildCellHasher>,
}

impl<'a> OnMesh<'a> {
    /// The layers of `grid` for `robot`.
    pub fn new(grid: &'a Grid, robot: Robot) -> Self {
        let r = (robot.radius_m / grid.resolution()).ceil().max(1.0) as i64;
        OnMesh {
            grid,
            robot,
            footprint: footprint(r),
            done: HashMap::default(),
        }
    }
}

impl VertexProperties for OnMesh<'_> {
    fn names(&self) -> &[&'static str] {
        &[
            "ground",
            "slope_deg",
            "step_m",
            "roughness_m",
            "border",
            "cost",
        ]
    }

    fn values(&mut self, position: [f32; 3], out: &mut [f32]) {
        let q = self.grid.level() * Vector3::from(position.map(f64::from));
        let c = self.grid.index_of(q.x, q.y);
        let on_ground = self
            .grid
            .elevation(c.0, c.1)
            .is_some_and(|(h, _)| (q.z - h).abs() <= self.robot.max_step_m);
        let values = if on_ground {
            let (grid, footprint, robot) = (self.grid, &self.footprint, &self.robot);
            let l = *self.done.entry(c).or_insert_with(|| {
                let l = Layers::at(grid, c, footprint, robot);
                let border = if l.border { 1.0 } else { 0.0 };
                [l.slope_deg, l.step_m, l.roughness_m, border, l.cost].map(|v| v as f32)
            });
            [1.0, l[0], l[1], l[2], l[3], l[4]]
        } else {
            [0.0, f32::NAN, f32::NAN, f32::NAN, 0.0, 1.0]
        };
        for (o, v) in out.iter_mut().zip(values) {
            *o = v;
        }
    }
}

/// One vertex's layers.
struct Layers {
    slope_deg: f64,
    step_m: f64,
    roughness_m: f64,
    border: bool,
    cost: f64,
}

impl Layers {
    /// The layers at cell `c` over `footprint` (cell offsets).
    fn at(grid: &Grid, c: CellIndex, footprint: &[(i64, i64)], robot: &Robot) -> Layers {
        let height = |i: CellIndex| grid.elevation(i.0, i.1).map(|(h, _)| h);
        let mut samples: Vec<(f64, f64, f64)> = Vec::with_capacity(footprint.len());
        let (mut step, mut border) = (0.0f64, false);
        for &(dx, dy) in footprint {
            let i = (c.0 + dx, c.1 + dy);
            let Some(h) = height(i) else {
                border |= grid.occupancy(i.0, i.1) == Occupancy::Unknown;
                continue;
            };
            samples.push((
                dx as f64 * grid.resolution(),
                dy as f64 * grid.resolution(),
                h,
            ));
            for n in [(i.0 + 1, i.1), (i.0, i.1 + 1)] {
                if let Some(g) = height(n) {
                    step = step.max((g - h).abs());
                }
            }
        }
        let (slope_deg, roughness_m) = plane_fit(&samples);
        let lethal = grid.occupancy(c.0, c.1) != Occupancy::Free
            || slope_deg > robot.max_slope_deg
            || step > robot.max_step_m;
        let cost = if lethal {
            1.0
        } else {
            [
                slope_deg / robot.max_slope_deg.max(1e-9),
                step / robot.max_step_m.max(1e-9),
                roughness_m / robot.max_step_m.max(1e-9),
                if border { 0.5 } else { 0.0 },
            ]
            .into_iter()
            .fold(0.0, f64::max)
            .min(0.99)
        };
        Layers {
            slope_deg,
            step_m: step,
            roughness_m,
            border,
            cost,
        }
    }
}

/// The slope (degrees) of the plane `z = a x + b y + c` fitted to `samples` by least squares,
/// and the RMS of its residuals; level and smooth with fewer than three samples or none that
/// span a plane.
fn plane_fit(samples: &[(f64, f64, f64)]) -> (f64, f64) {
    if samples.len() < 3 {
        return (0.0, 0.0);
    }
    let (mut m, mut r) = (Matrix3::<f64>::zeros(), Vector3::<f64>::zeros());
    for &(x, y, z) in samples {
        let v = Vector3::new(x, y, 1.0);
        m += v * v.transpose();
        r += v * z;
    }
    let Some(p) = m.try_inverse().map(|inv| inv * r) else {
        return (0.0, 0.0);
    };
    let slope = p.x.hypot(p.y).atan().to_degrees();
    let sq: f64 = samples
        .iter()
        .map(|&(x, y, z)| (z - (p.x * x + p.y * y + p.z)).powi(2))
        .sum();
    (slope, (sq / samples.len() as f64).sqrt())
}

/// The cell offsets within `r` cells (a disc).
fn footprint(r: i64) -> Vec<(i64, i64)> {
    (-r..=r)
        .flat_map(|dy| (-r..=r).map(move |dx| (dx, dy)))
        .filter(|(dx, dy)| dx * dx + dy * dy <= r * r)
        .collect()
}

/// Two triangles for each square of four vertices `stride` cells apart (one for three),
/// counter-clockwise from above, in the order of the vertices' cells.
fn triangles(index: &HashMap<CellIndex, u32>, stride: i64) -> Vec<[u32; 3]> {
    let mut corners: Vec<&CellIndex> = index.keys().collect();
    corners.sort_unstable_by_key(|&&(x, y)| (y, x));
    let mut out = Vec::new();
    for &(ix, iy) in corners {
        let at = |dx: i64, dy: i64| index.get(&(ix + dx * stride, iy + dy * stride)).copied();
        let (a, b, c, d) = (at(0, 0), at(1, 0), at(0, 1), at(1, 1));
        match (a, b, c, d) {
            (Some(a), Some(b), Some(c), Some(d)) => {
                out.push([a, b, d]);
                out.push([a, d, c]);
            }
            (Some(a), Some(b), None, Some(d)) => out.push([a, b, d]),
            (Some(a), None, Some(c), Some(d)) => out.push([a, d, c]),
            (Some(a), Some(b), Some(c), None) => out.push([a, b, c]),
            (None, Some(b), Some(c), Some(d)) => out.push([b, d, c]),
            _ => {}
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plane_s_slope_and_a_rough_patch() {
        // z = 0.2 x: 11.3 degrees, no residual.
        let plane: Vec<(f64, f64, f64)> = (-3..=3)
            .flat_map(|i| (-3..=3).map(move |j| (i as f64 * 0.1, j as f64 * 0.1, 0.02 * i as f64)))
            .collect();
        let (slope, rough) = plane_fit(&plane);
        assert!((slope - 0.2f64.atan().to_degrees()).abs() < 1e-9 && rough < 1e-12);
        let bumpy: Vec<(f64, f64, f64)> = plane
            .iter()
            .enumerate()
            .map(|(k, &(x, y, _))| (x, y, if k % 2 == 0 { 0.05 } else { -0.05 }))
            .collect();
        let (slope, rough) = plane_fit(&bumpy);
        assert!(
            slope < 5.0 && (rough - 0.05).abs() < 0.005,
            "{slope} {rough}"
        );
        assert_eq!(plane_fit(&plane[..2]), (0.0, 0.0));
    }

    #[test]
    fn squares_and_corners_make_counter_clockwise_triangles() {
        let index: HashMap<CellIndex, u32> = [
            ((0, 0), 0),
            ((2, 0), 1),
            ((0, 2), 2),
            ((2, 2), 3),
            ((4, 0), 4),
            ((4, 2), 5),
        ]
        .into_iter()
        .collect();
        let t = triangles(&index, 2);
        assert_eq!(t, vec![[0, 1, 3], [0, 3, 2], [1, 4, 5], [1, 5, 3]]);
    }
}
