//! Configuration files in TOML: a preset, then any parameter by section and name, then the
//! sliding window. Every parameter is listed once, in [`PARAMETERS`], with its documentation;
//! [`documented_toml`] prints a complete, commented file for any configuration.
//!
//! ```toml
//! preset = "kitti"          # default | quick | fast | kitti | meshing | town
//! [grid]
//! cell_size_m = 1.6
//! [register.lm]
//! huber_delta_m = 0.1
//! [window]
//! max_age_frames = 300
//! ```
//!
//! Errors name the file, and the line or the parameter, and the reason; the assembled
//! configuration is checked with [`Config::validate`].

use crate::inertial::{AccelUnit, ImuOptions};
use crate::io::error::FileError;
use crate::run::config_error::{BadValue, ConfigError};
use crate::run::window::Window;
use slamesh_core::Config;
use std::fmt::Write as _;
use std::path::Path;
use toml::Value;

/// The named presets.
pub const PRESETS: [&str; 6] = ["default", "quick", "fast", "kitti", "meshing", "town"];

/// Cell edge of the `town` preset (metres).
pub const TOWN_CELL_M: f64 = 1.4;

/// The configuration of a named preset.
///
/// - `default`: the most accurate general setting measured (docs/journal.md, "Presets"):
///   `town`'s, fitted to the scene's scale by the run ([`scales_itself`],
///   [`crate::run::scale`]).
/// - `quick`: `default` with one reconstruction a scan less: the map is updated with the last
///   registration round's layers moved to the final pose
///   (`map.reconstruct_at_final_pose = false`), fitted to the scene the same way. About a
///   quarter less time a scan than `default` on one thread and on two, about 1 % more step
///   error on KITTI
///   (docs/journal.md, "The `quick` preset").
/// - `fast`: the original's KITTI parameters ([`Config::default`]): 1.6 m cells, the lattice
///   at interval centres; about a quarter less time a scan, less accurate.
/// - `kitti`: `fast` with KITTI's vertical-angle correction ([`Config::kitti`]).
/// - `meshing`: [`Config::meshing`].
/// - `town`: `meshing` with [`TOWN_CELL_M`] cells (the original tunes the cell per dataset
///   too: 1.6 m for KITTI, 1.5 m for the simulated Mai City); the comparison with 1.6 m cells
///   is in docs/journal.md (The demo).
pub fn preset(name: &str) -> Option<Config> {
    match name {
        "fast" => Some(Config::default()),
        "kitti" => Some(Config::kitti()),
        "meshing" => Some(Config::meshing()),
        "default" | "town" => {
            let mut c = Config::meshing();
            c.grid.cell_size_m = TOWN_CELL_M;
            Some(c)
        }
        "quick" => {
            let mut c = preset("default")?;
            c.map.reconstruct_at_final_pose = false;
            Some(c)
        }
        _ => None,
    }
}

/// The settings of preset `name` (its configuration, no window); a name not in [`PRESETS`]
/// is refused with the list.
pub fn preset_settings(name: &str) -> Result<Settings, ConfigError> {
    let unknown = || ConfigError::UnknownPreset {
        name: name.to_string(),
        known: &PRESETS,
    };
    let preset = PRESETS
        .into_iter()
        .find(|p| *p == name)
        .ok_or_else(unknown)?;
    Ok(Settings {
        config: self::preset(preset).ok_or_else(unknown)?,
        preset,
        window: WindowSettings::default(),
        scale_to_scene: scales_itself(preset),
        imu: ImuOptions::default(),
    })
}

/// True for a preset that a run fits to the scale of its first whole scan
/// ([`crate::run::scale`]) unless the cell, the kernel or the nearest range is set: `default`
/// and `quick`.
pub fn scales_itself(name: &str) -> bool {
    matches!(name, "default" | "quick")
}

/// One tunable parameter: where it lives, what it means, how to read and write it.
pub struct Parameter {
    /// TOML section (`register.lm` for nested ones).
    pub section: &'static str,
    /// Name within the section (the core field's name).
    pub name: &'static str,
    /// What it does.
    pub doc: &'static str,
    get: fn(&Config) -> Value,
    set: fn(&mut Config, &Value) -> Result<(), BadValue>,
}

/// `v` is not `what`: the type it is instead.
fn expected(what: &'static str, v: &Value) -> BadValue {
    BadValue::Expected {
        what,
        found: v.type_str().to_string(),
    }
}

fn float(v: &Value) -> Result<f64, BadValue> {
    match v {
        Value::Float(f) => Ok(*f),
        Value::Integer(i) => Ok(*i as f64),
        _ => Err(expected("a number", v)),
    }
}

fn count<T: TryFrom<i64>>(v: &Value) -> Result<T, BadValue> {
    match v {
        Value::Integer(i) => T::try_from(*i).map_err(|_| BadValue::OutOfRange(*i)),
        _ => Err(expected("a whole number", v)),
    }
}

fn boolean(v: &Value) -> Result<bool, BadValue> {
    v.as_bool().ok_or_else(|| expected("true or false", v))
}

macro_rules! parameters {
    ($( $section:literal $($field:ident).+ : $read:ident as $to:expr, $doc:literal; )*) => {
        /// Every parameter of [`Config`], in file order.
        pub const PARAMETERS: &[Parameter] = &[$(
            Parameter {
                section: $section,
                name: parameters!(@last $($field).+),
                doc: $doc,
                get: |c| $to(c.$($field).+),
                set: |c, v| {
                    c.$($field).+ = $read(v)?;
                    Ok(())
                },
            },
        )*];
    };
    (@last $first:ident) => { stringify!($first) };
    (@last $first:ident . $($rest:ident).+) => { parameters!(@last $($rest).+) };
}

fn fv(x: f64) -> Value {
    Value::Float(x)
}
fn iv<T: Into<i64>>(x: T) -> Value {
    Value::Integer(x.into())
}
fn uv(x: usize) -> Value {
    Value::Integer(x as i64)
}

parameters! {
    "filter" filter.range_min_m: float as fv, "Points closer to the sensor are dropped (metres).";
    "filter" filter.range_max_m: float as fv, "Points farther from the sensor are dropped (metres).";
    "filter" filter.vertical_correction_deg: float as fv, "KITTI's vertical-angle calibration correction (degrees; 0 = off, 0.22 for KITTI).";
    "grid" grid.cell_size_m: float as fv, "Cell edge (metres); the down-sampling leaf is a sixth of it.";
    "grid" grid.min_points: count as uv, "Points a cell needs to be reconstructed.";
    "grid" grid.full_cover: boolean as Value::Boolean, "Lattice on the cell faces (gap-free meshes) instead of at interval centres.";
    "gp" gp.kappa_per_m: float as fv, "Kernel exp(-kappa |u - v|): kappa per metre.";
    "gp" gp.sensor_noise_m: float as fv, "Range noise standard deviation (metres).";
    "register" register.iterations: count as uv, "Registration rounds per scan.";
    "register" register.cross_cell_overlap: count as iv, "Cross-cell search reach (cells) in all but the last round.";
    "register" register.initial_iterations: count as uv, "Rounds while the motion is still unknown (the second scan).";
    "register" register.initial_cross_cell_overlap: count as iv, "Cross-cell reach while the motion is still unknown.";
    "register" register.variance_register: float as fv, "Vertices with a variance at or above this are not registered against.";
    "register" register.coarse_half_cells: boolean as Value::Boolean, "Rounds with a cross-cell reach reconstruct every other cell (a 3D checkerboard).";
    "register.lm" register.lm.max_iterations: count as uv, "Levenberg-Marquardt iterations per round.";
    "register.lm" register.lm.tolerance: float as fv, "Stop when the update's norm is below this.";
    "register.lm" register.lm.huber_delta_m: float as fv, "Huber loss threshold (metres).";
    "register.lm" register.lm.degenerate_ratio: float as fv, "A direction whose mean squared normal component is below this is left to the motion model.";
    "register.lm" register.lm.min_residuals: count as uv, "Fewer residuals than this and the scan keeps the motion prediction.";
    "register.recovery" register.recovery.enabled: boolean as Value::Boolean, "Try other initial guesses (the last pose, turned in yaw) when a registration did not converge.";
    "register.recovery" register.recovery.yaw_step_deg: float as fv, "Yaw between the guesses (degrees; 0: the last pose only).";
    "register.recovery" register.recovery.yaw_max_deg: float as fv, "Largest yaw tried either way (degrees).";
    "register.recovery" register.recovery.rounds: count as uv, "Registration rounds from each guess.";
    "register.recovery" register.recovery.confirm_share: float as fv, "A last round at LM's limit matching fewer of the scan's layers than this did not converge; one before the limit matching at least this did.";
    "register.recovery" register.recovery.accept_share: float as fv, "When no guess was sure, the best that converged and settled with at least this share matched is kept as recovered.";
    "register.recovery" register.recovery.settle_m: float as fv, "A last round that moved the sensor by more than this (metres) has not settled: the frame goes to recovery.";
    "register.recovery" register.recovery.settle_deg: float as fv, "As settle_m, in degrees.";
    "register.recovery" register.recovery.polish_rounds: count as uv, "Rounds that refine a recovered pose, or a converged one after a turn above polish_turn_deg (no cross-cell reach, polish_huber_delta_m); 0: none.";
    "register.recovery" register.recovery.polish_turn_deg: float as fv, "A frame that converged from a prediction turning more than this (degrees) is polished too.";
    "register.recovery" register.recovery.polish_huber_delta_m: float as fv, "LM's Huber threshold in the polishing rounds (metres).";
    "register.recovery" register.recovery.profile_turn_max_deg: float as fv, "The turn since the last scan is looked for in the two scans' azimuth profiles within this many degrees either way (0: not at all).";
    "register.recovery" register.recovery.profile_disagree_deg: float as fv, "When the profiles' turn and the motion prediction's differ by more than this (degrees), registration starts from the profiles' turn.";
    "register.recovery" register.recovery.profile_rounds: count as uv, "Registration rounds from the profiles' start (all but the last with the initial reach); it is then polished.";
    "map" map.variance_update: float as fv, "Vertices are fused when both variances are below this, else the surer one is kept.";
    "map" map.add_missing_layers: boolean as Value::Boolean, "Add a layer that a known cell lacks.";
    "map" map.reconstruct_at_final_pose: boolean as Value::Boolean, "Reconstruct the scan again at its final pose before fusing it (false: move the last round's reconstruction there instead; about a quarter faster, a little less accurate).";
    "map" map.stale_after_frames: count as iv, "A cell not seen for more than this many frames is left out of registration and mapped afresh when seen again (0: never; --loop-closure on sets 300).";
    "mesh" mesh.variance_show: float as fv, "Triangles whose mean vertex variance is at or above this are not shown.";
    "mesh" mesh.max_slope_deg: float as fv, "Triangles steeper than this against their layer's axis (degrees) are not shown (90: all shown).";
}

/// What a configuration file sets: the pipeline configuration and the sliding window.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    /// The pipeline configuration (validated).
    pub config: Config,
    /// The preset it started from.
    pub preset: &'static str,
    /// Sliding-window rules (the memory cap as megabytes in `memory_cap_mb`).
    pub window: WindowSettings,
    /// Fit the configuration to the scale of the first whole scan ([`crate::run::scale`]):
    /// the preset [`scales_itself`] and none of the fields the fit sets is given.
    pub scale_to_scene: bool,
    /// The `[imu]` section: the IMU's place on the LiDAR, its clock and limits.
    pub imu: ImuOptions,
}

/// The `[window]` section.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct WindowSettings {
    /// Evict cells not seen for this many frames.
    pub max_age_frames: Option<u32>,
    /// Evict cells farther than this from the sensor (metres).
    pub radius_m: Option<f64>,
    /// Keep the process under this many megabytes by evicting the oldest cells.
    pub memory_cap_mb: Option<f64>,
    /// Append evicted cells to the output mesh.
    pub save_evicted: bool,
}

impl WindowSettings {
    /// The window rules without the memory cap (which needs the capacity to become a budget).
    pub fn rules(&self) -> Window {
        Window {
            max_age_frames: self.max_age_frames,
            radius_m: self.radius_m,
            max_layers: None,
        }
    }

    /// Whether the map is a window: a memory cap or a rule evicts cells.
    pub fn is_windowed(&self) -> bool {
        self.memory_cap_mb.is_some() || !self.rules().is_off()
    }
}

const WINDOW_DOCS: [(&str, &str); 4] = [
    (
        "max_age_frames",
        "Evict cells not seen for more than this many frames.",
    ),
    (
        "radius_m",
        "Evict cells whose centre is farther than this from the sensor (metres).",
    ),
    (
        "memory_cap_mb",
        "Evict the oldest cells so that the process stays under this many MB.",
    ),
    (
        "save_evicted",
        "Append evicted cells to the output mesh, so nothing is lost.",
    ),
];

/// Reads a configuration file.
pub fn read(path: &Path) -> Result<Settings, FileError> {
    let text = std::fs::read_to_string(path).map_err(|e| FileError::at(path, e.to_string()))?;
    parse(&text).map_err(|e| FileError::at(path, e.to_string()))
}

/// Parses configuration text (see the module docs).
pub fn parse(text: &str) -> Result<Settings, ConfigError> {
    let table: toml::Table = toml::from_str(text).map_err(|e| ConfigError::Toml(e.to_string()))?;
    let preset_name = match table.get("preset") {
        None => "default",
        Some(Value::String(s)) => {
            PRESETS
                .into_iter()
                .find(|p| p == s)
                .ok_or_else(|| ConfigError::Value {
                    at: "preset".into(),
                    why: BadValue::OneOf {
                        choices: PRESETS.join(", "),
                        found: format!("{s:?}"),
                    },
                })?
        }
        Some(v) => {
            return Err(ConfigError::Value {
                at: "preset".into(),
                why: expected("a name", v),
            })
        }
    };
    let mut config = preset(preset_name).unwrap_or_default();
    let mut window = WindowSettings::default();
    let mut imu = ImuOptions::default();
    for (key, value) in &table {
        match (key.as_str(), value) {
            ("preset", _) => {}
            ("window", Value::Table(t)) => window = read_window(t)?,
            ("imu", Value::Table(t)) => imu = read_imu(t)?,
            (section, Value::Table(t)) => set_section(&mut config, section, t)?,
            _ => return Err(unknown(key.clone(), "top-level key", Vec::new())),
        }
    }
    config.validate().map_err(|e| ConfigError::Invalid {
        field: e.field.to_string(),
        reason: e.reason.to_string(),
    })?;
    let given = |section: &str, name: &str| {
        table
            .get(section)
            .and_then(Value::as_table)
            .is_some_and(|t| t.contains_key(name))
    };
    let fitted_given = given("grid", "cell_size_m")
        || given("gp", "kappa_per_m")
        || given("filter", "range_min_m");
    Ok(Settings {
        config,
        preset: preset_name,
        window,
        scale_to_scene: scales_itself(preset_name) && !fitted_given,
        imu,
    })
}

/// A key not known at `at`, taken for a `kind`, beside the `known` ones.
fn unknown(at: String, kind: &'static str, known: Vec<&'static str>) -> ConfigError {
    ConfigError::Unknown { at, kind, known }
}

fn set_section(config: &mut Config, section: &str, t: &toml::Table) -> Result<(), ConfigError> {
    for (name, v) in t {
        if let Value::Table(inner) = v {
            set_section(config, &format!("{section}.{name}"), inner)?;
            continue;
        }
        let p = PARAMETERS
            .iter()
            .find(|p| p.section == section && p.name == name)
            .ok_or_else(|| {
                let known: Vec<&str> = PARAMETERS
                    .iter()
                    .filter(|p| p.section == section)
                    .map(|p| p.name)
                    .collect();
                match known.is_empty() {
                    true => unknown(format!("[{section}]"), "section", known),
                    false => unknown(format!("[{section}] {name}"), "parameter", known),
                }
            })?;
        (p.set)(config, v).map_err(|why| ConfigError::Value {
            at: format!("[{section}] {name}"),
            why,
        })?;
    }
    Ok(())
}

fn read_window(t: &toml::Table) -> Result<WindowSettings, ConfigError> {
    let mut w = WindowSettings::default();
    for (name, v) in t {
        let e = |why| ConfigError::Value {
            at: format!("[window] {name}"),
            why,
        };
        match name.as_str() {
            "max_age_frames" => w.max_age_frames = Some(count(v).map_err(e)?),
            "radius_m" => w.radius_m = Some(positive(v).map_err(e)?),
            "memory_cap_mb" => w.memory_cap_mb = Some(positive(v).map_err(e)?),
            "save_evicted" => w.save_evicted = boolean(v).map_err(e)?,
            _ => {
                let known = WINDOW_DOCS.iter().map(|d| d.0).collect();
                return Err(unknown(format!("[window] {name}"), "parameter", known));
            }
        }
    }
    Ok(w)
}

const IMU_DOCS: [(&str, &str, &str); 8] = [
    (
        "translation_m",
        "The IMU's position in the LiDAR frame (metres): the lever arm.",
        "[0.0, 0.0, 0.0]",
    ),
    (
        "rotation_rpy_deg",
        "The IMU's axes in the LiDAR frame: roll, pitch, yaw (degrees, applied yaw first).",
        "[0.0, 0.0, 0.0]",
    ),
    (
        "time_offset_s",
        "Seconds added to an IMU stamp to put it on the LiDAR's clock.",
        "0.0",
    ),
    (
        "gyro_limit_deg_s",
        "A gyro reading at or above this is counted as saturated (degrees a second).",
        "2000.0",
    ),
    (
        "accel_limit_m_s2",
        "An accelerometer reading at or above this is counted as saturated (m/s²).",
        "156.9",
    ),
    (
        "bias_gain",
        "Share of the registration's disagreement with the gyro taken into its bias a frame.",
        "0.2",
    ),
    (
        "gyro_unit",
        "The gyro's unit: \"rad/s\" (as sensor_msgs/Imu says) or \"deg/s\".",
        "\"rad/s\"",
    ),
    (
        "accel_unit",
        "The accelerometer's unit: \"m/s2\", \"g\", or \"auto\" (told from the first readings).",
        "\"auto\"",
    ),
];

fn read_imu(t: &toml::Table) -> Result<ImuOptions, ConfigError> {
    let mut o = ImuOptions::default();
    let c = &mut o.calibration;
    let (mut translation, mut rpy) = ([0.0; 3], [0.0; 3]);
    for (name, v) in t {
        let e = |why| ConfigError::Value {
            at: format!("[imu] {name}"),
            why,
        };
        match name.as_str() {
            "translation_m" => {
                translation = triple(v).map_err(e)?;
                o.placed = true;
            }
            "rotation_rpy_deg" => {
                rpy = triple(v).map_err(e)?;
                o.placed = true;
            }
            "time_offset_s" => c.time_offset_s = finite(v).map_err(e)?,
            "gyro_limit_deg_s" => c.gyro_limit_rad_s = positive(v).map_err(e)?.to_radians(),
            "accel_limit_m_s2" => c.accel_limit_m_s2 = positive(v).map_err(e)?,
            "bias_gain" => o.bias_gain = positive(v).map_err(e)?.min(1.0),
            "gyro_unit" => {
                c.gyro_unit_rad_s = match v.as_str() {
                    Some("rad/s") => 1.0,
                    Some("deg/s") => 1f64.to_radians(),
                    _ => {
                        return Err(e(BadValue::OneOf {
                            choices: "\"rad/s\", \"deg/s\"".into(),
                            found: v.to_string(),
                        }))
                    }
                }
            }
            "accel_unit" => {
                o.accel_unit = match v.as_str() {
                    Some("auto") => AccelUnit::Auto,
                    Some("m/s2") => AccelUnit::MetresPerSecondSquared,
                    Some("g") => AccelUnit::G,
                    _ => {
                        return Err(e(BadValue::OneOf {
                            choices: "\"m/s2\", \"g\", \"auto\"".into(),
                            found: v.to_string(),
                        }))
                    }
                }
            }
            _ => {
                let known = IMU_DOCS.iter().map(|d| d.0).collect();
                return Err(unknown(format!("[imu] {name}"), "parameter", known));
            }
        }
    }
    let [r, p, y] = rpy.map(f64::to_radians);
    o.calibration.lidar_from_imu = slamesh_core::Pose::from_parts(
        nalgebra::Translation3::new(translation[0], translation[1], translation[2]),
        nalgebra::UnitQuaternion::from_euler_angles(r, p, y),
    );
    Ok(o)
}

fn finite(v: &Value) -> Result<f64, BadValue> {
    let x = float(v)?;
    x.is_finite().then_some(x).ok_or(BadValue::NotFinite(x))
}

fn triple(v: &Value) -> Result<[f64; 3], BadValue> {
    let Some([a, b, c]) = v.as_array().map(Vec::as_slice) else {
        return Err(BadValue::Expected {
            what: "three numbers",
            found: v.to_string(),
        });
    };
    Ok([finite(a)?, finite(b)?, finite(c)?])
}

fn positive(v: &Value) -> Result<f64, BadValue> {
    let x = float(v)?;
    if x > 0.0 && x.is_finite() {
        Ok(x)
    } else {
        Err(BadValue::NotPositive(x))
    }
}

/// A complete configuration file for `config` (from `preset`), every parameter with its
/// documentation; reading it back gives `config`.
pub fn documented_toml(config: &Config, preset: &str) -> String {
    let mut s = format!(
        "# slamesh configuration. Every parameter is optional; missing ones come from the preset.\n\
         preset = \"{preset}\"  # one of: {}\n",
        PRESETS.join(", ")
    );
    if scales_itself(preset) {
        s.push_str(
            "# A run fits this preset to the scale of its first scan (smaller cells indoors) when\n\
             # the file leaves out grid.cell_size_m, gp.kappa_per_m and filter.range_min_m:\n\
             # delete those three lines to keep the fit.\n",
        );
    }
    let mut section = "";
    for p in PARAMETERS {
        if p.section != section {
            section = p.section;
            let _ = writeln!(s, "\n[{section}]");
        }
        let _ = writeln!(s, "# {}\n{} = {}", p.doc, p.name, (p.get)(config));
    }
    s.push_str("\n# Sliding-window eviction for long runs (all off unless set).\n[window]\n");
    for (name, doc) in WINDOW_DOCS {
        let example = if name == "save_evicted" {
            "true"
        } else {
            "..."
        };
        let _ = writeln!(s, "# {doc}\n# {name} = {example}");
    }
    s
}

/// The `[imu]` section's documentation, every parameter commented out with its default: what
/// `slamesh config` adds to [`documented_toml`] (a map file keeps only the map's settings).
pub fn documented_imu_toml() -> String {
    let mut s = String::from(
        "\n# The IMU, when the input has one (defaults: at the LiDAR, in its axes).\n[imu]\n",
    );
    for (name, doc, example) in IMU_DOCS {
        let _ = writeln!(s, "# {doc}\n# {name} = {example}");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_preset_round_trips_through_its_documented_file() {
        for name in PRESETS {
            let c = preset(name).unwrap();
            let mut changed = c;
            changed.register.lm.huber_delta_m = 0.25;
            changed.grid.min_points = 7;
            changed.map.reconstruct_at_final_pose = !c.map.reconstruct_at_final_pose;
            changed.register.recovery.yaw_step_deg = 10.0;
            changed.register.recovery.enabled = false;
            changed.register.recovery.polish_turn_deg = 7.5;
            changed.register.recovery.profile_turn_max_deg = 45.0;
            changed.register.recovery.profile_disagree_deg = 8.0;
            changed.register.recovery.profile_rounds = 4;
            changed.map.stale_after_frames = 300;
            let text = documented_toml(&changed, name);
            let s = parse(&text).unwrap_or_else(|e| panic!("{name}: {e}\n{text}"));
            assert_eq!(s.config, changed, "{name}");
            assert_eq!(s.preset, name);
        }
        assert_eq!(PARAMETERS.len(), 39);
    }

    #[test]
    fn the_default_preset_scales_itself_unless_a_fitted_field_is_given() {
        assert!(parse("").unwrap().scale_to_scene);
        assert!(parse("preset = \"quick\"\n").unwrap().scale_to_scene);
        assert!(
            parse("preset = \"default\"\n[register]\niterations = 3\n")
                .unwrap()
                .scale_to_scene
        );
        for fixed in [
            "[grid]\ncell_size_m = 1.0\n",
            "[gp]\nkappa_per_m = 2.0\n",
            "[filter]\nrange_min_m = 0.5\n",
            "preset = \"town\"\n",
            "preset = \"fast\"\n",
        ] {
            assert!(!parse(fixed).unwrap().scale_to_scene, "{fixed}");
        }
        // `default` is `town`'s settings before the fit; `fast` the original's.
        assert_eq!(preset("default"), preset("town"));
        assert_eq!(preset("fast"), Some(Config::default()));
        // `quick` is `default` but for the map update from the last round's layers.
        let mut quick = preset("default").unwrap();
        quick.map.reconstruct_at_final_pose = false;
        assert_eq!(preset("quick"), Some(quick));
    }

    #[test]
    fn sections_override_the_preset_and_the_window_is_read() {
        let s = parse(
            "preset = \"meshing\"\n[grid]\ncell_size_m = 2\n[register.lm]\nmax_iterations = 4\n\
             [window]\nmax_age_frames = 50\nmemory_cap_mb = 120\nsave_evicted = true\n",
        )
        .unwrap();
        let mut want = Config::meshing();
        want.grid.cell_size_m = 2.0;
        want.register.lm.max_iterations = 4;
        assert_eq!(s.config, want);
        assert_eq!(s.window.max_age_frames, Some(50));
        assert_eq!(s.window.memory_cap_mb, Some(120.0));
        assert!(s.window.save_evicted);
    }

    #[test]
    fn the_imu_section_places_the_imu_and_names_its_mistakes() {
        let s = parse(
            "[imu]\ntranslation_m = [0.3, 0.0, -0.1]\nrotation_rpy_deg = [0.0, 0.0, 90.0]\n\
             time_offset_s = -0.02\nbias_gain = 0.5\n",
        )
        .unwrap();
        let c = s.imu.calibration;
        assert_eq!(c.lidar_from_imu.translation.vector.x, 0.3);
        let x = c.lidar_from_imu.rotation * nalgebra::Vector3::x();
        assert!((x - nalgebra::Vector3::y()).norm() < 1e-12, "{x}");
        assert_eq!((c.time_offset_s, s.imu.bias_gain), (-0.02, 0.5));
        assert!(s.imu.enabled);
        assert_eq!(s.imu.accel_unit, AccelUnit::Auto);
        let g = parse("[imu]\naccel_unit = \"g\"\n").unwrap().imu.accel_unit;
        assert_eq!(g, AccelUnit::G);
        let deg = parse("[imu]\ngyro_unit = \"deg/s\"\n")
            .unwrap()
            .imu
            .calibration;
        assert_eq!(deg.gyro_unit_rad_s, 1f64.to_radians());
        for (text, want) in [
            (
                "[imu]\ntranslation_m = [1, 2]\n",
                "[imu] translation_m: expected three numbers",
            ),
            (
                "[imu]\nlever = 1\n",
                "[imu] lever: unknown parameter (known: translation_m",
            ),
            (
                "[imu]\ngyro_limit_deg_s = -1\n",
                "[imu] gyro_limit_deg_s: must be a positive",
            ),
            (
                "[imu]\naccel_unit = \"ft/s2\"\n",
                "[imu] accel_unit: \"ft/s2\" is not one of \"m/s2\", \"g\", \"auto\"",
            ),
        ] {
            let e = parse(text).unwrap_err().to_string();
            assert!(e.starts_with(want), "{text}: {e}");
        }
        // `slamesh config`'s section reads back as the defaults.
        let documented = documented_toml(&Config::default(), "default") + &documented_imu_toml();
        assert_eq!(parse(&documented).unwrap().imu, ImuOptions::default());
    }

    #[test]
    fn mistakes_get_messages_that_name_them() {
        let cases = [
            (
                "[grid]\ncell_sise_m = 2\n",
                "[grid] cell_sise_m: unknown parameter",
            ),
            (
                "[grid]\nmin_points = -3\n",
                "[grid] min_points: -3 is out of range",
            ),
            ("[grid]\nfull_cover = 1\n", "expected true or false"),
            ("[gird]\nx = 1\n", "[gird]: unknown section"),
            ("preset = \"rapid\"\n", "preset: \"rapid\" is not one of"),
            ("[grid]\ncell_size_m = -1.6\n", "cell_size_m"),
            (
                "[window]\nradius_m = 0\n",
                "[window] radius_m: must be a positive",
            ),
            ("[grid\n", "line 1"),
        ];
        for (text, want) in cases {
            let e = parse(text).unwrap_err().to_string();
            assert!(e.contains(want), "{text:?}: {e}");
        }
        // Told apart by kind, not by words.
        let section = parse("[gird]\nx = 1\n").unwrap_err();
        assert!(matches!(
            section,
            ConfigError::Unknown {
                kind: "section",
                ..
            }
        ));
        let range = parse("[grid]\nmin_points = -3\n").unwrap_err();
        assert!(matches!(
            range,
            ConfigError::Value {
                why: BadValue::OutOfRange(-3),
                ..
            }
        ));
        assert!(matches!(parse("[grid\n"), Err(ConfigError::Toml(_))));
    }
}
