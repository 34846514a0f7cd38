//! The navigation map on the simulated yard's kerbs and ramps (`slamesh_sim::yard`), in the
//! run's files, in the grid the ROS 2 node keeps current and in what `slamesh navmap` makes
//! of the map the run saved, read back as [`crate::navmap`] reads them.

use crate::navmap::{free_path, seen_cells, Mapped};
use nalgebra::Point3;
use slamesh::navmap::Robot;
use slamesh_sim::Drive;
use std::collections::HashSet;

/// Issue 56's kerbs and ramps (`slamesh_sim::yard`): a kerb lower than the wheeled robot's
/// step keeps the pavement behind it in reach; a ramp within the robot's slope limit is free up
/// to its platform, and a planner finds its way up; a steeper one is not free where it stands
/// more than a step up, nor is its platform, and no way of free cells leads there. Each judged
/// over the cells of the area a true scan point fell in, 0.15 m in from its edges.
///
/// The kerb higher than a step (0.15 m) keeps the robot off the pavement behind it: the
/// mesh rounds it into a slope the robot could climb, but the scans' points saw it sharp
/// (`navmap::hits`), so the ground does not grow over it and the pavement stands a kerb
/// above the yard: occupied.
///
/// The grid the ROS 2 node keeps current during the run sees the kerbs as the file does: its
/// window is made from the scans' points too (`navmap::background`). It is judged over the
/// cells its updates judged (an update due while the last is being made is skipped, so which
/// windows were made varies from run to run).
#[test]
fn the_yard_s_kerbs_and_ramps() {
    use slamesh_sim::yard::{ramp, KERBS, RAMPS, RAMP_Y};
    let frames = 180;
    let drive = Drive::yard(frames, 3);
    let robot = Robot::WHEELED;
    let (mapped, live, saved) = Mapped::with_live(&drive, frames, robot, "navmap-yard", true, true);
    let (live, saved) = (live.unwrap(), saved.unwrap());
    let seen = seen_cells(&mapped, &drive, frames);
    // In `m`, the share of the area's seen cells that are `value` (0 free, 100 occupied),
    // and how many there are; with `judged`, of those not unknown.
    let share = |m: &Mapped, x: [f64; 2], y: [f64; 2], value: i8, judged: bool| {
        let mut cells = HashSet::new();
        let mut count = 0;
        let (nx, ny) = (
            ((x[1] - x[0]) / 0.05) as usize,
            ((y[1] - y[0]) / 0.05) as usize,
        );
        for (i, j) in (0..=nx).flat_map(|i| (0..=ny).map(move |j| (i, j))) {
            let (px, py) = (x[0] + 0.05 * i as f64, y[0] + 0.05 * j as f64);
            let cell = mapped.cell(&Point3::new(px, py, 0.0));
            let Some((c, r)) = m.pixel(px, py) else {
                continue;
            };
            let v = m.map.value(c, r);
            if seen.contains(&cell) && (!judged || v != -1) && cells.insert(cell) {
                count += usize::from(v == value);
            }
        }
        (count as f64 / cells.len().max(1) as f64, cells.len())
    };
    let map = &mapped.map;
    // Whether free cells join the yard's middle at `x` to `(x, y)`.
    let reached = |x: f64, y: f64| match (mapped.pixel(x, 0.0), mapped.pixel(x, y)) {
        (Some(from), Some(to)) => free_path(map, from, to),
        _ => false,
    };
    let inset = 0.15;
    let pavement = |m: &Mapped, [x0, x1, _]: [f64; 3], value: i8, judged: bool| {
        let (x, y) = ([x0 + inset, x1 - inset], [4.0 + inset, 6.0 - inset]);
        share(m, x, y, value, judged)
    };
    let (high, low) = (
        pavement(&mapped, KERBS[0], 0, false),
        pavement(&mapped, KERBS[1], 0, false),
    );
    let high_occupied = pavement(&mapped, KERBS[0], 100, false);
    let centre = |k: [f64; 3]| (k[0] + k[1]) / 2.0;
    let high_reached = reached(centre(KERBS[0]), 5.0);
    println!(
        "free behind the high kerb {high:?} (occupied {:.3}), reached {high_reached}; behind \
         the low one {low:?}",
        high_occupied.0
    );
    assert!(low.1 > 500 && low.0 > 0.9, "{low:?}");
    assert!(reached(centre(KERBS[1]), 5.0));
    assert!(high.1 > 500 && high.0 < 0.05 && !high_reached, "{high:?}");
    assert!(high_occupied.0 > 0.9, "{high_occupied:?}");
    let y = [RAMP_Y[0] + inset, RAMP_Y[1] - inset];
    let ramps = |m: &Mapped, judged: bool| {
        RAMPS.map(|[x0, x1, degrees]| {
            let (up, top) = ramp(x0, x1, degrees);
            // From where the ramp stands a step up.
            let from = up[0] + robot.max_step_m / degrees.to_radians().tan();
            let on_ramp = share(m, [from + inset, up[1] - inset], y, 0, judged);
            let platform = share(m, [top[0] + inset, top[1] - inset], y, 0, judged);
            (on_ramp, platform, (top[0] + top[1]) / 2.0)
        })
    };
    let [gentle, steep] = ramps(&mapped, false).map(|(r, p, x)| (r, p, reached(x, -5.5)));
    println!(
        "free on the gentle ramp, on its platform, reached: {gentle:?}; the steep one: {steep:?}"
    );
    assert!(gentle.0 .1 > 300 && gentle.0 .0 > 0.8, "{gentle:?}");
    assert!(
        gentle.1 .1 > 500 && gentle.1 .0 > 0.8 && gentle.2,
        "{gentle:?}"
    );
    assert!(steep.0 .1 > 100 && steep.0 .0 < 0.05, "{steep:?}");
    assert!(
        steep.1 .1 > 500 && steep.1 .0 == 0.0 && !steep.2,
        "{steep:?}"
    );
    // The live grid, over the cells it judged.
    let (high, low) = (
        pavement(&live, KERBS[0], 0, true),
        pavement(&live, KERBS[1], 0, true),
    );
    let high_occupied = pavement(&live, KERBS[0], 100, true);
    let [gentle, steep] = ramps(&live, true);
    println!(
        "live: free behind the high kerb {high:?} (occupied {:.3}), behind the low one {low:?}; \
         on the gentle ramp and its platform {:?}, the steep one {:?}",
        high_occupied.0,
        (gentle.0, gentle.1),
        (steep.0, steep.1)
    );
    assert!(
        high.1 > 300 && high.0 < 0.05 && high_occupied.0 > 0.9,
        "{high:?}"
    );
    assert!(low.1 > 300 && low.0 > 0.9, "{low:?}");
    assert!(gentle.1 .1 > 300 && gentle.1 .0 > 0.8, "{gentle:?}");
    assert!(steep.1 .1 > 300 && steep.1 .0 == 0.0, "{steep:?}");
    // `slamesh navmap` of the map the run saved, with the scans' floor kept beside it
    // (`navmap::floor_file`): the high kerb keeps the robot off as in the run's files.
    let (high, low) = (
        pavement(&saved, KERBS[0], 0, false),
        pavement(&saved, KERBS[1], 0, false),
    );
    let high_occupied = pavement(&saved, KERBS[0], 100, false);
    println!(
        "from the saved map: free behind the high kerb {high:?} (occupied {:.3}), behind the \
         low one {low:?}",
        high_occupied.0
    );
    assert!(
        high.1 > 500 && high.0 < 0.05 && high_occupied.0 > 0.9,
        "{high:?}"
    );
    assert!(low.1 > 500 && low.0 > 0.9, "{low:?}");
}
