//! The robot a navigation map is made for: how wide, how tall, how steep a slope and how high a
//! step it takes. Two profiles come with slamesh ([`Robot::WHEELED`], the default, and
//! [`Robot::LEGGED`]); a TOML file (`--robot FILE`) gives another, any key left out taken from
//! the profile it names with `base` (wheeled when none).

use crate::io::error::FileError;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// What the navigation map needs to know of the robot.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Robot {
    /// Its footprint's radius (m): the ground a cell is judged against is the lowest within it.
    pub radius_m: f64,
    /// The steepest ground it drives on (degrees from level).
    pub max_slope_deg: f64,
    /// The highest step it climbs (m): anything standing higher above the ground is an
    /// obstacle.
    pub max_step_m: f64,
    /// Its height (m): what stands higher above the ground (a roof, a tree's crown, a
    /// balcony) it passes under.
    pub height_m: f64,
}

impl Robot {
    /// A small wheeled robot (a TurtleBot-sized base with a sensor mast).
    pub const WHEELED: Robot = Robot {
        radius_m: 0.3,
        max_slope_deg: 15.0,
        max_step_m: 0.08,
        height_m: 1.0,
    };

    /// A quadruped (Spot-, ANYmal-sized): steeper slopes, higher steps, lower body.
    pub const LEGGED: Robot = Robot {
        radius_m: 0.45,
        max_slope_deg: 30.0,
        max_step_m: 0.2,
        height_m: 0.8,
    };

    /// The profile named `name` (`wheeled`, `legged`).
    pub fn named(name: &str) -> Option<Robot> {
        match name {
            "wheeled" => Some(Robot::WHEELED),
            "legged" => Some(Robot::LEGGED),
            _ => None,
        }
    }

    /// Reads a robot file: `base = "legged"` (optional) and any of the fields, e.g.
    /// `radius_m = 0.25`.
    pub fn read(path: &Path) -> Result<Robot, FileError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| FileError::at(path, format!("cannot read: {e}")))?;
        Robot::parse(&text).map_err(|e| FileError::at(path, e))
    }

    /// [`read`](Self::read)'s parser.
    pub fn parse(text: &str) -> Result<Robot, String> {
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct File {
            base: Option<String>,
            radius_m: Option<f64>,
            max_slope_deg: Option<f64>,
            max_step_m: Option<f64>,
            height_m: Option<f64>,
        }
        let f: File = toml::from_str(text).map_err(|e| e.message().to_string())?;
        let base = match f.base.as_deref() {
            None => Robot::WHEELED,
            Some(name) => Robot::named(name)
                .ok_or_else(|| format!("base: `{name}` is not a profile (wheeled, legged)"))?,
        };
        let robot = Robot {
            radius_m: f.radius_m.unwrap_or(base.radius_m),
            max_slope_deg: f.max_slope_deg.unwrap_or(base.max_slope_deg),
            max_step_m: f.max_step_m.unwrap_or(base.max_step_m),
            height_m: f.height_m.unwrap_or(base.height_m),
        };
        robot.check()?;
        Ok(robot)
    }

    /// Refuses a profile no map can be made for, naming the field.
    pub fn check(&self) -> Result<(), String> {
        let within = |v: f64, lo: f64, hi: f64| v.is_finite() && v >= lo && v <= hi;
        if !within(self.radius_m, 0.0, 10.0) {
            return Err(format!("radius_m: {} is not within 0 to 10", self.radius_m));
        }
        if !within(self.max_slope_deg, 0.0, 89.0) {
            return Err(format!(
                "max_slope_deg: {} is not within 0 to 89",
                self.max_slope_deg
            ));
        }
        if !within(self.max_step_m, 0.0, 5.0) {
            return Err(format!(
                "max_step_m: {} is not within 0 to 5",
                self.max_step_m
            ));
        }
        if !(within(self.height_m, 0.0, 20.0) && self.height_m > self.max_step_m) {
            return Err(format!(
                "height_m: {} is not above max_step_m ({}) and at most 20",
                self.height_m, self.max_step_m
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_overrides_its_base_and_bad_values_are_named() {
        let r = Robot::parse("base = \"legged\"\nradius_m = 0.25\n").unwrap();
        assert_eq!(
            r,
            Robot {
                radius_m: 0.25,
                ..Robot::LEGGED
            }
        );
        assert_eq!(Robot::parse("").unwrap(), Robot::WHEELED);
        let e = Robot::parse("max_step_m = 2.0\nheight_m = 1.0").unwrap_err();
        assert!(e.starts_with("height_m"), "{e}");
        assert!(Robot::parse("base = \"tracked\"")
            .unwrap_err()
            .contains("tracked"));
        assert!(Robot::parse("wheels = 4").is_err());
    }
}
