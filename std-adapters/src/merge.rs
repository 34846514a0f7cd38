//! Two saved maps made one (`slamesh merge A B --out C`, docs/design.md §1.20): two robots, or
//! two sessions that started in different places, mapped parts of one site, each in its own
//! frame. B is found in A by the relocalization search (§1.13), B's surfaces are fused into A
//! at the transform found, and C holds both in A's frame, with both paths.
//!
//! - **Finding B.** Places along B's path, one every [`MergeSettings::probe_every_m`], each
//!   give a cloud: the confident vertices of B's map within [`MergeSettings::probe_radius_m`]
//!   of that pose, in its sensor frame, as a scan taken there would be. Each cloud is searched
//!   for in A along A's path (candidates a cell apart and to each side, 24 headings) and
//!   judged as a relocalized frame is: settled, 30 % of it on A's surfaces and 10 % on its
//!   walls, nothing elsewhere nearly as good. Each accepted place gives a transform from B to
//!   A; two that agree (within [`MergeSettings::agree_m`] and
//!   [`MergeSettings::agree_deg`]) are the answer (the better placed of the two). None
//!   agreeing is a refusal that says what was tried and the best found: a map is never
//!   merged at a guess.
//! - **Fusing B** (`tiles`). A tile of the merged map at a time: A's blocks of the tile, and
//!   B's confident vertices that land in it at the transform found, fused as a scan from the
//!   nearest of B's path's poses a few metres apart, moved into A (the GP reconstruction and
//!   fusion of any scan, §1.3 and §1.5); the tile is written and let go. So a surface both
//!   mapped becomes one surface and what only B saw is added. The filter's range limits are
//!   lifted for it (a vertex under the pose is no LiDAR echo off the robot).
//! - **What C holds.** A's configuration and frame; every cell of both; A's path, then B's
//!   moved into A; the scans of both counted. Written to a temporary file and renamed.
//!
//! Memory: bounded whatever the maps' sizes ([`MergeSettings::resident_layers`]): the search
//! pages A's tiles in around the places it tries, as `localize` under a memory cap does; a
//! place's cloud is read from B's tiles within its radius; the fusion holds one tile of the
//! merged map, one of B's tiles at a time, and for each tile of the merged map the list of
//! B's tiles that land in it.

use crate::formats::map_file::{MapFile, MapWriter};
use crate::io::error::FileError;
use crate::localize::pager::MapPager;
use crate::run::saved_map;
use serde::Serialize;
use slamesh_core::math::rotation_angle;
use slamesh_core::pipeline::{Known, Relocalized, Scan, Stepped};
use slamesh_core::relocalize::Search;
use slamesh_core::{Config, KittiCapacity, NoProbe, Pipeline, Pose, RegistrationStatus, Serial};
use std::fmt;
use std::path::Path;
use std::time::Instant;
use tiles::TiledB;

mod tiles;

/// How B is looked for in A and fused.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MergeSettings {
    /// One place of B's path is tried every this many metres of it ...
    pub probe_every_m: f64,
    /// ... at most this many (evenly spread when the path is longer).
    pub max_probes: usize,
    /// A place's cloud: B's confident vertices within this distance of it (m).
    pub probe_radius_m: f64,
    /// Two places agree when their transforms differ by less than this (m) ...
    pub agree_m: f64,
    /// ... and this (degrees).
    pub agree_deg: f64,
    /// B's cells are fused from the nearest of its path's poses this far apart (m).
    pub fuse_every_m: f64,
    /// The most layers the merge holds at once: A's tiles paged in for the search take half,
    /// and the fusion one tile of the merged map (bounded memory, whatever the maps' sizes).
    pub resident_layers: usize,
}

impl Default for MergeSettings {
    fn default() -> Self {
        Self {
            probe_every_m: 10.0,
            max_probes: 16,
            probe_radius_m: 40.0,
            agree_m: 0.3,
            agree_deg: 0.5,
            fuse_every_m: 5.0,
            resident_layers: 120_000,
        }
    }
}

/// One place of B's path, searched for in A.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Probe {
    /// Its index in B's path.
    pub pose_index: usize,
    /// Points in its cloud.
    pub points: usize,
    /// Whether the search accepted a pose ([`RegistrationStatus::Relocalized`]).
    pub found: bool,
    /// Share of the cloud on A's surfaces at the best pose (accepted or not).
    pub hit_share: f64,
    /// The same on A's walls.
    pub wall_share: f64,
    /// The best pose elsewhere's share.
    pub runner_up_share: f64,
}

/// What a merge did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MergeReport {
    /// B's frame in A's: translation (m) ...
    pub translation_m: [f64; 3],
    /// ... and rotation (unit quaternion x, y, z, w).
    pub rotation_xyzw: [f64; 4],
    /// Every place tried, in order.
    pub probes: Vec<Probe>,
    /// Cells and layers of A, of B, and of the merged map.
    pub cells: [usize; 3],
    /// See `cells`.
    pub layers: [usize; 3],
    /// B's confident vertices fused into A.
    pub vertices_fused: usize,
    /// Seconds: the search, the fusion, the whole.
    pub seconds: [f64; 3],
}

/// Why two maps were not merged.
#[derive(Debug)]
pub enum MergeError {
    /// A file could not be read or written.
    File(FileError),
    /// The maps cannot be merged, or B was not found in A: why.
    Refused(String),
}

impl fmt::Display for MergeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MergeError::File(e) => write!(f, "{e}"),
            MergeError::Refused(why) => write!(f, "not merged: {why}"),
        }
    }
}

impl std::error::Error for MergeError {}

impl From<FileError> for MergeError {
    fn from(e: FileError) -> Self {
        MergeError::File(e)
    }
}

/// The 64-beam class: the largest scans, so a place's cloud is never cut by the capacity.
type Merging = Pipeline<KittiCapacity>;

/// Most points a place's cloud or a fused group may hold (under the class's 140 000).
const MAX_POINTS: usize = 120_000;

/// The farthest a vertex of B may lie from the pose of B's path it is fused from (m).
const FUSE_RANGE_M: f64 = 1_000.0;

/// Merges the saved map `b` into the saved map `a` and writes the result to `out` (see the
/// module docs).
pub fn merge(a: &Path, b: &Path, out: &Path, s: &MergeSettings) -> Result<MergeReport, MergeError> {
    let start = Instant::now();
    let (mut file_a, mut file_b) = open_both(a, b)?;
    let b_path = std::mem::take(&mut file_b.poses);
    let settings = saved_map::config_of(a)?;
    let mut pipeline = merging_pipeline(&settings.config, s)?;
    let a_path = std::mem::take(&mut file_a.poses);
    let mut pager = MapPager::open(a, s.resident_layers / 2, s.probe_radius_m)?;
    let mut tiled_b = TiledB::new(file_b, settings.config.mesh.variance_show as f32);
    let candidates = crate::localize::search::candidates(&a_path, settings.config.grid.cell_size_m);
    let found = find(
        &mut pipeline,
        &mut pager,
        &mut tiled_b,
        &b_path,
        &candidates,
        s,
    );
    if let Some(e) = pager.take_error() {
        return Err(e.into());
    }
    let (t_ab, probes) = found?;
    let searched_s = start.elapsed().as_secs_f64();
    let path: Vec<(f64, Pose)> = (a_path.iter().copied())
        .chain(b_path.iter().map(|(t, p)| (*t, t_ab * p)))
        .collect();
    let frames = file_a.info.frames.saturating_add(tiled_b.frames());
    let info = saved_map::info(&settings.config, settings.preset, frames);
    let mut writer = MapWriter::create(out, &info)?;
    let fused = tiles::fuse_by_tile(
        &mut pipeline,
        &mut file_a,
        &mut tiled_b,
        &b_path,
        &t_ab,
        s.fuse_every_m,
        &mut writer,
    );
    let fused = match fused {
        Ok(f) => f,
        Err(e) => {
            writer.discard();
            return Err(e.into());
        }
    };
    let written = writer.finish(&path)?;
    let q = t_ab.rotation.coords;
    Ok(MergeReport {
        translation_m: t_ab.translation.vector.into(),
        rotation_xyzw: [q.x, q.y, q.z, q.w],
        probes,
        cells: [fused.a.0, fused.b.0, written.cells as usize],
        layers: [fused.a.1, fused.b.1, written.layers as usize],
        vertices_fused: fused.vertices,
        seconds: [
            searched_s,
            start.elapsed().as_secs_f64() - searched_s,
            start.elapsed().as_secs_f64(),
        ],
    })
}

/// Opens both map files, refusing maps of different cells or a B with no path.
fn open_both(a: &Path, b: &Path) -> Result<(MapFile, MapFile), MergeError> {
    let (file_a, file_b) = (MapFile::open(a)?, MapFile::open(b)?);
    if file_a.info.lattice != file_b.info.lattice {
        let (la, lb) = (file_a.info.lattice, file_b.info.lattice);
        return Err(MergeError::Refused(format!(
            "{} and {} were made with different cells or lattices ({} m cells{} against {} m{}): \
             a cell of one is not a cell of the other; map both with one fixed configuration \
             (a preset that is not fitted to the scene, such as `--preset town`, or one \
             `--config` file)",
            a.display(),
            b.display(),
            la.cell_size,
            if la.full_cover { " on the faces" } else { "" },
            lb.cell_size,
            if lb.full_cover { " on the faces" } else { "" },
        )));
    }
    if file_b.poses.is_empty() {
        return Err(MergeError::Refused(format!(
            "{} has no path to search from",
            b.display()
        )));
    }
    Ok((file_a, file_b))
}

/// The pipeline that searches A and fuses B into it: A's configuration with the filter's
/// range limits lifted (B's vertices are no LiDAR echoes: none is too near or too far from
/// the pose they are fused from), a map of `s.resident_layers`.
fn merging_pipeline(config: &Config, s: &MergeSettings) -> Result<Merging, MergeError> {
    let mut config = *config;
    config.filter.range_min_m = 0.0;
    config.filter.range_max_m = FUSE_RANGE_M;
    Merging::with_map_layers(config, s.resident_layers)
        .map_err(|e| MergeError::Refused(format!("the maps' configuration: {e}")))
}

/// Indices of `path` about `every_m` apart along it (its first included), at most `most`,
/// evenly spread.
fn along(path: &[(f64, Pose)], every_m: f64, most: usize) -> Vec<usize> {
    let mut picked = vec![0];
    let mut since = 0.0;
    for i in 1..path.len() {
        since += (path[i].1.translation.vector - path[i - 1].1.translation.vector).norm();
        if since >= every_m {
            picked.push(i);
            since = 0.0;
        }
    }
    let step = picked.len().div_ceil(most.max(1)).max(1);
    picked.into_iter().step_by(step).collect()
}

/// Searches A (in `pipeline`) for places along B's path until two agree; the transform from
/// B's frame to A's, with every place tried, or why none was found.
fn find(
    pipeline: &mut Merging,
    pager: &mut MapPager,
    b: &mut TiledB,
    b_path: &[(f64, Pose)],
    candidates: &[Pose],
    s: &MergeSettings,
) -> Result<(Pose, Vec<Probe>), MergeError> {
    pipeline.set_map_updates(false);
    let mut probes = Vec::new();
    let mut found: Vec<(Pose, f64)> = Vec::new();
    for i in along(b_path, s.probe_every_m, s.max_probes) {
        let pose = b_path[i].1;
        let points = b.around(&pose, s.probe_radius_m)?;
        let known = Known::Somewhere {
            candidates,
            search: &Search::default(),
            paging: &mut *pager,
        };
        let result = pipeline.step(Scan::Raw(&points), known, &Serial, &mut NoProbe);
        let Ok(Stepped::Searched(r)) = result else {
            probes.push(probe(i, points.len(), None));
            continue;
        };
        probes.push(probe(i, points.len(), Some(&r)));
        if r.outcome.status != RegistrationStatus::Relocalized {
            continue;
        }
        let t = r.outcome.t_world_sensor * pose.inverse();
        let agreeing = found.iter().find(|(u, _)| {
            let apart = u.inverse() * t;
            apart.translation.vector.norm() < s.agree_m
                && rotation_angle(&apart).to_degrees() < s.agree_deg
        });
        if let Some((u, share)) = agreeing {
            let best = if *share >= r.hit_share { *u } else { t };
            return Ok((best, probes));
        }
        found.push((t, r.hit_share));
    }
    Err(MergeError::Refused(not_found(&probes, found.len())))
}

fn probe(pose_index: usize, points: usize, r: Option<&Relocalized>) -> Probe {
    Probe {
        pose_index,
        points,
        found: r.is_some_and(|r| r.outcome.status == RegistrationStatus::Relocalized),
        hit_share: r.map_or(0.0, |r| r.hit_share),
        wall_share: r.map_or(0.0, |r| r.wall_share),
        runner_up_share: r.map_or(0.0, |r| r.runner_up_share),
    }
}

/// Why B was not found: what was tried and the best of it.
fn not_found(probes: &[Probe], accepted: usize) -> String {
    let best = probes
        .iter()
        .max_by(|x, y| x.hit_share.total_cmp(&y.hit_share));
    let search = Search::default();
    format!(
        "no two places of B agree on where B is in A: {} places along B's path searched along \
         A's, {accepted} found{}; the best put {:.0} % of its cloud on A's surfaces and {:.0} % \
         on its walls (at least {:.0} % and {:.0} % needed), the best elsewhere {:.0} %",
        probes.len(),
        if accepted == 1 {
            " (one is not enough)"
        } else {
            ""
        },
        100.0 * best.map_or(0.0, |b| b.hit_share),
        100.0 * best.map_or(0.0, |b| b.wall_share),
        100.0 * search.min_hit_share,
        100.0 * search.min_wall_share,
        100.0 * best.map_or(0.0, |b| b.runner_up_share),
    )
}
