//! What stands where the mesh has no surface: the scans' floor raised over the ground
//! (docs/design.md §1.18, "The scans' floor raised").
//!
//! The surface reconstruction drops what few rings saw, at a grazing angle, from a sensor a
//! little above it: a car's roof, the top of a wall's plinth. The scans' points saw it all the
//! same, and their floor in such a cell ([`crate::navmap::hits`]: the lowest height two points
//! fell at) stands far above the ground the cell is judged against. Where the mesh saw no
//! ground in the cell and no ground beside it lies level with that floor (a hole in the mesh's
//! floor, or a platform's edge, is no obstacle), the floor is something standing there: an
//! obstacle up to the robot's height, and above it a surface seen from above (occupied where
//! the lines of sight were cast from higher, [`crate::navmap::sight`]).
//!
//! Owns no state: it marks the grid's cells. Guarantees: only cells with no ground of their
//! own change, and only towards an obstacle; a grid built with no scans' floor (a saved map's
//! with no floor file beside it) is untouched.

use crate::navmap::grid::{disc, tile_of, CellIndex, Grid, LOW_RISE_M};
use crate::navmap::ground::{GroundBlocks, REFERENCE_M};
use crate::navmap::hits::Floors;
use slamesh_core::cell::BuildCellHasher;
use std::collections::HashMap;

/// How far (m) around a raised floor ground level with it is looked for: ground beside it
/// makes it more of the same floor, not something standing.
pub const LEVEL_GROUND_M: f64 = 0.5;

/// How close in height (m) a neighbouring cell's floor must lie to bear out a cell's lowest
/// point where no two points fell in one of its bins: the two points a floor asks for, in
/// cells side by side (a car's roof seen by one ring a pass).
pub const BORNE_OUT_M: f64 = 0.1;

impl Grid {
    /// Marks the cells whose scans' floor (`floors`, as
    /// [`build_with_floors`](Self::build_with_floors) takes it; a lowest point alone only
    /// where a floor in a cell beside lies within [`BORNE_OUT_M`] of it) stands more than
    /// [`LOW_RISE_M`] over the cell's reference where the mesh saw no ground, with no ground
    /// within [`LEVEL_GROUND_M`] level with it (within a step): a height of the cell's
    /// ([`Cell::heights`](crate::navmap::grid::Cell)), and an obstacle when no higher than
    /// the robot. A cell with no ground within [`REFERENCE_M`] to judge it against is judged
    /// against ground up to twice as far, and only a floor over the robot's height counts
    /// there (a plinth's top, a roof: seen from above; `blocks`: the ground's blocks the
    /// references were found in, [`Grid::set_references`]). Run after the references are set
    /// and the mesh's samples classified.
    pub(super) fn raise_from_scans(&mut self, floors: &Floors, blocks: &GroundBlocks) {
        let (step, height) = (self.robot.max_step_m as f32, self.robot.height_m as f32);
        let near = disc((LEVEL_GROUND_M / self.resolution).round().max(1.0) as i64);
        let beside: Vec<CellIndex> = disc(1).into_iter().filter(|&d| d != (0, 0)).collect();
        let far = blocks.offsets(self.resolution, 2.0 * REFERENCE_M);
        let mut far_ground: HashMap<(i64, i64), Option<f32>, BuildCellHasher> = HashMap::default();
        // The floors raised near enough to bear out a raised one (a lone point's neighbours
        // on a car's roof, even where the mesh carried its ground under the roof), sorted by
        // cell.
        let bears = (LOW_RISE_M - BORNE_OUT_M) as f32;
        let mut seen: Vec<Raised> = Vec::new();
        floors(&mut |f| {
            let q = self.level * f.at;
            let (cell, z) = (self.index_of(q.x, q.y), q.z as f32);
            let Some(c) = self.cell(cell.0, cell.1) else {
                return;
            };
            let (reference, further) = match c.reference {
                r if r.is_finite() => (r, false),
                _ => {
                    let block = blocks.block_of(cell);
                    let r = *far_ground
                        .entry(block)
                        .or_insert_with(|| blocks.nearest(cell, &far));
                    (r.unwrap_or(f32::INFINITY), true)
                }
            };
            let above = z - reference;
            if above > bears {
                seen.push(Raised {
                    cell,
                    z,
                    twice: f.twice,
                    above,
                    further,
                });
            }
        });
        seen.sort_unstable_by_key(|r| r.cell);
        let borne_out = |(ix, iy): CellIndex, z: f32| {
            beside.iter().any(|&(dx, dy)| {
                let cell = (ix + dx, iy + dy);
                let from = seen.partition_point(|r| r.cell < cell);
                (seen[from..].iter())
                    .take_while(|r| r.cell == cell)
                    .any(|r| (r.z - z).abs() <= BORNE_OUT_M as f32)
            })
        };
        let mut standing = Vec::new();
        for r in &seen {
            let (ix, iy) = r.cell;
            if self.cell(ix, iy).is_none_or(|c| c.ground && c.n > 0) {
                continue;
            }
            // Judged against ground further off, only what stands over the robot counts: a
            // slope's rise over the distance does not reach so high.
            let over = if r.further { height } else { LOW_RISE_M as f32 };
            if !(r.above.is_finite() && r.above > over) {
                continue;
            }
            let level_ground = near.iter().any(|&(dx, dy)| {
                self.cell(ix + dx, iy + dy)
                    .is_some_and(|n| n.ground && (n.floor - r.z).abs() <= step)
            });
            if !level_ground && (r.twice || borne_out(r.cell, r.z)) {
                standing.push((r.cell, r.above));
            }
        }
        for ((ix, iy), above) in standing {
            let (key, k) = tile_of(ix, iy);
            if let Some(c) = self.tiles.get_mut(&key).map(|t| &mut t[k]) {
                c.mark_height(above);
                c.obstacle |= above <= height;
            }
        }
    }
}

/// A scans' floor raised over its cell's reference by more than a floor bearing out another
/// may lie below it.
struct Raised {
    cell: CellIndex,
    /// The floor's height (level frame).
    z: f32,
    /// Two points fell in its bin ([`crate::navmap::hits::ScanFloor::twice`]).
    twice: bool,
    /// Its rise over the reference.
    above: f32,
    /// The reference is the ground up to twice as far off (the cell had none near).
    further: bool,
}

#[cfg(test)]
mod tests {
    use crate::navmap::grid::tests::{floor, occupancy_at, Soup};
    use crate::navmap::grid::{Grid, Occupancy};
    use crate::navmap::hits::{hand, ScanFloor};
    use crate::navmap::robot::Robot;
    use nalgebra::Vector3;

    #[test]
    fn a_car_the_mesh_dropped_stands_where_the_points_saw_its_top() {
        // A street at 0 (y 0 to 10) with a hole in its mesh at x, y 4 to 6: a car whose top
        // (0.7 m) only the points saw, and the street's edge around it. A platform at 0.5 m
        // from y = 10, the robot's too (a point of the path on it), with a band at its edge
        // (x 4 to 6, y 10 to 10.5) that the mesh missed and the points saw level with it.
        let mut soup = floor(0.0, 0.0, 4.0, 10.0, 0.0);
        soup.extend(floor(6.0, 0.0, 10.0, 10.0, 0.0));
        soup.extend(floor(4.0, 0.0, 6.0, 4.0, 0.0));
        soup.extend(floor(4.0, 6.0, 6.0, 10.0, 0.0));
        soup.extend(floor(0.0, 10.0, 4.0, 12.0, 0.5));
        soup.extend(floor(6.0, 10.0, 10.0, 12.0, 0.5));
        soup.extend(floor(4.0, 10.5, 6.0, 12.0, 0.5));
        // The car's top: two points in a bin in each cell, but for one alone in each of a
        // stripe three cells wide (x 4.7 to 5.0), borne out by one another. A stray return alone at the car's height in the
        // hole's street cell (4.15, 4.15), its neighbours the street.
        let floors: Vec<ScanFloor> = (0..100)
            .flat_map(|ix| (0..120).map(move |iy| (ix, iy)))
            .map(|(ix, iy)| {
                let (x, y) = (ix as f64 * 0.1 + 0.05, iy as f64 * 0.1 + 0.05);
                let car = (4.3..5.7).contains(&x) && (4.3..5.7).contains(&y);
                let stray = (ix, iy) == (41, 41);
                let z = match y {
                    _ if car || stray => 0.7,
                    y if y < 10.0 => 0.01,
                    _ => 0.51,
                };
                let twice = !(stray || car && (47..50).contains(&ix));
                ScanFloor {
                    at: Vector3::new(x, y, z),
                    twice,
                }
            })
            .collect();
        // Beyond the street's end (x 10), further than a reference is looked for: a plinth's
        // top at 1.3 m (x 12.3 to 12.8, y 4 to 6) and something 0.5 m high (y 7 to 8).
        let beyond = (123..128).flat_map(|ix| (40..80).map(move |iy| (ix, iy)));
        let floors: Vec<ScanFloor> = (floors.into_iter())
            .chain(
                beyond
                    .filter(|&(_, iy)| !(60..70).contains(&iy))
                    .map(|(ix, iy)| {
                        let (x, y) = (ix as f64 * 0.1 + 0.05, iy as f64 * 0.1 + 0.05);
                        let z = if y < 6.0 { 1.3 } else { 0.5 };
                        ScanFloor {
                            at: Vector3::new(x, y, z),
                            twice: true,
                        }
                    }),
            )
            .collect();
        let path = [Vector3::new(2.0, 5.0, 1.7), Vector3::new(2.0, 11.0, 2.2)];
        let grid = |floors: &[ScanFloor]| {
            let (robot, z) = (Robot::WHEELED, Vector3::z());
            let (mut soup, each) = (Soup(soup.clone()), hand(floors));
            Grid::build_with_floors(&mut soup, &each, robot, 0.1, z, &path, &[]).unwrap()
        };
        let (mesh_only, with_points) = (grid(&[]), grid(&floors));
        let unseen = occupancy_at(&mesh_only, 5.05, 5.05);
        assert_eq!(unseen, Occupancy::Unknown, "no surface");
        let with = |x: f64, y: f64| occupancy_at(&with_points, x, y);
        assert_eq!(with(5.05, 5.05), Occupancy::Occupied, "the car");
        assert_eq!(with(4.85, 5.05), Occupancy::Occupied, "a lone point");
        assert_ne!(with(4.15, 4.15), Occupancy::Occupied, "the stray");
        assert_eq!(with(2.05, 5.05), Occupancy::Free, "the street");
        // The street's floor the points saw in the hole, and the platform's band level with
        // the platform beside it (though judged against the street, the nearer ground), are
        // nothing standing.
        assert_ne!(with(4.15, 5.05), Occupancy::Occupied, "the street");
        assert_ne!(with(5.05, 10.05), Occupancy::Occupied, "the band");
        // Judged against the street 2.5 m off: the plinth's top is seen from above, the lower
        // floor (a slope's rise over the distance, for all it tells) is not taken.
        assert_eq!(with(12.55, 5.05), Occupancy::Occupied, "the plinth's top");
        assert_eq!(with(12.55, 7.55), Occupancy::Unknown, "the lower floor");
    }
}
