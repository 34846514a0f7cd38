//! How whole a triangle mesh is: its edges by how many triangles use them, and its connected
//! pieces. An edge used by one triangle is a boundary edge (the rim of a hole or of the
//! mesh); one used by three or more is non-manifold. Pieces are sets of triangles connected
//! through shared vertices. Only indices count: two vertices at the same place but with
//! different indices are not connected (that is what welding changes).

use std::collections::HashMap;

/// Edge and piece counts of an indexed triangle mesh.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct Topology {
    /// Triangles.
    pub triangles: u64,
    /// Distinct edges.
    pub edges: u64,
    /// Edges of exactly one triangle.
    pub boundary_edges: u64,
    /// Edges of three or more triangles.
    pub non_manifold_edges: u64,
    /// Connected pieces (triangles joined by shared vertices).
    pub pieces: u64,
    /// Triangles in the largest piece.
    pub largest_piece: u64,
}

impl Topology {
    /// The counts of `triangles` (vertex indices).
    pub fn of(triangles: &[[u32; 3]]) -> Self {
        let mut edges: HashMap<(u32, u32), u32> = HashMap::with_capacity(triangles.len() * 2);
        let vertices = triangles
            .iter()
            .flatten()
            .map(|&i| i as usize + 1)
            .max()
            .unwrap_or(0);
        let mut parent: Vec<u32> = (0..vertices as u32).collect();
        for t in triangles {
            for k in 0..3 {
                let (p, q) = (t[k], t[(k + 1) % 3]);
                *edges.entry((p.min(q), p.max(q))).or_insert(0) += 1;
                union(&mut parent, p, q);
            }
        }
        let mut sizes: HashMap<u32, u64> = HashMap::new();
        for t in triangles {
            *sizes.entry(find(&mut parent, t[0])).or_insert(0) += 1;
        }
        Topology {
            triangles: triangles.len() as u64,
            edges: edges.len() as u64,
            boundary_edges: edges.values().filter(|&&n| n == 1).count() as u64,
            non_manifold_edges: edges.values().filter(|&&n| n >= 3).count() as u64,
            pieces: sizes.len() as u64,
            largest_piece: sizes.values().copied().max().unwrap_or(0),
        }
    }

    /// Boundary edges as a share of all edges (0 for no edges).
    pub fn boundary_share(&self) -> f64 {
        if self.edges == 0 {
            0.0
        } else {
            self.boundary_edges as f64 / self.edges as f64
        }
    }
}

fn find(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let up = parent[parent[i as usize] as usize];
        parent[i as usize] = up;
        i = up;
    }
    i
}

fn union(parent: &mut [u32], p: u32, q: u32) {
    let (rp, rq) = (find(parent, p), find(parent, q));
    if rp != rq {
        parent[rp.max(rq) as usize] = rp.min(rq);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_square_a_loose_triangle_and_a_fin_are_counted() {
        // Two triangles sharing an edge (a square: 4 boundary edges, 1 inner edge), a third
        // triangle on its own, and a fin: a fourth triangle on the square's inner edge.
        let square = [[0, 1, 2], [0, 2, 3]];
        let t = Topology::of(&square);
        assert_eq!((t.edges, t.boundary_edges, t.pieces), (5, 4, 1));
        let all = [[0, 1, 2], [0, 2, 3], [4, 5, 6], [0, 2, 7]];
        let t = Topology::of(&all);
        assert_eq!(
            t,
            Topology {
                triangles: 4,
                edges: 10,
                boundary_edges: 9,
                non_manifold_edges: 1,
                pieces: 2,
                largest_piece: 3,
            }
        );
        assert!((t.boundary_share() - 0.9).abs() < 1e-12);
        assert_eq!(Topology::of(&[]), Topology::default());
    }
}
