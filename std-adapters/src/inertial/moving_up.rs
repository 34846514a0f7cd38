//! Up over a run's first seconds of motion, when its start was not steady enough to level the
//! map (docs/design.md §1.19): between each two registered frames the IMU's specific force is
//! turned into the map's frame by the registered attitude and summed; at the end of
//! [`WINDOW_S`] the registered positions' change of velocity is taken out
//! ([`slamesh_core::gravity::up_from_motion`]) and what is left points up, in the map's frame.
//!
//! It owns the sums (a fixed size) and guarantees one answer a run: up, or why not (a frame in
//! the window not registered, readings that did not cover an interval, a result not
//! gravity's size). The map keeps its frame; the navigation map takes up from here.

use crate::io::le::{put_f64, put_u64, put_vec3, Damaged, Decoder};
use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use slamesh_core::gravity::up_from_motion;
use slamesh_core::imu::ForceMean;
use slamesh_core::Pose;

/// The time the sums span before up is read (seconds).
pub const WINDOW_S: f64 = 5.0;

/// What the first seconds of motion said of up (`summary.imu.gravity.moving`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MovingUp {
    /// Up in the map's frame (a unit vector), when found.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub up: Option<[f64; 3]>,
    /// The map's z axis from up (degrees), when found.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub z_off_deg: Option<f64>,
    /// The time read (seconds).
    pub seconds: f64,
    /// Why not, when not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub why_not: Option<String>,
}

/// The sums over the frames so far.
#[derive(Debug, Default)]
pub struct FirstSeconds {
    /// Σ (force in the map's frame × readings), and the readings.
    force: Vector3<f64>,
    readings: usize,
    /// The first interval's velocity and its middle's time.
    first: Option<(Vector3<f64>, f64)>,
    /// The answer was given.
    done: bool,
}

impl FirstSeconds {
    /// Appends its sums to a checkpoint's record ([`crate::io::le`]).
    pub(super) fn put(&self, e: &mut Vec<u8>) {
        put_vec3(e, &self.force);
        put_u64(e, self.readings as u64);
        let (v, t) = self.first.unwrap_or((Vector3::zeros(), 0.0));
        e.push(u8::from(self.first.is_some()));
        put_vec3(e, &v);
        put_f64(e, t);
        e.push(u8::from(self.done));
    }

    /// What [`put`](Self::put) wrote.
    pub(super) fn read(d: &mut Decoder) -> Result<Self, Damaged> {
        Ok(Self {
            force: d.vec3()?,
            readings: d.usize()?,
            first: d.option(|d| Ok((d.vec3()?, d.f64()?)))?,
            done: d.flag()?,
        })
    }

    /// Takes the interval from `before` (at `t_before`) to `last` (at `t`), both registered
    /// (`registered`), and the IMU's force over it in the frame at `t` (`force`: the readings
    /// did not cover it when an error); the answer when this interval ends the window or
    /// spoils it.
    pub fn add(
        &mut self,
        (before, t_before): (&Pose, f64),
        (last, t): (&Pose, f64),
        registered: bool,
        force: Result<ForceMean, String>,
    ) -> Option<MovingUp> {
        if self.done || t.partial_cmp(&t_before) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let middle = (t_before + t) / 2.0;
        let spoilt = match (&force, registered) {
            (_, false) => Some("a frame in the first seconds was not registered".to_string()),
            (Err(why), _) => Some(why.clone()),
            _ => None,
        };
        let seconds = self.first.map_or(0.0, |(_, m)| middle - m);
        if let Some(why) = spoilt {
            return self.answer(None, seconds, Some(why));
        }
        let f = force.as_ref().ok()?;
        self.force += last.rotation * f.mean * f.readings as f64;
        self.readings += f.readings;
        let velocity = (last.translation.vector - before.translation.vector) / (t - t_before);
        let (v0, _) = *self.first.get_or_insert((velocity, middle));
        if seconds < WINDOW_S {
            return None;
        }
        let mean = self.force / self.readings.max(1) as f64;
        match up_from_motion(&mean, &(velocity - v0), seconds) {
            Ok(up) => self.answer(Some(up), seconds, None),
            Err(e) => self.answer(None, seconds, Some(super::not_level(e))),
        }
    }

    fn answer(
        &mut self,
        up: Option<Vector3<f64>>,
        seconds: f64,
        why_not: Option<String>,
    ) -> Option<MovingUp> {
        self.done = true;
        Some(MovingUp {
            up: up.map(Into::into),
            z_off_deg: up.map(|u| u.angle(&Vector3::z()).to_degrees()),
            seconds,
            why_not,
        })
    }

    /// Whether it still takes intervals (no answer given yet).
    pub fn open(&self) -> bool {
        !self.done
    }
}
