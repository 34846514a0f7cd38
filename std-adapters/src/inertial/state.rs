//! The IMU's part of a run across a checkpoint (docs/design.md §1.19): everything an
//! [`Inertial`] holds but its options (the resumed run's, which its checkpoint's fingerprint
//! says are the same), as little-endian records ([`crate::io::le`]). The readings held, the
//! bias, the frames' counts, the checks' sums and what was said of up go on as the killed
//! run would have: a resumed run writes what a run never interrupted writes.

use crate::inertial::calibration::{CalibrationCheck, Verdict};
use crate::inertial::moving_up::{FirstSeconds, MovingUp};
use crate::inertial::trust::Trust;
use crate::inertial::{GravityReport, Inertial};
use crate::io::le::{
    put_f64, put_opt_str, put_option, put_str, put_u64, put_vec3, Damaged, Decoder,
};
use nalgebra::Vector3;
use slamesh_core::imu::{ImuCounts, Reading};

impl Inertial {
    /// Appends the IMU's state to a checkpoint's record.
    pub fn save(&self, e: &mut Vec<u8>) {
        let held = self.track.held();
        put_u64(e, held.len() as u64);
        for r in held {
            let (t, gyro, accel) = r.parts();
            put_f64(e, t);
            put_vec3(e, &gyro);
            put_vec3(e, &accel);
        }
        put_vec3(e, &self.track.bias());
        put_f64(e, self.track.period_s());
        let c = self.track.counts();
        let counts = [
            c.taken,
            c.not_finite,
            c.out_of_order,
            c.duplicate,
            c.saturated,
            c.forgotten_early,
        ];
        for n in counts {
            put_u64(e, n as u64);
        }
        put_f64(e, self.track.calibration().accel_unit_m_s2);
        put_option(e, self.refs.0, 0.0, put_f64);
        put_option(e, self.refs.1, 0.0, put_f64);
        e.push(u8::from(self.seen));
        let (a, b, c) = self.frames;
        for n in [a, b, c] {
            put_u64(e, n as u64);
        }
        self.trust.put(e);
        e.push(u8::from(self.gravity.is_some()));
        if let Some(g) = &self.gravity {
            put_gravity(e, g);
        }
        self.check.put(e);
        self.misses.put(e);
        self.moving.put(e);
        e.push(u8::from(self.checked.is_some()));
        if let Some(v) = &self.checked {
            put_str(e, &v.text);
            e.push(u8::from(v.wrong));
        }
        put_opt_str(e, self.unit.as_deref());
    }

    /// Takes back what [`save`](Self::save) wrote, in place of what it holds.
    pub fn restore(&mut self, record: &[u8]) -> Result<(), Damaged> {
        let mut d = Decoder { bytes: record };
        self.read(&mut d)?;
        match d.bytes.len() {
            0 => Ok(()),
            n => Err(Damaged(format!("{n} bytes after the IMU's state"))),
        }
    }

    fn read(&mut self, d: &mut Decoder) -> Result<(), Damaged> {
        let n = d.count(56)?;
        let mut held = Vec::with_capacity(n);
        for _ in 0..n {
            held.push(Reading::new(d.f64()?, d.vec3()?, d.vec3()?));
        }
        let bias = d.vec3()?;
        let period = d.f64()?;
        let counts = ImuCounts {
            taken: d.usize()?,
            not_finite: d.usize()?,
            out_of_order: d.usize()?,
            duplicate: d.usize()?,
            saturated: d.usize()?,
            forgotten_early: d.usize()?,
        };
        let unit = d.f64()?;
        (self.track)
            .restore(&held, bias, period, counts, unit)
            .map_err(|why| format!("its IMU readings: {why}"))?;
        self.refs = (d.option(Decoder::f64)?, d.option(Decoder::f64)?);
        self.seen = d.flag()?;
        self.frames = (d.usize()?, d.usize()?, d.usize()?);
        self.trust = Trust::read(d)?;
        self.gravity = match d.flag()? {
            true => Some(read_gravity(d)?),
            false => None,
        };
        let configured = self.options.calibration.lidar_from_imu.rotation;
        self.check = CalibrationCheck::read(d, configured)?;
        self.misses = CalibrationCheck::read(d, configured)?;
        self.moving = FirstSeconds::read(d)?;
        self.checked = match d.flag()? {
            true => Some(Verdict {
                text: d.string()?,
                wrong: d.flag()?,
            }),
            false => None,
        };
        self.unit = d.opt_string()?;
        self.resumed_at = self.track.last_t();
        Ok(())
    }
}

fn put_up(e: &mut Vec<u8>, up: Option<[f64; 3]>) {
    put_option(e, up, [0.0; 3], |e, v| put_vec3(e, &Vector3::from(v)));
}

fn read_up(d: &mut Decoder) -> Result<Option<[f64; 3]>, Damaged> {
    d.option(|d| Ok(d.vec3()?.into()))
}

fn put_gravity(e: &mut Vec<u8>, g: &GravityReport) {
    e.push(u8::from(g.levelled));
    put_up(e, g.up);
    put_option(e, g.tilt_deg, 0.0, put_f64);
    put_u64(e, g.readings as u64);
    for v in [g.seconds, g.magnitude_m_s2, g.spread_m_s2] {
        put_f64(e, v);
    }
    put_opt_str(e, g.why_not.as_deref());
    e.push(u8::from(g.moving.is_some()));
    if let Some(m) = &g.moving {
        put_up(e, m.up);
        put_option(e, m.z_off_deg, 0.0, put_f64);
        put_f64(e, m.seconds);
        put_opt_str(e, m.why_not.as_deref());
    }
}

fn read_gravity(d: &mut Decoder) -> Result<GravityReport, Damaged> {
    Ok(GravityReport {
        levelled: d.flag()?,
        up: read_up(d)?,
        tilt_deg: d.option(Decoder::f64)?,
        readings: d.usize()?,
        seconds: d.f64()?,
        magnitude_m_s2: d.f64()?,
        spread_m_s2: d.f64()?,
        why_not: d.opt_string()?,
        moving: match d.flag()? {
            true => Some(MovingUp {
                up: read_up(d)?,
                z_off_deg: d.option(Decoder::f64)?,
                seconds: d.f64()?,
                why_not: d.opt_string()?,
            }),
            false => None,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::inertial::ImuOptions;
    use crate::sources::Sample;
    use slamesh_core::imu::ImuSample;
    use slamesh_core::KittiCapacity;

    /// An IMU that took a still second of readings and levelled the map.
    fn used() -> Inertial {
        let mut imu = Inertial::new::<KittiCapacity>(ImuOptions::default());
        let samples: Vec<Sample> = (0..200)
            .map(|k| {
                Sample::Imu(ImuSample {
                    stamp: f64::from(k) * 0.005,
                    gyro: [0.001, -0.002, 0.01],
                    accel: [0.3, -0.2, 9.8],
                })
            })
            .collect();
        imu.take(&samples, "test", 0);
        assert!(imu.level(1.0, "test", 0).is_some());
        imu
    }

    #[test]
    fn the_state_reads_back_as_it_was_and_damage_is_an_error() {
        let imu = used();
        let mut record = Vec::new();
        imu.save(&mut record);
        let mut back = Inertial::new::<KittiCapacity>(ImuOptions::default());
        back.restore(&record).unwrap();
        let mut again = Vec::new();
        back.save(&mut again);
        assert_eq!(record, again);
        assert_eq!(back.summary(), imu.summary());
        assert_eq!(back.track.held(), imu.track.held());
        for cut in [0, 8, record.len() / 2, record.len() - 1] {
            let mut fresh = Inertial::new::<KittiCapacity>(ImuOptions::default());
            assert!(fresh.restore(&record[..cut]).is_err(), "cut at {cut}");
        }
        let mut longer = record.clone();
        longer.push(0);
        let e = Inertial::new::<KittiCapacity>(ImuOptions::default()).restore(&longer);
        assert_eq!(e, Err(Damaged("1 bytes after the IMU's state".to_string())));
    }
}
