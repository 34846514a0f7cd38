#![allow(unsafe_code)] // a counting global allocator needs it
//! The core allocates only when a pipeline is built: processing scans, meshing, and walking
//! the mesh allocate nothing (counted by a global allocator), and a pipeline built in caller
//! storage allocates nothing at all, not even when it is built; in either scalar of the
//! reconstruction (`f64`, `f32`). One test per binary, so no
//! other test's allocations are counted.

use slamesh_core::storage::Storage;
use slamesh_core::{Config, KittiCapacity, Pipeline, Pose};
use slamesh_sim::{sensor_pose, Lidar, Scene};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::SeqCst);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn processing_scans_allocates_nothing_after_construction() {
    let scene = Scene::street();
    let lidar = Lidar::hdl64(512);
    let poses: Vec<Pose> = (0..5)
        .map(|i| sensor_pose(0.7 * i as f64, 0.0, 1.73, (0.01 * i as f64).to_degrees()))
        .collect();
    let scans: Vec<_> = poses.iter().map(|p| lidar.scan(&scene, p)).collect();
    let mut bad = scans[0].clone();
    bad.extend([[f32::NAN; 3]; 10]);
    let mut pipeline = Pipeline::<KittiCapacity>::new(Config::default()).unwrap();
    // Caller storage, lent before the count starts.
    let storage = Storage::leak::<KittiCapacity>();
    let storage32 = Storage::leak::<KittiCapacity>();
    let mut single = Pipeline::<KittiCapacity, f32>::new(Config::default()).unwrap();
    let mut meshing = Pipeline::<KittiCapacity>::new(Config::meshing()).unwrap();

    let before = ALLOCATIONS.load(Ordering::SeqCst);
    let mut lent = Pipeline::<KittiCapacity>::in_storage(Config::default(), storage).unwrap();
    let mut lent32 =
        Pipeline::<KittiCapacity, f32>::in_storage(Config::default(), storage32).unwrap();
    let mut triangles = 0;
    for (scan, pose) in scans.iter().zip(&poses) {
        let own = pipeline.process_scan(scan).unwrap();
        let other = lent.process_scan(scan).unwrap();
        assert_eq!(
            own.t_world_sensor, other.t_world_sensor,
            "the same poses in storage"
        );
        let own32 = single.process_scan(scan).unwrap();
        let other32 = lent32.process_scan(scan).unwrap();
        assert_eq!(
            own32.t_world_sensor, other32.t_world_sensor,
            "the same f32 poses in storage"
        );
        meshing.integrate_scan(scan, pose).unwrap();
        triangles += pipeline.triangles().count();
    }
    pipeline.process_scan(&bad).unwrap();
    let _ = pipeline.process_scan(&[]);
    let evicted = pipeline
        .map_mut()
        .evict_where(|_, c| c.last_seen < 2, |_| {});
    pipeline.process_scan(&scans[4]).unwrap();
    let after = ALLOCATIONS.load(Ordering::SeqCst);

    assert!(triangles > 0 && evicted > 0);
    assert_eq!(
        after - before,
        0,
        "the core allocated {} times while processing scans",
        after - before
    );
}
