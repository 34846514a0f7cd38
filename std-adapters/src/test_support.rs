//! Scratch files and small map pieces for unit tests.

use std::ops::Deref;
use std::path::{Path, PathBuf};

// One scratch folder for the unit tests and the integration tests alike.
#[path = "../../tests/common/scratch.rs"]
mod scratch;
pub use scratch::Scratch;

/// A fresh folder for the test `tag`, removed when the test passes ([`Scratch`]).
pub fn scratch_dir(tag: &str) -> Scratch {
    scratch::scratch(tag)
}

/// A file in a scratch folder of its own (so that tests side by side never share one),
/// removed with it.
pub struct ScratchFile {
    path: PathBuf,
    _folder: Scratch,
}

impl Deref for ScratchFile {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.path
    }
}

/// Writes `bytes` to `name` in a scratch folder of `tag` and `name`.
pub fn scratch_file(tag: &str, name: &str, bytes: &[u8]) -> ScratchFile {
    let folder = scratch_dir(&format!("{tag}-{name}"));
    let path = folder.join(name);
    std::fs::write(&path, bytes).unwrap();
    ScratchFile {
        path,
        _folder: folder,
    }
}

/// A flat, certain layer: every triangle shown.
pub fn flat_layer() -> slamesh_core::layer::Layer {
    slamesh_core::layer::Layer {
        pred: [0.5; slamesh_core::lattice::VERTICES],
        var: [0.01; slamesh_core::lattice::VERTICES],
        facing: slamesh_core::facing::Facing::Unknown,
    }
}
