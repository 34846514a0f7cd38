//! `slamesh navmap`: a navigation map (Nav2's `map.yaml` + `map.pgm`, the elevation grids) from
//! a saved map or a PLY mesh; and the robot flags `run`, `mesh` and `localize` share for
//! `--navmap`.

use crate::cli::error::CliError;
use crate::formats::map_file::MapFile;
use crate::formats::ply::read_ply_mesh;
use crate::io::error::FileError;
use crate::navmap::{self, floor_file, NavMapOptions, Robot};
use crate::outputs::mesh_spool::{MeshFormat, MeshSpool};
use crate::run::saved_map;
use crate::say;
use clap::Args;
use std::path::{Path, PathBuf};

/// The robot a navigation map is for, and its cell size.
#[derive(Args, Debug, Clone)]
pub struct RobotArgs {
    /// The robot the navigation map is for: `wheeled` (radius 0.3 m, slopes to 15 degrees,
    /// steps to 0.08 m, 1 m tall), `legged` (0.45 m, 30 degrees, 0.2 m, 0.8 m), or a TOML file
    /// (`base = "legged"`, `radius_m`, `max_slope_deg`, `max_step_m`, `height_m`).
    #[arg(long, value_name = "PROFILE|FILE", default_value = "wheeled", value_parser = robot)]
    pub robot: Robot,
    /// The navigation map's cell size (m; 0.05 to 0.1 suits Nav2).
    #[arg(long, value_name = "M", default_value_t = DEFAULT_RESOLUTION_M, value_parser = resolution)]
    pub navmap_resolution: f64,
}

/// `--navmap-resolution`'s default (m).
pub const DEFAULT_RESOLUTION_M: f64 = 0.1;

impl Default for RobotArgs {
    /// The flags' defaults: `wheeled`, [`DEFAULT_RESOLUTION_M`].
    fn default() -> Self {
        RobotArgs {
            robot: Robot::WHEELED,
            navmap_resolution: DEFAULT_RESOLUTION_M,
        }
    }
}

impl RobotArgs {
    /// The navigation map's options (up: the map's z axis).
    pub fn options(&self) -> NavMapOptions {
        NavMapOptions {
            robot: self.robot,
            resolution_m: self.navmap_resolution,
            up: None,
        }
    }
}

/// The robot a profile's name or a TOML file's path names.
pub fn robot(text: &str) -> Result<Robot, String> {
    match Robot::named(text) {
        Some(r) => Ok(r),
        None => Robot::read(Path::new(text)).map_err(|e| e.to_string()),
    }
}

/// A navigation map's cell size from text (0.01 to 2 m).
pub fn resolution(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(r) if (0.01..=2.0).contains(&r) => Ok(r),
        _ => Err(format!("`{text}` is not a cell size from 0.01 to 2 m")),
    }
}

/// `slamesh navmap`'s arguments.
#[derive(Args, Debug)]
pub struct NavMapArgs {
    /// A map file (`run --save-map`), whose path grows the ground (with the scans' floor a
    /// run with `--navmap` kept beside it, `NAME.floor`: kerbs and cars' roofs as that run
    /// found them), or a PLY mesh (`mesh.ply`: the ground grows from its largest stretch of
    /// floor).
    pub input: PathBuf,
    /// Output folder (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// The robot and cell size.
    #[command(flatten)]
    pub robot: RobotArgs,
}

/// Writes the navigation map of `args.input` into `args.out`; a folder it made for them and
/// left empty (the input could not be read) is removed.
pub fn navmap(args: &NavMapArgs) -> Result<(), CliError> {
    let existed = args.out.exists();
    std::fs::create_dir_all(&args.out)
        .map_err(|e| FileError::at(&args.out, format!("cannot create: {e}")))?;
    let written = write_navmap(args);
    if written.is_err() && !existed {
        // Removes the folder only if nothing is in it.
        let _ = std::fs::remove_dir(&args.out);
    }
    written
}

/// [`navmap`] into a folder that exists.
fn write_navmap(args: &NavMapArgs) -> Result<(), CliError> {
    let how = args.robot.options();
    let is_ply = args
        .input
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("ply"));
    let summary = if is_ply {
        let mut mesh = read_ply_mesh(&args.input)?;
        navmap::make(&mut mesh, &|_| {}, &[], &how, &args.out)?.0
    } else {
        from_map_file(&args.input, &how, &args.out)?
    };
    let Some(s) = summary else {
        return Err(FileError::at(&args.input, "its mesh holds no ground or obstacle").into());
    };
    say!(
        "{}: {}; up: {}",
        args.out.join("map.yaml").display(),
        s.describe(),
        s.up
    );
    Ok(())
}

/// The navigation map of the saved map `path`: its mesh spooled beside the outputs (as a run
/// spools it), its path the ground's seeds, and the scans' floor kept beside it
/// ([`floor_file`]) when a run with `--navmap` saved it.
fn from_map_file(
    path: &Path,
    how: &NavMapOptions,
    out: &Path,
) -> Result<Option<navmap::files::NavMapSummary>, CliError> {
    let settings = saved_map::config_of(path)?;
    let mut file = MapFile::open(path)?;
    let map = file.load_new()?;
    let mut spool = MeshSpool::new(
        &out.join(".navmap-mesh.ply"),
        file.info.lattice,
        &settings.config.mesh,
    )?;
    spool.add_map(&map)?;
    drop(map);
    let seeds: Vec<_> = file
        .poses
        .iter()
        .map(|(_, p)| p.translation.vector)
        .collect();
    // The scans' floor the run kept beside the map (`run --navmap --save-map`), if it did.
    let floor = floor_file::read_beside(path, &file.poses);
    if let Some(f) = &floor {
        log::info!(
            "with the scans' floor beside the map: {} cells of {} m",
            f.count,
            f.resolution
        );
    }
    let floors = |each: &mut dyn FnMut(navmap::hits::ScanFloor)| {
        if let Some(f) = &floor {
            f.each(each);
        }
    };
    let (summary, grid) = navmap::make(&mut spool, &floors, &seeds, how, out)?;
    // The map's mesh with the layers on its vertices.
    let mut layers = navmap::layers::OnMesh::new(&grid, how.robot);
    let target = [(out.join("mesh.ply"), MeshFormat::Ply)];
    spool.finish_with(&target, summary.as_ref().map(|_| &mut layers as _))?;
    Ok(summary)
}
