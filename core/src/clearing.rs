//! Free space seen through the map: what moved away is taken out of it (docs/design.md §1.21).
//!
//! A scan's rays tell where space is empty: everything along a ray short of its return. A map
//! vertex the current scan's rays pass well beyond, all around it, is a surface that is no
//! longer there (a car that drove on, a person who walked past, a parked car that left), or
//! was never there. Each such sight raises the vertex's variance by a step, so a surface seen
//! through [`ClearingConfig::sightings`] times is hidden from the mesh and then forgotten
//! (variance infinite); a surface that is there is seen again and fused anew, as a vertex
//! of a high variance is replaced by the next observation ([`crate::fusion`]).
//!
//! The rays are the scan's kept points in a [`RangeImage`]: the nearest return in each bin of
//! a fixed grid of azimuth and elevation, the caller's memory ([`RangeImage::BINS`] ranges).
//! A vertex is seen through when every return in the 3 x 3 bins around its direction lies
//! farther than it by a margin: a surface's own edge, or anything in front of it, keeps it.
//!
//! Serial and in the map's own order: the same map whatever the thread count. No allocation.

use crate::bounded::BoundedVec;
use crate::cell::{Axis, CellKey};
use crate::lattice::{N, VERTICES};
use crate::layer::Layer;
use crate::map::MeshMap;
use crate::math::{Point, Pose, Vec3};

/// Azimuth bins of a [`RangeImage`]: equal steps of the diamond angle ([`diamond_angle`]),
/// 0.64 degrees along the axes to 1.27 on the diagonals.
const AZIMUTH_BINS: usize = 360;
/// Elevation bins of a [`RangeImage`]: equal steps of the elevation's tangent from
/// `-ELEVATION_TAN` to `+ELEVATION_TAN`, 1.1 degrees at the horizon and 0.8 at the ends.
const ELEVATION_BINS: usize = 64;
/// The tangent of the highest elevation a [`RangeImage`] holds (32 degrees); as low below.
const ELEVATION_TAN: f32 = 0.625;

/// An angle's stand-in that grows with it (from 0 to 4 round the turn, from +x towards +y)
/// and costs a division, where `atan2` costs tens of operations: bins of equal steps of it
/// are twice as wide at the diagonals as along the axes.
fn diamond_angle(x: f32, y: f32) -> f32 {
    let (ax, ay) = (libm::fabsf(x), libm::fabsf(y));
    let sum = ax + ay;
    match (y >= 0.0, x >= 0.0) {
        (true, true) => y / sum,
        (true, false) => 1.0 + ax / sum,
        (false, false) => 2.0 + ay / sum,
        (false, true) => 3.0 + x / sum,
    }
}

/// How the map is cleared of what the rays see through.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ClearingConfig {
    /// Vertices farther than this from the sensor are left alone (metres): past it a bin is
    /// wide and the kept points sparse. 80 m left 420 m² of ghost area where 30 m left 488
    /// on the simulated town with movers (every vertex, every frame: docs/journal.md).
    pub max_range_m: f32,
    /// Vertices nearer than this are left alone (metres).
    pub min_range_m: f32,
    /// How far past a vertex every return around it must lie (metres), plus
    /// `margin_ratio` of its range.
    pub margin_m: f32,
    /// The part of the margin that grows with range.
    pub margin_ratio: f32,
    /// Sightings that hide a vertex: each adds `variance_show / sightings` to its variance.
    pub sightings: u8,
}

impl Default for ClearingConfig {
    fn default() -> Self {
        Self {
            max_range_m: 80.0,
            min_range_m: 1.0,
            margin_m: 0.3,
            margin_ratio: 0.03,
            sightings: 3,
        }
    }
}

/// What one clearing did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ClearingStats {
    /// Vertices seen through (their variance raised).
    pub seen_through: u32,
    /// Of them, vertices forgotten (variance made infinite).
    pub forgotten: u32,
}

/// The nearest return in each bin of azimuth and elevation of one scan, in its sensor frame.
#[derive(Debug)]
#[cfg_attr(feature = "alloc", derive(Clone))]
pub struct RangeImage {
    /// Per bin (elevation-major), the nearest range; infinite where no ray returned.
    near: BoundedVec<f32>,
}

impl RangeImage {
    /// The ranges an image holds.
    pub const BINS: usize = AZIMUTH_BINS * ELEVATION_BINS;

    /// An image from the global allocator.
    #[cfg(any(feature = "alloc", test))]
    pub fn new() -> Self {
        Self {
            near: BoundedVec::filled(Self::BINS, f32::INFINITY),
        }
    }

    /// An image in the caller's `slots` (at least [`Self::BINS`]); `None` when shorter.
    pub fn in_slice(slots: &'static mut [f32]) -> Option<Self> {
        let slots = slots.get_mut(..Self::BINS)?;
        Some(Self {
            near: BoundedVec::in_slice_filled(slots, f32::INFINITY),
        })
    }

    /// The bin of the direction `p` (sensor frame) and its range; `None` outside the
    /// elevations held, at the origin or for a non-finite point.
    fn bin([x, y, z]: [f32; 3]) -> Option<(usize, usize, f32)> {
        let flat_sq = x * x + y * y;
        let flat = libm::sqrtf(flat_sq);
        let range = libm::sqrtf(flat_sq + z * z);
        if !(flat > 0.0 && range.is_finite()) {
            return None;
        }
        let turn = diamond_angle(x, y) * (AZIMUTH_BINS as f32 / 4.0);
        let rise = (z / flat + ELEVATION_TAN) * (ELEVATION_BINS as f32 / (2.0 * ELEVATION_TAN));
        if !(0.0..ELEVATION_BINS as f32).contains(&rise) {
            return None;
        }
        let a = (turn as usize).min(AZIMUTH_BINS - 1);
        Some((a, rise as usize, range))
    }

    /// Fills the image with `points` (sensor frame), then keeps in each bin the nearest
    /// return of the 3 x 3 bins around it (azimuth wraps round; empty bins count for
    /// nothing).
    pub fn fill(&mut self, points: &[Point]) {
        self.near.iter_mut().for_each(|r| *r = f32::INFINITY);
        for p in points {
            if let Some((a, e, range)) = Self::bin(*p) {
                if let Some(r) = self.near.get_mut(e * AZIMUTH_BINS + a) {
                    *r = r.min(range);
                }
            }
        }
        self.spread_along_rows();
        self.spread_across_rows();
    }

    /// Each bin the nearest of itself and its two neighbours in azimuth (wrapping round).
    fn spread_along_rows(&mut self) {
        for row in self.near.chunks_mut(AZIMUTH_BINS) {
            let (first, last) = (row[0], row[AZIMUTH_BINS - 1]);
            let mut before = last;
            for a in 0..AZIMUTH_BINS {
                let here = row[a];
                let after = if a + 1 < AZIMUTH_BINS {
                    row[a + 1]
                } else {
                    first
                };
                row[a] = here.min(before).min(after);
                before = here;
            }
        }
    }

    /// Each bin the nearest of itself and the bins above and below it.
    fn spread_across_rows(&mut self) {
        let mut before = [f32::INFINITY; AZIMUTH_BINS];
        for e in 0..ELEVATION_BINS {
            let start = e * AZIMUTH_BINS;
            for (a, below) in before.iter_mut().enumerate() {
                let here = self.near[start + a];
                let after = self
                    .near
                    .get(start + AZIMUTH_BINS + a)
                    .copied()
                    .unwrap_or(f32::INFINITY);
                self.near[start + a] = here.min(*below).min(after);
                *below = here;
            }
        }
    }

    /// The nearest return around the direction of `p` (sensor frame) and `p`'s range, when
    /// a return lies around it.
    fn around(&self, p: [f32; 3]) -> Option<(f32, f32)> {
        let (a, e, range) = Self::bin(p)?;
        let near = *self.near.get(e * AZIMUTH_BINS + a)?;
        near.is_finite().then_some((near, range))
    }
}

#[cfg(any(feature = "alloc", test))]
impl Default for RangeImage {
    fn default() -> Self {
        Self::new()
    }
}

/// One scan's view for clearing: its range image and where it was taken, in the form the
/// vertex test wants.
struct Sight<'a> {
    image: &'a RangeImage,
    cfg: &'a ClearingConfig,
    to_sensor: Pose,
    /// The world's axes in the sensor frame, in `f32`: a vertex's place in the sensor frame is
    /// its cell's corner's plus three steps along them (metres from the sensor).
    axes: [nalgebra::Vector3<f32>; 3],
    /// The lattice's coordinates, in `f32`.
    steps: [f32; N],
    cell_size: f64,
    /// What a sighting adds to a vertex's variance, and the variance that hides it.
    step: f32,
    variance_show: f32,
}

impl<'a> Sight<'a> {
    fn new(
        image: &'a RangeImage,
        t_world_sensor: &Pose,
        lattice: &crate::lattice::LatticeTable,
        variance_show: f32,
        cfg: &'a ClearingConfig,
    ) -> Self {
        let to_sensor = t_world_sensor.inverse();
        let axes = Axis::ALL.map(|a| {
            let mut unit = Vec3::zeros();
            unit[a.index()] = 1.0;
            (to_sensor.rotation * unit).map(|c| c as f32)
        });
        Self {
            image,
            cfg,
            to_sensor,
            axes,
            steps: lattice.coordinates.map(|c| c as f32),
            cell_size: lattice.cell_size,
            step: variance_show / f32::from(cfg.sightings.max(1)),
            variance_show,
        }
    }

    /// Raises the variance of each vertex of `layer` (cell `key`, along `axis`) the scan sees
    /// through, its [`PROBES`] first: a layer none of them is seen through is left (most are).
    fn clear_layer(&self, key: &CellKey, axis: Axis, layer: &mut Layer, stats: &mut ClearingStats) {
        let corner = key.min_corner(self.cell_size);
        let corner = (self.to_sensor * nalgebra::Point3::from(corner))
            .coords
            .map(|c| c as f32);
        let (a, b) = axis.locations();
        let (along_a, along_b, up) = (self.axes[a], self.axes[b], self.axes[axis.index()]);
        let cfg = self.cfg;
        let mut seen = |j: usize, layer: &mut Layer| {
            let var = layer.var[j];
            if !var.is_finite() {
                return false;
            }
            let local = corner
                + along_a * self.steps[j / N]
                + along_b * self.steps[j % N]
                + up * layer.pred[j];
            let Some((near, range)) = self.image.around([local.x, local.y, local.z]) else {
                return false;
            };
            if !(cfg.min_range_m..=cfg.max_range_m).contains(&range)
                || near <= range + cfg.margin_m + cfg.margin_ratio * range
            {
                return false;
            }
            stats.seen_through += 1;
            layer.var[j] = if var + self.step >= self.variance_show {
                stats.forgotten += 1;
                f32::INFINITY
            } else {
                var + self.step
            };
            true
        };
        let mut any = false;
        for &j in &PROBES {
            any |= seen(j, layer);
        }
        if any {
            for j in (0..VERTICES).filter(|j| !PROBES.contains(j)) {
                seen(j, layer);
            }
        }
    }
}

/// Raises the variance of every map vertex that the scan in `image`, taken at
/// `t_world_sensor`, sees through (see the module), by `variance_show / sightings`; a vertex
/// whose variance reaches `variance_show` is forgotten (infinite). Vertices of an unknown or
/// forgotten variance are left alone. `forgot` is told each layer that forgot a vertex (its
/// shown mesh changed), once, in the map's order.
pub fn clear_seen_through(
    map: &mut MeshMap,
    image: &RangeImage,
    t_world_sensor: &Pose,
    variance_show: f32,
    cfg: &ClearingConfig,
    mut forgot: impl FnMut(CellKey, Axis),
) -> ClearingStats {
    let mut stats = ClearingStats::default();
    let lattice = map.lattice().table();
    let sight = Sight::new(image, t_world_sensor, &lattice, variance_show, cfg);
    let origin = t_world_sensor.translation.vector;
    // A cell's vertices all lie within its half diagonal of its centre.
    let reach = f64::from(cfg.max_range_m) + lattice.cell_size * 0.87;
    map.update_layers(|key, axis, layer| {
        if (key.centre(lattice.cell_size) - origin).norm() <= reach {
            let before = stats.forgotten;
            sight.clear_layer(key, axis, layer, &mut stats);
            if stats.forgotten > before {
                forgot(*key, axis);
            }
        }
    });
    stats
}

/// The vertices of a layer looked at first ([`Sight::clear_layer`]): its corners, the middle
/// of each side and its middle, on the 6 x 6 lattice.
const PROBES: [usize; 9] = [0, 2, 5, 12, 14, 17, 30, 32, 35];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::facing::Facing;
    use crate::lattice::Lattice;

    /// A wall of returns `range` m ahead (+x), 20 m wide and 10 m high.
    fn wall_at(range: f32) -> [[f32; 3]; 2000] {
        core::array::from_fn(|k| {
            let (i, j) = ((k % 100) as f32, (k / 100) as f32);
            [range, -10.0 + 0.2 * i, -5.0 + 0.5 * j]
        })
    }

    /// A map with one confident layer along x across the cell at `x` (its surface 0.8 m into
    /// the cell).
    fn map_with_layer_at(x: i32) -> (MeshMap, CellKey) {
        let lattice = Lattice {
            cell_size: 1.6,
            full_cover: true,
        };
        let mut map = MeshMap::with_capacity(16, 16, lattice);
        let key = CellKey::new(x, -1, -1);
        let layer = Layer {
            pred: [0.8; VERTICES],
            var: [0.05; VERTICES],
            facing: Facing::Unknown,
        };
        map.insert_layer(key, Axis::X, layer, 0).expect("room");
        (map, key)
    }

    #[test]
    fn a_surface_the_rays_pass_beyond_is_hidden_after_its_sightings_and_one_in_front_is_kept() {
        // The layer's surface lies at x = 5 · 1.6 + 0.8 = 8.8 m.
        let (mut map, key) = map_with_layer_at(5);
        let cfg = ClearingConfig::default();
        let mut image = RangeImage::new();
        // Returns from the surface itself, and from a wall in front of it: never cleared.
        for range in [8.8, 6.0] {
            image.fill(&wall_at(range));
            let s = clear_seen_through(&mut map, &image, &Pose::identity(), 1.0, &cfg, |_, _| {});
            assert_eq!(s, ClearingStats::default(), "returns at {range} m");
        }
        // A wall 20 m away: the surface is seen through, three times over.
        image.fill(&wall_at(20.0));
        let mut forgotten = 0;
        for sight in 1..=3 {
            let s = clear_seen_through(&mut map, &image, &Pose::identity(), 1.0, &cfg, |_, _| {});
            assert_eq!(s.seen_through as usize, VERTICES, "sight {sight}");
            forgotten += s.forgotten;
            let var = map.layer(&key, Axis::X).expect("kept").var[0];
            if sight < 3 {
                assert!((var - (0.05 + sight as f32 / 3.0)).abs() < 1e-5, "{var}");
            }
        }
        assert_eq!(forgotten as usize, VERTICES);
        assert!(map
            .layer(&key, Axis::X)
            .expect("kept")
            .var
            .iter()
            .all(|v| v.is_infinite()));
        // Nothing left to see through.
        let s = clear_seen_through(&mut map, &image, &Pose::identity(), 1.0, &cfg, |_, _| {});
        assert_eq!(s, ClearingStats::default());
    }

    #[test]
    fn a_surface_past_the_range_or_outside_the_rays_is_left_alone() {
        // 88 m away: past the range cleared.
        let (mut map, _) = map_with_layer_at(55);
        let mut image = RangeImage::new();
        image.fill(&wall_at(150.0));
        let cfg = ClearingConfig::default();
        let s = clear_seen_through(&mut map, &image, &Pose::identity(), 1.0, &cfg, |_, _| {});
        assert_eq!(s, ClearingStats::default());
        // Behind the sensor, where no ray went.
        let (mut map, _) = map_with_layer_at(-6);
        let s = clear_seen_through(&mut map, &image, &Pose::identity(), 1.0, &cfg, |_, _| {});
        assert_eq!(s, ClearingStats::default());
        // No points at all, or only non-finite ones.
        image.fill(&[[f32::NAN; 3]; 4]);
        let (mut map, _) = map_with_layer_at(5);
        let s = clear_seen_through(&mut map, &image, &Pose::identity(), 1.0, &cfg, |_, _| {});
        assert_eq!(s, ClearingStats::default());
    }

    #[test]
    fn the_image_keeps_the_nearest_return_around_each_bin_across_the_azimuth_seam() {
        let mut image = RangeImage::new();
        let towards = |angle_deg: f32, r: f32| {
            let a = angle_deg.to_radians();
            [r * libm::cosf(a), r * libm::sinf(a), 0.0]
        };
        // The bins start at +x: one return just after it, one behind.
        image.fill(&[towards(0.3, 5.0), towards(180.0, 9.0)]);
        let at = |angle_deg: f32| {
            let p = towards(angle_deg, 1.0);
            image.around(p)
        };
        assert_eq!(at(-0.3).map(|(near, _)| near), Some(5.0), "across the seam");
        assert_eq!(at(0.3).map(|(near, _)| near), Some(5.0));
        assert_eq!(at(179.6).map(|(near, _)| near), Some(9.0));
        assert_eq!(at(-3.0), None);
        assert_eq!(at(3.0), None);
        assert_eq!(at(90.0), None);
    }

    /// A map with one layer along x in cell `(x, -1, -1)` at `pred` into the cell, its
    /// vertices of variance 0.05.
    fn map_with(x: i32, pred: f32) -> (MeshMap, CellKey) {
        let (mut map, key) = map_with_layer_at(x);
        map.update_layers(|_, _, l| l.pred = [pred; VERTICES]);
        (map, key)
    }

    /// The vertices of the layer seen through once (variance raised from 0.05).
    fn raised(map: &MeshMap, key: &CellKey) -> usize {
        let layer = map.layer(key, Axis::X).expect("kept");
        layer.var.iter().filter(|&&v| v > 0.06).count()
    }

    #[test]
    fn a_vertex_is_seen_through_only_past_the_margin() {
        let cfg = ClearingConfig::default();
        let mut image = RangeImage::new();
        // The surface at 8.8 m: returns from 9.3 m lie 0.5 m past it (the margin is 0.3 m and
        // 3 % of 8.8 to 9.1 m); from 10 m, 1.2 m past.
        for (wall, seen) in [(9.3, 0), (10.0, VERTICES)] {
            let (mut map, key) = map_with(5, 0.8);
            image.fill(&wall_at(wall));
            clear_seen_through(&mut map, &image, &Pose::identity(), 1.0, &cfg, |_, _| {});
            assert_eq!(raised(&map, &key), seen, "returns at {wall} m");
        }
        // Its prediction places it: at 0.2 m into the cell (8.2 m), 9.3 m is past the margin.
        let (mut map, key) = map_with(5, 0.2);
        image.fill(&wall_at(9.3));
        clear_seen_through(&mut map, &image, &Pose::identity(), 1.0, &cfg, |_, _| {});
        assert_eq!(raised(&map, &key), VERTICES);
    }

    #[test]
    fn only_the_vertices_the_rays_pass_are_seen_through() {
        // Near returns (6 m) straight ahead, within 0.45 m either side; far ones (20 m) beyond.
        let mut points = alloc::vec::Vec::from(wall_at(20.0));
        points.extend((0..1000).map(|k| {
            let (i, j) = ((k % 10) as f32, (k / 10) as f32);
            [6.0, -0.45 + 0.1 * i, -5.0 + 0.1 * j]
        }));
        let mut image = RangeImage::new();
        image.fill(&points);
        let (mut map, key) = map_with(5, 0.8);
        clear_seen_through(
            &mut map,
            &image,
            &Pose::identity(),
            1.0,
            &ClearingConfig::default(),
            |_, _| {},
        );
        // The layer's y (its first lattice index) runs from -1.6 to 0 m: the near returns
        // hide its vertices from y = -0.64 m up, three rows of six.
        let layer = map.layer(&key, Axis::X).expect("kept");
        for j in 0..VERTICES {
            assert_eq!(layer.var[j] > 0.06, j / N < 3, "vertex {j}");
        }
    }

    #[test]
    fn the_sensor_s_place_and_the_range_s_end_hold() {
        let cfg = ClearingConfig::default();
        let mut image = RangeImage::new();
        image.fill(&wall_at(120.0));
        // A cell whose centre lies past 80 m, its nearest vertex at 80 m exactly.
        let (mut map, key) = map_with(50, 0.0);
        clear_seen_through(&mut map, &image, &Pose::identity(), 1.0, &cfg, |_, _| {});
        assert_eq!(raised(&map, &key), 1, "only the vertex at 80 m");
        // The sensor 100 m along x: the layer 8.8 m ahead of it.
        let (mut map, key) = map_with(67, 0.8);
        image.fill(&wall_at(20.0));
        let there = Pose::translation(98.4, 0.0, 0.0);
        clear_seen_through(&mut map, &image, &there, 1.0, &cfg, |_, _| {});
        assert_eq!(raised(&map, &key), VERTICES);
    }

    #[test]
    fn directions_fall_in_the_bins_of_their_angle_and_elevation() {
        let root2 = libm::sqrtf(2.0);
        // 45 degrees round: a diamond angle of 0.5, bin 45 of 360; level: bin 32 of 64.
        assert_eq!(RangeImage::bin([1.0, 1.0, 0.0]), Some((45, 32, root2)));
        assert_eq!(RangeImage::bin([-1.0, -1.0, 0.0]), Some((225, 32, root2)));
        // The elevation's tangent in steps of 1.25 / 64 from -0.625.
        let up = |tan: f32| RangeImage::bin([1.0, 0.0, tan]).map(|(_, e, _)| e);
        assert_eq!(
            (up(-0.62), up(-0.6), up(0.6), up(0.62)),
            (Some(0), Some(1), Some(62), Some(63))
        );
        assert_eq!((up(-0.63), up(0.63)), (None, None));
        // A return is found where it is and not in the bin mirrored across the axis.
        let mut image = RangeImage::new();
        image.fill(&[[1.0, 1.0, 0.0]]);
        assert_eq!(image.around([2.0, 2.0, 0.0]), Some((root2, 2.0 * root2)));
        assert_eq!(image.around([2.0, -2.0, 0.0]), None);
        // Straight up or down, at the origin, or not finite: no bin.
        for p in [
            [0.0, 0.0, 1.0],
            [0.0; 3],
            [f32::NAN, 0.0, 0.0],
            [f32::INFINITY, 1.0, 0.0],
        ] {
            assert_eq!(RangeImage::bin(p), None, "{p:?}");
        }
    }

    #[test]
    fn an_image_in_the_caller_s_memory_is_one_from_the_allocator() {
        let short: &'static mut [f32] = alloc::vec![0.0; RangeImage::BINS - 1].leak();
        assert!(RangeImage::in_slice(short).is_none());
        let slots: &'static mut [f32] = alloc::vec![0.0; RangeImage::BINS].leak();
        let mut lent = RangeImage::in_slice(slots).expect("long enough");
        let mut own = RangeImage::new();
        for image in [&mut lent, &mut own] {
            image.fill(&wall_at(7.0));
        }
        assert_eq!(&lent.near[..], &own.near[..]);
        assert!(own.near.iter().any(|r| r.is_finite()));
    }

    #[test]
    fn the_diamond_angle_grows_with_the_angle_round_the_turn() {
        // A quarter turn apart: the diagonals at 0.5, 1.5, 2.5 and 3.5, and 30 degrees at
        // sin / (sin + cos).
        for (x, y, d) in [
            (1.0, 1.0, 0.5),
            (-1.0, 1.0, 1.5),
            (-1.0, -1.0, 2.5),
            (1.0, -1.0, 3.5),
        ] {
            assert!((diamond_angle(x, y) - d).abs() < 1e-6, "{x} {y}");
        }
        let a = core::f32::consts::FRAC_PI_6;
        let (c, s) = (libm::cosf(a), libm::sinf(a));
        assert!((diamond_angle(c, s) - s / (s + c)).abs() < 1e-6);
        let mut last = -1.0;
        for k in 0..3600 {
            let a = (k as f32 / 10.0).to_radians();
            let d = diamond_angle(libm::cosf(a), libm::sinf(a));
            assert!(d > last && (0.0..4.0).contains(&d), "{k}: {d}");
            last = d;
        }
    }
}
