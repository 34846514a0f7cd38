//! One way in and one way out: samples that are not scans (an IMU's) come in with their frame
//! from the source and go out with its event. A run (`slamesh::run::sink`) fans each frame's
//! event out to the sinks it is
//! given, in frame order; a sink that asks for the map gets each used frame's changes; every
//! sink is told the end with the run's summary; a slow sink behind a dropping queue changes
//! nothing the run writes.

use crate::common::scratch;
use slamesh::run::files::{ReportFile, Trajectories};
use slamesh::run::sink::{FnSink, Queued, Sink, SinkFault, WhenFull};
use slamesh::run::{run_to, FrameEvent, FrameSource, RunOptions, Sinks, Summary};
use slamesh::sources::{ImuReading, OtherSample, Sample};
use slamesh_core::{Config, KittiCapacity};
use slamesh_sim::Drive;
use std::sync::{Arc, Mutex};

fn options(out: &std::path::Path) -> RunOptions {
    RunOptions {
        out: out.to_path_buf(),
        config: Config::default(),
        threads: 2,
        mesh_formats: vec![slamesh::outputs::mesh_spool::MeshFormat::Ply],
        ..RunOptions::default()
    }
}

/// Keeps what it is shown of the map, and asks for it.
struct MapWatcher(Arc<Mutex<Vec<(usize, usize, usize)>>>);

impl Sink for MapWatcher {
    fn name(&self) -> String {
        "map watcher".into()
    }
    fn wants_map(&self) -> bool {
        true
    }
    fn frame(&mut self, event: Arc<FrameEvent>) -> Result<(), SinkFault> {
        if let Some(m) = &event.map {
            let seen = (m.frame, m.points.len(), m.layers.len());
            self.0.lock().unwrap().push(seen);
        }
        Ok(())
    }
}

/// Keeps the frames the run used, from the summary it is told at the end.
struct End(Arc<Mutex<Option<usize>>>);

impl Sink for End {
    fn name(&self) -> String {
        "end".into()
    }
    fn frame(&mut self, _: Arc<FrameEvent>) -> Result<(), SinkFault> {
        Ok(())
    }
    fn finish(&mut self, summary: Option<&Summary>) -> Result<Option<String>, SinkFault> {
        *self.0.lock().unwrap() = summary.map(|s| s.used);
        Ok(None)
    }
}

/// Takes 100 ms a frame.
struct Slow;

impl Sink for Slow {
    fn name(&self) -> String {
        "slow".into()
    }
    fn frame(&mut self, _: Arc<FrameEvent>) -> Result<(), SinkFault> {
        std::thread::sleep(std::time::Duration::from_millis(100));
        Ok(())
    }
}

#[test]
fn a_run_fans_each_frame_out_to_its_sinks_in_order() {
    let dir = scratch("sinks");
    let frames = 6;
    let (with, plain) = (dir.join("with"), dir.join("plain"));
    let mut events: Vec<(usize, bool)> = Vec::new();
    let seen = Arc::new(Mutex::new(Vec::new()));
    let used = Arc::new(Mutex::new(None));
    let summary = {
        let mut sinks = Sinks::new();
        sinks.add(FnSink::new("events", |e: &FrameEvent| {
            events.push((e.record.frame, e.pose.is_some()))
        }));
        sinks.add(MapWatcher(Arc::clone(&seen)));
        sinks.add(Queued::new(Slow, 1, WhenFull::DropNewest).unwrap());
        sinks.add(Queued::new(End(Arc::clone(&used)), 1, WhenFull::DropNewest).unwrap());
        run_to::<KittiCapacity>(&mut Drive::town(frames, 1), &options(&with), sinks).unwrap()
    };
    assert_eq!(events, (0..frames).map(|i| (i, true)).collect::<Vec<_>>());
    // The end reaches a queued sink with the summary, however full its queue was.
    assert_eq!(*used.lock().unwrap(), Some(frames));
    let seen = seen.lock().unwrap().clone();
    assert_eq!(seen.len(), frames, "every used frame's map changes");
    for (k, (frame, points, layers)) in seen.iter().enumerate() {
        assert_eq!(*frame, k);
        assert!(
            *points > 100 && *layers > 10,
            "frame {frame}: {points} points, {layers} layers"
        );
    }
    // The same run with no sink writes the same trajectory and mesh.
    let alone =
        slamesh::run::run::<KittiCapacity>(&mut Drive::town(frames, 1), &options(&plain), |_| {})
            .unwrap();
    assert_eq!(alone.poses, summary.poses);
    for f in ["poses_kitti.txt", "mesh.ply"] {
        assert_eq!(
            std::fs::read(with.join(f)).unwrap(),
            std::fs::read(plain.join(f)).unwrap(),
            "{f}"
        );
    }
}

#[test]
fn the_runs_own_files_are_sinks_that_write_the_same_files_elsewhere() {
    let dir = scratch("file-sinks");
    let (own, copy) = (dir.join("own"), dir.join("copy"));
    std::fs::create_dir_all(&copy).unwrap();
    let mut sinks = Sinks::new();
    let report = ReportFile::create(&options(&copy)).unwrap();
    sinks.add(Queued::new(report, 2, WhenFull::Wait).unwrap());
    sinks.add(Trajectories::new(&copy));
    run_to::<KittiCapacity>(&mut Drive::town(5, 3), &options(&own), sinks).unwrap();
    for f in ["report.json", "poses_tum.txt", "poses_kitti.txt"] {
        let (a, b) = (
            std::fs::read(own.join(f)).unwrap(),
            std::fs::read(copy.join(f)),
        );
        assert!(a.len() > 100, "{f}: {} bytes", a.len());
        assert_eq!(a, b.unwrap(), "{f}");
    }
    assert!(!copy.join(".report.frames.spool").exists());
}

/// A drive whose frames each come with a camera's image and four IMU readings (the one way
/// in for what is not a scan).
struct WithImu(Drive);

impl FrameSource for WithImu {
    fn frames(&self) -> usize {
        self.0.frames()
    }
    fn label(&self, i: usize) -> String {
        self.0.label(i)
    }
    fn stamp(&self, i: usize) -> f64 {
        self.0.stamp(i)
    }
    fn read(&mut self, i: usize) -> Result<Vec<slamesh_core::Point>, slamesh::FileError> {
        self.0.read(i)
    }
    fn samples(&mut self, i: usize) -> Vec<Sample> {
        let image = Sample::Other(OtherSample {
            stamp: self.0.stamp(i) - 0.09,
            kind: "image",
            value: Arc::new(vec![i as u8; 16]),
        });
        let imu = (1..=4).map(|k| {
            Sample::Imu(ImuReading {
                stamp: self.0.stamp(i) - 0.1 + 0.025 * k as f64,
                gyro: [0.0, 0.0, i as f64],
                accel: [0.0, 0.0, 9.81],
            })
        });
        std::iter::once(image).chain(imu).collect()
    }
}

#[test]
fn samples_between_scans_reach_the_sinks_with_their_frame() {
    let dir = scratch("sinks-imu");
    let mut got: Vec<(usize, usize, Option<f64>, Option<u8>)> = Vec::new();
    let summary = {
        let mut sinks = Sinks::new();
        sinks.add(FnSink::new("imu", |e: &FrameEvent| {
            let gyro_z = e.samples.iter().find_map(Sample::imu).map(|r| r.gyro[2]);
            let image = e.samples.iter().find_map(|s| match s {
                Sample::Other(o) if o.kind == "image" => o.data::<Vec<u8>>().map(|v| v[0]),
                _ => None,
            });
            got.push((e.record.frame, e.record.samples, gyro_z, image));
            assert_eq!(e.samples.len(), e.record.samples);
            assert!(e.samples.windows(2).all(|w| w[0].stamp() < w[1].stamp()));
        }));
        let mut source = WithImu(Drive::town(4, 1));
        run_to::<KittiCapacity>(&mut source, &options(&dir), sinks).unwrap()
    };
    assert_eq!(summary.used, 4);
    assert_eq!(
        got,
        (0..4)
            .map(|i| (i, 5, Some(i as f64), Some(i as u8)))
            .collect::<Vec<_>>(),
        "each frame's own readings and image"
    );
}
