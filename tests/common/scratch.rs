//! A test's scratch folder: fresh when made, gone when the test passes.
//!
//! The tests write whole runs (meshes, maps, spools: some hundreds of megabytes each) into the
//! system's temporary folder. Left there, every `cargo test` added gigabytes, and a CI machine
//! ran out of disk. A failing test keeps its folder for a look and says where it is.

use std::ops::Deref;
use std::path::{Path, PathBuf};

/// A folder of this process for one test, removed when dropped unless the thread is
/// panicking (a failing test).
pub struct Scratch(PathBuf);

/// A fresh, empty folder for the test `name`: `slamesh-test-<name>-<process>` in the system's
/// temporary folder.
pub fn scratch(name: &str) -> Scratch {
    let d = std::env::temp_dir().join(format!("slamesh-test-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    Scratch(d)
}

impl Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if std::thread::panicking() {
            eprintln!("the failing test's files are kept in {}", self.0.display());
        } else if let Err(e) = std::fs::remove_dir_all(&self.0) {
            // Removed by the test itself is fine; anything else is worth a line, not a failure.
            if e.kind() != std::io::ErrorKind::NotFound {
                eprintln!("cannot remove {}: {e}", self.0.display());
            }
        }
    }
}
