//! Memory with 64-beam scans under a tight cap, on a simulated street (no data needed). One
//! test in its own binary, so the process's resident memory is this run's alone.
//!
//! The scans are KITTI-sized (64 beams, 2 000 firings a turn: about 120 000 points within
//! range), so the run needs the 64-beam class's scan buffers. The cap leaves room for them and
//! a small map but not for the look-ahead's filter buffers too: the run reads each frame ahead
//! and filters it in line, evicts the oldest cells to stay within its layer budget, and the
//! process stays under the cap.

mod common;

use slamesh::run::config_file::WindowSettings;
use slamesh::run::lookahead::LookAhead;
use slamesh::run::memory;
use slamesh::run::window::Window;
use slamesh::run::{FrameRecord, Summary};
use slamesh_core::{Capacity, Config, KittiCapacity};
use slamesh_sim::Drive;

/// The 64-beam class's points and map, with a scan's layers at a fifth of its, so that a
/// budget of a few scans' layers fills within this short drive.
struct Beam64;
impl Capacity for Beam64 {
    const POINTS: usize = KittiCapacity::POINTS;
    const SCAN_CELLS: usize = 2_048;
    const SCAN_LAYERS: usize = 2_560;
    const MAP_CELLS: usize = KittiCapacity::MAP_CELLS;
    const MAP_LAYERS: usize = KittiCapacity::MAP_LAYERS;
}

fn drive(d: &mut Drive, window: WindowSettings, name: &str) -> (Vec<FrameRecord>, Summary) {
    common::run_drive::<Beam64>(d, window, &format!("memory64-{name}"))
}

fn street(frames: usize) -> Drive {
    let mut d = Drive::long_street(frames, 1.0, 21);
    d.lidar.azimuth_steps = 2_000;
    d
}

#[test]
fn a_64_beam_drive_stays_under_a_tight_cap() {
    if std::env::var_os("SLAMESH_TEST_RUNNER").is_some() {
        // Under qemu-user, /proc/self/status is the emulator's, translation cache and all.
        println!("skipped: resident memory under an emulator is the emulator's");
        return;
    }
    // A short run first, so that the process's one-time growth (the thread pool, the
    // allocator's arenas) is in the resident memory measured next (as in tests/memory.rs).
    drive(&mut street(3), WindowSettings::default(), "warm-up");
    let mut d = street(400);
    let kept = slamesh::run::capacity::points_in_range(&d.scan(0), &Config::default().filter);
    assert!(
        kept > 100_000,
        "a KITTI-sized scan: {kept} points within range"
    );
    let other = memory::other_bytes();
    let least = Window::least_cap_bytes::<Beam64>(other, false);
    // Room for about 2 000 layers above one scan's, and not for the look-ahead's filter.
    let cap = least + 600_000;
    assert!(
        cap < least + LookAhead::bytes::<Beam64>(),
        "too tight to filter ahead"
    );
    let window = WindowSettings {
        memory_cap_mb: Some(cap as f64 / 1e6),
        ..WindowSettings::default()
    };
    let (records, summary) = drive(&mut d, window, "cap");
    let budget = summary.max_layers.unwrap();
    println!(
        "budget {budget}, map layers at the end {}, evicted {}",
        summary.map_layers, summary.evicted_cells
    );
    common::assert_within_budget(&records, &summary);
    let peak = memory::peak_rss_bytes().expect("peak RSS from /proc/self/status");
    println!(
        "cap {:.1} MB, budget {budget} layers, peak {:.1} MB",
        cap as f64 / 1e6,
        peak as f64 / 1e6
    );
    assert!(
        peak as usize <= cap,
        "peak RSS {:.1} MB over the cap {:.1} MB",
        peak as f64 / 1e6,
        cap as f64 / 1e6
    );
    // Tracked throughout: each step within 5 cm of the truth's.
    let truth = &d.poses;
    for w in summary.poses.windows(2) {
        let ((i, a), (j, b)) = (w[0], w[1]);
        let step = a.inverse() * b;
        let true_step = truth[i].inverse() * truth[j];
        let err = (step.translation.vector - true_step.translation.vector).norm();
        assert!(err < 0.05, "frames {i}-{j}: step off by {err:.3} m");
    }
}
