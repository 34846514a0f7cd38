//! A procedural town for long simulated drives with ground truth (deterministic from a seed).
//!
//! A grid of blocks (90 m apart, 16 m streets) over gently rolling, rough ground: buildings of
//! several heights and depths along every block edge with gaps between them, balconies and
//! plinths on the facades, street lights, trees (trunk and crown), parked cars, fences and bus
//! shelters on the sidewalks. The route is a loop around the middle blocks with rounded
//! corners, about 1.1 km, driven from standstill with speed changes (slower in the corners).

use crate::scene::{OrientedBox, Scene, Sphere, Terrain};
use nalgebra::{Translation3, UnitQuaternion};
use slamesh_core::random::SplitMix64;
use slamesh_core::Pose;

/// Distance between street centre lines (metres).
pub const PITCH_M: f64 = 90.0;
/// Streets per direction.
const STREETS: usize = 6;
/// Half the width between facades (metres).
const STREET_HALF_M: f64 = 8.0;
/// Sensor height above the ground (metres).
pub const SENSOR_HEIGHT_M: f64 = 1.73;

/// The town's scene.
pub fn scene(seed: u64) -> Scene {
    let mut rng = SplitMix64(seed);
    let terrain = Terrain {
        hill_m: 1.5,
        hill_wavelength_m: 320.0,
        roughness_m: 0.03,
    };
    let mut boxes = Vec::new();
    // Buildings along the four edges of every block.
    for bi in 0..STREETS - 1 {
        for bj in 0..STREETS - 1 {
            let (x0, y0) = (
                bi as f64 * PITCH_M + STREET_HALF_M,
                bj as f64 * PITCH_M + STREET_HALF_M,
            );
            let side = PITCH_M - 2.0 * STREET_HALF_M;
            // Edges: origin, direction along the edge, inward normal.
            let edges = [
                ([x0, y0], [1.0, 0.0], [0.0, 1.0]),
                ([x0 + side, y0], [0.0, 1.0], [-1.0, 0.0]),
                ([x0 + side, y0 + side], [-1.0, 0.0], [0.0, -1.0]),
                ([x0, y0 + side], [0.0, -1.0], [1.0, 0.0]),
            ];
            for edge in edges {
                buildings_along(&mut rng, &terrain, edge, side, &mut boxes);
            }
        }
    }
    let mut scene = Scene {
        ground_z: 0.0,
        terrain: Some(terrain),
        boxes,
        spheres: Vec::new(),
    };
    street_furniture(&mut rng, &terrain, &mut scene);
    scene
}

/// A block's edge: where it starts, the direction along it and the block's inward normal.
type Edge = ([f64; 2], [f64; 2], [f64; 2]);

/// Buildings of random widths, with gaps, along `edge` (`side` metres long).
fn buildings_along(
    rng: &mut SplitMix64,
    terrain: &Terrain,
    edge: Edge,
    side: f64,
    boxes: &mut Vec<OrientedBox>,
) {
    let mut t = 0.0;
    while t < side - 6.0 {
        let width = rng.range(8.0, 22.0).min(side - t);
        if rng.next_f64() > 0.12 {
            building(rng, terrain, edge, t + width / 2.0, width, boxes);
        }
        t += width + rng.range(0.0, 4.0);
    }
}

/// One building `width` wide centred `centre_edge` metres along `edge`: its block, a plinth
/// and balconies on the street face.
fn building(
    rng: &mut SplitMix64,
    terrain: &Terrain,
    (start, along, inward): Edge,
    centre_edge: f64,
    width: f64,
    boxes: &mut Vec<OrientedBox>,
) {
    let depth = rng.range(8.0, 14.0);
    let setback = rng.range(0.0, 1.5);
    let height = rng.range(5.0, 20.0);
    let cx = start[0] + along[0] * centre_edge + inward[0] * (setback + depth / 2.0);
    let cy = start[1] + along[1] * centre_edge + inward[1] * (setback + depth / 2.0);
    let base = terrain.height(cx, cy) - 0.5;
    let yaw = along[1].atan2(along[0]) + rng.range(-0.03, 0.03);
    boxes.push(OrientedBox {
        centre: [cx, cy, base + height / 2.0],
        half: [width / 2.0, depth / 2.0, height / 2.0],
        yaw,
    });
    // A plinth and balconies on the street face.
    let face = setback - 0.25;
    let fx = start[0] + along[0] * centre_edge + inward[0] * face;
    let fy = start[1] + along[1] * centre_edge + inward[1] * face;
    boxes.push(OrientedBox {
        centre: [fx, fy, base + 0.9],
        half: [width / 2.0, 0.3, 0.9],
        yaw,
    });
    let floors = (height / 3.0) as usize;
    for floor in 1..floors {
        if rng.next_f64() < 0.5 {
            let off = rng.range(-width / 3.0, width / 3.0);
            let depth_b = rng.range(0.4, 1.0);
            let bx = fx + along[0] * off - inward[0] * depth_b / 2.0;
            let by = fy + along[1] * off - inward[1] * depth_b / 2.0;
            boxes.push(OrientedBox {
                centre: [bx, by, base + 0.5 + 3.0 * floor as f64],
                half: [rng.range(1.0, 2.0), depth_b / 2.0, rng.range(0.1, 0.5)],
                yaw,
            });
        }
    }
}

/// Street furniture along both sides of every street, intersections kept clear.
fn street_furniture(rng: &mut SplitMix64, terrain: &Terrain, scene: &mut Scene) {
    let size = PITCH_M * (STREETS - 1) as f64;
    for k in 0..STREETS {
        let c = k as f64 * PITCH_M;
        for horizontal in [true, false] {
            for side in [-1.0, 1.0] {
                let mut t = rng.range(0.0, 10.0);
                while t < size {
                    t += rng.range(6.0, 16.0);
                    // Keep intersections clear.
                    let local = t % PITCH_M;
                    if !(STREET_HALF_M + 3.0..PITCH_M - STREET_HALF_M - 3.0).contains(&local) {
                        continue;
                    }
                    let lateral = side * rng.range(4.2, 6.8);
                    let (x, y) = if horizontal {
                        (t, c + lateral)
                    } else {
                        (c + lateral, t)
                    };
                    let yaw = if horizontal {
                        0.0
                    } else {
                        std::f64::consts::FRAC_PI_2
                    };
                    furniture(rng, [x, y, terrain.height(x, y)], yaw, scene);
                }
            }
        }
    }
}

/// A square post `height` tall and `half_width` either side, standing at `[x, y, ground]`.
fn post([x, y, g]: [f64; 3], height: f64, half_width: f64) -> OrientedBox {
    OrientedBox {
        centre: [x, y, g + height / 2.0],
        half: [half_width, half_width, height / 2.0],
        yaw: 0.0,
    }
}

/// One piece of street furniture standing at `[x, y, ground]`, facing along `yaw`: a parked
/// car, a tree, a street light, a fence or a bus shelter.
fn furniture(rng: &mut SplitMix64, [x, y, g]: [f64; 3], yaw: f64, scene: &mut Scene) {
    let boxes = &mut scene.boxes;
    match rng.next_f64() {
        f if f < 0.35 => boxes.push(OrientedBox {
            centre: [x, y, g + 0.75],
            half: [2.2, 0.9, 0.75],
            yaw: yaw + rng.range(-0.08, 0.08),
        }),
        f if f < 0.55 => {
            // A tree: its trunk, then its crown.
            let h = rng.range(2.0, 3.5);
            boxes.push(post([x, y, g], h, 0.15));
            scene.spheres.push(Sphere {
                centre: [x, y, g + h + 1.2],
                radius: rng.range(1.4, 2.4),
            });
        }
        f if f < 0.75 => boxes.push(post([x, y, g], rng.range(4.0, 8.0), 0.1)),
        f if f < 0.9 => boxes.push(OrientedBox {
            centre: [x, y, g + 0.6],
            half: [rng.range(2.5, 7.0), 0.03, 0.6],
            yaw,
        }),
        _ => boxes.push(OrientedBox {
            centre: [x, y, g + 1.3],
            half: [1.8, 0.8, 1.3],
            yaw,
        }),
    }
}

/// Points about 0.25 m apart from `a` (included) to `b` (not).
fn straight(pts: &mut Vec<[f64; 2]>, a: [f64; 2], b: [f64; 2]) {
    let n = (((b[0] - a[0]).hypot(b[1] - a[1])) / 0.25).ceil() as usize;
    for i in 0..n {
        let f = i as f64 / n as f64;
        pts.push([a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])]);
    }
}

/// The route: a loop around the middle blocks (from the second to the fifth street), corners
/// rounded with a 10 m radius, as points about 0.25 m apart; it starts and ends mid-street.
pub fn route() -> Vec<[f64; 2]> {
    let (lo, hi, r) = (PITCH_M, 4.0 * PITCH_M, 10.0);
    let mid = (lo + hi) / 2.0;
    let mut pts = Vec::new();
    let arc = |pts: &mut Vec<[f64; 2]>, centre: [f64; 2], from: f64| {
        let n = (r * std::f64::consts::FRAC_PI_2 / 0.25).ceil() as usize;
        for i in 0..n {
            let a = from + std::f64::consts::FRAC_PI_2 * i as f64 / n as f64;
            pts.push([centre[0] + r * a.cos(), centre[1] + r * a.sin()]);
        }
    };
    use std::f64::consts::{FRAC_PI_2, PI};
    straight(&mut pts, [mid, lo], [hi - r, lo]);
    arc(&mut pts, [hi - r, lo + r], -FRAC_PI_2);
    straight(&mut pts, [hi, lo + r], [hi, hi - r]);
    arc(&mut pts, [hi - r, hi - r], 0.0);
    straight(&mut pts, [hi - r, hi], [lo + r, hi]);
    arc(&mut pts, [lo + r, hi - r], FRAC_PI_2);
    straight(&mut pts, [lo, hi - r], [lo, lo + r]);
    arc(&mut pts, [lo + r, lo + r], PI);
    straight(&mut pts, [lo + r, lo], [mid, lo]);
    pts
}

/// A drive's path: `corners` (metres) joined by straights, each turn rounded with a 10 m
/// radius, as points about 0.25 m apart. Corners must turn by a right angle (or not at all).
pub fn path_through(corners: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let r = 10.0;
    let mut pts = Vec::new();
    let unit = |a: [f64; 2], b: [f64; 2]| {
        let l = (b[0] - a[0]).hypot(b[1] - a[1]).max(1e-9);
        [(b[0] - a[0]) / l, (b[1] - a[1]) / l]
    };
    let Some(&first) = corners.first() else {
        return pts;
    };
    let mut from = first;
    for w in corners.windows(3) {
        let (a, c, b) = (w[0], w[1], w[2]);
        let (din, dout) = (unit(a, c), unit(c, b));
        if din[0] * dout[0] + din[1] * dout[1] > 0.999 {
            continue;
        }
        let start = [c[0] - din[0] * r, c[1] - din[1] * r];
        straight(&mut pts, from, start);
        let centre = [start[0] + dout[0] * r, start[1] + dout[1] * r];
        let left = din[0] * dout[1] - din[1] * dout[0] > 0.0;
        let from_angle = (start[1] - centre[1]).atan2(start[0] - centre[0]);
        let sweep = if left { 1.0 } else { -1.0 } * std::f64::consts::FRAC_PI_2;
        let n = (r * std::f64::consts::FRAC_PI_2 / 0.25).ceil() as usize;
        for i in 0..n {
            let t = from_angle + sweep * i as f64 / n as f64;
            pts.push([centre[0] + r * t.cos(), centre[1] + r * t.sin()]);
        }
        from = [c[0] + dout[0] * r, c[1] + dout[1] * r];
    }
    if let Some(&last) = corners.last() {
        straight(&mut pts, from, last);
        pts.push(last);
    }
    pts
}

/// [`path_through`] corners in street units (street `k` runs along `k · PITCH_M`).
fn on_grid(corners: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let metres: Vec<[f64; 2]> = corners
        .iter()
        .map(|c| [c[0] * PITCH_M, c[1] * PITCH_M])
        .collect();
    path_through(&metres)
}

/// A campus drive of several loops through the town (about 2.2 km): once round the middle
/// blocks as [`route`] goes, then up the second street, back down the third, and across
/// the fourth, coming back to streets and crossings it has driven five more times.
pub fn campus_path() -> Vec<[f64; 2]> {
    on_grid(&[
        [2.5, 1.0],
        [4.0, 1.0],
        [4.0, 4.0],
        [1.0, 4.0],
        [1.0, 1.0],
        [2.0, 1.0],
        [2.0, 4.0],
        [3.0, 4.0],
        [3.0, 1.0],
        [4.0, 1.0],
        [4.0, 3.0],
        [1.0, 3.0],
    ])
}

/// One block round and 60 m on past the start (about 420 m): the shortest drive that
/// comes back to where it began.
pub fn block_path() -> Vec<[f64; 2]> {
    on_grid(&[
        [1.5, 1.0],
        [2.0, 1.0],
        [2.0, 2.0],
        [1.0, 2.0],
        [1.0, 1.0],
        [1.5 + 60.0 / PITCH_M, 1.0],
    ])
}

/// Sensor poses along `path` at 10 Hz over the scene's ground, as [`drive_poses`] drives
/// [`route`]: up to `frames` frames or the path's end.
pub fn drive_poses_along(scene: &Scene, path: Vec<[f64; 2]>, frames: usize) -> Vec<Pose> {
    poses_along(
        path,
        frames,
        |x, y| scene.ground_height(x, y),
        [0.5, 0.5],
        false,
    )
}

/// Sensor poses along [`route`] at 10 Hz: from standstill, accelerating at 2 m/s² to
/// 10 m/s on the straights and 5 m/s in the corners; up to `frames` frames or once round.
/// The sensor sits `SENSOR_HEIGHT_M` above the ground, level with it (pitch and roll follow
/// the slope).
pub fn drive_poses(scene: &Scene, frames: usize) -> Vec<Pose> {
    poses_along_route_with(frames, |x, y| scene.ground_height(x, y), [0.5, 0.5], false)
}

/// [`drive_poses`] going on round the loop past its start for as many frames as asked: a
/// drive that comes back to where it began and sees it again (for loop closure).
pub fn drive_poses_round(scene: &Scene, frames: usize) -> Vec<Pose> {
    poses_along_route_with(frames, |x, y| scene.ground_height(x, y), [0.5, 0.5], true)
}

/// [`drive_poses`] for a car body: its height, pitch and roll follow the hills only (the
/// suspension takes up the few centimetres of roughness), over a 2.7 m wheelbase and a 1.6 m
/// track. A smooth attitude, as a car's is, which a constant-velocity model predicts well.
pub fn car_poses(scene: &Scene, frames: usize) -> Vec<Pose> {
    let ground = scene.ground_z;
    match scene.terrain {
        Some(t) => {
            poses_along_route_with(frames, |x, y| ground + t.hills(x, y), [1.35, 0.8], false)
        }
        None => poses_along_route_with(frames, |_, _| ground, [1.35, 0.8], false),
    }
}

/// Poses along the route over the ground `h`, the pitch from `h` `half[0]` m ahead and behind,
/// the roll from `h` `half[1]` m to each side; once round, or on past the start with `round`.
fn poses_along_route_with(
    frames: usize,
    h: impl Fn(f64, f64) -> f64,
    half: [f64; 2],
    round: bool,
) -> Vec<Pose> {
    poses_along(route(), frames, h, half, round)
}

/// [`poses_along_route_with`] along any `path` (`round`: a closed one, driven on past its end).
fn poses_along(
    path: Vec<[f64; 2]>,
    frames: usize,
    h: impl Fn(f64, f64) -> f64,
    half: [f64; 2],
    round: bool,
) -> Vec<Pose> {
    let line = Polyline::new(path, round);
    let total = line.total();
    let at = |s: f64| line.at(s);
    // Curvature near s: heading change over the next 15 m.
    let cornering = |s: f64| {
        let (_, h0) = at(s);
        let (_, h1) = at(if round {
            s + 15.0
        } else {
            (s + 15.0).min(total)
        });
        let mut d = (h1 - h0).abs();
        if d > std::f64::consts::PI {
            d = std::f64::consts::TAU - d;
        }
        d > 0.2
    };
    let (mut s, mut v) = (0.0f64, 0.0f64);
    let mut poses = Vec::with_capacity(frames);
    while poses.len() < frames && (round || s < total) {
        let ([x, y], yaw) = at(s);
        let (c, sn) = (yaw.cos(), yaw.sin());
        let [e, w] = half;
        let slope_fwd = (h(x + e * c, y + e * sn) - h(x - e * c, y - e * sn)) / (2.0 * e);
        let slope_left = (h(x - w * sn, y + w * c) - h(x + w * sn, y - w * c)) / (2.0 * w);
        let rotation = UnitQuaternion::from_euler_angles(slope_left.atan(), -slope_fwd.atan(), yaw);
        poses.push(Pose::from_parts(
            Translation3::new(x, y, h(x, y) + SENSOR_HEIGHT_M),
            rotation,
        ));
        let target = if cornering(s) { 5.0 } else { 10.0 };
        v = if v < target {
            (v + 0.2).min(target)
        } else {
            (v - 0.3).max(target)
        };
        s += v * 0.1;
    }
    poses
}

/// A path as a curve by arc length: where along it, and which way it heads, `s` metres from
/// its start (a closed path wraps round; an open one is held at its ends).
#[derive(Debug, Clone)]
pub struct Polyline {
    path: Vec<[f64; 2]>,
    /// Arc length at each point of `path`.
    cum: Vec<f64>,
    closed: bool,
}

impl Polyline {
    /// `path` (at least two points) as a curve; `closed`: driven on past its end from its start.
    pub fn new(path: Vec<[f64; 2]>, closed: bool) -> Self {
        let mut cum = vec![0.0];
        for w in path.windows(2) {
            cum.push(cum[cum.len() - 1] + (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]));
        }
        Polyline { path, cum, closed }
    }

    /// Whether it wraps round.
    pub fn closed(&self) -> bool {
        self.closed
    }

    /// Its length (metres).
    pub fn total(&self) -> f64 {
        self.cum[self.cum.len() - 1]
    }

    /// The point `s` metres along and the heading there (radians).
    pub fn at(&self, s: f64) -> ([f64; 2], f64) {
        let (path, cum) = (&self.path, &self.cum);
        let s = if self.closed {
            s.rem_euclid(self.total())
        } else {
            s
        };
        let i = cum.partition_point(|&c| c <= s).clamp(1, path.len() - 1);
        let f = ((s - cum[i - 1]) / (cum[i] - cum[i - 1]).max(1e-9)).clamp(0.0, 1.0);
        let (a, b) = (path[i - 1], path[i]);
        (
            [a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])],
            (b[1] - a[1]).atan2(b[0] - a[0]),
        )
    }
}

/// How a hand-held rig or a drone moves along [`route`]: 2 scans a second, the walking or
/// flying speed, the height above the ground, and the swings of its heading, pitch and roll.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Carried {
    /// Speed along the route (m/s).
    pub speed_m_s: f64,
    /// Height above the ground (m).
    pub height_m: f64,
    /// Largest change of heading between two scans (degrees), drawn uniformly.
    pub max_turn_deg: f64,
    /// Largest departure of the heading from the route's direction (degrees).
    pub max_look_deg: f64,
    /// Amplitude of the pitch and roll swings (degrees).
    pub tilt_deg: f64,
}

impl Carried {
    /// A person walking with a hand-held scanner: 1.2 m/s, 1.5 m up, looking around (turns of
    /// up to 45 degrees between scans), tilting by up to 15 degrees.
    pub const HANDHELD: Carried = Carried {
        speed_m_s: 1.2,
        height_m: 1.5,
        max_turn_deg: 45.0,
        max_look_deg: 90.0,
        tilt_deg: 15.0,
    };
    /// A small drone: 1.5 m/s, 5 m up (2 m under a hall's roof), yawing by up to 45 degrees between scans, pitching and
    /// rolling by up to 15 degrees.
    pub const DRONE: Carried = Carried {
        speed_m_s: 1.5,
        height_m: 5.0,
        max_turn_deg: 45.0,
        max_look_deg: 120.0,
        tilt_deg: 15.0,
    };
}

/// An indoor hall over the start of [`route`], for the carried rigs: 30 m long, 12 m wide and
/// 7 m high, across the first street from 20 m after the route's start, with 4 m wide, 6 m
/// high doors in both end walls where the route passes (a hand-held rig is inside from about
/// its 33rd scan to its 83rd, a drone from its 27th to its 67th). The street's lights, cars and
/// shelters in it stand in as furniture. Not part of [`scene`]: the car drives keep the open
/// street.
pub fn hall(scene: &Scene) -> Vec<OrientedBox> {
    // The route starts mid-street at (2.5 pitches, 1 pitch), heading along +x.
    let (start, y) = (2.5 * PITCH_M, PITCH_M);
    let (x0, x1) = (start + 20.0, start + 50.0);
    let (half_width, height, door_half, door_height, wall) = (6.0, 7.0, 2.0, 6.0, 0.15);
    let base = scene.ground_height((x0 + x1) / 2.0, y) - 1.0;
    let top = base + 1.0 + height;
    let slab = |xa: f64, xb: f64, ya: f64, yb: f64, za: f64, zb: f64| OrientedBox {
        centre: [(xa + xb) / 2.0, (ya + yb) / 2.0, (za + zb) / 2.0],
        half: [(xb - xa) / 2.0, (yb - ya) / 2.0, (zb - za) / 2.0],
        yaw: 0.0,
    };
    let (ya, yb) = (y - half_width, y + half_width);
    let mut boxes = vec![
        // Side walls and the roof.
        slab(x0, x1, ya - wall, ya + wall, base, top),
        slab(x0, x1, yb - wall, yb + wall, base, top),
        slab(
            x0 - wall,
            x1 + wall,
            ya - wall,
            yb + wall,
            top,
            top + 2.0 * wall,
        ),
    ];
    for x in [x0, x1] {
        // An end wall either side of its door, and the lintel over it.
        boxes.push(slab(x - wall, x + wall, ya, y - door_half, base, top));
        boxes.push(slab(x - wall, x + wall, y + door_half, yb, base, top));
        let lintel = base + 1.0 + door_height;
        boxes.push(slab(
            x - wall,
            x + wall,
            y - door_half,
            y + door_half,
            lintel,
            top,
        ));
    }
    boxes
}

/// Scans a second of [`carried_poses`].
pub const CARRIED_HZ: f64 = 2.0;

/// Sensor poses of a rig carried along [`route`] at [`CARRIED_HZ`] (see [`Carried`]): the
/// heading follows the route plus a look-around offset that changes by a random amount up to
/// `max_turn_deg` each scan (kept within `max_look_deg`), and pitch and roll swing
/// sinusoidally; deterministic from `seed`.
pub fn carried_poses(scene: &Scene, frames: usize, how: Carried, seed: u64) -> Vec<Pose> {
    let line = Polyline::new(route(), false);
    let mut rng = SplitMix64(seed);
    let mut look = 0.0f64;
    (0..frames)
        .map(|k| {
            let s = (k as f64 * how.speed_m_s / CARRIED_HZ).min(line.total());
            let ([x, y], along) = line.at(s);
            if k > 0 {
                look = (look + rng.range(-how.max_turn_deg, how.max_turn_deg))
                    .clamp(-how.max_look_deg, how.max_look_deg);
            }
            let t = k as f64;
            let pitch = how.tilt_deg * (0.9 * t + 0.3).sin();
            let roll = how.tilt_deg * 0.8 * (1.3 * t).sin();
            let rotation = UnitQuaternion::from_euler_angles(
                roll.to_radians(),
                pitch.to_radians(),
                along + look.to_radians(),
            );
            let bob = 0.05 * (2.1 * t).sin();
            Pose::from_parts(
                Translation3::new(x, y, scene.ground_height(x, y) + how.height_m + bob),
                rotation,
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_loop_is_about_a_kilometre_and_the_drive_starts_from_standstill() {
        let r = route();
        let length: f64 = r
            .windows(2)
            .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
            .sum();
        assert!((1000.0..1100.0).contains(&length), "{length}");
        let s = scene(1);
        let poses = drive_poses(&s, 100_000);
        let steps: Vec<f64> = poses
            .windows(2)
            .map(|w| (w[1].translation.vector - w[0].translation.vector).norm())
            .collect();
        assert!(steps[0] < 0.03, "standstill start: {}", steps[0]);
        let fastest = steps.iter().copied().fold(0.0, f64::max);
        assert!(
            (0.95..1.05).contains(&fastest),
            "10 m/s at 10 Hz: {fastest}"
        );
        assert!(
            steps.iter().any(|&d| (0.45..0.55).contains(&d)),
            "slower in corners"
        );
        // The sensor stays above the ground, and scans are deterministic.
        for p in poses.iter().step_by(50) {
            let t = p.translation.vector;
            assert!((t.z - s.ground_height(t.x, t.y) - SENSOR_HEIGHT_M).abs() < 1e-9);
        }
        assert_eq!(scene(1), s);
    }

    #[test]
    fn the_hall_roofs_the_route_from_20_to_50_m_with_doors_at_both_ends() {
        let mut s = scene(1);
        s.boxes.extend(hall(&s));
        let poses = carried_poses(&s, 100, Carried::HANDHELD, 1);
        let up = nalgebra::Vector3::z();
        let roofed = |p: &Pose| s.cast(&p.translation.vector, &up, 20.0).is_some();
        let inside: Vec<usize> = (0..100).filter(|&k| roofed(&poses[k])).collect();
        // 0.6 m a scan from 2.5 pitches: inside from 20 m to 50 m along the route.
        assert_eq!(inside.first(), Some(&34), "{inside:?}");
        assert_eq!(inside.last(), Some(&83), "{inside:?}");
        assert_eq!(inside.len(), 50);
        // Through the door: nothing ahead of the route within a metre of the end wall, the
        // wall 3 m to either side.
        let at_door = poses[33].translation.vector;
        let east = nalgebra::Vector3::x();
        assert!(s.cast(&at_door, &east, 1.0).is_none());
        for side in [3.0, -3.0] {
            let beside = at_door + nalgebra::Vector3::y() * side;
            let d = s.cast(&beside, &east, 1.0);
            assert!(d.is_some(), "{side}: {d:?}");
        }
    }

    #[test]
    fn carried_rigs_turn_and_tilt_as_described() {
        let scene = scene(1);
        for how in [Carried::HANDHELD, Carried::DRONE] {
            let poses = carried_poses(&scene, 80, how, 3);
            let mut largest_turn = 0.0f64;
            for w in poses.windows(2) {
                let step = w[0].inverse() * w[1];
                let d = step.translation.vector.norm();
                // The speed along the route, a little more with the bob and the corners cut.
                assert!(d < how.speed_m_s / CARRIED_HZ + 0.15, "{d} m in one step");
                largest_turn = largest_turn.max(step.rotation.angle().to_degrees());
            }
            // Heading changes of up to max_turn_deg plus the swings of pitch and roll.
            assert!(
                largest_turn > 30.0 && largest_turn < 75.0,
                "{largest_turn} deg"
            );
            for p in &poses {
                let (roll, pitch, _) = p.rotation.euler_angles();
                assert!(roll.to_degrees().abs() <= how.tilt_deg + 1e-9);
                assert!(pitch.to_degrees().abs() <= how.tilt_deg + 1e-9);
                let t = p.translation.vector;
                let above = t.z - scene.ground_height(t.x, t.y);
                assert!((above - how.height_m).abs() <= 0.05 + 1e-9);
            }
        }
    }
}
