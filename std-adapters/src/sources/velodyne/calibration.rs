//! A Velodyne unit's own calibration, as the YAML file Velodyne's ROS driver
//! (`gen_calibration.py`, from the unit's `db.xml`) and velodyne_decoder write it: the distance
//! unit, and per laser its angles (radians), distance corrections and offsets (metres).
//!
//! ```yaml
//! distance_resolution: 0.002
//! lasers:
//!   - {laser_id: 0, rot_correction: -0.0781, vert_correction: -0.1244,
//!      dist_correction: 1.41, dist_correction_x: 1.44, dist_correction_y: 1.42,
//!      vert_offset_correction: 0.2148, horiz_offset_correction: 0.026}
//! ```
//!
//! Block and flow styles are both read. A key a laser lacks is 0, as in those tools; a laser's
//! two-point distance correction is used when both its `dist_correction_x` and `_y` are set.

use yaml_rust2::{Yaml, YamlLoader};

/// One laser's corrections.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LaserCorrection {
    /// Azimuth offset (radians).
    pub rot_correction: f64,
    /// Elevation (radians).
    pub vert_correction: f64,
    /// Added to every distance (metres, at the far calibration point).
    pub dist_correction: f64,
    /// The distance corrections at the near calibration points along x and y (metres).
    pub dist_correction_x: f64,
    /// See [`dist_correction_x`](Self::dist_correction_x).
    pub dist_correction_y: f64,
    /// The laser's height above the sensor's origin (metres).
    pub vert_offset_correction: f64,
    /// The laser's offset across its beam (metres).
    pub horiz_offset_correction: f64,
}

impl LaserCorrection {
    /// Whether the two-point distance correction applies.
    pub fn two_point(&self) -> bool {
        self.dist_correction_x != 0.0 && self.dist_correction_y != 0.0
    }
}

/// A unit's calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// Metres a raw distance count.
    pub distance_resolution_m: f64,
    /// By laser id.
    pub lasers: Vec<LaserCorrection>,
}

fn number(y: &Yaml) -> Option<f64> {
    y.as_f64()
        .or_else(|| y.as_i64().map(|i| i as f64))
        .filter(|v| v.is_finite())
}

/// The lasers a calibration may hold, at most.
pub const MAX_LASERS: usize = 128;

impl Calibration {
    /// Reads the YAML text.
    pub fn parse(text: &str) -> Result<Self, String> {
        let docs = YamlLoader::load_from_str(text).map_err(|e| format!("not YAML ({e})"))?;
        let doc = docs.first().ok_or("an empty file")?;
        let distance_resolution_m = match &doc["distance_resolution"] {
            Yaml::BadValue => return Err("no distance_resolution".to_string()),
            v => number(v)
                .filter(|d| *d > 0.0 && *d < 1.0)
                .ok_or("distance_resolution is not a number of metres between 0 and 1")?,
        };
        let list = doc["lasers"].as_vec().ok_or("no list of lasers")?;
        if list.len() > MAX_LASERS {
            return Err(format!("{} lasers, more than {MAX_LASERS}", list.len()));
        }
        let mut lasers: Vec<Option<LaserCorrection>> = vec![None; list.len()];
        for (k, l) in list.iter().enumerate() {
            let field = |key: &str| -> Result<f64, String> {
                match &l[key] {
                    Yaml::BadValue | Yaml::Null => Ok(0.0),
                    v => number(v).ok_or(format!("laser {k}: {key} is not a number")),
                }
            };
            let id = l["laser_id"]
                .as_i64()
                .ok_or(format!("laser {k}: no laser_id"))?;
            let slot = usize::try_from(id)
                .ok()
                .and_then(|i| lasers.get_mut(i))
                .ok_or(format!(
                    "laser {k}: laser_id {id} is not one of 0 to {}",
                    list.len() - 1
                ))?;
            if slot.is_some() {
                return Err(format!("laser_id {id} is given twice"));
            }
            if matches!(l["vert_correction"], Yaml::BadValue) {
                return Err(format!("laser {id}: no vert_correction"));
            }
            *slot = Some(LaserCorrection {
                rot_correction: field("rot_correction")?,
                vert_correction: field("vert_correction")?,
                dist_correction: field("dist_correction")?,
                dist_correction_x: field("dist_correction_x")?,
                dist_correction_y: field("dist_correction_y")?,
                vert_offset_correction: field("vert_offset_correction")?,
                horiz_offset_correction: field("horiz_offset_correction")?,
            });
        }
        // Every id once, and as many ids as lasers: none is missing.
        let lasers = lasers.into_iter().flatten().collect();
        Ok(Self {
            distance_resolution_m,
            lasers,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_and_flow_styles_read_alike() {
        let block = "distance_resolution: 0.002\nlasers:\n  - laser_id: 1\n    vert_correction: 0.1\n    dist_correction_x: 1.2\n    dist_correction_y: 1.3\n  - laser_id: 0\n    rot_correction: -0.05\n    vert_correction: -0.2\n    dist_correction: 1\nnum_lasers: 2\n";
        let flow = "lasers:\n- {laser_id: 0, rot_correction: -0.05, vert_correction: -0.2, dist_correction: 1}\n- {laser_id: 1, vert_correction: 0.1, dist_correction_x: 1.2, dist_correction_y: 1.3}\ndistance_resolution: 0.002\n";
        let a = Calibration::parse(block).unwrap();
        assert_eq!(a, Calibration::parse(flow).unwrap());
        assert_eq!(a.lasers.len(), 2);
        assert_eq!(a.lasers[0].dist_correction, 1.0);
        assert_eq!(a.lasers[0].rot_correction, -0.05);
        assert!(a.lasers[1].two_point() && !a.lasers[0].two_point());
    }

    #[test]
    fn a_wrong_calibration_is_refused_with_what_is_wrong() {
        let e = |t: &str| Calibration::parse(t).unwrap_err();
        assert!(e("lasers: []").contains("no distance_resolution"));
        assert!(e("distance_resolution: 0.002").contains("no list of lasers"));
        let two = "distance_resolution: 0.002\nlasers:\n- {laser_id: 0, vert_correction: 0}\n- {laser_id: 0, vert_correction: 0}\n";
        assert!(e(two).contains("laser_id 0 is given twice"));
        let far = "distance_resolution: 0.002\nlasers:\n- {laser_id: 5, vert_correction: 0}\n";
        assert!(e(far).contains("laser_id 5 is not one of 0 to 0"));
        let word = "distance_resolution: 0.002\nlasers:\n- {laser_id: 0, vert_correction: x}\n";
        assert!(e(word).contains("vert_correction is not a number"));
        assert!(e("[").contains("not YAML"));
    }
}
