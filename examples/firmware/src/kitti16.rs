//! Real scans: kitti-mini 00's ten HDL-64E scans cut down to 16 beams and the front half
//! (`build.rs` makes them at build time, into the image), tracked by a pipeline of the
//! `Kitti16` capacity in a `static`, each step compared with the reference poses, with QEMU's
//! instruction count a scan ([`crate::clock`]).

use crate::clock;
use cortex_m_semihosting::hprintln;
use slamesh_core::math::pose_from_row;
use slamesh_core::{storage_for, Capacity, Config, Pipeline, Point, Pose};

/// Capacities for the cut KITTI scans: under 8 500 points, 250 cells and 310 layers a scan,
/// 420 cells and 660 layers in the map after ten scans (measured on the host with
/// `slamesh run`), with room to spare.
pub struct Kitti16;
impl Capacity for Kitti16 {
    const POINTS: usize = 9_216;
    const SCAN_CELLS: usize = 512;
    const SCAN_LAYERS: usize = 640;
    const MAP_CELLS: usize = 1_024;
    const MAP_LAYERS: usize = 1_280;
    const RADIX_SORT: bool = false;
}

/// The pipeline's memory.
pub type Memory = storage_for!(Kitti16);
/// Points of one scan at most.
pub const POINTS: usize = Kitti16::POINTS;

include!(concat!(env!("OUT_DIR"), "/kitti16.rs"));
/// The scans' points, `i16` centimetres `x, y, z`; scan `i` ends at point `KITTI16_ENDS[i]`.
static SCANS: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/kitti16.bin"));

/// Acceptance: each step's error against the reference's step.
const STEP_TOLERANCE_M: f64 = 0.05;
const STEP_TOLERANCE_DEG: f64 = 0.5;

/// The LiDAR's reference pose of scan `i`: `inv(Tr) * P_i * Tr`; `None` for a non-finite one.
fn lidar_reference(i: usize) -> Option<Pose> {
    let tr = pose_from_row(&KITTI16_TR)?;
    Some(tr.inverse() * pose_from_row(KITTI16_CAMERA_POSES.get(i)?)? * tr)
}

/// Decodes scan points `[start, end)` into `out`; returns how many.
fn decode(start: usize, end: usize, out: &mut [Point; POINTS]) -> usize {
    let bytes = SCANS.get(start * 6..end * 6).unwrap_or_default();
    let mut n = 0;
    for (p, slot) in bytes.chunks_exact(6).zip(out.iter_mut()) {
        let cm = |k: usize| f32::from(i16::from_le_bytes([p[2 * k], p[2 * k + 1]]));
        *slot = [cm(0) / 100.0, cm(1) / 100.0, cm(2) / 100.0];
        n += 1;
    }
    n
}

/// Tracks the scans and prints each step's error and instructions; true when every step is
/// within the tolerance (or there are no scans: the build had no data).
pub fn run(memory: &'static mut Memory, buffer: &mut [Point; POINTS]) -> bool {
    if KITTI16_ENDS.is_empty() {
        hprintln!("real scans: skipped (SLAMESH_DATA was not set when the firmware was built)");
        return true;
    }
    // The `default` preset as `slamesh run` fits it to these scans: meshing, 1.4 m cells.
    let mut config = Config::meshing();
    config.grid.cell_size_m = 1.4;
    config.gp.kappa_per_m = 1.2;
    config.filter.range_min_m = 1.2;
    let mut pipeline = match Pipeline::<Kitti16, crate::Scalar>::in_storage(config, memory.lend()) {
        Ok(p) => p,
        Err(e) => {
            hprintln!("FAIL: configuration {}: {}", e.field, e.reason);
            return false;
        }
    };
    hprintln!(
        "real scans: kitti-mini 00 cut to 16 beams and the front half, Kitti16 capacity in a static of {} bytes",
        core::mem::size_of::<Memory>()
    );
    let (mut ok, mut start, mut previous) = (true, 0, None::<(Pose, Pose)>);
    let mut instructions = [0u64; KITTI16_ENDS.len()];
    let (mut sum_cm, mut worst_cm, mut worst_deg) = (0.0, 0.0f64, 0.0f64);
    for (i, &end) in KITTI16_ENDS.iter().enumerate() {
        let n = decode(start, end, buffer);
        start = end;
        let Some(reference) = lidar_reference(i) else {
            hprintln!("real scan {}: its reference pose is not finite", i);
            ok = false;
            continue;
        };
        // Profiled (feature `profile`): the steady state, after the first registration.
        #[cfg(feature = "profile")]
        crate::profile::sampling(i >= 2);
        let t0 = clock::ticks();
        let result = pipeline.process_scan(&buffer[..n]);
        instructions[i] = (clock::ticks() - t0) * clock::INSTRUCTIONS_PER_TICK;
        #[cfg(feature = "profile")]
        crate::profile::sampling(false);
        let out = match result {
            Ok(out) => out,
            Err(e) => {
                hprintln!("real scan {}: skipped: {}", i, e);
                ok = false;
                continue;
            }
        };
        let estimate = out.t_world_sensor;
        if let Some((e0, r0)) = previous {
            let d = (e0.inverse() * estimate).inverse() * (r0.inverse() * reference);
            let (cm, deg) = (
                d.translation.vector.norm() * 100.0,
                d.rotation.angle().to_degrees(),
            );
            hprintln!(
                "real scan {}: {} points, {:?}; step error {:.2} cm, {:.3} deg; {} instructions",
                i,
                n,
                out.status,
                cm,
                deg,
                instructions[i]
            );
            sum_cm += cm;
            worst_cm = worst_cm.max(cm);
            worst_deg = worst_deg.max(deg);
            ok &= cm <= STEP_TOLERANCE_M * 100.0 && deg <= STEP_TOLERANCE_DEG;
        } else {
            hprintln!(
                "real scan {}: {} points, {:?}; {} instructions",
                i,
                n,
                out.status,
                instructions[i]
            );
        }
        previous = Some((estimate, reference));
    }
    instructions.sort_unstable();
    hprintln!(
        "real scans: step error mean {:.2} cm, worst {:.2} cm and {:.3} deg (tolerance {} cm, {} deg); median {} instructions a scan under qemu -icount (not a real M4's cycles)",
        sum_cm / (KITTI16_ENDS.len() - 1).max(1) as f64,
        worst_cm,
        worst_deg,
        STEP_TOLERANCE_M * 100.0,
        STEP_TOLERANCE_DEG,
        instructions[instructions.len() / 2]
    );
    ok
}
