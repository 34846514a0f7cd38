//! Capabilities that plug in: a stage of the caller's own ([`slamesh::stage::RunStage`]),
//! given to a run from outside `run/`, is told each fused frame and each pose kept, counts
//! into the frame records and the summary, and writes a file of its own from the whole map
//! at the end, as the run's own stages (the navigation map, clearing what moves) do.

use crate::common::scratch;
use slamesh::outputs::mesh_spool::{MeshFormat, MeshSpool};
use slamesh::run::{run_with, RunOptions, Sinks};
use slamesh::stage::{End, Note, RunStage, Stages, Used};
use slamesh::FileError;
use slamesh_core::{Config, KittiCapacity, Pipeline, Pose};
use slamesh_sim::Drive;

/// An end-of-run output: the highest point of the map's mesh, written to `highest.txt`;
/// along the way, the map's layers after each fused frame and the frames used.
#[derive(Default)]
struct Highest {
    layers: Vec<u64>,
    used: Vec<usize>,
    top: Option<f32>,
}

impl RunStage<KittiCapacity> for Highest {
    fn name(&self) -> &'static str {
        "highest"
    }

    fn fused(&mut self, pipeline: &mut Pipeline<KittiCapacity>, _: &Pose) -> Option<Note> {
        let n = pipeline.map().layer_count() as u64;
        self.layers.push(n);
        Some(Note::of("map_layers_fused", n))
    }

    fn used(&mut self, frame: &Used<'_>) -> Option<Note> {
        self.used.push(frame.frame);
        None
    }

    fn finish(&mut self, mesh: &mut MeshSpool, end: &End<'_>) -> Result<(), FileError> {
        let mut top = f32::MIN;
        mesh.for_each_triangle(|t, _| {
            top = t.iter().fold(top, |m, p| m.max(p[2]));
        })?;
        self.top = Some(top);
        let path = end.out.join("highest.txt");
        std::fs::write(&path, format!("{top}\n")).map_err(|e| FileError::at(&path, e.to_string()))
    }

    fn summary(&self) -> Option<serde_json::Value> {
        Some(serde_json::json!({ "frames": self.used.len(), "top_m": self.top }))
    }

    fn outputs(&self) -> &'static [&'static str] {
        &["highest.txt"]
    }
}

#[test]
fn a_stage_from_outside_the_run_writes_from_the_whole_map_at_its_end() {
    let dir = scratch("stages-plugged");
    let out = dir.join("out");
    let opts = RunOptions {
        out: out.clone(),
        config: Config::default(),
        threads: 2,
        mesh_formats: vec![MeshFormat::Ply],
        picture: false,
        ..RunOptions::default()
    };
    let mut stages = Stages::new();
    stages.push(Box::new(Highest::default()));
    let frames = 6;
    let summary =
        run_with::<KittiCapacity>(&mut Drive::town(frames, 1), &opts, Sinks::new(), stages)
            .unwrap();
    assert_eq!(summary.used, frames);
    assert!(
        summary.files.iter().any(|f| f == "highest.txt"),
        "{:?}",
        summary.files
    );
    // Its part of the summary, under its name, with the frames it was shown.
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let part = &report["summary"]["highest"];
    assert_eq!(part["frames"], frames, "{part}");
    // The file it wrote from the whole map: the mesh's highest vertex, as mesh.ply has it.
    let top: f32 = std::fs::read_to_string(out.join("highest.txt"))
        .unwrap()
        .trim()
        .parse()
        .unwrap();
    let mesh = slamesh::formats::ply::read_ply_mesh(&out.join("mesh.ply")).unwrap();
    let highest = mesh.vertices.iter().fold(f32::MIN, |m, p| m.max(p[2]));
    assert!((top - highest).abs() < 1e-4, "{top} against {highest}");
    assert_eq!(part["top_m"].as_f64().map(|t| t as f32), Some(top));
    // Its count in every used frame's record, the map growing under it.
    let counts: Vec<u64> = report["frames"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|f| f["map_layers_fused"].as_u64())
        .collect();
    assert_eq!(counts.len(), frames);
    assert!(
        counts.windows(2).all(|w| w[0] <= w[1]) && counts[0] > 0,
        "{counts:?}"
    );
}

/// A run owns its output folder's outputs: what a run before wrote there and this one does
/// not (the navigation files of a run with `--navmap`, before one without) is removed, and
/// `report.json` lists what this run wrote.
#[test]
fn a_run_removes_what_a_run_before_left_and_lists_what_it_wrote() {
    let dir = scratch("stages-owned");
    let out = dir.join("out");
    let opts = |navmap: bool| RunOptions {
        out: out.clone(),
        config: Config::default(),
        threads: 2,
        mesh_formats: vec![MeshFormat::Ply],
        picture: false,
        navmap: navmap.then(slamesh::navmap::NavMapOptions::default),
        ..RunOptions::default()
    };
    let there = || {
        let mut names: Vec<String> = std::fs::read_dir(&out)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    };
    let listed = || {
        let text = std::fs::read_to_string(out.join("report.json")).unwrap();
        let report: serde_json::Value = serde_json::from_str(&text).unwrap();
        let mut files: Vec<String> =
            serde_json::from_value(report["summary"]["files"].clone()).expect("the files it wrote");
        files.sort();
        files
    };
    let run = |navmap: bool| {
        let mut drive = Drive::town(6, 1);
        run_with::<KittiCapacity>(&mut drive, &opts(navmap), Sinks::new(), Stages::new()).unwrap()
    };
    run(true);
    assert!(there().iter().any(|f| f == "map.pgm"), "{:?}", there());
    assert_eq!(listed(), there());
    std::fs::write(out.join("notes.txt"), "the user's own").unwrap();
    run(false);
    let mut expected = listed();
    expected.push("notes.txt".into());
    expected.sort();
    assert_eq!(
        there(),
        expected,
        "the navigation files went; the user's file stayed"
    );
    assert!(!listed()
        .iter()
        .any(|f| f.starts_with("map.") || f.starts_with("elevation")));
}
