//! The serial and parallel cell loops give bit-identical poses and meshes.

use slamesh::parallel::Rayon;
use slamesh::sim::{sensor_pose, Lidar, Scene};
use slamesh_core::reconstruct::{CellLoop, Serial};
use slamesh_core::{Config, KittiCapacity, NoProbe, Pipeline, Pose};

fn run(
    cells: &impl CellLoop,
    config: Config,
    scans: &[Vec<[f32; 3]>],
) -> (Vec<Pose>, Vec<slamesh_core::mesh::Triangle>) {
    let mut p = Pipeline::<KittiCapacity>::new(config).unwrap();
    let poses = scans
        .iter()
        .map(|s| {
            p.process_scan_with(s, cells, &mut NoProbe)
                .unwrap()
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
    for config in [Config::default(), Config::meshing()] {
        let serial = run(&Serial, config, &scans);
        for threads in [1, 2, 4] {
            let parallel = run(&Rayon::new(threads).unwrap(), config, &scans);
            assert_eq!(serial.0, parallel.0, "poses differ with {threads} threads");
            assert_eq!(serial.1, parallel.1, "meshes differ with {threads} threads");
        }
        assert!(!serial.1.is_empty());
    }
}
