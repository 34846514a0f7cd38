//! `Source`: what the command reads (a folder of scans, a recording, a packet capture, a live
//! UDP stream), opened as the command opens it ([`slamesh::run::Input`]) and read frame by
//! frame.

use crate::arrays;
use crate::{error, FrameError};
use numpy::{PyArray1, PyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use slamesh::formats::kitti::BinFields;
use slamesh::run::{FrameSource, Input};
use slamesh::sources::packets::PacketOptions;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// One frame: points (N, 3), their times (N,) or `None`, its stamp (seconds), its label and
/// the IMU's readings that came with it ((M, 7) or `None`).
type FrameTuple<'py> = (
    Bound<'py, PyArray2<f32>>,
    Option<Bound<'py, PyArray1<f32>>>,
    f64,
    String,
    Option<Bound<'py, PyArray2<f64>>>,
);

/// An input opened for reading (see the package's `slamesh.read`).
#[pyclass(module = "slamesh._slamesh")]
pub struct Source {
    input: Mutex<Input>,
    /// Set to end a live input.
    stop: Arc<AtomicBool>,
}

#[pymethods]
impl Source {
    /// Opens `path` as `slamesh run` would, with its flags as arguments.
    #[new]
    #[pyo3(signature = (path, topic=None, bin_fields="x,y,z,i", sensor=None, metadata=None,
                        calibration=None, cut_azimuth=None, idle_timeout=None, imu=None,
                        imu_topic=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        path: PathBuf,
        topic: Option<String>,
        bin_fields: &str,
        sensor: Option<String>,
        metadata: Option<PathBuf>,
        calibration: Option<PathBuf>,
        cut_azimuth: Option<f64>,
        idle_timeout: Option<f64>,
        imu: Option<String>,
        imu_topic: Option<String>,
    ) -> PyResult<Self> {
        let fields = BinFields::parse(bin_fields)
            .map_err(|e| PyValueError::new_err(format!("bin_fields: {e}")))?;
        let stop = Arc::new(AtomicBool::new(false));
        let packets = PacketOptions {
            sensor,
            metadata,
            calibration,
            cut_azimuth_deg: cut_azimuth,
            idle: idle_timeout
                .filter(|s| s.is_finite() && *s > 0.0)
                .map(Duration::from_secs_f64),
            stop: stop.clone(),
        };
        let input = py
            .detach(|| {
                let mut input = Input::open_with(&path, topic.as_deref(), fields, &packets)?;
                input.attach_imu(&path, imu.as_deref(), imu_topic.as_deref())?;
                Ok::<_, slamesh::io::FileError>(input)
            })
            .map_err(error)?;
        Ok(Source {
            input: Mutex::new(input),
            stop,
        })
    }

    /// Frames known so far (a live input's grow as they come).
    fn frames(&self) -> usize {
        self.lock().frames()
    }

    /// Whether frame `i` exists; a live input waits for it (or for its end).
    fn has(&self, py: Python<'_>, i: usize) -> bool {
        py.detach(|| self.lock().has(i))
    }

    /// Frame `i`, with the IMU's readings that come with it (the command's rule: those up to a
    /// frame period past its stamp not handed before); raises `FrameError` (naming it) when it
    /// cannot be read.
    fn read<'py>(&self, py: Python<'py>, i: usize) -> PyResult<FrameTuple<'py>> {
        let (read, stamp, label, samples) = py.detach(|| {
            let mut input = self.lock();
            if !input.has(i) {
                return (None, 0.0, String::new(), Vec::new());
            }
            let read = input.read_timed(i);
            let samples = input.samples(i);
            (Some(read), input.stamp(i), input.label(i), samples)
        });
        let Some(read) = read else {
            return Err(pyo3::exceptions::PyIndexError::new_err(format!(
                "frame {i}: the input has no such frame"
            )));
        };
        let (points, times) = read.map_err(|e| FrameError::new_err(e.to_string()))?;
        Ok((
            arrays::point_array(py, &points),
            times.map(|t| arrays::vector(py, t)),
            stamp,
            label,
            arrays::imu_array(py, &samples),
        ))
    }

    /// What was opened: "12 scan files (times from times.txt)", "40 frames of topic /points".
    fn describe(&self) -> String {
        self.lock().describe()
    }

    /// Ends a live input: the frames it has are read, then no more come.
    fn close(&self) {
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
    }
}

impl Source {
    fn lock(&self) -> std::sync::MutexGuard<'_, Input> {
        // A panic while the lock was held cannot leave the input half-changed in a way a
        // reader could misread: take it back.
        self.input.lock().unwrap_or_else(|p| p.into_inner())
    }
}
