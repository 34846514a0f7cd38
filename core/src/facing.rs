//! [`Facing`]: which way a layer's surface faces, told by the side the sensor saw it from
//! (docs/design.md §1.5, "Faces").
//!
//! A layer predicts `d = f(a, b)` along its axis. Seen from a viewpoint on the `+d` side of
//! that surface it faces `+d`, from the other side `-d`. A solid object's faces are only ever
//! seen from outside, so a layer's facing stays put from scan to scan; it flips only where two
//! surfaces facing apart share a cell: the two faces of a wall thinner than a cell, or the one
//! surface of a sheet (a fence, a board, leaves). Knowing it, fusion
//! ([`integrate`](crate::fusion::integrate)) keeps a wall's faces apart (the face in view
//! replaces the other instead of being averaged with it) and fuses a sheet's, which lie within
//! [`MIN_THICKNESS_M`] of each other, as one surface facing [`Both`](Facing::Both) ways.
//! Registration does not look at facings: the map holds the face last in view, which is the
//! face the next scan sees (a filter that kept a scan's face from pairing with a map face
//! facing the other way was tried and cost accuracy; docs/journal.md, "Faces").
//!
//! The facing is decided from the layer's own lattice: a least-squares plane through its
//! confident vertices, and the viewpoint's signed distance to it. A viewpoint nearly in that
//! plane (a grazing view: less than [`MIN_VIEW_SINE`] of its distance off it), or a layer no
//! plane fits (fewer than three confident vertices, all on a line, or farther than
//! [`MAX_PLANE_RMS_M`] from it: foliage, a corner, a curved body), leaves it
//! [`Facing::Unknown`], which fuses with either facing, as every layer did before facings were
//! kept.

use crate::cell::{Axis, CellKey};
use crate::lattice::{LatticeTable, VERTICES};
use crate::math::Vec3;
use crate::plane::Plane;

/// The least sine of the angle between a viewpoint's line to a layer and the layer's plane for
/// the view to decide its facing (about 6 degrees).
pub const MIN_VIEW_SINE: f64 = 0.1;

/// The largest RMS distance of a layer's confident vertices from their plane for the layer to
/// have a facing.
pub const MAX_PLANE_RMS_M: f64 = 0.03;

/// Which way a layer's surface faces along its axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum Facing {
    /// Not known: seen at grazing angles only, or made before facings were kept.
    #[default]
    Unknown = 0,
    /// Towards `+axis` (ground seen from above faces `+z`).
    Positive = 1,
    /// Towards `-axis` (a ceiling faces `-z`).
    Negative = 2,
    /// Both ways: a sheet thinner than [`MIN_THICKNESS_M`] (a fence, a board, foliage) seen
    /// from both sides, its two faces one surface.
    Both = 3,
}

/// Two faces facing apart nearer than this (mean over the vertices both are sure of) are one
/// sheet seen from both sides, fused as one surface; farther apart they are two surfaces (the
/// faces of a wall), and the one in view replaces the other.
pub const MIN_THICKNESS_M: f32 = 0.05;

impl Facing {
    /// Whether surfaces of these facings may be the same surface: yes unless one faces
    /// `+axis` and the other `-axis`.
    #[inline]
    pub fn agrees(self, other: Facing) -> bool {
        !matches!(
            (self, other),
            (Facing::Positive, Facing::Negative) | (Facing::Negative, Facing::Positive)
        )
    }

    /// The facing of a map layer after a scan layer facing `seen` is fused into it: the
    /// first known facing, [`Both`](Facing::Both) once it is seen facing the other way too.
    #[inline]
    pub fn fused_with(self, seen: Facing) -> Facing {
        match (self, seen) {
            (Facing::Unknown, s) => s,
            (m, Facing::Unknown) => m,
            (m, s) if m == s => m,
            _ => Facing::Both,
        }
    }

    /// The facing as its two bits (0 unknown, 1 positive, 2 negative, 3 both).
    #[inline]
    pub fn bits(self) -> u8 {
        self as u8
    }

    /// The facing of the low two bits of `bits` ([`bits`](Self::bits)).
    #[inline]
    pub fn from_bits(bits: u8) -> Facing {
        match bits & 3 {
            0 => Facing::Unknown,
            1 => Facing::Positive,
            2 => Facing::Negative,
            _ => Facing::Both,
        }
    }

    /// The facing of the layer of predictions `pred` and variances `var` (cell `key`, `axis`)
    /// seen from `viewpoint` (world), counting its vertices with a variance below `max_var`.
    pub fn seen_from(
        (pred, var): (&[f32; VERTICES], &[f32; VERTICES]),
        lattice: &LatticeTable,
        key: &CellKey,
        axis: Axis,
        viewpoint: &Vec3,
        max_var: f32,
    ) -> Facing {
        let Some(plane) = plane_of(pred, var, lattice, max_var) else {
            return Facing::Unknown;
        };
        // The viewpoint in the cell's own (a, b, d) coordinates.
        let local = viewpoint - key.min_corner(lattice.cell_size);
        let (ia, ib) = axis.locations();
        let v = [local[ia], local[ib], local[axis.index()]];
        let offset = [
            v[0] - plane.centre[0],
            v[1] - plane.centre[1],
            v[2] - plane.centre[2],
        ];
        let above = v[2] - plane.at(v[0], v[1]);
        let tilt =
            libm::sqrt(1.0 + plane.slope[0] * plane.slope[0] + plane.slope[1] * plane.slope[1]);
        let distance = above / tilt;
        let range =
            libm::sqrt(offset[0] * offset[0] + offset[1] * offset[1] + offset[2] * offset[2]);
        if !(libm::fabs(distance) > MIN_VIEW_SINE * range) {
            Facing::Unknown
        } else if distance > 0.0 {
            Facing::Positive
        } else {
            Facing::Negative
        }
    }
}

/// The least-squares plane through the vertices (predictions `pred`, variances `var`) with a
/// variance below `max_var`; `None` when they are fewer than three, lie on a line or are
/// farther from it than [`MAX_PLANE_RMS_M`].
fn plane_of(
    pred: &[f32; VERTICES],
    var: &[f32; VERTICES],
    lattice: &LatticeTable,
    max_var: f32,
) -> Option<Plane<f64>> {
    let confident: heapless::Vec<[f64; 3], VERTICES> = (0..VERTICES)
        .filter(|&j| var[j] < max_var)
        .map(|j| {
            let (a, b) = lattice.location(j);
            [a, b, f64::from(pred[j])]
        })
        .collect();
    let plane = Plane::fit(&confident);
    if confident.len() < 3 || !plane.determined {
        return None;
    }
    let squares: f64 = confident
        .iter()
        .map(|s| {
            let off = s[2] - plane.at(s[0], s[1]);
            off * off
        })
        .sum();
    // A surface no plane fits (foliage, a corner, a curved body) faces no one way.
    let most = MAX_PLANE_RMS_M * MAX_PLANE_RMS_M * confident.len() as f64;
    (squares <= most).then_some(plane)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lattice::Lattice;
    use crate::layer::Layer;

    fn seen(l: &Layer, key: &CellKey, axis: Axis, from: &Vec3) -> Facing {
        Facing::seen_from((&l.pred, &l.var), &lattice(), key, axis, from, 0.5)
    }

    fn lattice() -> LatticeTable {
        Lattice {
            cell_size: 1.0,
            full_cover: false,
        }
        .table()
    }

    /// A layer `d = f(a, b)` with every vertex confident.
    fn layer(f: impl Fn(f64, f64) -> f64) -> Layer {
        let t = lattice();
        let mut l = Layer::UNKNOWN;
        for j in 0..VERTICES {
            let (a, b) = t.location(j);
            l.pred[j] = f(a, b) as f32;
            l.var[j] = 0.01;
        }
        l
    }

    #[test]
    fn the_two_faces_of_a_thin_wall_face_apart() {
        // A wall across x in cell (4, 0, 0): its faces at x = 4.3 and 4.6 m, seen from either
        // side, one metre off the ground.
        let key = CellKey::new(4, 0, 0);
        let near = layer(|_, _| 0.3);
        let far = layer(|_, _| 0.6);
        let west = Vec3::new(1.0, 0.5, 1.0);
        let east = Vec3::new(8.0, 0.5, 1.0);
        assert_eq!(seen(&near, &key, Axis::X, &west), Facing::Negative);
        assert_eq!(seen(&far, &key, Axis::X, &east), Facing::Positive);
        assert!(!Facing::Negative.agrees(Facing::Positive));
        assert!(
            Facing::Unknown.agrees(Facing::Positive) && Facing::Negative.agrees(Facing::Unknown)
        );
        assert!(Facing::Both.agrees(Facing::Positive) && Facing::Negative.agrees(Facing::Both));
        assert_eq!(Facing::Positive.fused_with(Facing::Negative), Facing::Both);
        assert_eq!(Facing::Both.fused_with(Facing::Positive), Facing::Both);
        assert_eq!(
            Facing::Unknown.fused_with(Facing::Negative),
            Facing::Negative
        );
        assert_eq!(
            Facing::Negative.fused_with(Facing::Unknown),
            Facing::Negative
        );
    }

    #[test]
    fn a_slope_is_judged_by_its_plane_not_its_axis() {
        // Ground rising 1 in 1 along a (d = a): a viewpoint above the cell's centre but below
        // the plane's continuation far along +a sees it from below.
        let key = CellKey::new(0, 0, 0);
        let ramp = layer(|a, _| a);
        let above = Vec3::new(0.5, 0.5, 3.0);
        let beyond = Vec3::new(10.0, 0.5, 4.0);
        assert_eq!(seen(&ramp, &key, Axis::Z, &above), Facing::Positive);
        assert_eq!(seen(&ramp, &key, Axis::Z, &beyond), Facing::Negative);
    }

    #[test]
    fn grazing_views_and_unsure_layers_leave_it_unknown() {
        let key = CellKey::new(0, 0, 0);
        let ground = layer(|_, _| 0.5);
        // 20 m away and 1 m above the plane: under 6 degrees.
        let grazing = Vec3::new(20.5, 0.5, 1.5);
        assert_eq!(seen(&ground, &key, Axis::Z, &grazing), Facing::Unknown);
        let mut line = Layer::UNKNOWN;
        for j in 0..6 {
            line.pred[j] = 0.5;
            line.var[j] = 0.01;
        }
        let above = Vec3::new(0.5, 0.5, 3.0);
        assert_eq!(seen(&line, &key, Axis::Z, &above), Facing::Unknown);
        assert_eq!(
            seen(&Layer::UNKNOWN, &key, Axis::Z, &above),
            Facing::Unknown
        );
        for f in [
            Facing::Unknown,
            Facing::Positive,
            Facing::Negative,
            Facing::Both,
        ] {
            assert_eq!(Facing::from_bits(f.bits()), f);
        }
    }
}
