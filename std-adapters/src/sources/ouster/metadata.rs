//! An Ouster sensor's metadata: the JSON its HTTP API (`/api/v1/sensor/metadata`) and its
//! tools write beside every recording, read into what the packet decoder needs.
//!
//! Two layouts exist and both are read: the flat one of firmware 1.x and 2.0-2.1 (the angles,
//! `lidar_mode` and `data_format` at the top) and the nested one of later firmware and SDKs
//! (`beam_intrinsics`, `lidar_intrinsics`, `lidar_data_format`, `config_params`,
//! `sensor_info`). What is missing takes the sensor's own default (the legacy profile, 16
//! columns a packet, the full column window); what is there but wrong (angle lists of another
//! length than the beams, an unknown profile or mode) is refused with the field named.

use super::packet::Profile;
use serde_json::Value;

/// What the decoder needs from a sensor's metadata.
#[derive(Debug, Clone, PartialEq)]
pub struct Metadata {
    /// The product line (`OS-1-64`, `OS-0-128`, ...), for messages.
    pub prod_line: String,
    /// The lidar packets' profile.
    pub profile: Profile,
    /// Columns a turn (512, 1024, 2048 or 4096).
    pub columns_per_frame: u16,
    /// Turns a second (10 or 20; 5 for 4096-column modes).
    pub fps: u16,
    /// Columns a packet (16 unless the sensor was set otherwise).
    pub columns_per_packet: u16,
    /// Beams.
    pub pixels_per_column: u16,
    /// The first and last column the sensor sends (inclusive; may wrap past the last column).
    pub column_window: (u16, u16),
    /// Each beam's elevation (degrees).
    pub altitude_deg: Vec<f64>,
    /// Each beam's azimuth offset (degrees).
    pub azimuth_deg: Vec<f64>,
    /// From the beams' origin to the lidar frame (row-major 4x4, millimetres).
    pub beam_to_lidar: [f64; 16],
    /// From the lidar frame to the sensor frame (row-major 4x4, millimetres).
    pub lidar_to_sensor: [f64; 16],
    /// The port lidar packets go to, when the metadata says.
    pub udp_port_lidar: Option<u16>,
    /// From the IMU's frame to the sensor frame (row-major 4x4, millimetres).
    pub imu_to_sensor: [f64; 16],
    /// The port IMU packets go to, when the metadata says.
    pub udp_port_imu: Option<u16>,
}

/// The port Ouster sensors send lidar packets to unless set otherwise.
pub const LIDAR_PORT: u16 = 7502;
/// The port they send IMU packets to unless set otherwise.
pub const IMU_PORT: u16 = 7503;

/// The identity as a row-major 4x4 matrix: a transform the metadata does not give.
pub const IDENTITY: [f64; 16] = [
    1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
];

/// The value at `path` in the nested layout, else at `flat` at the top.
fn field<'a>(doc: &'a Value, path: &[&str], flat: &str) -> Option<&'a Value> {
    let nested = path.iter().try_fold(doc, |v, k| v.get(k));
    nested
        .filter(|v| !v.is_null())
        .or_else(|| doc.get(flat).filter(|v| !v.is_null()))
}

/// Why an Ouster sensor's metadata JSON could not be read, by kind, in words.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum MetadataError {
    /// The text is not a JSON object.
    NotJson(String),
    /// A field every sensor's metadata has is not there.
    Missing(String),
    /// A field whose value this reader cannot take: which, and why.
    Bad(String),
}

impl std::fmt::Display for MetadataError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MetadataError::NotJson(why) | MetadataError::Missing(why) | MetadataError::Bad(why) => {
                f.write_str(why)
            }
        }
    }
}

impl std::error::Error for MetadataError {}

use MetadataError::{Bad, Missing, NotJson};

fn numbers(v: &Value, name: &str) -> Result<Vec<f64>, MetadataError> {
    let list = v
        .as_array()
        .ok_or_else(|| Bad(format!("{name} is not a list of numbers")))?;
    list.iter()
        .map(|x| {
            x.as_f64()
                .filter(|f| f.is_finite())
                .ok_or_else(|| Bad(format!("{name} holds {x}, not a finite number")))
        })
        .collect()
}

fn small(v: &Value, name: &str, max: u64) -> Result<u16, MetadataError> {
    v.as_u64()
        .filter(|n| *n <= max)
        .map(|n| n as u16)
        .ok_or_else(|| Bad(format!("{name} is {v}, not a whole number up to {max}")))
}

fn matrix(v: &Value, name: &str) -> Result<[f64; 16], MetadataError> {
    let m = numbers(v, name)?;
    <[f64; 16]>::try_from(m.as_slice()).map_err(|_| {
        Bad(format!(
            "{name} has {} numbers, not a 4x4 matrix's 16",
            m.len()
        ))
    })
}

/// `1024x10` to (1024, 10).
fn lidar_mode(mode: &str) -> Result<(u16, u16), MetadataError> {
    let bad = || {
        Bad(format!(
            "lidar_mode {mode:?} is not one of 512x10, 512x20, 1024x10, 1024x20, 2048x10, 4096x5"
        ))
    };
    let (w, f) = mode.split_once('x').ok_or_else(bad)?;
    let (w, f) = (
        w.parse::<u16>().map_err(|_| bad())?,
        f.parse::<u16>().map_err(|_| bad())?,
    );
    match (w, f) {
        (512, 10 | 20) | (1024, 10 | 20) | (2048, 10) | (4096, 5) => Ok((w, f)),
        _ => Err(bad()),
    }
}

/// The beams' angles `name` (degrees); `missing` when absent.
fn beam_angles(doc: &Value, name: &str, missing: &str) -> Result<Vec<f64>, MetadataError> {
    numbers(
        field(doc, &["beam_intrinsics", name], name).ok_or_else(|| Missing(missing.into()))?,
        name,
    )
}

/// Columns a packet (`v`, 16 when absent), a divisor of the turn's.
fn columns_per_packet(v: Option<&Value>, columns_per_frame: u16) -> Result<u16, MetadataError> {
    let n = match v {
        Some(v) => small(v, "columns_per_packet", 64)?,
        None => 16,
    };
    if n == 0 || !columns_per_frame.is_multiple_of(n) {
        return Err(Bad(format!(
            "columns_per_packet is {n}, not a divisor of the {columns_per_frame} columns a turn"
        )));
    }
    Ok(n)
}

/// The lidar packets' profile: the data format's (`in_format`), the configuration's, or the
/// legacy one.
fn lidar_profile(doc: &Value, in_format: Option<&Value>) -> Result<Profile, MetadataError> {
    let name = in_format
        .or_else(|| {
            field(
                doc,
                &["config_params", "udp_profile_lidar"],
                "udp_profile_lidar",
            )
        })
        .and_then(Value::as_str)
        .unwrap_or("LEGACY");
    Profile::named(name).ok_or_else(|| {
        Bad(format!(
            "udp_profile_lidar {name:?} is not one this reader decodes ({})",
            Profile::ALL.map(|p| p.name()).join(", ")
        ))
    })
}

/// The UDP port `name`, when set (0 is not a port).
fn port(doc: &Value, name: &str) -> Option<u16> {
    field(doc, &["config_params", name], name)
        .and_then(Value::as_u64)
        .and_then(|p| u16::try_from(p).ok())
        .filter(|p| *p != 0)
}

/// The beams' origin to the lidar frame: the transform, or the older offset along x.
fn beam_to_lidar(doc: &Value) -> Result<[f64; 16], MetadataError> {
    if let Some(v) = field(
        doc,
        &["beam_intrinsics", "beam_to_lidar_transform"],
        "beam_to_lidar_transform",
    ) {
        return matrix(v, "beam_to_lidar_transform");
    }
    let n = field(
        doc,
        &["beam_intrinsics", "lidar_origin_to_beam_origin_mm"],
        "lidar_origin_to_beam_origin_mm",
    )
    .map(|v| {
        v.as_f64().filter(|f| f.is_finite()).ok_or_else(|| {
            Bad(format!(
                "lidar_origin_to_beam_origin_mm is {v}, not a number"
            ))
        })
    })
    .transpose()?
    .unwrap_or(0.0);
    let mut m = IDENTITY;
    m[3] = n;
    Ok(m)
}

/// The 4x4 transform `name` (under `group` in the nested layout); the identity when absent.
fn transform(doc: &Value, group: &str, name: &str) -> Result<[f64; 16], MetadataError> {
    match field(doc, &[group, name], name) {
        Some(v) => matrix(v, name),
        None => Ok(IDENTITY),
    }
}

/// The first and last column sent (`column_window`), all of them when absent.
fn column_window(v: Option<&Value>, columns_per_frame: u16) -> Result<(u16, u16), MetadataError> {
    let Some(v) = v else {
        return Ok((0, columns_per_frame - 1));
    };
    let w = numbers(v, "column_window")?;
    let ok = |x: f64| x >= 0.0 && x < f64::from(columns_per_frame) && x.fract() == 0.0;
    match w.as_slice() {
        [a, b] if ok(*a) && ok(*b) => Ok((*a as u16, *b as u16)),
        _ => Err(Bad(format!(
            "column_window is {v}, not two columns below {columns_per_frame}"
        ))),
    }
}

impl Metadata {
    /// Reads the metadata JSON's text.
    pub fn parse(text: &str) -> Result<Self, MetadataError> {
        let doc: Value =
            serde_json::from_str(text).map_err(|e| NotJson(format!("not JSON ({e})")))?;
        if !doc.is_object() {
            return Err(NotJson("not a JSON object".into()));
        }
        let altitude_deg = beam_angles(
            &doc,
            "beam_altitude_angles",
            "no beam_altitude_angles: not an Ouster sensor's metadata",
        )?;
        let azimuth_deg = beam_angles(&doc, "beam_azimuth_angles", "no beam_azimuth_angles")?;
        let mode = field(&doc, &["config_params", "lidar_mode"], "lidar_mode")
            .and_then(Value::as_str)
            .ok_or_else(|| Missing("no lidar_mode".into()))?;
        let (columns_per_frame, fps) = lidar_mode(mode)?;
        let format = field(&doc, &["lidar_data_format"], "data_format");
        let in_format = |k: &str| format.and_then(|f| f.get(k)).filter(|v| !v.is_null());
        let beams = match in_format("pixels_per_column") {
            Some(v) => small(v, "pixels_per_column", 256)?,
            None => u16::try_from(altitude_deg.len()).unwrap_or(u16::MAX),
        };
        if !matches!(beams, 8 | 16 | 32 | 64 | 128) {
            return Err(Bad(format!(
                "pixels_per_column is {beams}, not 8, 16, 32, 64 or 128"
            )));
        }
        for (name, list) in [
            ("beam_altitude_angles", &altitude_deg),
            ("beam_azimuth_angles", &azimuth_deg),
        ] {
            if list.len() != usize::from(beams) {
                return Err(Bad(format!(
                    "{name} has {} angles for {beams} beams (per-pixel angles, as a \
                     solid-state sensor's, are not read)",
                    list.len()
                )));
            }
        }
        let columns_per_packet =
            columns_per_packet(in_format("columns_per_packet"), columns_per_frame)?;
        if let Some(v) = in_format("columns_per_frame") {
            let w = small(v, "columns_per_frame", 4096)?;
            if w != columns_per_frame {
                return Err(Bad(format!(
                    "columns_per_frame is {w}, but lidar_mode {mode:?} says {columns_per_frame}"
                )));
            }
        }
        let column_window = column_window(in_format("column_window"), columns_per_frame)?;
        let profile = lidar_profile(&doc, in_format("udp_profile_lidar"))?;
        let beam_to_lidar = beam_to_lidar(&doc)?;
        let lidar_to_sensor = transform(&doc, "lidar_intrinsics", "lidar_to_sensor_transform")?;
        let imu_to_sensor = transform(&doc, "imu_intrinsics", "imu_to_sensor_transform")?;
        let (udp_port_lidar, udp_port_imu) =
            (port(&doc, "udp_port_lidar"), port(&doc, "udp_port_imu"));
        let prod_line = field(&doc, &["sensor_info", "prod_line"], "prod_line")
            .and_then(Value::as_str)
            .unwrap_or("Ouster")
            .to_string();
        Ok(Self {
            prod_line,
            profile,
            columns_per_frame,
            fps,
            columns_per_packet,
            pixels_per_column: beams,
            column_window,
            altitude_deg,
            azimuth_deg,
            beam_to_lidar,
            lidar_to_sensor,
            udp_port_lidar,
            imu_to_sensor,
            udp_port_imu,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flat(beams: usize) -> String {
        let angles: Vec<String> = (0..beams).map(|i| format!("{}", i as f64 * 0.5)).collect();
        format!(
            r#"{{"prod_line": "OS-1-{beams}", "lidar_mode": "1024x10",
               "beam_altitude_angles": [{a}], "beam_azimuth_angles": [{a}],
               "lidar_origin_to_beam_origin_mm": 12.163,
               "lidar_to_sensor_transform": [-1,0,0,0, 0,-1,0,0, 0,0,1,36.18, 0,0,0,1]}}"#,
            a = angles.join(",")
        )
    }

    #[test]
    fn the_flat_layout_takes_the_sensors_defaults_for_what_it_lacks() {
        let m = Metadata::parse(&flat(16)).unwrap();
        assert_eq!(m.profile, Profile::Legacy);
        assert_eq!(
            (m.columns_per_frame, m.fps, m.columns_per_packet),
            (1024, 10, 16)
        );
        assert_eq!((m.pixels_per_column, m.column_window), (16, (0, 1023)));
        assert_eq!(m.beam_to_lidar[3], 12.163);
        assert_eq!(m.lidar_to_sensor[11], 36.18);
        assert_eq!(m.udp_port_lidar, None);
    }

    #[test]
    fn the_nested_layout_is_read() {
        let text = r#"{
            "beam_intrinsics": {"beam_altitude_angles": [1,2,3,4,5,6,7,8],
                                "beam_azimuth_angles": [0,0,0,0,0,0,0,0],
                                "beam_to_lidar_transform": [1,0,0,27.67, 0,1,0,0, 0,0,1,0, 0,0,0,1]},
            "config_params": {"lidar_mode": "512x20", "udp_port_lidar": 7502,
                              "udp_profile_lidar": "RNG19_RFL8_SIG16_NIR16"},
            "lidar_data_format": {"columns_per_frame": 512, "columns_per_packet": 16,
                                  "pixels_per_column": 8, "column_window": [10, 500],
                                  "udp_profile_lidar": "RNG15_RFL8_NIR8"},
            "sensor_info": {"prod_line": "OS-0-8"}}"#;
        let m = Metadata::parse(text).unwrap();
        // The data format's profile is the one the packets have.
        assert_eq!(m.profile, Profile::Rng15);
        assert_eq!(
            (m.columns_per_frame, m.fps, m.column_window),
            (512, 20, (10, 500))
        );
        assert_eq!(
            (m.udp_port_lidar, m.prod_line.as_str()),
            (Some(7502), "OS-0-8")
        );
        assert_eq!(m.beam_to_lidar[3], 27.67);
    }

    #[test]
    fn wrong_metadata_is_refused_with_the_field_named() {
        let e = Metadata::parse(&flat(16).replace("1024x10", "1000x10"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("lidar_mode \"1000x10\""), "{e}");
        let e = Metadata::parse(&flat(12)).unwrap_err().to_string();
        assert!(e.contains("pixels_per_column is 12"), "{e}");
        let e = Metadata::parse(&flat(16).replace(
            "\"lidar_mode\"",
            "\"udp_profile_lidar\": \"X\", \"lidar_mode\"",
        ))
        .unwrap_err()
        .to_string();
        assert!(e.contains("udp_profile_lidar \"X\""), "{e}");
        let e = Metadata::parse("{\"a\": 1}").unwrap_err();
        assert!(matches!(&e, Missing(why) if why.contains("not an Ouster sensor's metadata")));
        assert!(matches!(Metadata::parse("[1"), Err(NotJson(_))));
    }
}
