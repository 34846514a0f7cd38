//! What the grid says of a cell ([`Grid::occupancy`]): the cell's own samples, then the
//! obstacle's edge (ground beside an obstacle is unknown) and the mesh's seams (a cell where
//! nothing was seen between two free, or two occupied, cells is what they are). Reads the
//! grid's cells, changes nothing.

use super::{Cell, Grid, Occupancy, EDGE_M};

impl Grid {
    /// What the map says of cell `(ix, iy)`.
    ///
    /// Two rules beyond the cell's own: a cell with ground within [`EDGE_M`] of an obstacle
    /// cell is unknown, not free, since the obstacle's edge (a wall's foot, which the surface
    /// reconstruction rounds and carries ground under) may lie in it (unknown rather than
    /// occupied: a planner's inflation around the obstacle covers it, and a doorway keeps its
    /// width); and a cell where nothing was seen between two occupied cells, or else between
    /// two free ones (a seam of the mesh between its voxel cells, one or two cells wide, on a
    /// car's roof or on a street, or where such seams cross), is occupied, or free.
    pub fn occupancy(&self, ix: i64, iy: i64) -> Occupancy {
        let at = self.cell(ix, iy);
        match self.own(at) {
            Occupancy::Free
                if self.touches_obstacle(ix, iy) && !crate::mutants::on("edge-band") =>
            {
                Occupancy::Unknown
            }
            Occupancy::Unknown if nothing_seen(at) => {
                self.seam(ix, iy).unwrap_or(Occupancy::Unknown)
            }
            own => own,
        }
    }

    /// What a cell's own samples say (`None`: a cell never touched). A surface higher than
    /// the robot but lower than the sensor, over a cell whose ground was never seen, was seen
    /// from above: the top or the upper face of something standing there (a car's roof, a
    /// wall above a plinth). The robot passes under what it saw the ground beneath (or saw
    /// from below, a ceiling), nothing else.
    fn own(&self, cell: Option<&Cell>) -> Occupancy {
        match cell {
            Some(c) if c.obstacle => Occupancy::Occupied,
            Some(c) if c.ground && c.n > 0 && (c.visible || !self.carved) => {
                if c.doubtful {
                    Occupancy::Unknown
                } else {
                    Occupancy::Free
                }
            }
            Some(c) if c.heights & self.from_above != 0 => Occupancy::Occupied,
            _ => Occupancy::Unknown,
        }
    }

    /// Whether an obstacle cell lies within [`EDGE_M`] of the cell.
    fn touches_obstacle(&self, ix: i64, iy: i64) -> bool {
        let r = (EDGE_M / self.resolution).round().max(1.0) as i64;
        (-r..=r).any(|dy| {
            (-r..=r).any(|dx| {
                dx * dx + dy * dy <= r * r
                    && self.cell(ix + dx, iy + dy).is_some_and(|c| c.obstacle)
            })
        })
    }

    /// What a cell where nothing was seen is for lying between two cells that are one thing of
    /// their own (free ones not at an obstacle's edge), in a row, a column or a diagonal, at
    /// most two cells apart: a seam of the mesh between its voxel cells, on a street or on a
    /// car's roof, occupied between occupied cells, else free between free ones. The diagonals
    /// take the cells where four voxel cells' seams cross, whose rows and columns run along
    /// the seams. `None` when it lies in no seam. Each neighbour is looked up once (most cells
    /// of a map's grid have nothing around them).
    fn seam(&self, ix: i64, iy: i64) -> Option<Occupancy> {
        const DIRECTIONS: [(i64, i64); 4] = [(1, 0), (0, 1), (1, 1), (1, -1)];
        // Each direction's two neighbours, behind and ahead: what they are of their own, and
        // whether nothing was seen in them.
        let near = DIRECTIONS.map(|(dx, dy)| {
            [-1, 1].map(|s| {
                let c = self.cell(ix + s * dx, iy + s * dy);
                (self.own(c), nothing_seen(c))
            })
        });
        [Occupancy::Occupied, Occupancy::Free]
            .into_iter()
            .find(|&what| {
                // Whether the cell `s` steps along direction `d`, `own` of its own, counts.
                let is = |own: Occupancy, d: (i64, i64), s: i64| {
                    own == what
                        && (what != Occupancy::Free
                            || !self.touches_obstacle(ix + s * d.0, iy + s * d.1))
                };
                let far = |d: (i64, i64), s: i64| {
                    is(self.own(self.cell(ix + s * d.0, iy + s * d.1)), d, s)
                };
                DIRECTIONS.iter().zip(&near).any(
                    |(&d, &[(behind, behind_empty), (ahead, ahead_empty)])| {
                        let (b, a) = (is(behind, d, -1), is(ahead, d, 1));
                        (b && a)
                            || (b && ahead_empty && far(d, 2))
                            || (a && behind_empty && far(d, -2))
                    },
                )
            })
    }
}

/// Whether nothing was seen in a cell looked up (`None`: never touched): no floor and no
/// heights.
fn nothing_seen(cell: Option<&Cell>) -> bool {
    cell.is_none_or(|c| !c.floor.is_finite() && c.heights == 0)
}
