//! Checkpoints of a run: the map and everything else a killed run needs to resume with
//! `run --resume` and finish exactly as it would have without the interruption.
//!
//! A checkpoint is one file, `checkpoint.bin` in the output folder, written atomically (a kill
//! while writing leaves the previous one). It holds:
//! - a fingerprint of the run (input, frame count, configuration, window, capacity, given
//!   poses): resuming a different run is refused, naming the difference;
//! - the frame to resume at, the pipeline's frame counter and motion history;
//! - the session's running totals: poses, skipped frames, evicted cells, stage times, seconds;
//! - how many bytes of the frame-record spool and how many mesh-spool records belong to it
//!   (resuming cuts the spools back to those lengths: frames after the checkpoint are redone);
//! - the IMU's state ([`crate::inertial::state`]: its readings held, bias and checks);
//! - every map cell with its last-seen frame and layers (facings included), bit for bit.
//!
//! The encoding is little-endian and versioned; every read is checked, so a damaged file is
//! a [`FileError`] naming it, never a panic.

use crate::io::atomic::write_atomic;
use crate::io::error::FileError;
use crate::io::le::{put_f64, put_pose, put_str, put_u32, put_u64, Damaged, Decoder};
use crate::outputs::mesh_spool::MeshCounts;
use crate::run::timing::StageMs;
use slamesh_core::cell::{Axis, CellKey};
use slamesh_core::facing::Facing;
use slamesh_core::lattice::VERTICES;
use slamesh_core::layer::Layer;
use slamesh_core::map::MeshMap;
use slamesh_core::motion::ConstantVelocity;
use slamesh_core::Pose;
use std::io::Write;
use std::path::{Path, PathBuf};

const MAGIC: &[u8; 12] = b"SLAMESH-CKPT";
/// 2: each layer's facing after its axis. 3: the IMU's state after the mesh's counts. 4: the
/// IMU's trust ([`crate::inertial::trust`]) in place of its misses and reason.
const VERSION: u32 = 5;

/// The checkpoint file of the output folder `out`.
pub fn path(out: &Path) -> PathBuf {
    out.join("checkpoint.bin")
}

/// The state of a run after frame `next_frame - 1`, without the map (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Progress {
    /// What run this is (see the module docs).
    pub fingerprint: String,
    /// The first frame still to do.
    pub next_frame: usize,
    /// The pipeline's frame counter.
    pub pipeline_frames: u32,
    /// The motion model's `(before, last)` poses.
    pub motion: (Option<Pose>, Option<Pose>),
    /// The pose of each used frame so far, frame index first.
    pub poses: Vec<(usize, Pose)>,
    /// Messages of the frames skipped so far.
    pub skipped: Vec<String>,
    /// Cells evicted so far.
    pub evicted_cells: usize,
    /// Stage times of the used frames so far.
    pub used_ms: Vec<StageMs>,
    /// Wall time of the frame loop so far (seconds).
    pub seconds: f64,
    /// Length of the frame-record spool at the checkpoint.
    pub report_bytes: u64,
    /// Records of the mesh spool at the checkpoint.
    pub mesh: MeshCounts,
    /// The run's stages' state ([`Stages::save`](crate::stage::Stages::save): the IMU's;
    /// empty before the first checkpoint).
    pub stages: Vec<u8>,
}

impl Progress {
    /// The progress of a run that has not begun, identified by `fingerprint`.
    pub fn new(fingerprint: String) -> Self {
        Progress {
            fingerprint,
            next_frame: 0,
            pipeline_frames: 0,
            motion: (None, None),
            poses: Vec::new(),
            skipped: Vec::new(),
            evicted_cells: 0,
            used_ms: Vec::new(),
            seconds: 0.0,
            report_bytes: 0,
            mesh: MeshCounts::default(),
            stages: Vec::new(),
        }
    }

    /// The motion model this progress had.
    pub fn motion_model(&self) -> ConstantVelocity {
        ConstantVelocity::from_history(self.motion.0, self.motion.1)
    }
}

/// Writes `progress` and `map` to `file`, atomically.
pub fn write(file: &Path, progress: &Progress, map: &MeshMap) -> Result<(), FileError> {
    let mut e = Vec::with_capacity(64 + map.layer_count() * (8 * VERTICES + 24));
    e.extend_from_slice(MAGIC);
    put_u32(&mut e, VERSION);
    put_str(&mut e, &progress.fingerprint);
    put_u64(&mut e, progress.next_frame as u64);
    put_u32(&mut e, progress.pipeline_frames);
    for p in [progress.motion.0, progress.motion.1] {
        e.push(u8::from(p.is_some()));
        put_pose(&mut e, &p.unwrap_or_else(Pose::identity));
    }
    put_u64(&mut e, progress.poses.len() as u64);
    for (i, p) in &progress.poses {
        put_u64(&mut e, *i as u64);
        put_pose(&mut e, p);
    }
    put_u64(&mut e, progress.skipped.len() as u64);
    for s in &progress.skipped {
        put_str(&mut e, s);
    }
    put_u64(&mut e, progress.evicted_cells as u64);
    put_u64(&mut e, progress.used_ms.len() as u64);
    for ms in &progress.used_ms {
        for v in ms.values() {
            put_f64(&mut e, v);
        }
    }
    put_f64(&mut e, progress.seconds);
    put_u64(&mut e, progress.report_bytes);
    put_u64(&mut e, progress.mesh.vertices);
    put_u64(&mut e, progress.mesh.triangles);
    put_u64(&mut e, progress.stages.len() as u64);
    e.extend_from_slice(&progress.stages);
    put_u64(&mut e, map.cell_count() as u64);
    for (key, cell) in map.cells() {
        for v in [key.x, key.y, key.z] {
            e.extend_from_slice(&v.to_le_bytes());
        }
        put_u32(&mut e, cell.last_seen);
        let axes: Vec<Axis> = cell.axes().collect();
        e.push(axes.len() as u8);
        for axis in axes {
            let layer = map.layer(&key, axis).copied().unwrap_or(Layer::UNKNOWN);
            e.extend_from_slice(&[axis.index() as u8, layer.facing.bits()]);
            for v in layer.pred.iter().chain(&layer.var) {
                e.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    write_atomic(file, |w| w.write_all(&e))
}

/// Reads `file`, restoring its map into `map` (which must be empty and large enough); returns
/// the progress.
pub fn read(file: &Path, map: &mut MeshMap) -> Result<Progress, FileError> {
    let bytes = std::fs::read(file).map_err(|e| FileError::at(file, e.to_string()))?;
    parse(&bytes, map)
        .map_err(|reason| FileError::at(file, format!("not a usable checkpoint: {reason}")))
}

/// [`read`]'s work on the file's bytes: the progress, the map into `map`, or why not.
pub fn parse(bytes: &[u8], map: &mut MeshMap) -> Result<Progress, Damaged> {
    let mut d = Decoder { bytes };
    let progress = read_progress(&mut d)?;
    read_map(&mut d, map)?;
    if !d.bytes.is_empty() {
        return Err(format!("{} bytes after the map", d.bytes.len()).into());
    }
    Ok(progress)
}

/// The run's progress: the signature and version, then everything before the map.
fn read_progress(d: &mut Decoder) -> Result<Progress, Damaged> {
    if d.take(MAGIC.len())? != MAGIC {
        return Err("it does not start with the checkpoint signature".into());
    }
    let version = d.u32()?;
    if version != VERSION {
        return Err(format!("format version {version}, this program reads {VERSION}").into());
    }
    let fingerprint = d.string()?;
    let next_frame = d.u64()? as usize;
    let pipeline_frames = d.u32()?;
    let mut motion = [None, None];
    for m in &mut motion {
        let known = d.u8()? != 0;
        let pose = d.pose()?;
        *m = known.then_some(pose);
    }
    let n = d.count(8 + 56)?;
    let mut poses = Vec::with_capacity(n);
    for _ in 0..n {
        poses.push((d.u64()? as usize, d.pose()?));
    }
    let n = d.count(4)?;
    let mut skipped = Vec::with_capacity(n);
    for _ in 0..n {
        skipped.push(d.string()?);
    }
    let evicted_cells = d.u64()? as usize;
    let n = d.count(8 * StageMs::NAMES.len())?;
    let mut used_ms = Vec::with_capacity(n);
    for _ in 0..n {
        let mut v = [0.0; StageMs::NAMES.len()];
        for x in &mut v {
            *x = d.f64()?;
        }
        used_ms.push(StageMs::from_values(v));
    }
    Ok(Progress {
        fingerprint,
        next_frame,
        pipeline_frames,
        motion: (motion[0], motion[1]),
        poses,
        skipped,
        evicted_cells,
        used_ms,
        seconds: d.f64()?,
        report_bytes: d.u64()?,
        mesh: MeshCounts {
            vertices: d.u64()?,
            triangles: d.u64()?,
        },
        stages: {
            let n = d.count(1)?;
            d.take(n)?.to_vec()
        },
    })
}

/// The map's cells and layers, into `map`.
fn read_map(d: &mut Decoder, map: &mut MeshMap) -> Result<(), Damaged> {
    let cells = d.count(17)?;
    for _ in 0..cells {
        let key = CellKey::new(d.i32()?, d.i32()?, d.i32()?);
        let last_seen = d.u32()?;
        let axes = d.u8()?;
        for _ in 0..axes {
            let axis = match d.u8()? {
                0 => Axis::X,
                1 => Axis::Y,
                2 => Axis::Z,
                a => return Err(format!("axis {a}").into()),
            };
            let mut layer = Layer::UNKNOWN;
            layer.facing = match d.u8()? {
                f @ 0..=3 => Facing::from_bits(f),
                f => return Err(format!("facing {f}").into()),
            };
            for v in layer.pred.iter_mut().chain(layer.var.iter_mut()) {
                *v = f32::from_le_bytes(d.array()?);
            }
            map.insert_layer(key, axis, layer, last_seen)
                .map_err(|e| format!("its map does not fit this capacity: {e}"))?;
        }
    }
    Ok(())
}

/// What identifies a run for resuming: its input, frames, capacity, configuration, window and
/// given poses (the thread count is left out: it does not change the results).
pub fn fingerprint<C: slamesh_core::Capacity>(
    source: &impl crate::sources::FrameSource,
    opts: &crate::run::options::RunOptions,
) -> String {
    format!(
        "input {:?}, {} frames, capacity {}, config {:?}, window {:?}, {} given poses",
        opts.input,
        source.frames(),
        std::any::type_name::<C>(),
        opts.config,
        opts.window,
        opts.given_poses.as_ref().map_or(0, |t| t.poses.len())
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};
    use slamesh_core::lattice::Lattice;

    fn sample() -> (Progress, MeshMap) {
        let lattice = Lattice {
            cell_size: 1.6,
            full_cover: false,
        };
        let mut map = MeshMap::with_capacity(16, 16, lattice);
        let mut layer = Layer::UNKNOWN;
        for (j, (p, v)) in layer.pred.iter_mut().zip(&mut layer.var).enumerate() {
            *p = 0.1 + j as f32 * 0.013;
            *v = 0.3 / (1.0 + j as f32);
        }
        map.insert_layer(CellKey::new(-3, 7, 0), Axis::Z, layer, 4)
            .unwrap();
        map.insert_layer(CellKey::new(-3, 7, 0), Axis::X, Layer::UNKNOWN, 5)
            .unwrap();
        map.insert_layer(CellKey::new(9, -1, 2), Axis::Y, layer, 2)
            .unwrap();
        let pose = Pose::from_parts(
            Translation3::new(1.5, -2.25, 0.125),
            UnitQuaternion::from_euler_angles(0.01, -0.02, 0.3),
        );
        let progress = Progress {
            fingerprint: "input=x frames=9".into(),
            next_frame: 6,
            pipeline_frames: 6,
            motion: (Some(Pose::identity()), Some(pose)),
            poses: vec![(0, Pose::identity()), (2, pose)],
            skipped: vec!["frame 1: empty file".into()],
            evicted_cells: 3,
            used_ms: vec![StageMs::from_values([
                1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0,
            ])],
            seconds: 0.75,
            report_bytes: 1234,
            mesh: MeshCounts {
                vertices: 10,
                triangles: 7,
            },
            stages: vec![3, 1, 4, 1, 5],
        };
        (progress, map)
    }

    #[test]
    fn a_checkpoint_reads_back_bit_for_bit() {
        let dir = crate::test_support::scratch_dir("checkpoint");
        let (progress, map) = sample();
        let file = path(&dir);
        write(&file, &progress, &map).unwrap();
        let mut back = MeshMap::with_capacity(16, 16, *map.lattice());
        assert_eq!(read(&file, &mut back).unwrap(), progress);
        let mut a: Vec<_> = map
            .cells()
            .flat_map(|(k, c)| c.axes().map(|x| (k, x, c.last_seen)).collect::<Vec<_>>())
            .collect();
        let mut b: Vec<_> = back
            .cells()
            .flat_map(|(k, c)| c.axes().map(|x| (k, x, c.last_seen)).collect::<Vec<_>>())
            .collect();
        a.sort();
        b.sort();
        assert_eq!(a, b);
        for (key, axis, _) in a {
            assert_eq!(map.layer(&key, axis), back.layer(&key, axis));
        }
    }

    #[test]
    fn damaged_checkpoints_are_errors_naming_the_file() {
        let dir = crate::test_support::scratch_dir("checkpoint-damaged");
        let (progress, map) = sample();
        let file = path(&dir);
        write(&file, &progress, &map).unwrap();
        let good = std::fs::read(&file).unwrap();
        let lattice = *map.lattice();
        for cut in [0, 5, 20, good.len() / 2, good.len() - 1] {
            std::fs::write(&file, &good[..cut]).unwrap();
            let e = read(&file, &mut MeshMap::with_capacity(16, 16, lattice)).unwrap_err();
            assert_eq!(e.path, file);
            assert!(e.reason.starts_with("not a usable checkpoint"), "{e}");
        }
        let mut other = good.clone();
        other[12] = 9;
        std::fs::write(&file, &other).unwrap();
        let e = read(&file, &mut MeshMap::with_capacity(16, 16, lattice)).unwrap_err();
        assert!(e.reason.contains("version 9"), "{e}");
        // A map bigger than the capacity it is read into.
        std::fs::write(&file, &good).unwrap();
        let e = read(&file, &mut MeshMap::with_capacity(1, 16, lattice)).unwrap_err();
        assert!(e.reason.contains("capacity"), "{e}");
    }
}
