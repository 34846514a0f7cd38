//! Inputs that plug in: a kind of input of the caller's own ([`slamesh::sources::kinds`]),
//! told apart and opened by itself, runs as the command's own kinds do, with nothing in the
//! run or in `sources/input.rs` changed for it.

use crate::common::scratch;
use slamesh::io::FileError;
use slamesh::run::{run, FrameSource, Input, RunOptions};
use slamesh::sources::kinds::{InputKind, Kinds, OpenOptions, Opened, OpenedInput};
use slamesh_core::{KittiCapacity, Point};
use slamesh_sim::Drive;
use std::path::{Path, PathBuf};

/// Scans as text, one `x y z` line a point, in `.xyz` files of a folder, 10 Hz.
struct XyzKind;

struct XyzFolder {
    files: Vec<PathBuf>,
}

impl InputKind for XyzKind {
    fn name(&self) -> &'static str {
        "text scans (.xyz)"
    }

    fn open(&self, path: &Path, _how: &OpenOptions) -> Option<Result<Opened, FileError>> {
        let mut files: Vec<PathBuf> = std::fs::read_dir(path)
            .ok()?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "xyz"))
            .collect();
        if files.is_empty() {
            return None;
        }
        files.sort();
        Some(Ok(Box::new(XyzFolder { files })))
    }
}

impl FrameSource for XyzFolder {
    fn frames(&self) -> usize {
        self.files.len()
    }
    fn label(&self, i: usize) -> String {
        self.files[i].display().to_string()
    }
    fn stamp(&self, i: usize) -> f64 {
        i as f64 * 0.1
    }
    fn read(&mut self, i: usize) -> Result<Vec<Point>, FileError> {
        let path = &self.files[i];
        let text = std::fs::read_to_string(path).map_err(|e| FileError::at(path, e.to_string()))?;
        let point = |line: &str| -> Option<Point> {
            let mut v = line.split(' ').map(|c| c.parse::<f32>().ok());
            Some([v.next()??, v.next()??, v.next()??])
        };
        (text.lines().enumerate())
            .map(|(n, line)| {
                point(line).ok_or_else(|| FileError::at(path, format!("line {}: not x y z", n + 1)))
            })
            .collect()
    }
}

impl OpenedInput for XyzFolder {
    fn describe(&self) -> String {
        format!("{} text scans", self.files.len())
    }
}

/// Writes `scans` into `dir` as KITTI `.bin` files and as `.xyz` text into `dir/text`.
fn write_both(scans: &[Vec<Point>], dir: &Path) -> (PathBuf, PathBuf) {
    let (bin, text) = (dir.join("bin"), dir.join("text"));
    for d in [&bin, &text] {
        std::fs::create_dir_all(d).unwrap();
    }
    for (i, scan) in scans.iter().enumerate() {
        let mut bytes = Vec::with_capacity(scan.len() * 16);
        let mut lines = String::new();
        for p in scan {
            for c in p.iter().chain(&[0.0]) {
                bytes.extend_from_slice(&c.to_le_bytes());
            }
            // Rust writes the shortest text that reads back to the same f32.
            lines.push_str(&format!("{} {} {}\n", p[0], p[1], p[2]));
        }
        std::fs::write(bin.join(format!("{i:06}.bin")), bytes).unwrap();
        std::fs::write(text.join(format!("{i:06}.xyz")), lines).unwrap();
    }
    (bin, text)
}

#[test]
fn an_input_kind_from_outside_runs_as_the_commands_own() {
    let dir = scratch("input-kinds");
    let mut drive = Drive::town(8, 3);
    let scans: Vec<Vec<Point>> = (0..8).map(|i| drive.read(i).unwrap()).collect();
    let (bin, text) = write_both(&scans, &dir);

    // The command's kinds read no .xyz: the folder holds no scan files they know.
    let refused = Input::open(&text, None, Default::default()).err();
    assert!(
        refused.is_some(),
        "the standard kinds opened a folder of .xyz"
    );

    let kinds = Kinds::standard().with(XyzKind);
    assert_eq!(kinds.names()[0], "text scans (.xyz)");
    let mut input = Input::open_among(&kinds, &text, &OpenOptions::default()).unwrap();
    assert_eq!(input.describe(), "8 text scans");
    assert!(input.downcast_ref::<XyzFolder>().is_some());
    // A kind that does not know a path leaves it to the next: the .bin folder is scan files.
    let mut files = Input::open_among(&kinds, &bin, &OpenOptions::default()).unwrap();
    assert!(
        files.describe().starts_with("8 scan files"),
        "{}",
        files.describe()
    );

    let poses = |source: &mut Input, name: &str| {
        let opts = RunOptions {
            out: dir.join(name),
            threads: 2,
            picture: false,
            ..RunOptions::default()
        };
        let summary = run::<KittiCapacity>(source, &opts, |_| {}).unwrap();
        assert_eq!(summary.used, 8, "{name}");
        std::fs::read_to_string(dir.join(name).join("poses_kitti.txt")).unwrap()
    };
    let (from_text, from_bin) = (poses(&mut input, "text"), poses(&mut files, "bin"));
    assert_eq!(from_text.lines().count(), 8);
    assert_eq!(from_text, from_bin, "the same scans, the same poses");
}
