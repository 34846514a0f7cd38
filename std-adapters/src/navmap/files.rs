//! A navigation map's files, each written to a temporary name then renamed:
//! - `map.yaml` + `map.pgm`: the occupancy grid as Nav2's `map_saver` writes it (trinary: 0
//!   occupied, 254 free, 205 unknown; rows top-down, the YAML's `origin` the lower-left
//!   pixel's corner), loadable by `map_server` as it is, with a `free_thresh` that keeps
//!   unknown space unknown;
//! - `elevation.asc`, `elevation_variance.asc`: the ground's height (m) and the variance of
//!   the ground samples in each cell (m²), ESRI ASCII grids (GDAL, QGIS and
//!   `numpy.loadtxt(path, skiprows=6)` read them), -9999 where no ground was seen, over the
//!   same cells as the image;
//! - `navmesh.ply`: the seen ground as a mesh with its traversability layers as vertex
//!   properties ([`crate::navmap::layers`]);
//! - `navmap.json`: the counts, the grid's size and origin, the robot and which way was up.
//!
//! The grid's frame is the map frame turned so that up is its z (the same frame when up is
//! the map's z axis): x and y as the map's, for a map made level.

use crate::formats::ply::write_mesh_with_properties;
use crate::io::atomic::write_atomic;
use crate::io::error::FileError;
use crate::navmap::grid::{corner_in, CellIndex, Grid, Occupancy};
use crate::navmap::layers::NavMesh;
use crate::navmap::NavMapOptions;
use serde::Serialize;
use std::io::Write;
use std::path::Path;

/// Nav2's pixel values (`map_saver`, trinary).
const OCCUPIED: u8 = 0;
const FREE: u8 = 254;
const UNKNOWN: u8 = 205;
/// The most cells an image may have (20 000 x 20 000: 2 km square at 0.1 m).
const MAX_CELLS: usize = 400_000_000;
/// What the elevation grids hold where no ground was seen.
const NO_DATA: &str = "-9999";

/// The files a navigation map is written as, in the order above.
pub const FILES: [&str; 6] = [
    "map.yaml",
    "map.pgm",
    "elevation.asc",
    "elevation_variance.asc",
    "navmesh.ply",
    "navmap.json",
];

/// What a navigation map holds (`navmap.json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NavMapSummary {
    /// Cells free, occupied and unknown in the image.
    pub free: usize,
    /// See [`free`](Self::free).
    pub occupied: usize,
    /// See [`free`](Self::free).
    pub unknown: usize,
    /// The image's width and height (cells).
    pub width: usize,
    /// See [`width`](Self::width).
    pub height: usize,
    /// Cell size (m).
    pub resolution_m: f64,
    /// The lower-left corner of the lower-left cell (m, grid frame).
    pub origin: [f64; 2],
    /// Which way was up, and what said so.
    pub up: String,
    /// The robot it was made for.
    pub robot: crate::navmap::Robot,
    /// The navigation mesh's vertices and triangles (`navmesh.ply`).
    pub navmesh: [usize; 2],
    /// Cells whose floor the run's own points saw (`run --navmap`; docs/design.md §1.18,
    /// "The scans' floor"): 0 when the grid is the mesh's alone (from a saved map, or a run
    /// under a memory cap or a window), which may climb a kerb the mesh rounded.
    pub scans_floor_cells: usize,
}

impl NavMapSummary {
    /// `3573 x 3569 cells of 0.1 m (2664191 free, 183462 occupied, 9904384 unknown)`.
    pub fn describe(&self) -> String {
        format!(
            "{} x {} cells of {} m ({} free, {} occupied, {} unknown)",
            self.width, self.height, self.resolution_m, self.free, self.occupied, self.unknown
        )
    }
}

/// Writes the navigation map of `grid` into `dir`; `None` (and nothing written) when the grid
/// saw nothing.
pub fn write(
    dir: &Path,
    grid: &Grid,
    opts: &NavMapOptions,
) -> Result<Option<NavMapSummary>, FileError> {
    let Some((lo, hi)) = grid.bounds() else {
        return Ok(None);
    };
    let (width, height) = ((hi.0 - lo.0 + 1) as usize, (hi.1 - lo.1 + 1) as usize);
    if width.saturating_mul(height) > MAX_CELLS {
        return Err(FileError::at(
            &dir.join("map.pgm"),
            format!(
                "{width} x {height} cells is more than a navigation map holds ({MAX_CELLS}): \
                 the mesh spans {:.0} x {:.0} m; give a coarser --navmap-resolution",
                width as f64 * grid.resolution(),
                height as f64 * grid.resolution()
            ),
        ));
    }
    let res = grid.resolution();
    let origin = corner_in(res, lo);
    let mut counts = [0usize; 3];
    write_atomic(&dir.join("map.pgm"), |w| {
        write!(
            w,
            "P5\n# CREATOR: slamesh navmap {res:.3} m/pix\n{width} {height}\n255\n"
        )?;
        let mut row = Vec::with_capacity(width);
        for iy in (lo.1..=hi.1).rev() {
            row.clear();
            for ix in lo.0..=hi.0 {
                let (k, pixel) = match grid.occupancy(ix, iy) {
                    Occupancy::Free => (0, FREE),
                    Occupancy::Occupied => (1, OCCUPIED),
                    Occupancy::Unknown => (2, UNKNOWN),
                };
                counts[k] += 1;
                row.push(pixel);
            }
            w.write_all(&row)?;
        }
        Ok(())
    })?;
    let (_, up) = opts.up();
    write_atomic(&dir.join("map.yaml"), |w| write_yaml(w, res, origin, &up))?;
    write_elevation(dir, grid, (lo, hi), origin)?;
    let mesh = NavMesh::of(grid, &opts.robot);
    write_atomic(&dir.join("navmesh.ply"), |w| {
        write_mesh_with_properties(
            w,
            "slamesh navmesh: the seen ground with its traversability for the robot",
            &mesh.vertices,
            &mesh.properties(),
            &mesh.triangles,
        )
    })?;
    let summary = NavMapSummary {
        free: counts[0],
        occupied: counts[1],
        unknown: counts[2],
        width,
        height,
        resolution_m: res,
        origin,
        up,
        robot: opts.robot,
        navmesh: [mesh.vertices.len(), mesh.triangles.len()],
        scans_floor_cells: grid.scans_floor_cells(),
    };
    write_atomic(&dir.join("navmap.json"), |w| {
        serde_json::to_writer_pretty(&mut *w, &summary).map_err(std::io::Error::from)?;
        w.write_all(b"\n")
    })?;
    Ok(Some(summary))
}

/// `map.yaml` as Nav2's `map_saver` writes it, but for `free_thresh`.
fn write_yaml(w: &mut impl Write, res: f64, origin: [f64; 2], up: &str) -> std::io::Result<()> {
    writeln!(w, "image: map.pgm")?;
    writeln!(w, "mode: trinary")?;
    writeln!(w, "resolution: {res}")?;
    writeln!(w, "origin: [{}, {}, 0]", origin[0], origin[1])?;
    writeln!(w, "negate: 0")?;
    writeln!(w, "occupied_thresh: 0.65")?;
    writeln!(
        w,
        "# Below 0.196, not map_saver's 0.25: map_server takes a pixel p as free when\n\
         # (255 - p) / 255 < free_thresh, and the unknown pixel 205 gives 0.196, so 0.25 would\n\
         # load every unknown cell as free (slam_toolbox issue 587)."
    )?;
    writeln!(w, "free_thresh: 0.19")?;
    writeln!(w, "# up: {up}")
}

/// `elevation.asc` and `elevation_variance.asc` over the cells `lo..=hi`.
fn write_elevation(
    dir: &Path,
    grid: &Grid,
    (lo, hi): (CellIndex, CellIndex),
    origin: [f64; 2],
) -> Result<(), FileError> {
    let header = |w: &mut dyn Write| {
        write!(
            w,
            "ncols {}\nnrows {}\nxllcorner {}\nyllcorner {}\ncellsize {}\nNODATA_value {NO_DATA}\n",
            hi.0 - lo.0 + 1,
            hi.1 - lo.1 + 1,
            origin[0],
            origin[1],
            grid.resolution()
        )
    };
    for (name, variance) in [("elevation.asc", false), ("elevation_variance.asc", true)] {
        write_atomic(&dir.join(name), |w| {
            header(w)?;
            for iy in (lo.1..=hi.1).rev() {
                let mut line = String::new();
                for ix in lo.0..=hi.0 {
                    if ix > lo.0 {
                        line.push(' ');
                    }
                    match grid.elevation(ix, iy) {
                        Some((_, v)) if variance => line.push_str(&format!("{v:.6}")),
                        Some((h, _)) => line.push_str(&format!("{h:.3}")),
                        None => line.push_str(NO_DATA),
                    }
                }
                line.push('\n');
                w.write_all(line.as_bytes())?;
            }
            Ok(())
        })?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::navmap::grid::Triangles;
    use nalgebra::Vector3;
    use slamesh_core::Point;

    /// Two floors of 2 x 2 m, 3 km apart on both axes.
    struct FarApart;

    impl Triangles for FarApart {
        fn each_triangle(
            &mut self,
            each: &mut dyn FnMut([Point; 3], f32),
        ) -> Result<(), FileError> {
            for o in [0.0f32, 3000.0] {
                each(
                    [[o, o, 0.0], [o + 2.0, o, 0.0], [o + 2.0, o + 2.0, 0.0]],
                    0.0,
                );
                each(
                    [[o, o, 0.0], [o + 2.0, o + 2.0, 0.0], [o, o + 2.0, 0.0]],
                    0.0,
                );
            }
            Ok(())
        }
    }

    #[test]
    fn a_map_too_large_for_an_image_is_refused_naming_its_size() {
        let path = [
            Vector3::new(1.0, 1.0, 1.7),
            Vector3::new(3001.0, 3001.0, 1.7),
        ];
        let opts = NavMapOptions::default();
        let grid = Grid::build(&mut FarApart, opts.robot, 0.1, Vector3::z(), &path).unwrap();
        let dir = crate::test_support::scratch_dir("navmap-too-large");
        let e = write(&dir, &grid, &opts).unwrap_err().to_string();
        assert!(e.contains("map.pgm") && e.contains("coarser"), "{e}");
        assert!(!dir.join("map.pgm").exists());
    }

    #[test]
    fn the_origin_is_written_as_the_whole_cells_it_is() {
        use crate::navmap::grid::tests::{floor, Soup};
        // A floor whose lower-left cell is (-287, -165): -287 x 0.1 is -28.700000000000003.
        let mut soup = Soup(floor(-28.65, -16.45, -25.0, -13.0, 0.0));
        let path = [Vector3::new(-27.0, -15.0, 1.7)];
        let opts = NavMapOptions::default();
        let grid = Grid::build(&mut soup, opts.robot, 0.1, Vector3::z(), &path).unwrap();
        let dir = crate::test_support::scratch_dir("navmap-origin");
        let summary = write(&dir, &grid, &opts).unwrap().unwrap();
        let yaml = std::fs::read_to_string(dir.join("map.yaml")).unwrap();
        let [x, y] = summary.origin;
        assert!(yaml.contains(&format!("origin: [{x}, {y}, 0]")), "{yaml}");
        for (v, text) in [(x, x.to_string()), (y, y.to_string())] {
            let decimals = text.split('.').nth(1).map_or(0, str::len);
            assert!(decimals <= 6, "{text}");
            assert!(((v / 0.1) - (v / 0.1).round()).abs() < 1e-6, "{text}");
        }
        let asc = std::fs::read_to_string(dir.join("elevation.asc")).unwrap();
        assert!(
            asc.contains(&format!("xllcorner {x}\nyllcorner {y}\n")),
            "{asc}"
        );
    }
}
