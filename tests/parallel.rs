//! The serial and parallel cell loops give bit-identical poses and meshes, and so does the run
//! loop reading and filtering ahead.

use slamesh::parallel::Rayon;
use slamesh_core::executor::{Executor, Serial};
use slamesh_core::pipeline::{Known, Scan};
use slamesh_core::{Config, KittiCapacity, NoProbe, Pipeline, Pose};
use slamesh_sim::{sensor_pose, Lidar, Scene};

fn run(
    cells: &impl Executor,
    config: Config,
    scans: &[Vec<[f32; 3]>],
) -> (Vec<Pose>, Vec<slamesh_core::mesh::Triangle>) {
    let mut p = Pipeline::<KittiCapacity>::new(config).unwrap();
    let poses = scans
        .iter()
        .map(|s| {
            p.step(Scan::Raw(s), Known::Nothing, cells, &mut NoProbe)
                .unwrap()
                .outcome()
                .t_world_sensor
        })
        .collect();
    (poses, p.triangles().collect())
}

#[test]
fn serial_and_parallel_agree_bit_for_bit() {
    let scene = Scene::street();
    let lidar = Lidar::hdl64(900);
    let scans: Vec<_> = (0..5)
        .map(|i| {
            let t = sensor_pose(
                0.9 * i as f64,
                0.05 * i as f64,
                1.73,
                (0.02 * i as f64).to_degrees(),
            );
            lidar.scan(&scene, &t)
        })
        .collect();
    let mut moved = Config::default();
    moved.map.reconstruct_at_final_pose = false;
    for config in [Config::default(), Config::meshing(), moved] {
        let serial = run(&Serial, config, &scans);
        for threads in [1, 2, 4] {
            let parallel = run(&Rayon::new(threads).unwrap(), config, &scans);
            assert_eq!(serial.0, parallel.0, "poses differ with {threads} threads");
            assert_eq!(serial.1, parallel.1, "meshes differ with {threads} threads");
        }
        assert!(!serial.1.is_empty());
    }
}

/// The parallel sort gives the serial sort's order exactly: keys over one to four radix
/// passes, a pass whose digit every entry shares, ties in input order, and sizes around
/// where the parallel sort starts splitting.
#[test]
fn the_parallel_sort_orders_entries_exactly_as_the_serial_one() {
    use slamesh_core::bounded::BoundedVec;
    use slamesh_core::cell::CellKey;
    use slamesh_core::sort::KeySorter;
    let rayon = Rayon::new(3).unwrap();
    let mut seed = 7u64;
    let mut next = move || {
        seed = seed
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (seed >> 33) as i32
    };
    // Parts of at least 16 384 entries (up to the three threads): three from 49 152, two
    // from 32 768.
    let capacity = 200_000;
    let (mut serial_sorter, mut parallel_sorter) = (
        KeySorter::with_capacity(capacity),
        KeySorter::with_capacity(capacity),
    );
    // (entries, spread of x and y, spread of z, step of x): a step of 2048 (with y and z
    // fixed) leaves the first pass's digit the same for every entry.
    for (n, spread, z, step) in [
        (200_000, 4, 0, 1),
        (200_000, 700, 3, 1),
        (150_000, 100_000, 5, 1),
        (32_767, 300, 1, 1),
        (32_768, 300, 1, 1),
        (49_152, 300, 1, 1),
        (140_000, 3, 0, 2048),
        (25_000, 1, 0, 1),
    ] {
        let mut serial = BoundedVec::with_capacity(capacity);
        for i in 0..n {
            let x = (next() % spread) * step;
            let y = if step > 1 { 0 } else { next() % spread };
            let key = CellKey::new(x, y, next() % (z + 1));
            serial.push((key, [i as f32, 0.0, 0.0])).unwrap();
        }
        let mut parallel = serial.clone();
        serial_sorter.sort(&mut serial);
        rayon.sort(&mut parallel_sorter, &mut parallel);
        assert_eq!(serial.len(), parallel.len());
        assert!(
            serial.iter().zip(parallel.iter()).all(|(a, b)| a == b),
            "{n} entries, spread {spread}"
        );
        assert!(serial.windows(2).all(|w| w[0].0 <= w[1].0));
    }
}

/// With two threads or more the run loop filters the next frame as a task of its own
/// (`run/lookahead.rs`; yielding on two threads, its loops spread over the pool on more): the
/// same poses and mesh as one thread, which filters in line; and a rolling sweep's frames,
/// deskewed before filtering, are filtered in line.
#[test]
fn the_run_loop_filtering_ahead_writes_what_one_thread_writes() {
    use slamesh::run::{run, RunOptions};
    use slamesh_sim::Drive;
    for sweep in [None, Some(0.1)] {
        let outputs: Vec<(String, Vec<u8>, usize)> = [1, 2, 4]
            .iter()
            .map(|&threads| {
                let mut drive = Drive::car(12, 3);
                drive.sweep_s = sweep;
                let out = crate::common::scratch(&format!("ahead-{threads}-{}", sweep.is_some()));
                let opts = RunOptions {
                    out: out.to_path_buf(),
                    threads,
                    input: "simulated car".into(),
                    mesh_formats: vec![slamesh::outputs::mesh_spool::MeshFormat::Ply],
                    ..RunOptions::default()
                };
                let mut used = 0;
                run::<KittiCapacity>(&mut drive, &opts, |r| {
                    used += usize::from(r.error.is_none())
                })
                .unwrap();
                let poses = std::fs::read_to_string(out.join("poses_kitti.txt")).unwrap();
                let mesh = std::fs::read(out.join("mesh.ply")).unwrap();
                (poses, mesh, used)
            })
            .collect();
        assert_eq!(outputs[0].2, 12);
        assert_eq!(outputs[0], outputs[1], "sweep {sweep:?}, 2 threads");
        assert_eq!(outputs[0], outputs[2], "sweep {sweep:?}, 4 threads");
    }
}
