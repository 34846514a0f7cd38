//! slamesh-core on a Cortex-M4F with no allocator: a fixed-capacity pipeline (`Sparse16`,
//! under 1 MB) lives in a `static` (zeroed RAM, `.bss`), tracks a simulated 16-beam sensor
//! through a small room and prints, over semihosting, each estimated pose next to the true
//! one; then tracks real scans cut down to 16 beams ([`kitti16`]) against their reference.
//! Ends with `PASS` (and exit status 0) when every position is within `TOLERANCE_M` and every
//! orientation within `TOLERANCE_DEG` of the truth and every real step within its tolerance,
//! else `FAIL`.
//!
//! The pipelines reconstruct in `f32` ([`Scalar`]), which the M4F's FPU computes; the feature
//! `f64` builds the same firmware in `f64`, done in software routines here, for comparison
//! (docs/design.md §1.17).
//!
//! Run it under QEMU (`qemu-system-arm`, board `mps2-an386`): `cargo run --release` in this
//! folder (the runner is set in `.cargo/config.toml`), `--features f64` for the other build.
//! The link writes `target/slamesh-firmware.map`, whose section sizes `.ci/run` prints as
//! the footprint; `tools/firmware_compare.py` compares the two builds.
#![no_std]
#![no_main]

mod clock;
mod kitti16;
#[cfg(feature = "profile")]
mod profile;

use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};
use slamesh_core::{storage_for, Capacity, Config, Pipeline, Point, Pose};

/// Capacities for a 16-beam sensor with 360 firings a turn in rooms and corridors: a few
/// hundred cells per scan and in the map.
struct Sparse16;
impl Capacity for Sparse16 {
    const POINTS: usize = 6_144;
    const SCAN_CELLS: usize = 256;
    const SCAN_LAYERS: usize = 384;
    const MAP_CELLS: usize = 512;
    const MAP_LAYERS: usize = 768;
    // The comparison sort: 147 KB less RAM, and 6 144 points sort quickly either way.
    const RADIX_SORT: bool = false;
}

/// The scalar of the pipelines' reconstruction (`slamesh_core::Real`): `f32`, which the M4F's
/// FPU computes, or `f64` (feature `f64`, in software here), the build it is compared with.
#[cfg(not(feature = "f64"))]
pub type Scalar = f32;
/// The scalar of the pipelines' reconstruction: `f64` (feature `f64`).
#[cfg(feature = "f64")]
pub type Scalar = f64;

/// The pipeline's memory, sized at compile time by `Sparse16`.
type Memory = storage_for!(Sparse16);

/// Cell edge (metres).
const CELL_M: f64 = 0.8;
/// Firings per turn of the simulated sensor.
const FIRINGS: usize = 360;
/// Points of one simulated scan at most.
const SCAN_POINTS: usize = 16 * FIRINGS;
/// Acceptance: position error (metres) and orientation error (degrees) of every frame.
const TOLERANCE_M: f64 = 0.03;
const TOLERANCE_DEG: f64 = 1.0;
/// Frames driven.
const FRAMES: usize = 6;

/// Everything this program keeps: the pipelines' buffers and a scan for each.
struct Statics {
    memory: Memory,
    scan: [Point; SCAN_POINTS],
    kitti: kitti16::Memory,
    kitti_scan: [Point; kitti16::POINTS],
}

static mut STATICS: Statics = Statics {
    memory: Memory::new(),
    scan: [[0.0; 3]; SCAN_POINTS],
    kitti: kitti16::Memory::new(),
    kitti_scan: [[0.0; 3]; kitti16::POINTS],
};

/// An axis-aligned box: min and max corners.
type Aabb = ([f64; 3], [f64; 3]);

/// The room (its inside is seen) and the objects in it (their outsides are seen).
const ROOM: Aabb = ([-4.6, -3.7, 0.0], [4.9, 4.1, 3.0]);
const OBJECTS: [Aabb; 3] = [
    ([1.8, 1.2, 0.0], [2.6, 2.3, 1.4]),     // a cupboard
    ([-3.0, -2.9, 0.0], [-2.2, -2.1, 0.9]), // a crate
    ([-0.4, 2.9, 0.0], [0.4, 4.1, 2.2]),    // a wall pillar
];

/// Entry and exit ranges of a ray through a box (slab test).
fn slabs(o: &[f64; 3], d: &[f64; 3], b: &Aabb) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
    for k in 0..3 {
        if libm::fabs(d[k]) < 1e-12 {
            if o[k] < b.0[k] || o[k] > b.1[k] {
                return (f64::INFINITY, f64::NEG_INFINITY);
            }
            continue;
        }
        let (s0, s1) = ((b.0[k] - o[k]) / d[k], (b.1[k] - o[k]) / d[k]);
        lo = lo.max(s0.min(s1));
        hi = hi.min(s0.max(s1));
    }
    (lo, hi)
}

/// Range to the first surface along a unit ray from inside the room.
fn cast(o: &[f64; 3], d: &[f64; 3]) -> f64 {
    let mut best = slabs(o, d, &ROOM).1;
    for b in &OBJECTS {
        let (lo, hi) = slabs(o, d, b);
        if lo <= hi && lo > 0.0 && lo < best {
            best = lo;
        }
    }
    best
}

/// A level sensor pose at `(x, y, z)` heading `yaw` radians.
fn pose(x: f64, y: f64, z: f64, yaw: f64) -> Pose {
    Pose::from_parts(
        nalgebra::Translation3::new(x, y, z),
        nalgebra::UnitQuaternion::from_euler_angles(0.0, 0.0, yaw),
    )
}

/// A 16-beam scan (-30 to +30 degrees, `FIRINGS` a turn) from `t_world_sensor`, in the
/// sensor frame, with uniform ±1 cm range noise from a seeded generator, written into `out`;
/// returns the number of points.
fn scan(t: &Pose, seed: u64, out: &mut [Point; SCAN_POINTS]) -> usize {
    let mut n = 0;
    let mut state = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
    let mut noise = move || {
        // xorshift64*: uniform in [-1, 1).
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        (state.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    };
    let o = t.translation.vector;
    for beam in 0..16 {
        let el = (-30.0 + 4.0 * beam as f64) * core::f64::consts::PI / 180.0;
        for step in 0..FIRINGS {
            let az = core::f64::consts::TAU * step as f64 / FIRINGS as f64;
            let ds = nalgebra::Vector3::new(
                libm::cos(el) * libm::cos(az),
                libm::cos(el) * libm::sin(az),
                libm::sin(el),
            );
            let dw = t.rotation * ds;
            let r = cast(&[o.x, o.y, o.z], &[dw.x, dw.y, dw.z]);
            if r.is_finite() && r < 30.0 {
                let r = r + 0.01 * noise();
                if let Some(p) = out.get_mut(n) {
                    *p = [(ds.x * r) as f32, (ds.y * r) as f32, (ds.z * r) as f32];
                    n += 1;
                }
            }
        }
    }
    n
}

#[entry]
fn main() -> ! {
    // SAFETY: `main` runs once and never returns; this is the only place `STATICS` is named,
    // so the reference is the only one there ever is.
    #[allow(unsafe_code)]
    let statics: &'static mut Statics = unsafe { &mut *core::ptr::addr_of_mut!(STATICS) };
    let Statics {
        memory,
        scan: points,
        kitti,
        kitti_scan,
    } = statics;
    match cortex_m::Peripherals::take() {
        Some(mut p) => clock::start(&mut p.SYST),
        None => hprintln!("no SysTick: instruction counts will read 0"),
    }
    hprintln!(
        "slamesh-core on Cortex-M4F, no allocator, reconstruction in {}: Sparse16 capacity in a static of {} bytes (Capacity::memory_bytes {}; POINTS {}, SCAN_CELLS {}, MAP_CELLS {}, MAP_LAYERS {})",
        <Scalar as slamesh_core::Real>::NAME,
        core::mem::size_of::<Memory>(),
        Sparse16::memory_bytes(),
        Sparse16::POINTS,
        Sparse16::SCAN_CELLS,
        Sparse16::MAP_CELLS,
        Sparse16::MAP_LAYERS
    );
    // Indoors, at a few metres' range: cells of 0.8 m instead of KITTI's 1.6 m.
    let mut config = Config::default();
    config.grid.cell_size_m = CELL_M;
    let mut pipeline = match Pipeline::<Sparse16, Scalar>::in_storage(config, memory.lend()) {
        Ok(p) => p,
        Err(e) => {
            hprintln!("FAIL: configuration {}: {}", e.field, e.reason);
            finish(false)
        }
    };
    let start = pose(-0.8, -0.4, 1.2, 0.1);
    let mut ok = true;
    for i in 0..FRAMES {
        let truth = pose(
            -0.8 + 0.25 * i as f64,
            -0.4 + 0.06 * i as f64,
            1.2,
            0.1 + 0.035 * i as f64,
        );
        let n = scan(&truth, i as u64 + 1, points);
        let relative = start.inverse() * truth;
        match pipeline.process_scan(&points[..n]) {
            Ok(out) => {
                let e = out.t_world_sensor.translation.vector - relative.translation.vector;
                let yaw_err = (out.t_world_sensor.rotation.inverse() * relative.rotation)
                    .angle()
                    .to_degrees();
                let t = out.t_world_sensor.translation.vector;
                let r = relative.translation.vector;
                hprintln!(
                    "frame {}: {} points, {:?}; estimate ({:.3}, {:.3}, {:.3}) truth ({:.3}, {:.3}, {:.3}); error {:.2} cm, {:.3} deg",
                    i,
                    n,
                    out.status,
                    t.x, t.y, t.z, r.x, r.y, r.z,
                    e.norm() * 100.0,
                    yaw_err
                );
                ok &= e.norm() <= TOLERANCE_M && yaw_err <= TOLERANCE_DEG;
            }
            Err(e) => {
                hprintln!("frame {}: skipped: {}", i, e);
                ok = false;
            }
        }
    }
    hprintln!(
        "map: {} cells, {} layers; tolerance {} cm, {} deg",
        pipeline.map().cell_count(),
        pipeline.map().layer_count(),
        TOLERANCE_M * 100.0,
        TOLERANCE_DEG
    );
    ok &= kitti16::run(kitti, kitti_scan);
    #[cfg(feature = "profile")]
    profile::print();
    hprintln!("{}", if ok { "PASS" } else { "FAIL" });
    finish(ok)
}

/// Ends the run with QEMU's exit status (semihosting), then waits.
fn finish(ok: bool) -> ! {
    debug::exit(if ok {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    hprintln!("FAIL: panic: {}", info);
    finish(false)
}
