//! defmt support (feature `defmt`): `defmt::Format` for the public types that hold nalgebra
//! values (poses as translation and quaternion, vectors as arrays; containers as their fill),
//! and the one place the core logs. Without the feature this module is empty.

#[cfg(feature = "defmt")]
mod formats {
    use crate::bounded::BoundedVec;
    use crate::capacity::Capacity;
    use crate::lm::{Residual, Solution};
    use crate::map::{LayerRef, MeshMap};
    use crate::math::{Pose, Vec3};
    use crate::motion::ConstantVelocity;
    use crate::pipeline::{Pipeline, ScanOutcome};
    use defmt::{write, Format, Formatter};

    fn vec3(v: &Vec3) -> [f64; 3] {
        [v.x, v.y, v.z]
    }

    /// A pose as `t=[x, y, z] q=[x, y, z, w]`.
    struct PoseFmt<'a>(&'a Pose);

    impl Format for PoseFmt<'_> {
        fn format(&self, f: Formatter) {
            let q = self.0.rotation.coords;
            write!(
                f,
                "t={} q={}",
                vec3(&self.0.translation.vector),
                [q[0], q[1], q[2], q[3]]
            )
        }
    }

    impl Format for Residual {
        fn format(&self, f: Formatter) {
            write!(
                f,
                "Residual {{ p: {}, q: {}, n: {}, weight: {} }}",
                vec3(&self.p),
                vec3(&self.q),
                vec3(&self.n),
                self.weight
            )
        }
    }

    impl Format for Solution {
        fn format(&self, f: Formatter) {
            write!(
                f,
                "Solution {{ correction: {}, iterations: {}, cost: {}, conditioning: {}, degenerate_directions: {} }}",
                PoseFmt(&self.correction),
                self.iterations,
                self.cost,
                self.conditioning,
                self.degenerate_directions
            )
        }
    }

    impl Format for ScanOutcome {
        fn format(&self, f: Formatter) {
            write!(
                f,
                "ScanOutcome {{ {}, {}, {} }}",
                PoseFmt(&self.t_world_sensor),
                self.status,
                self.stats
            )
        }
    }

    impl Format for ConstantVelocity {
        fn format(&self, f: Formatter) {
            match self.last() {
                Some(p) => write!(
                    f,
                    "ConstantVelocity {{ last: {}, known: {} }}",
                    PoseFmt(&p),
                    self.velocity_known()
                ),
                None => write!(f, "ConstantVelocity {{ empty }}"),
            }
        }
    }

    impl Format for LayerRef<'_> {
        fn format(&self, f: Formatter) {
            write!(
                f,
                "LayerRef {{ {}, {}, {} }}",
                self.key, self.axis, self.layer
            )
        }
    }

    impl Format for MeshMap {
        fn format(&self, f: Formatter) {
            write!(
                f,
                "MeshMap {{ cells: {}, layers: {} }}",
                self.cell_count(),
                self.layer_count()
            )
        }
    }

    impl<T> Format for BoundedVec<T> {
        fn format(&self, f: Formatter) {
            write!(
                f,
                "BoundedVec {{ len: {}, capacity: {} }}",
                self.len(),
                self.capacity()
            )
        }
    }

    impl<C: Capacity> Format for Pipeline<C> {
        fn format(&self, f: Formatter) {
            write!(
                f,
                "Pipeline {{ frames: {}, map: {} }}",
                self.frames(),
                self.map()
            )
        }
    }
}

/// Logs the end of one scan (defmt `debug`, or `warn` when registration fell back).
#[cfg(feature = "defmt")]
pub(crate) fn scan_done(outcome: &crate::pipeline::ScanOutcome) {
    use crate::pipeline::RegistrationStatus as S;
    match outcome.status {
        S::FirstScan | S::Converged | S::Given => {
            defmt::debug!("scan {}: {}", outcome.stats.frame, outcome)
        }
        _ => defmt::warn!(
            "scan {}: kept the motion prediction: {}",
            outcome.stats.frame,
            outcome
        ),
    }
}

/// Logs a rejected scan.
#[cfg(feature = "defmt")]
pub(crate) fn scan_rejected(frame: u32, error: &crate::pipeline::ScanError) {
    defmt::warn!("scan {} rejected: {}", frame, error);
}
