//! The PLY point and mesh readers (ascii and both binary byte orders) on arbitrary bytes: a
//! mesh's faces only refer to vertices it has, and its normals and variances are one a vertex
//! or none.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz.ply");
    let _ = slamesh::formats::ply::parse_ply_points(path, data);
    if let Ok(mesh) = slamesh::formats::ply::parse_ply_mesh(path, data) {
        let n = mesh.vertices.len() as u64;
        assert!(mesh.triangles.iter().flatten().all(|&i| u64::from(i) < n));
        assert_eq!(mesh.triangle_corners().count(), mesh.triangles.len());
        assert!(mesh.normals.is_empty() || mesh.normals.len() == mesh.vertices.len());
        assert!(mesh.variances.is_empty() || mesh.variances.len() == mesh.vertices.len());
    }
});
