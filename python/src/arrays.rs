//! numpy arrays in and out: points and times checked into slamesh's types (a wrong shape or
//! length is a `ValueError`, never a panic), poses and meshes out as float arrays.

use numpy::ndarray::{Array1, Array2, Array3};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use slamesh::formats::ply::PlyMesh;
use slamesh::sources::{ImuReading, Sample};
use slamesh_core::{Point, Pose};

/// A mesh as arrays: vertices (V, 3), triangles (F, 3), normals (V, 3) or (0, 3), variances
/// (V,) or (0,).
pub(crate) type MeshArrays<'py> = (
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray2<u32>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray1<f32>>,
);

/// An (N, 3) array's rows as points.
pub(crate) fn points(a: &PyReadonlyArray2<'_, f32>) -> PyResult<Vec<Point>> {
    let a = a.as_array();
    if a.ncols() != 3 {
        return Err(PyValueError::new_err(format!(
            "points: an (N, 3) array is needed, this one is {:?}",
            a.shape()
        )));
    }
    Ok(a.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect())
}

/// Per-point times, one for each of `n` points.
pub(crate) fn times(t: &PyReadonlyArray1<'_, f32>, n: usize) -> PyResult<Vec<f32>> {
    let t = t.as_array();
    if t.len() != n {
        return Err(PyValueError::new_err(format!(
            "times: one a point is needed, {} for {n} points",
            t.len()
        )));
    }
    Ok(t.iter().copied().collect())
}

/// The IMU readings among `samples` as an (M, 7) float64 array (the layout [`imu`] takes);
/// `None` when there are none.
pub(crate) fn imu_array<'py>(
    py: Python<'py>,
    samples: &[Sample],
) -> Option<Bound<'py, PyArray2<f64>>> {
    let rows: Vec<[f64; 7]> = samples
        .iter()
        .filter_map(Sample::imu)
        .map(|r| {
            let ([gx, gy, gz], [ax, ay, az]) = (r.gyro, r.accel);
            [r.stamp, gx, gy, gz, ax, ay, az]
        })
        .collect();
    if rows.is_empty() {
        return None;
    }
    let a = Array2::from_shape_fn((rows.len(), 7), |(i, j)| rows[i][j]);
    Some(a.into_pyarray(py))
}

/// IMU readings from an (M, 7) float64 array: time (s), gyro x y z (rad/s), accelerometer
/// x y z (m/s²) a row, every value finite.
pub(crate) fn imu(a: &PyReadonlyArray2<'_, f64>) -> PyResult<Vec<Sample>> {
    let a = a.as_array();
    if a.ncols() != 7 {
        return Err(PyValueError::new_err(format!(
            "imu: an (M, 7) array is needed (time, gyro x y z, accelerometer x y z), this one \
             has {} columns",
            a.ncols()
        )));
    }
    a.rows()
        .into_iter()
        .enumerate()
        .map(|(k, r)| {
            if !r.iter().all(|v| v.is_finite()) {
                return Err(PyValueError::new_err(format!("imu: row {k} is not finite")));
            }
            Ok(Sample::Imu(ImuReading {
                stamp: r[0],
                gyro: [r[1], r[2], r[3]],
                accel: [r[4], r[5], r[6]],
            }))
        })
        .collect()
}

/// Points as an (N, 3) float32 array.
pub(crate) fn point_array<'py>(py: Python<'py>, points: &[Point]) -> Bound<'py, PyArray2<f32>> {
    rows(points.len(), points.iter().flatten().copied()).into_pyarray(py)
}

/// A pose as its 4 x 4 homogeneous matrix.
pub(crate) fn pose_array<'py>(py: Python<'py>, pose: &Pose) -> Bound<'py, PyArray2<f64>> {
    let m = pose.to_homogeneous();
    Array2::from_shape_fn((4, 4), |(r, c)| m[(r, c)]).into_pyarray(py)
}

/// Poses as an (N, 4, 4) array of homogeneous matrices.
pub(crate) fn pose_stack<'py>(py: Python<'py>, poses: &[Pose]) -> Bound<'py, PyArray3<f64>> {
    let m: Vec<_> = poses.iter().map(Pose::to_homogeneous).collect();
    Array3::from_shape_fn((m.len(), 4, 4), |(i, r, c)| m[i][(r, c)]).into_pyarray(py)
}

/// A vector as a 1-D array.
pub(crate) fn vector<'py, T: numpy::Element>(
    py: Python<'py>,
    v: Vec<T>,
) -> Bound<'py, PyArray1<T>> {
    Array1::from_vec(v).into_pyarray(py)
}

/// A mesh's arrays.
pub(crate) fn mesh(py: Python<'_>, m: PlyMesh) -> MeshArrays<'_> {
    (
        point_array(py, &m.vertices),
        Array2::from_shape_fn((m.triangles.len(), 3), |(i, k)| m.triangles[i][k]).into_pyarray(py),
        point_array(py, &m.normals),
        vector(py, m.variances),
    )
}

/// `n` rows of three from a flat iterator.
fn rows(n: usize, flat: impl Iterator<Item = f32>) -> Array2<f32> {
    let v: Vec<f32> = flat.collect();
    // The iterator gives three values a row, so the shape always fits.
    Array2::from_shape_vec((n, 3), v).unwrap_or_else(|_| Array2::zeros((0, 3)))
}
