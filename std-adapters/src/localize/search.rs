//! Where a run searches for its pose in a saved map, and what it says of the search: the
//! candidates lie on the map's own path, every `spacing` metres along the poses its sensor
//! had and a cell to either side of each (a robot localizing in a map drives where the
//! mapping one drove, in another lane perhaps); each is tried at every heading
//! ([`slamesh_core::relocalize`]). A frame whose search found nothing convincing is a frame
//! not used (`run::FrameFault::NotLocalized`, which says why).

use slamesh_core::pipeline::Relocalized;
use slamesh_core::relocalize::along_path;
use slamesh_core::Pose;

/// Candidate poses for the search along a saved map's path
/// ([`slamesh_core::relocalize::along_path`]).
pub fn candidates(path: &[(f64, Pose)], spacing_m: f64) -> Vec<Pose> {
    let mut out = Vec::new();
    along_path(path.iter().map(|(_, p)| p), spacing_m, |c| out.push(c));
    out
}

/// What the report says of the frame whose search found the pose.
pub fn found(r: &Relocalized) -> String {
    let p = r.outcome.t_world_sensor.translation.vector;
    format!(
        "found in the map at ({:.2}, {:.2}, {:.2}) with no pose given: {:.0} % of the scan on \
         the map's surfaces ({:.0} % on walls), the best elsewhere {:.0} % ({} hypotheses, {} \
         registered)",
        p.x,
        p.y,
        p.z,
        100.0 * r.hit_share,
        100.0 * r.wall_share,
        100.0 * r.runner_up_share,
        r.hypotheses,
        r.registered
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn candidates_follow_the_path_and_its_sides() {
        let path: Vec<(f64, Pose)> = (0..10)
            .map(|i| (i as f64, Pose::translation(0.5 * i as f64, 0.0, 1.7)))
            .collect();
        let c = candidates(&path, 1.6);
        // Poses at x = 0, 2 and 4 (each 1.6 m or more on), three to a place.
        assert_eq!(c.len(), 9);
        let at: Vec<[f64; 3]> = c.iter().map(|p| p.translation.vector.into()).collect();
        assert_eq!(at[0], [0.0, 0.0, 1.7]);
        assert_eq!(at[1], [0.0, 1.6, 1.7]);
        assert_eq!(at[2], [0.0, -1.6, 1.7]);
        assert_eq!(at[3], [2.0, 0.0, 1.7]);
    }
}
