//! How sure the map is of a triangle, and how sure the grid asks it to be
//! ([`crate::navmap::grid`]).
//!
//! A triangle's variance is its corners' mean Gaussian-process variance
//! ([`mean_variance`]). The mesh shows only triangles under `mesh.variance_show` (0.3 by
//! default), the ground's limit. What would stand is held to more ([`is_sure`]): an unsure
//! standing surface leaves its cell unknown instead of occupied. A triangle whose variance is
//! not known (NaN: a PLY without the property, a corner welded in from an earlier set) passes.

/// The mean of a triangle's corners' variances that are known (not NaN); NaN when none is.
pub fn mean_variance(v: [f32; 3]) -> f32 {
    let known = v.iter().filter(|x| !x.is_nan());
    let n = known.clone().count();
    if n == 0 {
        f32::NAN
    } else {
        known.sum::<f32>() / n as f32
    }
}

/// The highest mean variance of a standing triangle (one steeper than the robot's slope)
/// the grid takes; NaN (no variance known) passes. The mesh's own limit (`mesh.variance_show`,
/// 0.3 by default) is the ground's: a stricter one for the ground too cost the office's floor
/// its doorways, while one for what stands alone drops the unsure surfaces the reconstruction
/// carries past a wall's or a car's edge (docs/journal.md, "Low rises and unsure standing
/// surfaces").
pub const STANDING_VARIANCE: f32 = 0.2;

/// The highest mean variance of a level triangle (one within the robot's slope) the grid takes
/// as something standing, where it lies more than a step over the cell's reference and under
/// the robot's height; NaN passes. Above it the cell is doubtful (unknown), as for
/// [`STANDING_VARIANCE`]; as ground, or over the robot, the triangle counts whatever its
/// variance. The mesh's level shelves a few centimetres off a wall, where a single scan ring
/// crossed a cell and its points' plane came out level, are unsure (one in the town: 0.07 to
/// 0.46 at its vertices, the street's and the wall's beside it 0.00 to 0.01): 0.1 lifted the town's IoU from 0.84 to 0.86 and the office's
/// from 0.57 to 0.66 with no free cell more over an obstacle, on every seed tried
/// (docs/journal.md, "Unsure level surfaces").
pub const LEVEL_VARIANCE: f32 = 0.1;

/// Whether the grid takes a triangle of mean `variance` as something standing where it would
/// stand: steep ones (`is_floor` false) up to [`STANDING_VARIANCE`], level ones up to
/// [`LEVEL_VARIANCE`]; NaN passes.
pub fn is_sure(variance: f32, is_floor: bool) -> bool {
    let limit = if is_floor {
        LEVEL_VARIANCE
    } else {
        STANDING_VARIANCE
    };
    variance.is_nan() || variance <= limit
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_corners_are_left_out_and_level_triangles_are_held_to_less() {
        assert_eq!(mean_variance([0.1, f32::NAN, 0.3]), 0.2);
        assert!(mean_variance([f32::NAN; 3]).is_nan());
        assert!(is_sure(f32::NAN, true) && is_sure(f32::NAN, false));
        assert!(is_sure(0.15, false) && !is_sure(0.15, true));
        assert!(is_sure(0.1, true) && !is_sure(0.25, false));
    }
}
