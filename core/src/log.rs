//! defmt support (feature `defmt`): `defmt::Format` for the public types that hold nalgebra
//! values (poses as translation and quaternion, vectors as arrays; containers as their fill).
//! The pipeline's own types and its two log lines are in [`crate::pipeline`]. Without the
//! feature this module is empty.

#[cfg(feature = "defmt")]
pub(crate) mod formats {
    use crate::bounded::BoundedVec;
    use crate::lm::{Residual, Solution};
    use crate::map::{LayerRef, MeshMap};
    use crate::math::{Pose, Vec3};
    use crate::motion::ConstantVelocity;
    use defmt::{write, Format, Formatter};

    fn vec3(v: &Vec3) -> [f64; 3] {
        [v.x, v.y, v.z]
    }

    /// A pose as `t=[x, y, z] q=[x, y, z, w]`.
    pub(crate) struct PoseFmt<'a>(pub(crate) &'a Pose);

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
}
