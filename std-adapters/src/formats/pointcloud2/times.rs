//! Per-point times as seconds relative to the stamp, by the table in
//! [`pointcloud2`](super)'s docs: a cloud's time field, and a point-cloud file's (PCD, PLY),
//! whose stamp comes from its folder.

use super::{datatype, CloudError, Field, MAX_SWEEP_S, TIME_FIELDS};
use slamesh_core::Point;

/// The values `raw` of the time field `name` (a [`datatype`]) as times relative to `stamp` in
/// seconds, by the table in the module's docs; an error says which reading failed and why.
pub fn relative_times(
    name: &str,
    datatype: u8,
    raw: &[f64],
    stamp: f64,
) -> Result<Vec<f32>, CloudError> {
    let f = Field {
        name: name.to_owned(),
        offset: 0,
        datatype,
        count: 1,
    };
    let (lo, hi) = raw
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        });
    if raw.is_empty() {
        return Ok(Vec::new());
    }
    let (scale, offset, unit) = if f.is_integer() {
        (1e-9, 0.0, "nanoseconds since the stamp")
    } else if lo.abs().max(hi.abs()) < 1e6 {
        (1.0, 0.0, "seconds since the stamp")
    } else if f.datatype == datatype::FLOAT64 && lo > 1e15 {
        (1e-9, -stamp, "absolute nanoseconds")
    } else if f.datatype == datatype::FLOAT64 {
        (1.0, -stamp, "absolute seconds")
    } else {
        return Err(CloudError::Times(format!(
            "time field {} (FLOAT32) runs from {lo} to {hi}: too large for relative seconds, \
             too coarse for absolute ones",
            f.name
        )));
    };
    let rel = |v: f64| v * scale + offset;
    let (a, b) = (rel(lo), rel(hi));
    if !(a.is_finite() && b.is_finite()) || a < -MAX_SWEEP_S || b > MAX_SWEEP_S {
        return Err(CloudError::Times(format!(
            "time field {} (datatype {}) read as {unit} gives {a:.3} to {b:.3} s from the stamp, \
             outside +-{MAX_SWEEP_S} s; no reading in the table fits",
            f.name, f.datatype
        )));
    }
    Ok(raw.iter().map(|&v| rel(v) as f32).collect())
}

/// A point-cloud file's (PCD, PLY) time field: the first of [`TIME_FIELDS`] that `position`
/// finds among its fields.
pub fn file_time_field(position: impl Fn(&str) -> Option<usize>) -> Option<usize> {
    TIME_FIELDS.iter().find_map(|n| position(n))
}

/// A point-cloud file's values, read `x, y, z` (and the time, when `time` names its field, its
/// [`datatype`] and the file's stamp) a point, as points and times relative to the stamp by
/// [`file_relative_times`].
pub fn file_points_and_times(
    rows: &[f64],
    time: Option<(&str, u8, f64)>,
) -> Result<(Vec<Point>, Option<Vec<f32>>), CloudError> {
    let n = if time.is_some() { 4 } else { 3 };
    let points = rows
        .chunks_exact(n)
        .map(|r| [r[0] as f32, r[1] as f32, r[2] as f32])
        .collect();
    let Some((name, datatype, stamp)) = time else {
        return Ok((points, None));
    };
    let raw: Vec<f64> = rows.chunks_exact(n).map(|r| r[3]).collect();
    Ok((
        points,
        Some(file_relative_times(name, datatype, &raw, stamp)?),
    ))
}

/// [`relative_times`] for a point-cloud file (PCD, PLY) whose stamp comes from its folder:
/// absolute times that do not fit that stamp (assumed 10 Hz, or another clock) are taken
/// from the scan's earliest point instead, as deskewing needs only their differences.
pub fn file_relative_times(
    name: &str,
    datatype: u8,
    raw: &[f64],
    stamp: f64,
) -> Result<Vec<f32>, CloudError> {
    let first = raw.iter().copied().fold(f64::INFINITY, f64::min);
    relative_times(name, datatype, raw, stamp).or_else(|e| match first {
        t if t > 1e15 => relative_times(name, datatype, raw, t * 1e-9),
        t if t > 1e6 => relative_times(name, datatype, raw, t),
        _ => Err(e),
    })
}
