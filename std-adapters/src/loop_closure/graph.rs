//! A pose graph over keyframes and its Gauss-Newton solve (docs/design.md §1.14).
//!
//! Nodes are sensor poses in the world; an edge `(a, b, Z, Ω)` says that `X_a⁻¹ X_b` was
//! measured as `Z` with information `Ω` (6 x 6, twist order `(ω, ρ)` as
//! [`se3_log`]). The error is `e = log(Z⁻¹ X_a⁻¹ X_b)`, nodes are
//! perturbed on the right (`X ← X exp(δ)`), and the first node is held fixed.
//!
//! The normal equations are solved by a block Cholesky factorisation in *envelope* storage:
//! each block row keeps the blocks from its first non-zero column to the diagonal, and the
//! factor's fill stays inside that envelope. Odometry edges make the graph a chain (one block
//! left of the diagonal); a loop edge widens the rows of the later node back to the earlier
//! one. A drive that closes its loop near its end costs `rows that closed × nodes` blocks,
//! not the square of the nodes: a few hundred kilobytes for a town loop of 500 keyframes.

use nalgebra::{Matrix6, Vector6};
use slamesh_core::lm::PoseInformation;
use slamesh_core::math::{se3_exp, se3_log, skew, Pose};

/// One measured relative pose between two nodes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Edge {
    /// The earlier node.
    pub a: usize,
    /// The later node.
    pub b: usize,
    /// The measured `X_a⁻¹ X_b`.
    pub z: Pose,
    /// Its information (the inverse covariance), twist order `(ω, ρ)`.
    pub info: Matrix6<f64>,
}

/// Keyframe poses and the edges between them.
#[derive(Debug, Clone, Default)]
pub struct PoseGraph {
    /// The node poses: the odometry's until [`PoseGraph::optimize`] corrects them.
    pub nodes: Vec<Pose>,
    /// Odometry and loop edges.
    pub edges: Vec<Edge>,
}

/// What an optimisation did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Solved {
    /// Gauss-Newton iterations run.
    pub iterations: usize,
    /// The weighted squared error before and after.
    pub cost: (f64, f64),
}

/// The adjoint of `t` for twists `(ω, ρ)`: `t exp(ξ) t⁻¹ = exp(Ad ξ)`.
pub fn adjoint(t: &Pose) -> Matrix6<f64> {
    let r = t.rotation.to_rotation_matrix().into_inner();
    let tr = skew(&t.translation.vector) * r;
    let mut ad = Matrix6::zeros();
    ad.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
    ad.fixed_view_mut::<3, 3>(3, 3).copy_from(&r);
    ad.fixed_view_mut::<3, 3>(3, 0).copy_from(&tr);
    ad
}

/// The covariance of `pose` in its own frame (a perturbation `pose · exp(ε)`) from a
/// registration's [`PoseInformation`] (about its centre, on the left): `A = Ad(T_c⁻¹ · pose)`
/// takes `ε` to the registration's `δ`, so the information is `Aᵀ H A`. A direction the
/// registration did not constrain gets a standard deviation of about 1 (metre or radian), not
/// infinity.
pub fn local_covariance(info: &PoseInformation, pose: &Pose) -> Matrix6<f64> {
    let h = Matrix6::from_fn(|i, j| info.matrix[i][j]);
    let c = nalgebra::Translation3::new(info.centre[0], info.centre[1], info.centre[2]);
    let a = adjoint(&(Pose::from_parts(c, nalgebra::UnitQuaternion::identity()).inverse() * pose));
    let local = a.transpose() * h * a + Matrix6::identity();
    local.try_inverse().unwrap_or_else(Matrix6::identity)
}

impl PoseGraph {
    /// The error of `e` at the current node poses.
    pub fn error(&self, e: &Edge) -> Vector6<f64> {
        se3_log(&(e.z.inverse() * self.nodes[e.a].inverse() * self.nodes[e.b]))
    }

    /// The weighted squared error of all edges (those naming a missing node left out).
    pub fn cost(&self) -> f64 {
        let n = self.nodes.len();
        self.edges
            .iter()
            .filter(|e| e.a < n && e.b < n)
            .map(|e| {
                let r = self.error(e);
                (r.transpose() * e.info * r)[0]
            })
            .sum()
    }

    /// Gauss-Newton until the largest update is below 1e-6 (radians or metres) or after
    /// `max_iterations`. An edge naming a node that does not exist is ignored; a system that
    /// cannot be factored leaves the nodes as they were.
    pub fn optimize(&mut self, max_iterations: usize) -> Solved {
        let before = self.cost();
        let mut iterations = 0;
        while iterations < max_iterations {
            iterations += 1;
            let Some(delta) = self.step() else { break };
            let largest = delta.iter().map(|d| d.amax()).fold(0.0, f64::max);
            for (x, d) in self.nodes.iter_mut().zip(&delta) {
                *x *= se3_exp(d);
            }
            if largest < 1e-6 {
                break;
            }
        }
        Solved {
            iterations,
            cost: (before, self.cost()),
        }
    }

    /// One Gauss-Newton step: the normal equations built and solved, `None` if singular.
    fn step(&self) -> Option<Vec<Vector6<f64>>> {
        let n = self.nodes.len();
        if n == 0 {
            return None;
        }
        let valid = |e: &&Edge| e.a < n && e.b < n && e.a != e.b;
        // Each row's first column: the earliest node it shares an edge with.
        let mut first: Vec<usize> = (0..n).collect();
        for e in self.edges.iter().filter(valid) {
            let (lo, hi) = (e.a.min(e.b), e.a.max(e.b));
            first[hi] = first[hi].min(lo);
        }
        let mut h = Envelope::new(first);
        let mut g = vec![Vector6::zeros(); n];
        // The first node is held: a stiff prior on its update.
        *h.at(0, 0) += Matrix6::identity() * 1e12;
        for e in self.edges.iter().filter(valid) {
            let r = self.error(e);
            let ja = -adjoint(&(self.nodes[e.b].inverse() * self.nodes[e.a]));
            let w = e.info;
            let jaw = ja.transpose() * w;
            *h.at(e.a, e.a) += jaw * ja;
            *h.at(e.b, e.b) += w;
            g[e.a] += jaw * r;
            g[e.b] += w * r;
            if e.a > e.b {
                *h.at(e.a, e.b) += jaw;
            } else {
                *h.at(e.b, e.a) += w * ja;
            }
        }
        h.factor()?;
        Some(h.solve(g.into_iter().map(|v| -v).collect()))
    }
}

/// A symmetric block matrix stored as its lower envelope (see the module docs), factored in
/// place into `L` with `A = L Lᵀ`.
struct Envelope {
    first: Vec<usize>,
    /// Row `i`'s blocks for columns `first[i]..=i`.
    rows: Vec<Vec<Matrix6<f64>>>,
}

impl Envelope {
    fn new(first: Vec<usize>) -> Self {
        let rows = first
            .iter()
            .enumerate()
            .map(|(i, &f)| vec![Matrix6::zeros(); i - f + 1])
            .collect();
        Self { first, rows }
    }

    /// Block `(i, j)`, `j` in row `i`'s envelope.
    fn at(&mut self, i: usize, j: usize) -> &mut Matrix6<f64> {
        let f = self.first[i];
        &mut self.rows[i][j - f]
    }

    /// Row by row: `L_ij = (A_ij - Σ_k L_ik L_jkᵀ) L_jj⁻ᵀ`, then the diagonal block's own
    /// Cholesky factor. `None` when a diagonal block is not positive definite.
    fn factor(&mut self) -> Option<()> {
        for i in 0..self.rows.len() {
            let fi = self.first[i];
            for j in fi..i {
                let fj = self.first[j];
                let mut s = self.rows[i][j - fi];
                for k in fi.max(fj)..j {
                    s -= self.rows[i][k - fi] * self.rows[j][k - fj].transpose();
                }
                let ljj = self.rows[j][j - fj];
                // L_ij L_jjᵀ = s, so L_jj L_ijᵀ = sᵀ.
                self.rows[i][j - fi] = ljj.solve_lower_triangular(&s.transpose())?.transpose();
            }
            let mut d = self.rows[i][i - fi];
            for k in fi..i {
                let l = self.rows[i][k - fi];
                d -= l * l.transpose();
            }
            self.rows[i][i - fi] = d.cholesky()?.l();
        }
        Some(())
    }

    /// Solves `L Lᵀ x = b` with the factor.
    fn solve(&self, mut b: Vec<Vector6<f64>>) -> Vec<Vector6<f64>> {
        let n = self.rows.len();
        for i in 0..n {
            let fi = self.first[i];
            let mut y = b[i];
            for (l, bk) in self.rows[i].iter().zip(&b[fi..i]) {
                y -= l * bk;
            }
            b[i] = self.rows[i][i - fi]
                .solve_lower_triangular(&y)
                .unwrap_or_else(Vector6::zeros);
        }
        for i in (0..n).rev() {
            let fi = self.first[i];
            let x = self.rows[i][i - fi]
                .transpose()
                .solve_upper_triangular(&b[i])
                .unwrap_or_else(Vector6::zeros);
            b[i] = x;
            for (l, bk) in self.rows[i].iter().zip(&mut b[fi..i]) {
                *bk -= l.transpose() * x;
            }
        }
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    fn pose(x: f64, y: f64, yaw: f64) -> Pose {
        Pose::from_parts(
            Translation3::new(x, y, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
        )
    }

    /// A registration that pinned the pose down only across a corridor (`y`) and in yaw: its
    /// covariance in the sensor's frame is small there and about 1 elsewhere, whatever the
    /// point the registration turned about.
    #[test]
    fn a_corridor_registration_is_sure_across_and_unsure_along() {
        let mut m = [[0.0; 6]; 6];
        m[2][2] = 1e6; // yaw
        m[4][4] = 1e6; // y
        let pose = pose(10.0, 0.0, 0.0);
        let info = PoseInformation {
            matrix: m,
            centre: [10.0, 0.0, 0.0],
        };
        let c = local_covariance(&info, &pose);
        assert!(c[(4, 4)] < 1e-5 && c[(2, 2)] < 1e-5, "{c}");
        assert!(
            (c[(3, 3)] - 1.0).abs() < 1e-6 && (c[(5, 5)] - 1.0).abs() < 1e-6,
            "{c}"
        );
        // Turning about a point 5 m behind couples yaw with y, but the sensor's own frame is
        // as sure across and in yaw as before.
        let behind = PoseInformation {
            centre: [5.0, 0.0, 0.0],
            ..info
        };
        let a = adjoint(&Pose::from_parts(
            Translation3::new(5.0, 0.0, 0.0),
            UnitQuaternion::identity(),
        ));
        let mut moved = [[0.0; 6]; 6];
        let h = Matrix6::from_fn(|i, j| m[i][j]);
        let shifted = a.transpose().try_inverse().unwrap() * h * a.try_inverse().unwrap();
        for (i, row) in moved.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = shifted[(i, j)];
            }
        }
        let c2 = local_covariance(
            &PoseInformation {
                matrix: moved,
                ..behind
            },
            &pose,
        );
        assert!((c2 - c).amax() < 1e-6, "{c2}");
    }

    #[test]
    fn adjoint_moves_a_twist_through_a_transform() {
        let t = Pose::from_parts(
            Translation3::new(1.0, -2.0, 0.5),
            UnitQuaternion::from_euler_angles(0.1, -0.2, 0.7),
        );
        let xi = Vector6::new(0.01, 0.02, -0.03, 0.1, -0.05, 0.2);
        let left = t * se3_exp(&xi) * t.inverse();
        let right = se3_exp(&(adjoint(&t) * xi));
        assert!((left.to_homogeneous() - right.to_homogeneous()).amax() < 1e-12);
    }

    /// A square driven with a turn that drifts, closed by one loop edge: the optimisation
    /// brings the last pose back onto the first and spreads the correction along the way.
    #[test]
    fn a_drifting_square_closes_on_its_loop_edge() {
        let (side, per_side) = (20.0, 10);
        let step = pose(side / per_side as f64, 0.0, 0.0);
        let corner = pose(side / per_side as f64, 0.0, core::f64::consts::FRAC_PI_2);
        let drift = pose(0.0, 0.0, 0.004);
        let mut truth = vec![Pose::identity()];
        let mut odom = vec![Pose::identity()];
        let mut graph = PoseGraph::default();
        let info = Matrix6::from_diagonal(&Vector6::new(1e4, 1e4, 1e4, 1e2, 1e2, 1e2));
        for k in 1..=4 * per_side {
            let m = if k % per_side == 0 { corner } else { step };
            truth.push(truth[k - 1] * m);
            odom.push(odom[k - 1] * m * drift);
            graph.edges.push(Edge {
                a: k - 1,
                b: k,
                z: m * drift,
                info,
            });
        }
        let last = truth.len() - 1;
        assert!(
            (truth[last].translation.vector).norm() < 1e-9,
            "the square closes"
        );
        let before = (odom[last].translation.vector - truth[last].translation.vector).norm();
        assert!(before > 0.5, "the odometry drifted {before} m");
        graph.nodes = odom;
        graph.edges.push(Edge {
            a: 0,
            b: last,
            z: truth[last],
            info: info * 10.0,
        });
        let solved = graph.optimize(10);
        assert!(solved.cost.1 < solved.cost.0 * 1e-2, "{solved:?}");
        let after = (graph.nodes[last].translation.vector - truth[last].translation.vector).norm();
        assert!(
            after < 0.05,
            "end point {after} m from the truth after closing"
        );
        let worst = graph
            .nodes
            .iter()
            .zip(&truth)
            .map(|(x, t)| (x.translation.vector - t.translation.vector).norm())
            .fold(0.0, f64::max);
        assert!(
            worst < before / 3.0,
            "worst node {worst} m off, drift {before} m"
        );
        let first = graph.nodes[0].to_homogeneous() - Pose::identity().to_homogeneous();
        assert!(first.amax() < 1e-9, "the first node is held");
    }

    #[test]
    fn edges_to_missing_nodes_are_ignored_and_an_empty_graph_is_a_no_op() {
        let mut empty = PoseGraph::default();
        assert_eq!(empty.optimize(5).iterations, 1);
        let mut g = PoseGraph {
            nodes: vec![Pose::identity(), pose(1.0, 0.0, 0.0)],
            edges: vec![Edge {
                a: 0,
                b: 7,
                z: Pose::identity(),
                info: Matrix6::identity(),
            }],
        };
        g.optimize(5);
        assert_eq!(
            g.nodes[1],
            pose(1.0, 0.0, 0.0),
            "an unconstrained node stays"
        );
    }
}
