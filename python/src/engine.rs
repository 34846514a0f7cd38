//! `Engine`: the pipeline for Python, frame by frame. It is the command's own run
//! ([`slamesh::run::Run`]) fed by a source that holds the frames Python pushes, so a frame
//! goes through the same steps as in `slamesh run` (capacity and scale chosen on the first
//! frame, deskewing, skipping with a reason, the report's record) and the poses are the
//! command's to the bit. Its spools live in a scratch folder, removed with it.

use crate::arrays::{self, MeshArrays};
use crate::{error, FrameError};
use numpy::{PyArray1, PyArray2, PyArray3, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use slamesh::io::FileError;
use slamesh::outputs::mesh_spool::{MeshColour, MeshFormat, MeshSpool};
use slamesh::run::capacity::{self, ClassId};
use slamesh::run::config_file::{self, Settings};
use slamesh::run::scale::fit_to_scene;
use slamesh::run::session::Deskew;
use slamesh::run::{FrameRecord, FrameSource, Run, RunError, RunOptions, Sample};
use slamesh_core::{Capacity, Config, Point, Pose};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// The frames pushed so far: each one's stamp, and the last one's points until the run reads
/// them (a read takes them: a frame's points are not copied).
#[derive(Default)]
struct Pushed {
    stamps: Vec<f64>,
    frame: Option<(Vec<Point>, Option<Vec<f32>>)>,
    /// The samples pushed with the last frame (an IMU's), until the run takes them.
    samples: Vec<Sample>,
}

impl FrameSource for Pushed {
    fn samples(&mut self, i: usize) -> Vec<Sample> {
        match i + 1 == self.stamps.len() {
            true => std::mem::take(&mut self.samples),
            false => Vec::new(),
        }
    }
    fn frames(&self) -> usize {
        self.stamps.len()
    }
    fn label(&self, _i: usize) -> String {
        "register()".into()
    }
    fn stamp(&self, i: usize) -> f64 {
        self.stamps.get(i).copied().unwrap_or(0.0)
    }
    fn read(&mut self, i: usize) -> Result<Vec<Point>, FileError> {
        self.read_timed(i).map(|(p, _)| p)
    }
    fn read_timed(&mut self, i: usize) -> Result<(Vec<Point>, Option<Vec<f32>>), FileError> {
        match self.frame.take() {
            Some(f) if i + 1 == self.stamps.len() => Ok(f),
            _ => Err(FileError::at(
                Path::new("register()"),
                format!("frame {i} was not pushed"),
            )),
        }
    }
}

/// The used frames' indices (N,), stamps (N,) and poses (N, 4, 4).
type PoseArrays<'py> = (
    Bound<'py, PyArray1<u64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray3<f64>>,
);

/// A run of one capacity class, whichever it is: the command's [`Run`] behind what the
/// engine asks of it (the class is chosen once, by [`slamesh::with_capacity!`]).
trait AnyRun: Send {
    /// Runs frame `i` of `source`: its record, and its pose when it was used.
    fn step(
        &mut self,
        source: &mut Pushed,
        i: usize,
    ) -> Result<(FrameRecord, Option<Pose>), RunError>;
    /// The used frames' indices and poses.
    fn poses(&self) -> &[(usize, Pose)];
    /// The capacity class's name.
    fn class_name(&self) -> &'static str;
    /// The configuration in use.
    fn config(&self) -> Config;
    /// Writes the map's mesh to `path` (welded binary PLY); its vertex and triangle counts.
    fn write_mesh(&self, path: &Path) -> Result<(u64, u64), FileError>;
}

impl<C: Capacity> AnyRun for Run<'static, C> {
    fn step(
        &mut self,
        source: &mut Pushed,
        i: usize,
    ) -> Result<(FrameRecord, Option<Pose>), RunError> {
        let rec = Run::step(self, source, i)?;
        let pose = self
            .poses()
            .last()
            .filter(|(j, _)| *j == i)
            .map(|(_, p)| *p);
        Ok((rec, pose))
    }
    fn poses(&self) -> &[(usize, Pose)] {
        Run::poses(self)
    }
    fn class_name(&self) -> &'static str {
        C::NAME
    }
    fn config(&self) -> Config {
        *self.pipeline().config()
    }
    fn write_mesh(&self, path: &Path) -> Result<(u64, u64), FileError> {
        let p = self.pipeline();
        let mut spool = MeshSpool::new(path, p.config().lattice(), &p.config().mesh)?;
        spool.add_map(p.map())?;
        let counts = spool.finish(&[(path.to_path_buf(), MeshFormat::Ply)])?;
        Ok((counts.vertices, counts.triangles))
    }
}

/// What a run needs before its first frame: the settings, the class asked for and the
/// options the run will take.
struct Start {
    settings: Settings,
    /// The class asked for; `None`: chosen on the first frame.
    capacity: Option<ClassId>,
    opts: RunOptions,
}

/// Where an engine stands.
enum Stage {
    /// No frame yet.
    Waiting(Box<Start>),
    Running(Box<dyn AnyRun>),
    /// A run that could not start keeps the reason.
    Failed(String),
}

struct State {
    source: Pushed,
    stage: Stage,
    /// The preset the settings started from (a configuration file names its own), for
    /// `config_toml`.
    preset: String,
}

/// The pipeline (see the package's `slamesh.Pipeline`).
#[pyclass(module = "slamesh._slamesh")]
pub struct Engine {
    state: Mutex<State>,
    scratch: PathBuf,
}

#[pymethods]
impl Engine {
    #[new]
    #[pyo3(signature = (preset=None, config=None, capacity="auto", threads=0, deskew=true))]
    fn new(
        preset: Option<String>,
        config: Option<PathBuf>,
        capacity: &str,
        threads: usize,
        deskew: bool,
    ) -> PyResult<Self> {
        if preset.is_some() && config.is_some() {
            return Err(PyValueError::new_err(
                "preset and config: give one (a configuration file names every parameter)",
            ));
        }
        let capacity = match capacity {
            "auto" => None,
            flag => Some(ClassId::from_flag(flag).ok_or_else(|| {
                let flags: Vec<_> = ClassId::ALL.iter().map(|c| c.flag()).collect();
                PyValueError::new_err(format!(
                    "capacity: {flag:?} is not one of auto, {}",
                    flags.join(", ")
                ))
            })?),
        };
        let settings = match &config {
            Some(path) => config_file::read(path).map_err(error)?,
            None => config_file::preset_settings(preset.as_deref().unwrap_or("default"))
                .map_err(|e| PyValueError::new_err(format!("preset: {e}")))?,
        };
        let scratch = scratch_folder().map_err(error)?;
        let opts = RunOptions {
            out: scratch.clone(),
            preset: settings.preset.to_string(),
            window: settings.window,
            threads,
            mesh_formats: vec![MeshFormat::Ply],
            mesh_colour: MeshColour::None,
            input: "Python".into(),
            deskew: if deskew { Deskew::Auto } else { Deskew::Off },
            ..RunOptions::default()
        };
        Ok(Engine {
            state: Mutex::new(State {
                preset: settings.preset.to_string(),
                source: Pushed::default(),
                stage: Stage::Waiting(Box::new(Start {
                    settings,
                    capacity,
                    opts,
                })),
            }),
            scratch,
        })
    }

    /// Registers one frame: its report record (JSON) and its pose, or `FrameError` when the
    /// frame was skipped. `imu`: the IMU's readings since the last frame, (M, 7) rows of
    /// time, gyro x y z (rad/s), accelerometer x y z (m/s²). The GIL is released while it runs.
    #[pyo3(signature = (points, times, stamp, imu=None))]
    fn register<'py>(
        &self,
        py: Python<'py>,
        points: PyReadonlyArray2<'py, f32>,
        times: Option<PyReadonlyArray1<'py, f32>>,
        stamp: f64,
        imu: Option<PyReadonlyArray2<'py, f64>>,
    ) -> PyResult<(String, Bound<'py, PyArray2<f64>>)> {
        let points = arrays::points(&points)?;
        let times = times.map(|t| arrays::times(&t, points.len())).transpose()?;
        let samples = imu
            .map(|a| arrays::imu(&a))
            .transpose()?
            .unwrap_or_default();
        if !stamp.is_finite() {
            return Err(PyValueError::new_err(format!(
                "stamp: {stamp} is not finite"
            )));
        }
        let (record, pose) = py
            .detach(|| {
                let mut state = self.lock();
                let State { source, stage, .. } = &mut *state;
                source.stamps.push(stamp);
                source.frame = Some((points, times));
                source.samples = samples;
                let i = source.stamps.len() - 1;
                if let Stage::Waiting(_) = stage {
                    *stage = start(stage, source);
                }
                let result = match stage {
                    Stage::Running(run) => run.step(source, i).map_err(|e| e.to_string()),
                    Stage::Failed(e) => Err(e.clone()),
                    Stage::Waiting(_) => Err("the run did not start".into()),
                };
                source.frame = None;
                result
            })
            .map_err(error)?;
        let json = serde_json::to_string(&record).map_err(error)?;
        match (pose, &record.error) {
            (Some(p), _) => Ok((json, arrays::pose_array(py, &p))),
            (None, Some(e)) => Err(FrameError::new_err(e.clone())),
            (None, None) => Err(FrameError::new_err(format!(
                "frame {}: no pose",
                record.frame
            ))),
        }
    }

    /// The used frames' indices, stamps and poses ((N,), (N,), (N, 4, 4)).
    fn poses<'py>(&self, py: Python<'py>) -> PoseArrays<'py> {
        let state = self.lock();
        let poses: &[(usize, Pose)] = match &state.stage {
            Stage::Running(run) => run.poses(),
            _ => &[],
        };
        let index = poses.iter().map(|(i, _)| *i as u64).collect();
        let stamps = poses.iter().map(|(i, _)| state.source.stamp(*i)).collect();
        let p: Vec<Pose> = poses.iter().map(|(_, p)| *p).collect();
        (
            arrays::vector(py, index),
            arrays::vector(py, stamps),
            arrays::pose_stack(py, &p),
        )
    }

    /// Writes `poses_kitti.txt` and `poses_tum.txt` into `folder` (created if missing), as
    /// the command writes them.
    fn save_trajectories(&self, py: Python<'_>, folder: PathBuf) -> PyResult<()> {
        py.detach(|| {
            std::fs::create_dir_all(&folder)
                .map_err(|e| FileError::at(&folder, format!("cannot create: {e}")))?;
            let state = self.lock();
            let poses: &[(usize, Pose)] = match &state.stage {
                Stage::Running(run) => run.poses(),
                _ => &[],
            };
            let stamped: Vec<(usize, f64, Pose)> = poses
                .iter()
                .map(|&(i, p)| (i, state.source.stamp(i), p))
                .collect();
            slamesh::run::files::write_trajectories(&folder, state.source.frames(), &stamped)
        })
        .map_err(error)
    }

    /// Writes the map's mesh to `path` as `slamesh run` writes `mesh.ply` (welded, binary PLY
    /// with normals and variances); returns its vertex and triangle counts.
    fn save_mesh(&self, py: Python<'_>, path: PathBuf) -> PyResult<(u64, u64)> {
        py.detach(|| self.write_mesh(&path)).map_err(error)
    }

    /// The map's mesh as arrays: what `save_mesh` writes.
    fn mesh<'py>(&self, py: Python<'py>) -> PyResult<MeshArrays<'py>> {
        let path = self.scratch.join("mesh-for-python.ply");
        let mesh = py
            .detach(|| {
                self.write_mesh(&path)?;
                let m = slamesh::formats::ply::read_ply_mesh(&path);
                let _ = std::fs::remove_file(&path);
                m
            })
            .map_err(error)?;
        Ok(arrays::mesh(py, mesh))
    }

    /// The capacity class in use (`None` before the first frame).
    #[getter]
    fn capacity(&self) -> Option<&'static str> {
        match &self.lock().stage {
            Stage::Running(run) => Some(run.class_name()),
            _ => None,
        }
    }

    /// The configuration in use, as the TOML file `slamesh config` prints (before the first
    /// frame: the preset's, not yet fitted to the scene).
    #[getter]
    fn config_toml(&self) -> String {
        let state = self.lock();
        let config = match &state.stage {
            Stage::Running(run) => run.config(),
            Stage::Waiting(start) => start.settings.config,
            Stage::Failed(_) => slamesh_core::Config::default(),
        };
        slamesh::run::config_file::documented_toml(&config, &state.preset)
    }
}

impl Engine {
    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn write_mesh(&self, path: &Path) -> Result<(u64, u64), FileError> {
        let state = self.lock();
        let Stage::Running(run) = &state.stage else {
            return Err(FileError::at(path, "no mesh yet: no frame was registered"));
        };
        run.write_mesh(path)
    }
}

impl Drop for Engine {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.scratch);
    }
}

/// The run for the first frame, as the command starts one: the configuration fitted to its
/// scale (when the preset scales itself), the capacity class chosen by its points.
fn start(stage: &mut Stage, source: &mut Pushed) -> Stage {
    let Stage::Waiting(start) = std::mem::replace(stage, Stage::Failed(String::new())) else {
        return Stage::Failed("the run had started".into());
    };
    let Start {
        mut settings,
        capacity,
        opts,
    } = *start;
    // The fit and the choice read the first frame, which the run then reads again: only this
    // frame's points are copied.
    let first = source.frame.clone();
    fit_to_scene(&mut settings, source);
    source.frame.clone_from(&first);
    let opts = RunOptions {
        config: settings.config,
        ..opts
    };
    let class = capacity.unwrap_or_else(|| capacity::choose(source, &opts).id);
    source.frame = first;
    let run = slamesh::with_capacity!(class, C => Run::<C>::start(source, opts)
        .map(|r| Box::new(r) as Box<dyn AnyRun>));
    match run {
        Ok(r) => Stage::Running(r),
        Err(e) => Stage::Failed(RunError::to_string(&e)),
    }
}

/// A new folder for an engine's spools, in the system's temporary folder.
fn scratch_folder() -> Result<PathBuf, FileError> {
    use std::sync::atomic::{AtomicU64, Ordering};
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let dir = std::env::temp_dir().join(format!(
        "slamesh-python-{}-{}",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&dir)
        .map_err(|e| FileError::at(&dir, format!("cannot create a scratch folder: {e}")))?;
    Ok(dir)
}
