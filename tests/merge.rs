//! Two saved maps made one (`slamesh::merge`, docs/design.md §1.20): the two halves of a town
//! drive, mapped apart with other noise and a lane apart, merge into one map in the first's
//! frame that localizes a third drive as well as a map made in one run, with the street both
//! saw one surface; a map of another town, or one made with other cells, is refused, saying
//! why.

use crate::common;

use common::{scratch, slamesh, test_run_options};
use nalgebra::Translation3;
use slamesh::eval::duplicates::duplicated_near;
use slamesh::formats::map_file::MapFile;
use slamesh::merge::{merge, MergeError, MergeSettings};
use slamesh::run::{run, RunOptions, Summary};
use slamesh_core::math::rotation_angle;
use slamesh_core::{Config, KittiCapacity, Pose};
use slamesh_sim::Drive;
use std::path::{Path, PathBuf};

fn options(out: &Path, config: Config) -> RunOptions {
    RunOptions {
        picture: false,
        ..test_run_options(out, config)
    }
}

fn run_ok(drive: &mut Drive, opts: &RunOptions) -> Summary {
    match run::<KittiCapacity>(drive, opts, |_| {}) {
        Ok(s) => s,
        Err(e) => panic!("{e}"),
    }
}

/// Frames `range` of `town`'s loop with noise `seed`, `left_m` to the left.
fn part(town: &Drive, range: std::ops::Range<usize>, seed: u64, left_m: f64) -> Drive {
    let mut d = town.clone();
    d.seed = seed;
    let left = Translation3::new(0.0, left_m, 0.0);
    d.poses = town.poses[range].iter().map(|p| p * left).collect();
    d
}

/// Maps `drive` into `dir/name.slamesh`.
fn mapped(drive: &mut Drive, dir: &Path, name: &str) -> (Summary, PathBuf) {
    let file = dir.join(format!("{name}.slamesh"));
    let opts = RunOptions {
        save_map: Some(file.clone()),
        ..options(&dir.join(name), Config::default())
    };
    (run_ok(drive, &opts), file)
}

/// The largest distance from the truth of a drive localized in `map` from no initial pose,
/// in the map's frame (no alignment: a map in the wrong frame shows).
fn localized(drive: &mut Drive, map: &Path, out: &Path, truth: &[Pose]) -> f64 {
    let opts = RunOptions {
        map: Some(map.to_path_buf()),
        localize_only: true,
        ..options(out, Config::default())
    };
    let s = run_ok(drive, &opts);
    assert_eq!(
        s.used,
        truth.len(),
        "{}: every frame localized",
        map.display()
    );
    s.poses
        .iter()
        .zip(truth)
        .map(|((_, p), t)| (p.translation.vector - t.translation.vector).norm())
        .fold(0.0, f64::max)
}

#[test]
fn two_halves_of_a_drive_merge_into_one_map_and_another_town_is_refused() {
    let dir = scratch("merge");
    let town = Drive::town(130, 5);
    let to_a = town.poses[0].inverse();
    // A: frames 0 to 70; B: 50 to 120, other noise, a metre to the left; C's check: 95 to
    // 125, in B's half only, other noise again.
    let (_, a) = mapped(&mut part(&town, 0..70, 5, 0.0), &dir, "a");
    let mut b_drive = part(&town, 50..120, 1_000, 1.0);
    let b_first = to_a * b_drive.poses[0];
    let (_, b) = mapped(&mut b_drive, &dir, "b");
    let (_, whole) = mapped(&mut part(&town, 0..125, 5, 0.0), &dir, "whole");

    let merged = dir.join("merged.slamesh");
    let r = merge(&a, &b, &merged, &MergeSettings::default()).unwrap();
    // B's map frame is its first pose: in A's frame, where the truth has it (A's own drift
    // over 50 frames included).
    let q = r.rotation_xyzw;
    let found = Pose::from_parts(
        Translation3::new(r.translation_m[0], r.translation_m[1], r.translation_m[2]),
        nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            q[3], q[0], q[1], q[2],
        )),
    );
    let off = b_first.inverse() * found;
    let (off_m, off_deg) = (
        off.translation.vector.norm(),
        rotation_angle(&off).to_degrees(),
    );
    println!(
        "merge: B found {off_m:.3} m and {off_deg:.3} deg from the truth; {} of {} places \
         found; cells {:?}, layers {:?}; {:.1} s",
        r.probes.iter().filter(|p| p.found).count(),
        r.probes.len(),
        r.cells,
        r.layers,
        r.seconds[2]
    );
    assert!(off_m < 0.15 && off_deg < 0.3, "{off_m} m, {off_deg} deg");
    // Both maps' cells, the street both saw once.
    assert!(r.cells[2] > r.cells[0].max(r.cells[1]) && r.cells[2] < r.cells[0] + r.cells[1]);
    let file = MapFile::open(&merged).unwrap();
    assert_eq!(file.poses.len(), 140, "both paths");

    // A third drive localizes in the merged map as well as in the map of one run.
    let mut third = part(&town, 95..125, 2_000, 0.5);
    let truth: Vec<Pose> = third.poses.iter().map(|p| to_a * p).collect();
    let in_merged = localized(&mut third, &merged, &dir.join("third-merged"), &truth);
    let in_whole = localized(&mut third, &whole, &dir.join("third-whole"), &truth);
    println!("a third drive, farthest from the truth: {in_merged:.3} m in the merged map, {in_whole:.3} m in one run's");
    assert!(
        in_merged <= in_whole + 0.05,
        "{in_merged} against {in_whole}"
    );
    // Where both drove, the street is one surface: no more surfaces mapped twice than in the
    // map of one run.
    let load = |p: &Path| MapFile::open(p).unwrap().load_new().unwrap();
    let overlap = to_a * town.poses[60];
    let twice = |p: &Path| duplicated_near(&load(p), 0.3, 0.3, &overlap, 30.0);
    let (dup_merged, dup_whole) = (twice(&merged), twice(&whole));
    println!("surfaces mapped twice within 30 m of the overlap: merged {dup_merged}, one run {dup_whole}");
    assert!(
        dup_merged <= dup_whole + dup_whole / 2 + 5,
        "{dup_merged} against {dup_whole}"
    );

    refusals(&dir, &a, &town);
}

/// Merging into `a` a map of another town is refused, saying what was tried, and writes
/// nothing; a map made with other cells is refused before any search, by the command too.
fn refusals(dir: &Path, a: &Path, town: &Drive) {
    // Another town: refused, saying what was tried; nothing written.
    let (_, other) = mapped(&mut Drive::town(40, 7), dir, "other");
    let not = dir.join("not.slamesh");
    match merge(a, &other, &not, &MergeSettings::default()) {
        Err(MergeError::Refused(why)) => {
            assert!(why.contains("places along B's path searched"), "{why}")
        }
        r => panic!("another town merged: {r:?}"),
    }
    assert!(!not.exists());
    // Other cells: refused before any search, by the command too.
    let coarse = Config {
        grid: slamesh_core::config::GridConfig {
            cell_size_m: 2.0,
            ..Config::default().grid
        },
        ..Config::default()
    };
    let coarse_map = dir.join("coarse.slamesh");
    let opts = RunOptions {
        save_map: Some(coarse_map.clone()),
        ..options(&dir.join("coarse"), coarse)
    };
    run_ok(&mut part(town, 0..10, 5, 0.0), &opts);
    let o = slamesh(&[
        "merge",
        a.to_str().unwrap(),
        coarse_map.to_str().unwrap(),
        "--out",
        not.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && stderr.contains("different cells or lattices"),
        "{stderr}"
    );
}
