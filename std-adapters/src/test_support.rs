//! Scratch files and small map pieces for unit tests.

use std::path::PathBuf;

/// A folder of this process for the test `tag` (created, initially as left by earlier runs).
pub fn scratch_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("slamesh-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Writes `bytes` to `name` in the scratch folder of `tag`; returns its path.
pub fn scratch_file(tag: &str, name: &str, bytes: &[u8]) -> PathBuf {
    let p = scratch_dir(tag).join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

/// A flat, certain layer: every triangle shown.
pub fn flat_layer() -> slamesh_core::layer::Layer {
    slamesh_core::layer::Layer {
        pred: [0.5; slamesh_core::lattice::VERTICES],
        var: [0.01; slamesh_core::lattice::VERTICES],
        facing: slamesh_core::facing::Facing::Unknown,
    }
}
