//! The extension module `slamesh._slamesh`: the Rust side of slamesh's Python package.
//!
//! The package (`python/slamesh/`) is the API a Python user sees; it checks arrays and
//! arguments and words their errors, then calls this module, which owns no math of its own:
//!
//! | what | module |
//! |---|---|
//! | the pipeline, step by step: a [`slamesh::run::Run`] fed pushed frames | `engine` |
//! | the command's readers, frame by frame | `source` |
//! | numpy arrays in and out | `arrays` |
//!
//! Guarantees: the GIL is released while slamesh works (registration, reading, meshing, a
//! whole command); every failure is a Python exception whose message is the one the command
//! prints; nothing here panics on what Python passes.

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

mod arrays;
mod engine;
mod source;

create_exception!(
    slamesh,
    SlameshError,
    PyException,
    "A file, an input or a setting slamesh cannot use; the message is the command's."
);
create_exception!(
    slamesh,
    FrameError,
    SlameshError,
    "A frame the pipeline skipped (the message names it and says why); the pipeline goes on."
);

/// A failure as a `SlameshError` with its message.
pub(crate) fn error(e: impl std::fmt::Display) -> PyErr {
    SlameshError::new_err(e.to_string())
}

/// Runs a subcommand of the `slamesh` command from its arguments (`["run", "scans/", "--out",
/// "out/"]`), as the command runs it; raises `SlameshError` with the command's message when it
/// fails. The GIL is released meanwhile.
#[pyfunction]
fn command(py: Python<'_>, args: Vec<String>) -> PyResult<()> {
    py.detach(|| slamesh::cli::run_args(args)).map_err(error)
}

/// The vertices, triangles, normals and variances of a PLY mesh (normals and variances empty
/// when the file has none).
#[pyfunction]
fn read_mesh<'py>(py: Python<'py>, path: std::path::PathBuf) -> PyResult<arrays::MeshArrays<'py>> {
    let mesh = py
        .detach(|| slamesh::formats::ply::read_ply_mesh(&path))
        .map_err(error)?;
    Ok(arrays::mesh(py, mesh))
}

/// The module.
#[pymodule]
fn _slamesh(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("SlameshError", py.get_type::<SlameshError>())?;
    m.add("FrameError", py.get_type::<FrameError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("PRESETS", slamesh::run::config_file::PRESETS.to_vec())?;
    m.add_function(wrap_pyfunction!(command, m)?)?;
    m.add_function(wrap_pyfunction!(read_mesh, m)?)?;
    m.add_class::<engine::Engine>()?;
    m.add_class::<source::Source>()?;
    Ok(())
}
