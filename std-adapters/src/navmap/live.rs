//! An occupancy grid kept current while a run goes on (the ROS 2 node's `map`, docs/design.md
//! §1.18): an update rebuilds the grid of a square window around the sensor
//! ([`Grid::build_with_floors`] on the triangles in the window and the floor the scans' points
//! saw there, the ground grown from the path in it) and keeps the cells
//! of the window's inner square ([`LiveGrid::keep_m`]: the ground a window's edge cuts off
//! from the path is not judged there); everywhere else the cells stay as the last update that
//! covered them left them. An update costs what its window holds, not what the map holds.
//!
//! It owns the cells: one byte each (Nav2's -1 unknown, 0 free, 100 occupied) in tiles of
//! [`TILE`] x [`TILE`], made as updates first reach them. It guarantees that a cell no update
//! has judged is unknown, and that [`LiveGrid::cells`] gives them row by row from the lower
//! left, as `nav_msgs/OccupancyGrid` holds them.

use crate::io::error::FileError;
use crate::navmap::grid::{corner_in, index_in, level_of, CellIndex, Grid, Occupancy, Triangles};
use crate::navmap::hits::Floors;
use crate::navmap::NavMapOptions;
use nalgebra::{Rotation3, Translation3, UnitQuaternion, Vector3};
use slamesh_core::{Point, Pose};
use std::collections::BTreeMap;

/// Cells along a tile's side.
pub const TILE: i64 = 128;
/// A cell no update has judged, and one judged unknown.
pub const UNKNOWN: i8 = -1;
/// A free cell.
pub const FREE: i8 = 0;
/// An occupied cell.
pub const OCCUPIED: i8 = 100;

/// The cells of a [`LiveGrid`], row by row from the lower left.
#[derive(Debug, Clone, PartialEq)]
pub struct Cells {
    /// The lower-left cell's index (level frame x and y over the resolution).
    pub origin: CellIndex,
    /// Columns and rows.
    pub width: usize,
    /// See [`width`](Self::width).
    pub height: usize,
    /// `width · height` cells, row `0` the lowest.
    pub data: Vec<i8>,
}

/// The grid, by tile.
pub struct LiveGrid {
    how: NavMapOptions,
    level: Rotation3<f64>,
    /// The rebuilt window's side (m).
    window_m: f64,
    /// The inner square kept (m).
    keep_m: f64,
    tiles: BTreeMap<CellIndex, Box<[i8]>>,
}

impl LiveGrid {
    /// A grid made `how` says, from windows of `window_m` metres of which the inner `keep_m`
    /// are kept.
    pub fn new(how: NavMapOptions, window_m: f64, keep_m: f64) -> Self {
        let level = level_of(&how.up().0);
        LiveGrid {
            how,
            level,
            window_m,
            keep_m: keep_m.min(window_m),
            tiles: BTreeMap::new(),
        }
    }

    /// The cell size (m).
    pub fn resolution(&self) -> f64 {
        self.how.resolution_m
    }

    /// The rotation from the map frame to the grid's level frame.
    pub fn level(&self) -> Rotation3<f64> {
        self.level
    }

    /// The inner square an update keeps (m).
    pub fn keep_m(&self) -> f64 {
        self.keep_m
    }

    /// Rebuilds the window around `at` (map frame) from `mesh` (any triangles: those outside
    /// the window are passed over), the floor the scans' points saw (`floors`, map frame, as
    /// [`Grid::build_with_floors`] takes it) and `path` (the sensor's positions, map frame),
    /// and keeps its inner square's cells.
    pub fn update(
        &mut self,
        mesh: &mut dyn Triangles,
        floors: &Floors,
        path: &[Vector3<f64>],
        at: &Vector3<f64>,
    ) -> Result<(), FileError> {
        let centre = self.level * at;
        let half = self.window_m / 2.0;
        let inside = |p: &Vector3<f64>| {
            let q = self.level * p;
            (q.x - centre.x).abs() <= half && (q.y - centre.y).abs() <= half
        };
        let near: Vec<Vector3<f64>> = path.iter().filter(|p| inside(p)).copied().collect();
        let mut window = Window {
            mesh,
            inside: &inside,
        };
        let (robot, res, up) = (self.how.robot, self.how.resolution_m, self.how.up().0);
        let index = |x: f64, y: f64| index_in(res, x, y);
        let keep = self.keep_m / 2.0;
        let lo = index(centre.x - keep, centre.y - keep);
        let hi = index(centre.x + keep, centre.y + keep);
        // The free cells earlier updates left between the inner square and the window's edge
        // are ground this update grows from too: a ramp whose foot lies outside the window
        // is still climbed from where the robot was.
        let (outer_lo, outer_hi) = (
            index(centre.x - half, centre.y - half),
            index(centre.x + half, centre.y + half),
        );
        let ground: Vec<CellIndex> = (outer_lo.1..outer_hi.1)
            .flat_map(|iy| (outer_lo.0..outer_hi.0).map(move |ix| (ix, iy)))
            .filter(|&(ix, iy)| !((lo.0..hi.0).contains(&ix) && (lo.1..hi.1).contains(&iy)))
            .filter(|&i| self.get(i) == FREE)
            .collect();
        let grid = Grid::build_with_floors(&mut window, floors, robot, res, up, &near, &ground)?;
        for iy in lo.1..hi.1 {
            for ix in lo.0..hi.0 {
                let value = match grid.occupancy(ix, iy) {
                    Occupancy::Free => FREE,
                    Occupancy::Occupied => OCCUPIED,
                    Occupancy::Unknown => UNKNOWN,
                };
                self.set((ix, iy), value);
            }
        }
        Ok(())
    }

    fn set(&mut self, (ix, iy): CellIndex, value: i8) {
        let (tile, k) = split((ix, iy));
        let cells = self.tiles.entry(tile).or_insert_with(|| {
            // A tile's first cells: the rest unknown until an update reaches them.
            vec![UNKNOWN; (TILE * TILE) as usize].into_boxed_slice()
        });
        cells[k] = value;
    }

    /// The cell `(ix, iy)`.
    pub fn get(&self, (ix, iy): CellIndex) -> i8 {
        let (tile, k) = split((ix, iy));
        self.tiles.get(&tile).map_or(UNKNOWN, |c| c[k])
    }

    /// Every cell within the tiles made, row by row from the lower left; `None` before any
    /// update.
    pub fn cells(&self) -> Option<Cells> {
        let xs = || self.tiles.keys().map(|t| t.0);
        let ys = || self.tiles.keys().map(|t| t.1);
        let (x0, x1, y0, y1) = (xs().min()?, xs().max()?, ys().min()?, ys().max()?);
        let origin = (x0 * TILE, y0 * TILE);
        let width = ((x1 - x0 + 1) * TILE) as usize;
        let height = ((y1 - y0 + 1) * TILE) as usize;
        let mut data = vec![UNKNOWN; width * height];
        for (&(tx, ty), cells) in &self.tiles {
            for row in 0..TILE {
                let at = ((ty - y0) * TILE + row) as usize * width + ((tx - x0) * TILE) as usize;
                let from = (row * TILE) as usize;
                data[at..at + TILE as usize].copy_from_slice(&cells[from..from + TILE as usize]);
            }
        }
        Some(Cells {
            origin,
            width,
            height,
            data,
        })
    }

    /// Where `cells` lie in the map frame: the pose of their lower-left cell's lower-left
    /// corner, its x and y along the grid's rows and columns (the level frame turned back).
    pub fn corner_pose(&self, cells: &Cells) -> Pose {
        let [x, y] = corner_in(self.resolution(), cells.origin);
        let corner = Vector3::new(x, y, 0.0);
        let level_inv = self.level.inverse();
        Pose::from_parts(
            Translation3::from(level_inv * corner),
            UnitQuaternion::from_rotation_matrix(&level_inv),
        )
    }

    /// Bytes the cells take.
    pub fn bytes(&self) -> usize {
        self.tiles.len() * (TILE * TILE) as usize
    }
}

/// A cell's tile and its place in it.
fn split((ix, iy): CellIndex) -> (CellIndex, usize) {
    let tile = (ix.div_euclid(TILE), iy.div_euclid(TILE));
    let k = iy.rem_euclid(TILE) * TILE + ix.rem_euclid(TILE);
    (tile, k as usize)
}

/// The triangles of `mesh` with a corner inside the window.
struct Window<'a> {
    mesh: &'a mut dyn Triangles,
    inside: &'a dyn Fn(&Vector3<f64>) -> bool,
}

impl Triangles for Window<'_> {
    fn each_triangle(&mut self, each: &mut dyn FnMut([Point; 3], f32)) -> Result<(), FileError> {
        let inside = self.inside;
        self.mesh.each_triangle(&mut |t, variance| {
            let corner =
                |p: &Point| Vector3::new(f64::from(p[0]), f64::from(p[1]), f64::from(p[2]));
            if t.iter().any(|p| inside(&corner(p))) {
                each(t, variance);
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::navmap::Robot;

    struct Soup(Vec<[Point; 3]>);

    impl Triangles for Soup {
        fn each_triangle(
            &mut self,
            each: &mut dyn FnMut([Point; 3], f32),
        ) -> Result<(), FileError> {
            self.0.iter().for_each(|t| each(*t, f32::NAN));
            Ok(())
        }
    }

    /// A rectangle split into two triangles, corners `a`, `b`, `c`, `a + c - b`.
    fn quad(a: Point, b: Point, c: Point) -> [[Point; 3]; 2] {
        let d = [a[0] + c[0] - b[0], a[1] + c[1] - b[1], a[2] + c[2] - b[2]];
        [[a, b, c], [a, c, d]]
    }

    /// A street 80 m long and 10 m wide in strips of a metre, a wall across half of it at
    /// x = 40 m, a box at x = 20 m.
    fn street() -> Vec<[Point; 3]> {
        let mut soup = Vec::new();
        for x in 0..80 {
            for y in 0..10 {
                let (x, y) = (x as f32, y as f32);
                soup.extend(quad(
                    [x, y, 0.0],
                    [x + 1.0, y, 0.0],
                    [x + 1.0, y + 1.0, 0.0],
                ));
            }
        }
        soup.extend(quad([40.0, 0.0, 0.0], [40.0, 4.0, 0.0], [40.0, 4.0, 2.0]));
        soup.extend(quad([20.0, 7.0, 0.0], [21.0, 7.0, 0.0], [21.0, 7.0, 0.5]));
        soup
    }

    #[test]
    fn windows_along_the_path_agree_with_the_whole_grid_where_they_keep_cells() {
        let path: Vec<Vector3<f64>> = (0..80)
            .map(|x| Vector3::new(f64::from(x), 5.5, 1.0))
            .collect();
        let how = NavMapOptions {
            robot: Robot::WHEELED,
            resolution_m: 0.1,
            up: None,
        };
        let whole = Grid::build(&mut Soup(street()), how.robot, 0.1, Vector3::z(), &path).unwrap();
        let mut live = LiveGrid::new(how, 30.0, 20.0);
        assert!(live.cells().is_none());
        for at in [10, 30, 50, 70] {
            let upto = &path[..=at];
            live.update(&mut Soup(street()), &|_| {}, upto, &path[at])
                .unwrap();
        }
        let cells = live.cells().unwrap();
        assert_eq!(cells.data.len(), cells.width * cells.height);
        let (mut same, mut judged, mut occupied) = (0, 0, 0);
        for ix in 0..800 {
            for iy in 0..100 {
                let want = match whole.occupancy(ix, iy) {
                    Occupancy::Free => FREE,
                    Occupancy::Occupied => OCCUPIED,
                    Occupancy::Unknown => UNKNOWN,
                };
                let got = live.get((ix, iy));
                // Row by row from the lower left, as the message holds them.
                let (cx, cy) = (
                    (ix - cells.origin.0) as usize,
                    (iy - cells.origin.1) as usize,
                );
                assert_eq!(cells.data[cy * cells.width + cx], got);
                judged += usize::from(got != UNKNOWN || want != UNKNOWN);
                same += usize::from(got == want && (got != UNKNOWN || want != UNKNOWN));
                occupied += usize::from(got == OCCUPIED);
            }
        }
        // The windows saw the street the path drove down, its box and its wall.
        assert!(occupied > 20, "{occupied}");
        println!("{same} of {judged} cells either judges agree");
        assert!(same as f64 >= 0.98 * judged as f64, "{same} of {judged}");
        // Cells past the last window's kept square were never judged.
        assert_eq!(live.get((900, 50)), UNKNOWN);
        // The kept squares (y from -4.5 to 15.5 m, x from 0 to 80) touch 3 rows of 9 tiles.
        assert!(
            live.bytes() <= 27 * (TILE * TILE) as usize,
            "{}",
            live.bytes()
        );
    }
}
