//! The simulated world: oriented boxes and spheres over a ground plane with optional relief,
//! and the ray casting that finds the nearest surface along a ray. Deterministic.

use nalgebra::Vector3;
use slamesh_core::random::SplitMix64;
use std::cell::Cell;

/// A box with a yaw about z: centre, half extents along its own axes, yaw in radians.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrientedBox {
    /// Centre (world, metres).
    pub centre: [f64; 3],
    /// Half extents along the box's x, y, z (metres).
    pub half: [f64; 3],
    /// Rotation about world z (radians).
    pub yaw: f64,
}

/// An axis-aligned box (no yaw) from its lowest and highest corners.
pub fn slab(lo: [f64; 3], hi: [f64; 3]) -> OrientedBox {
    OrientedBox {
        centre: [0, 1, 2].map(|k| (lo[k] + hi[k]) / 2.0),
        half: [0, 1, 2].map(|k| (hi[k] - lo[k]) / 2.0),
        yaw: 0.0,
    }
}

/// A sphere (tree crowns).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    /// Centre (world, metres).
    pub centre: [f64; 3],
    /// Radius (metres).
    pub radius: f64,
}

/// Ground relief on top of `ground_z`: gentle hills and a rough surface of a few centimetres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Terrain {
    /// Amplitude of the hills (metres).
    pub hill_m: f64,
    /// Wavelength of the hills (metres).
    pub hill_wavelength_m: f64,
    /// Amplitude of the roughness (metres), at wavelengths of 3 to 7 m.
    pub roughness_m: f64,
}

impl Terrain {
    /// Height above `ground_z` at `(x, y)`.
    pub fn height(&self, x: f64, y: f64) -> f64 {
        self.hills(x, y) + self.rough(x, y)
    }

    /// The hills alone: what a car body follows, its suspension taking up the roughness.
    pub fn hills(&self, x: f64, y: f64) -> f64 {
        let k = std::f64::consts::TAU / self.hill_wavelength_m;
        self.hill_m * (k * x).sin() * (0.8 * k * y + 0.5).cos()
    }

    /// The roughness alone.
    fn rough(&self, x: f64, y: f64) -> f64 {
        self.roughness_m
            * (0.5 * (1.3 * x + 0.4 * y).sin()
                + 0.3 * (0.9 * y - 1.7).sin()
                + 0.2 * (2.0 * x - 1.1 * y + 0.7).sin())
    }

    /// A lower bound on the height [`height`](Self::height) gives: the hills' and the
    /// roughness's amplitudes below zero.
    pub fn lowest(&self) -> f64 {
        -self.hill_m.abs() - self.roughness_m.abs()
    }

    /// An upper bound on the slope `|∇h|`.
    pub fn max_slope(&self) -> f64 {
        let k = std::f64::consts::TAU / self.hill_wavelength_m;
        self.hill_m * k * 1.3 + self.roughness_m * (0.5 * 1.37 + 0.3 * 0.9 + 0.2 * 2.3)
    }
}

/// A world of boxes and spheres over the ground `z = ground_z (+ terrain)`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Scene {
    /// Height of the ground plane.
    pub ground_z: f64,
    /// Relief on the ground plane, if any.
    pub terrain: Option<Terrain>,
    /// Walls, buildings, boxes, poles.
    pub boxes: Vec<OrientedBox>,
    /// Tree crowns.
    pub spheres: Vec<Sphere>,
}

impl Scene {
    /// A structured street corner: ground, facades in three directions, boxes (parked cars,
    /// kiosks) and poles; well constrained in all six degrees of freedom.
    pub fn street() -> Self {
        let b = |c: [f64; 3], h: [f64; 3], yaw: f64| OrientedBox {
            centre: c,
            half: h,
            yaw,
        };
        Scene {
            ground_z: 0.0,
            terrain: None,
            spheres: Vec::new(),
            boxes: vec![
                b([0.0, 14.0, 5.0], [30.0, 0.5, 5.0], 0.0), // facade north
                b([0.0, -12.0, 4.0], [30.0, 0.5, 4.0], 0.0), // facade south
                b([32.0, 0.0, 6.0], [0.5, 14.0, 6.0], 0.0), // facade east, end of street
                b([-20.0, 6.0, 3.0], [4.0, 3.0, 3.0], 0.5), // a rotated building
                b([8.0, 8.0, 0.8], [2.2, 0.9, 0.8], 0.0),   // parked car
                b([16.0, -7.0, 0.8], [2.2, 0.9, 0.8], 0.1), // parked car
                b([-6.0, -6.5, 1.2], [1.5, 1.5, 1.2], 0.8), // kiosk
                b([4.0, -3.5, 2.5], [0.12, 0.12, 2.5], 0.0), // pole
                b([12.0, 3.5, 2.5], [0.12, 0.12, 2.5], 0.0), // pole
                b([22.0, 9.0, 1.0], [3.0, 3.0, 1.0], -0.3), // low block
            ],
        }
    }

    /// The range along the unit ray `origin + s·dir` to the nearest surface, up to `max_range`.
    pub fn cast(&self, origin: &Vector3<f64>, dir: &Vector3<f64>, max_range: f64) -> Option<f64> {
        Prepared::new(self, origin, f64::INFINITY, 0.0).cast(origin, dir, max_range)
    }

    /// A long straight street along +x from `x = 0` to `length_m`, deterministic from `seed`:
    /// facades of varying height, depth and setback with gaps (side streets), parked cars,
    /// poles and kiosks on both sides, a wall at each end. For long runs (memory, eviction).
    pub fn long_street(length_m: f64, seed: u64) -> Self {
        let mut rng = SplitMix64(seed);
        let mut boxes = Vec::new();
        let b = |c: [f64; 3], h: [f64; 3], yaw: f64| OrientedBox {
            centre: c,
            half: h,
            yaw,
        };
        for side in [-1.0, 1.0] {
            let mut x = -20.0;
            while x < length_m + 20.0 {
                let w = rng.range(8.0, 30.0);
                if rng.next_f64() > 0.15 {
                    let (setback, height) = (rng.range(9.0, 13.0), rng.range(4.0, 18.0));
                    let yaw = rng.range(-0.05, 0.05);
                    boxes.push(b(
                        [x + w / 2.0, side * (setback + 4.0), height / 2.0],
                        [w / 2.0, 4.0, height / 2.0],
                        yaw,
                    ));
                }
                x += w + rng.range(0.0, 3.0);
            }
            let mut x = 0.0;
            while x < length_m {
                x += rng.range(4.0, 14.0);
                let y = side * rng.range(4.5, 7.0);
                match rng.next_f64() {
                    f if f < 0.5 => {
                        boxes.push(b([x, y, 0.75], [2.2, 0.9, 0.75], rng.range(-0.1, 0.1)))
                    }
                    f if f < 0.8 => boxes.push(b([x, y, 2.5], [0.12, 0.12, 2.5], 0.0)),
                    _ => boxes.push(b([x, y, 1.2], [1.2, 1.2, 1.2], rng.range(0.0, 1.5))),
                }
            }
        }
        boxes.push(b([-25.0, 0.0, 6.0], [0.5, 20.0, 6.0], 0.0));
        boxes.push(b([length_m + 25.0, 0.0, 6.0], [0.5, 20.0, 6.0], 0.0));
        Scene {
            ground_z: 0.0,
            boxes,
            ..Scene::default()
        }
    }

    /// Two look-alike streets `gap_m` apart: [`Scene::long_street`]'s buildings, cars, poles
    /// and shelters along `y = 0`, and the very same again along `y = gap_m`, with no end
    /// walls (a car drives from one to the other round the ends). Standing in one, a scan
    /// looks exactly as in the other.
    pub fn twin_streets(length_m: f64, gap_m: f64, seed: u64) -> Self {
        let mut one = Self::long_street(length_m, seed);
        // The two end walls are the last boxes.
        one.boxes.truncate(one.boxes.len().saturating_sub(2));
        let copy: Vec<OrientedBox> = one
            .boxes
            .iter()
            .map(|b| OrientedBox {
                centre: [b.centre[0], b.centre[1] + gap_m, b.centre[2]],
                ..*b
            })
            .collect();
        one.boxes.extend(copy);
        one
    }

    /// Ground height at `(x, y)`.
    pub fn ground_height(&self, x: f64, y: f64) -> f64 {
        self.ground_z + self.terrain.map_or(0.0, |t| t.height(x, y))
    }
}

/// Azimuth sectors of a [`Prepared`] scene.
const SECTORS: usize = 720;

/// The azimuth sector a ray along `dir` lies in.
fn sector_of(dir: &Vector3<f64>) -> usize {
    let per = std::f64::consts::TAU / SECTORS as f64;
    ((dir.y.atan2(dir.x) / per).floor() as i64).rem_euclid(SECTORS as i64) as usize
}

/// A scene made ready for many rays from one place: objects out of reach dropped, box
/// rotations computed once, and each object listed in the azimuth sectors it covers as seen
/// from the origin, nearest first, so that a ray tests only the objects of its sector and
/// stops at the first that cannot come nearer than what it hit. The ground, whose terrain
/// costs most (a few dozen sines a ray), is traced last and only up to that hit. Each ray's
/// range is the same as testing everything: the nearest hit is one number whatever the order.
///
/// The sectors are drawn from the origin given, so a ray cast from where a rolling sweep has
/// moved to tests the objects its direction's sector lists from there, and may miss one close
/// by at a sector's edge (one or two rays in a thousand on a street with the origin moved up
/// to 0.8 m). Left so: the sweeps stay the scans every figure was measured on.
pub(crate) struct Prepared {
    ground_z: f64,
    terrain: Option<Terrain>,
    /// Centre, half extents, cos and sin of `-yaw`.
    boxes: Vec<([f64; 3], [f64; 3], f64, f64)>,
    spheres: Vec<Sphere>,
    /// Per prepared box, its index in the scene's boxes.
    box_index: Vec<u32>,
    /// Per object (boxes first, then spheres): a range along any ray from within `travel` of
    /// the origin short of which the ray cannot meet it.
    nearest: Vec<f64>,
    /// Per sector, object ids (boxes first, then spheres), by `nearest`.
    sectors: Vec<Vec<u32>>,
    /// The last origin traced from and the terrain's height under it: a scan's rays (a
    /// rolling sweep's firing's) share their origin, and so the tracing's first step.
    under_origin: Cell<([f64; 2], f64)>,
}

/// The object id [`Prepared::cast_object`] gives the ground.
const GROUND: u32 = u32::MAX;

/// The clearance over the terrain at which sphere tracing calls it met (m).
const CONTACT_CLEARANCE_M: f64 = 1e-4;

/// How far short of an object's `nearest` range a ray's hit on it may fall through rounding
/// (m): far more than the rounding of ranges within a few kilometres.
const NEAREST_SLACK_M: f64 = 1e-6;

impl Prepared {
    /// The objects of `scene` that can be hit within `reach` of `origin` by rays cast from
    /// within `travel` of it (a rolling sweep's origin moves; `reach` counts the move).
    pub(crate) fn new(scene: &Scene, origin: &Vector3<f64>, reach: f64, travel: f64) -> Self {
        let mut sectors = vec![Vec::new(); SECTORS];
        let mut list = |id: u32, centre: [f64; 3], radius_xy: f64| {
            let (dx, dy) = (centre[0] - origin.x, centre[1] - origin.y);
            let d = dx.hypot(dy);
            if d <= radius_xy + 0.5 {
                sectors.iter_mut().for_each(|s| s.push(id));
                return;
            }
            let width =
                (radius_xy / d).min(1.0).asin() + 2.0 * std::f64::consts::TAU / SECTORS as f64;
            let centre_angle = dy.atan2(dx);
            let per = std::f64::consts::TAU / SECTORS as f64;
            let (lo, hi) = (
                ((centre_angle - width) / per).floor() as i64,
                ((centre_angle + width) / per).ceil() as i64,
            );
            for k in lo..=hi {
                sectors[k.rem_euclid(SECTORS as i64) as usize].push(id);
            }
        };
        let mut boxes = Vec::new();
        let mut box_index = Vec::new();
        // Every point of an object lies within its bounding radius `r` of its centre, `d` away.
        let mut nearest = Vec::new();
        let nearest_of = |d: f64, r: f64| d - r - travel - NEAREST_SLACK_M;
        for (index, b) in scene.boxes.iter().enumerate() {
            let r = Vector3::from(b.half).norm();
            let d = (Vector3::from(b.centre) - origin).norm();
            if d > reach + r {
                continue;
            }
            nearest.push(nearest_of(d, r));
            list(boxes.len() as u32, b.centre, b.half[0].hypot(b.half[1]));
            let (s, c) = (-b.yaw).sin_cos();
            boxes.push((b.centre, b.half, c, s));
            box_index.push(index as u32);
        }
        let mut spheres = Vec::new();
        for sp in &scene.spheres {
            let d = (Vector3::from(sp.centre) - origin).norm();
            if d > reach + sp.radius {
                continue;
            }
            nearest.push(nearest_of(d, sp.radius));
            list((boxes.len() + spheres.len()) as u32, sp.centre, sp.radius);
            spheres.push(*sp);
        }
        for sector in &mut sectors {
            sector.sort_by(|&a, &b| nearest[a as usize].total_cmp(&nearest[b as usize]));
        }
        Prepared {
            ground_z: scene.ground_z,
            terrain: scene.terrain,
            boxes,
            spheres,
            box_index,
            nearest,
            sectors,
            under_origin: Cell::new(([f64::NAN; 2], 0.0)),
        }
    }

    /// Range to the ground along the ray, if it meets it before `max_range`.
    fn ground(&self, o: &Vector3<f64>, d: &Vector3<f64>, max_range: f64) -> Option<f64> {
        let Some(t) = self.terrain else {
            let s = (self.ground_z - o.z) / d.z;
            return (d.z < -1e-9 && s > 0.0 && s < max_range).then_some(s);
        };
        // Sphere tracing on the height field: steps as long as the clearance over the terrain
        // divided by the fastest rate it can shrink at, until it is under
        // `CONTACT_CLEARANCE_M` (a hit), `max_range` is passed or 200 steps are taken (none).
        let horizontal = d.x.hypot(d.y);
        let rate = -d.z + t.max_slope() * horizontal;
        if rate <= 1e-9 {
            return None;
        }
        let clearance =
            |s: f64| o.z + s * d.z - self.ground_z - t.height(o.x + s * d.x, o.y + s * d.y);
        // At the first step (s = 0) the height is the one under the origin: `o.x + 0 * d.x`
        // is `o.x` for any finite direction.
        let (last, under) = self.under_origin.get();
        let under = if last == [o.x, o.y] {
            under
        } else {
            let h = t.height(o.x, o.y);
            self.under_origin.set(([o.x, o.y], h));
            h
        };
        let mut c = o.z - self.ground_z - under;
        let mut s = 0.0;
        for _ in 0..200 {
            if c < CONTACT_CLEARANCE_M {
                return (s > 0.0).then_some(s);
            }
            s += c / rate;
            if s >= max_range {
                return None;
            }
            c = clearance(s);
        }
        None
    }

    pub(crate) fn cast(
        &self,
        origin: &Vector3<f64>,
        dir: &Vector3<f64>,
        max_range: f64,
    ) -> Option<f64> {
        self.cast_to(origin, dir, max_range).map(|(range, _)| range)
    }

    /// [`cast`](Self::cast) with what the ray met: the index of the scene's box, or `None`
    /// for the ground or a sphere.
    pub(crate) fn cast_to(
        &self,
        origin: &Vector3<f64>,
        dir: &Vector3<f64>,
        max_range: f64,
    ) -> Option<(f64, Option<usize>)> {
        self.cast_object(origin, dir, max_range).map(|(range, id)| {
            let scene_box = self.box_index.get(id as usize).map(|&b| b as usize);
            (range, scene_box)
        })
    }

    /// The range and the object the ray met ([`GROUND`] for the ground).
    fn cast_object(
        &self,
        origin: &Vector3<f64>,
        dir: &Vector3<f64>,
        max_range: f64,
    ) -> Option<(f64, u32)> {
        let objects = &self.sectors[sector_of(dir)];
        let (mut best, mut hit) = (max_range, None);
        let Some(t) = self.terrain else {
            // Flat ground: one division, so first, and the objects only nearer than it.
            if let Some(s) = self.ground(origin, dir, best) {
                (best, hit) = (s, Some(GROUND));
            }
            self.hit_objects(objects, origin, dir, f64::INFINITY, &mut best, &mut hit);
            return hit.map(|id| (best, id));
        };
        // Terrain costs a few dozen sines a ray to trace, so the objects first, those short of
        // where a falling ray has sunk below the terrain's lowest point (it has met the
        // ground by then), and the ground traced only up to the nearest of them.
        let lowest = self.ground_z + t.lowest();
        let sunk = if dir.z < 0.0 {
            (origin.z - lowest) / -dir.z
        } else {
            f64::INFINITY
        };
        let stopped = self.hit_objects(objects, origin, dir, sunk, &mut best, &mut hit);
        match self.ground(origin, dir, best) {
            Some(s) => (best, hit) = (s, Some(GROUND)),
            // The tracing gave up (it stops after 200 steps): the objects past the bound too.
            None => {
                self.hit_objects(
                    &objects[stopped..],
                    origin,
                    dir,
                    f64::INFINITY,
                    &mut best,
                    &mut hit,
                );
            }
        }
        hit.map(|id| (best, id))
    }

    /// Tests the objects `ids` (nearest first) in turn, keeping in `best` the nearest hit
    /// short of it, until one's `nearest` range reaches `best` or `bound`; where it stopped.
    fn hit_objects(
        &self,
        ids: &[u32],
        origin: &Vector3<f64>,
        dir: &Vector3<f64>,
        bound: f64,
        best: &mut f64,
        hit: &mut Option<u32>,
    ) -> usize {
        for (k, &id) in ids.iter().enumerate() {
            let id = id as usize;
            if self.nearest[id] >= best.min(bound) {
                // Nor can any after it come nearer.
                return k;
            }
            let s = match self.boxes.get(id) {
                Some(b) => hit_box(b, origin, dir),
                None => self
                    .spheres
                    .get(id - self.boxes.len())
                    .and_then(|sp| hit_sphere(sp, origin, dir)),
            };
            if let Some(s) = s.filter(|&s| s < *best) {
                (*best, *hit) = (s, Some(id as u32));
            }
        }
        ids.len()
    }
}

/// Entry range of the ray into a prepared box (slab test in the box's frame).
fn hit_box(
    b: &([f64; 3], [f64; 3], f64, f64),
    origin: &Vector3<f64>,
    dir: &Vector3<f64>,
) -> Option<f64> {
    let (centre, half, c, s) = b;
    let (ox, oy) = (origin.x - centre[0], origin.y - centre[1]);
    let o = [c * ox - s * oy, s * ox + c * oy, origin.z - centre[2]];
    let d = [c * dir.x - s * dir.y, s * dir.x + c * dir.y, dir.z];
    let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
    for k in 0..3 {
        if d[k].abs() < 1e-12 {
            if o[k].abs() > half[k] {
                return None;
            }
            continue;
        }
        let (s0, s1) = ((-half[k] - o[k]) / d[k], (half[k] - o[k]) / d[k]);
        lo = lo.max(s0.min(s1));
        hi = hi.min(s0.max(s1));
    }
    (lo <= hi && lo > 0.0).then_some(lo)
}

/// Entry range of the unit ray into a sphere.
fn hit_sphere(sp: &Sphere, origin: &Vector3<f64>, dir: &Vector3<f64>) -> Option<f64> {
    let oc = origin - Vector3::from(sp.centre);
    let b = oc.dot(dir);
    let disc = b * b - (oc.norm_squared() - sp.radius * sp.radius);
    if disc < 0.0 {
        return None;
    }
    let s = -b - disc.sqrt();
    (s > 0.0).then_some(s)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit direction whose horizontal parts are drawn from -1 to 1 and vertical part
    /// from `down` to `up`, before scaling.
    fn random_direction(rng: &mut SplitMix64, down: f64, up: f64) -> Vector3<f64> {
        Vector3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(down, up),
        )
        .normalize()
    }

    #[test]
    fn rays_hit_ground_and_boxes_at_the_right_range() {
        let scene = Scene {
            ground_z: 0.0,
            terrain: None,
            spheres: Vec::new(),
            boxes: vec![OrientedBox {
                centre: [10.0, 0.0, 1.0],
                half: [1.0, 5.0, 1.0],
                yaw: 0.0,
            }],
        };
        let o = Vector3::new(0.0, 0.0, 1.0);
        assert!((scene.cast(&o, &Vector3::x(), 100.0).unwrap() - 9.0).abs() < 1e-12);
        let down = Vector3::new(1.0, 0.0, -1.0).normalize();
        assert!((scene.cast(&o, &down, 100.0).unwrap() - 2f64.sqrt()).abs() < 1e-12);
        assert!(scene.cast(&o, &Vector3::z(), 100.0).is_none());
        // Turned by 90 degrees, the 5 m half extent lies along x: the face is at x = 5.
        let mut turned = scene.clone();
        turned.boxes[0].yaw = std::f64::consts::FRAC_PI_2;
        assert!((turned.cast(&o, &Vector3::x(), 100.0).unwrap() - 5.0).abs() < 1e-9);
    }

    /// Sectors, the objects nearest first and the ground last (over terrain) find the very
    /// range that testing every object and the ground finds, over flat ground and terrain; and
    /// from an origin that has moved (a rolling sweep's), what testing every object of the
    /// ray's sector finds (the sectors are drawn from where the sweep began).
    #[test]
    fn sector_culling_finds_what_testing_every_object_finds() {
        let mut scene = Scene::long_street(120.0, 3);
        scene.spheres = vec![
            Sphere {
                centre: [10.0, 3.0, 4.0],
                radius: 2.0,
            },
            Sphere {
                centre: [0.5, 0.2, 1.7],
                radius: 0.6,
            },
        ];
        let hills = |hill_m, hill_wavelength_m| Terrain {
            hill_m,
            hill_wavelength_m,
            roughness_m: 0.03,
        };
        let start = Vector3::new(20.0, 0.5, 1.7);
        let travel = 2.0;
        for terrain in [Some(hills(1.0, 150.0)), Some(hills(3.0, 40.0)), None] {
            scene.terrain = terrain;
            let prepared = Prepared::new(&scene, &start, 80.0 + travel, travel);
            let mut rng = SplitMix64(1);
            for k in 0..20_000 {
                let dir = random_direction(&mut rng, -0.3, 0.1);
                // Every other ray from where the sweep has moved to.
                let origin = match k % 2 {
                    0 => start,
                    _ => start + Vector3::new(-1.2, 1.5, 0.3) * rng.next_f64(),
                };
                let culled = prepared.cast(&origin, &dir, 80.0);
                // Every object (of the ray's sector from a moved origin), in any order.
                let sector = &prepared.sectors[sector_of(&dir)];
                let listed = |id: usize| k % 2 == 0 || sector.contains(&(id as u32));
                let mut best = prepared.ground(&origin, &dir, 80.0);
                let boxes = prepared.boxes.iter().map(|b| hit_box(b, &origin, &dir));
                let spheres = prepared
                    .spheres
                    .iter()
                    .map(|sp| hit_sphere(sp, &origin, &dir));
                for (id, hit) in boxes.chain(spheres).enumerate() {
                    if let Some(s) = hit.filter(|_| listed(id)) {
                        best = Some(best.map_or(s, |x: f64| x.min(s))).filter(|&x| x < 80.0);
                    }
                }
                assert_eq!(culled, best, "ray {dir:?} from {origin:?}, {terrain:?}");
            }
        }
    }

    #[test]
    fn the_height_kept_under_the_origin_is_the_one_under_each_ray_s_origin() {
        let mut scene = Scene::long_street(120.0, 3);
        scene.terrain = Some(Terrain {
            hill_m: 1.0,
            hill_wavelength_m: 60.0,
            roughness_m: 0.03,
        });
        let start = Vector3::new(20.0, 0.5, 1.7);
        let kept = Prepared::new(&scene, &start, 102.0, 2.0);
        let mut rng = SplitMix64(7);
        let mut hits = 0;
        for k in 0..2_000 {
            let dir = random_direction(&mut rng, -0.4, 0.1);
            // Runs of rays from one origin, then from another, as a rolling sweep's firings.
            let origin = start + Vector3::new(-1.2, 1.5, 0.3) * ((k / 8) % 5) as f64 * 0.25;
            let fresh = Prepared::new(&scene, &start, 102.0, 2.0);
            let ground = kept.ground(&origin, &dir, 100.0);
            assert_eq!(ground, fresh.ground(&origin, &dir, 100.0), "ray {k}");
            hits += usize::from(ground.is_some());
        }
        // Both kinds of ray were met: the ground's hits and misses.
        assert!((200..1_800).contains(&hits), "{hits}");
    }

    #[test]
    fn rays_meet_spheres_and_the_terrain_on_their_surfaces() {
        let t = Terrain {
            hill_m: 2.0,
            hill_wavelength_m: 120.0,
            roughness_m: 0.03,
        };
        let scene = Scene {
            terrain: Some(t),
            spheres: vec![Sphere {
                centre: [30.0, 0.0, 5.0],
                radius: 2.0,
            }],
            ..Scene::default()
        };
        let o = Vector3::new(0.0, 0.0, 5.0);
        assert!((scene.cast(&o, &Vector3::x(), 100.0).unwrap() - 28.0).abs() < 1e-9);
        let mut rng = SplitMix64(2);
        for _ in 0..2_000 {
            let dir = Vector3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, -0.05),
            )
            .normalize();
            if let Some(s) = scene.cast(&o, &dir, 200.0) {
                let p = o + dir * s;
                if (p - Vector3::new(30.0, 0.0, 5.0)).norm() > 2.0 + 1e-6 {
                    assert!((p.z - scene.ground_height(p.x, p.y)).abs() < 2e-4, "{p:?}");
                }
            }
        }
    }
}
