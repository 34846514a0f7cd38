//! Ouster lidar packets decoded to points with each one's firing time: the OS0, OS1, OS2 and
//! OSDome lines, legacy and profiled packets ([`packet`]), with the beam angles and transforms
//! of the unit's own metadata ([`metadata`]); its IMU packets too ([`imu_packet`]).
//!
//! Every beam of a column fires at the column's timestamp, which the packet carries, so each
//! point's time is exact. Its position follows Ouster's sensor documentation ("Lidar Range to
//! XYZ"): the column's encoder angle `e = 2 pi (1 - m / W)` (measurement id `m` of `W` a turn),
//! the beam's azimuth offset `a` and elevation `p`, the beam origin's offset `n` from the lidar
//! axis (`beam_to_lidar_transform`), and range `r` (millimetres):
//! `d = (cos(e + a) cos p, sin(e + a) cos p, sin p)`,
//! `x = (r - n) d + (cos(e) b03, sin(e) b03, b23)`, then `lidar_to_sensor_transform`, then
//! metres. The result is in the sensor frame, as Ouster's SDK gives it.
//!
//! A point's azimuth, for cutting turns, is its column's (clockwise from the sensor frame's x
//! axis, as Velodyne reports azimuths), so a turn is cut between whole columns. A turn's
//! natural start, column 0, is [`Sensor::frame_start_deg`].
//!
//! Nothing here panics on a packet: its size and type are checked before a point is handed
//! out, a column with a measurement id out of range refuses the packet ([`PacketError`]), and
//! columns the sensor marked invalid (outside its column window) give no points.

pub mod imu_packet;
pub mod metadata;
pub mod packet;

use metadata::Metadata;
use packet::Layout;

/// Why a packet was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PacketError {
    /// Not the metadata's packet size.
    Size {
        /// The packet's.
        got: usize,
        /// The metadata's.
        want: usize,
    },
    /// A profiled packet whose type is not 1 (lidar data).
    PacketType(u16),
    /// A column's measurement id is past the turn's columns.
    MeasurementId(u16),
}

impl core::fmt::Display for PacketError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            PacketError::Size { got, want } => {
                write!(
                    f,
                    "{got} bytes, not the metadata's {want}-byte lidar packet"
                )
            }
            PacketError::PacketType(t) => write!(f, "packet type {t}, not lidar data (1)"),
            PacketError::MeasurementId(m) => write!(f, "measurement id {m} is past the turn"),
        }
    }
}

/// One decoded point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Firing {
    /// Sensor-frame position (metres).
    pub point: [f32; 3],
    /// Firing time (seconds, the sensor's clock).
    pub time_s: f64,
    /// The column's azimuth (hundredths of a degree, 0 to 35 999).
    pub azimuth: u16,
    /// The column (its measurement id: 0 to the columns a turn less one).
    pub column: u16,
    /// The beam.
    pub beam: u8,
    /// The return (0; 1 for a dual profile's second).
    pub ret: u8,
}

/// A beam's direction in the sensor frame at encoder angle `e`, as
/// `cos(e) cos_part + sin(e) sin_part + fixed` (the sum formulas of `d` above, turned by the
/// lidar-to-sensor rotation once, here, rather than at every point).
#[derive(Debug, Clone, Copy)]
struct Beam {
    cos_part: [f64; 3],
    sin_part: [f64; 3],
    fixed: [f64; 3],
}

/// A column's encoder angle, and its azimuth in the sensor frame.
#[derive(Debug, Clone, Copy)]
struct Column {
    cos_e: f64,
    sin_e: f64,
    azimuth: u16,
}

/// One unit, from its metadata: the packet layout and the geometry tables.
#[derive(Debug, Clone)]
pub struct Sensor {
    meta: Metadata,
    layout: Layout,
    beams: Vec<Beam>,
    columns: Vec<Column>,
    /// `beam_to_lidar`'s x and z offsets and their length (mm).
    b03: f64,
    b23: f64,
    n: f64,
    /// `lidar_to_sensor`'s rotation (row-major) and translation (mm).
    rotation: [f64; 9],
    translation: [f64; 3],
}

impl Sensor {
    /// The unit its metadata describes.
    pub fn new(meta: Metadata) -> Self {
        let t = &meta.lidar_to_sensor;
        let rotation = [t[0], t[1], t[2], t[4], t[5], t[6], t[8], t[9], t[10]];
        let layout = Layout {
            profile: meta.profile,
            columns: usize::from(meta.columns_per_packet),
            beams: usize::from(meta.pixels_per_column),
        };
        let beams = meta
            .altitude_deg
            .iter()
            .zip(&meta.azimuth_deg)
            .map(|(p, a)| {
                let (sin_a, cos_a) = (-a).to_radians().sin_cos();
                let (sin_p, cos_p) = p.to_radians().sin_cos();
                Beam {
                    cos_part: turn(&rotation, [cos_a * cos_p, sin_a * cos_p, 0.0]),
                    sin_part: turn(&rotation, [-sin_a * cos_p, cos_a * cos_p, 0.0]),
                    fixed: turn(&rotation, [0.0, 0.0, sin_p]),
                }
            })
            .collect();
        let w = f64::from(meta.columns_per_frame);
        let columns = (0..meta.columns_per_frame)
            .map(|m| {
                let e = std::f64::consts::TAU * (1.0 - f64::from(m) / w);
                let (sin_e, cos_e) = e.sin_cos();
                // The column's heading in the sensor frame, clockwise from its x axis.
                let x = rotation[0] * cos_e + rotation[1] * sin_e;
                let y = rotation[3] * cos_e + rotation[4] * sin_e;
                let cw = (-y.atan2(x)).to_degrees().rem_euclid(360.0);
                let azimuth = ((cw * 100.0).round() as u32 % 36_000) as u16;
                Column {
                    cos_e,
                    sin_e,
                    azimuth,
                }
            })
            .collect();
        let b = &meta.beam_to_lidar;
        let (b03, b23) = (b[3], b[11]);
        Self {
            layout,
            beams,
            columns,
            b03,
            b23,
            n: if b23 == 0.0 { b03 } else { b03.hypot(b23) },
            rotation,
            translation: [t[3], t[7], t[11]],
            meta,
        }
    }

    /// Its metadata.
    pub fn metadata(&self) -> &Metadata {
        &self.meta
    }

    /// Its name for messages: the product line and the profile.
    pub fn name(&self) -> String {
        format!("{} ({})", self.meta.prod_line, self.meta.profile.name())
    }

    /// Bytes of its lidar packets.
    pub fn packet_bytes(&self) -> usize {
        self.layout.packet_bytes()
    }

    /// Seconds between packets.
    pub fn packet_period_s(&self) -> f64 {
        f64::from(self.meta.columns_per_packet)
            / (f64::from(self.meta.columns_per_frame) * f64::from(self.meta.fps))
    }

    /// Where a turn starts, column 0 (degrees of azimuth, as [`Firing::azimuth`]).
    pub fn frame_start_deg(&self) -> f64 {
        self.columns
            .first()
            .map_or(0.0, |c| f64::from(c.azimuth) / 100.0)
    }

    /// Whether `packet` looks like this unit's lidar packet: its size, its type, and its
    /// columns' measurement ids within the turn.
    pub fn matches(&self, packet: &[u8]) -> bool {
        self.check(packet).is_ok()
    }

    fn check(&self, packet: &[u8]) -> Result<(), PacketError> {
        let want = self.layout.packet_bytes();
        if packet.len() != want {
            return Err(PacketError::Size {
                got: packet.len(),
                want,
            });
        }
        if let Some(t) = self.layout.packet_type(packet) {
            if t != 1 {
                return Err(PacketError::PacketType(t));
            }
        }
        for c in 0..self.layout.columns {
            if let Some((h, _)) = self.layout.column(packet, c) {
                if h.valid && usize::from(h.measurement_id) >= self.columns.len() {
                    return Err(PacketError::MeasurementId(h.measurement_id));
                }
            }
        }
        Ok(())
    }

    /// Decodes one lidar packet, handing each point to `sink` in column, beam and return
    /// order; returns the packet's time, its first column's that has one (seconds; columns
    /// outside the window have their times too), `None` when none has.
    pub fn decode(
        &self,
        packet: &[u8],
        mut sink: impl FnMut(Firing),
    ) -> Result<Option<f64>, PacketError> {
        self.check(packet)?;
        let profile = self.layout.profile;
        let block = profile.block_bytes();
        let mut first = None;
        for c in 0..self.layout.columns {
            let Some((h, blocks)) = self.layout.column(packet, c) else {
                continue;
            };
            let time_s = h.timestamp_ns as f64 * 1e-9;
            if h.timestamp_ns != 0 {
                first.get_or_insert(time_s);
            }
            let Some(col) = self.columns.get(usize::from(h.measurement_id)) else {
                continue;
            };
            if !h.valid {
                continue;
            }
            // The beam origin's offset, the same for every beam of the column, in the sensor
            // frame (metres).
            let o = turn(
                &self.rotation,
                [col.cos_e * self.b03, col.sin_e * self.b03, self.b23],
            );
            let o: [f64; 3] = core::array::from_fn(|k| (o[k] + self.translation[k]) * 1e-3);
            let (c, s) = (col.cos_e, col.sin_e);
            for (i, (beam, bytes)) in self
                .beams
                .iter()
                .zip(blocks.chunks_exact(block))
                .enumerate()
            {
                let d: [f64; 3] = core::array::from_fn(|k| {
                    c * beam.cos_part[k] + s * beam.sin_part[k] + beam.fixed[k]
                });
                for ret in 0..profile.returns() {
                    let range = profile.range_mm(bytes, ret);
                    if range == 0 {
                        continue;
                    }
                    let m = (f64::from(range) - self.n) * 1e-3;
                    sink(Firing {
                        point: core::array::from_fn(|k| (d[k] * m + o[k]) as f32),
                        time_s,
                        azimuth: col.azimuth,
                        column: h.measurement_id,
                        beam: i as u8,
                        ret: ret as u8,
                    });
                }
            }
        }
        Ok(first)
    }
}

/// `r` (row-major 3x3) times `v`.
fn turn(r: &[f64; 9], v: [f64; 3]) -> [f64; 3] {
    core::array::from_fn(|k| r[3 * k] * v[0] + r[3 * k + 1] * v[1] + r[3 * k + 2] * v[2])
}

/// Whether `payload` is the size of an Ouster lidar packet of 16 columns of 16 to 128 beams,
/// of any profile, and looks like one (a profiled packet's type 1, or a legacy packet's column
/// status words all set or all clear): a description for a message asking for the metadata.
pub fn sniff(payload: &[u8]) -> Option<String> {
    let layouts = packet::Profile::ALL.into_iter().flat_map(|profile| {
        [16, 32, 64, 128].map(|beams| Layout {
            profile,
            columns: 16,
            beams,
        })
    });
    for l in layouts {
        if payload.len() != l.packet_bytes() {
            continue;
        }
        let plausible = match l.packet_type(payload) {
            Some(t) => t == 1,
            None => (0..l.columns).all(|c| {
                let end = (c + 1) * l.column_bytes();
                matches!(
                    payload.get(end - 4..end),
                    Some([0, 0, 0, 0] | [0xff, 0xff, 0xff, 0xff])
                )
            }),
        };
        if plausible {
            return Some(format!(
                "datagrams of {} bytes, the size of an Ouster's lidar packets",
                payload.len()
            ));
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::packet::Profile;
    use super::*;

    fn sensor(profile: Profile) -> Sensor {
        Sensor::new(Metadata {
            prod_line: "OS-1-8".into(),
            profile,
            columns_per_frame: 512,
            fps: 10,
            columns_per_packet: 4,
            pixels_per_column: 8,
            column_window: (0, 511),
            altitude_deg: (0..8).map(|i| f64::from(i) * 2.0 - 7.0).collect(),
            azimuth_deg: vec![1.5; 8],
            beam_to_lidar: [
                1.0, 0.0, 0.0, 15.8, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
            ],
            lidar_to_sensor: [
                -1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 36.18, 0.0, 0.0, 0.0, 1.0,
            ],
            udp_port_lidar: None,
            imu_to_sensor: metadata::IDENTITY,
            udp_port_imu: None,
        })
    }

    /// A packet of `s`'s layout: columns `first..` at 1 ms apart, every beam at `range_mm`.
    fn packet(s: &Sensor, first: u16, range_mm: u32) -> Vec<u8> {
        let l = s.layout;
        let mut p = vec![0u8; l.packet_bytes()];
        let head = if l.profile == Profile::Legacy { 0 } else { 32 };
        if head > 0 {
            p[0] = 1;
        }
        for c in 0..l.columns {
            let at = head + c * l.column_bytes();
            let col = &mut p[at..at + l.column_bytes()];
            col[..8].copy_from_slice(&(1_000_000 * (u64::from(first) + c as u64)).to_le_bytes());
            col[8..10].copy_from_slice(&(first + c as u16).to_le_bytes());
            let hb = if l.profile == Profile::Legacy { 16 } else { 12 };
            for b in 0..l.beams {
                let o = hb + b * l.profile.block_bytes();
                let raw = if matches!(l.profile, Profile::Rng15 | Profile::Rng15Dual) {
                    range_mm / 8
                } else {
                    range_mm
                };
                col[o..o + 4].copy_from_slice(&raw.to_le_bytes());
            }
            if l.profile == Profile::Legacy {
                let n = col.len();
                col[n - 4..].copy_from_slice(&u32::MAX.to_le_bytes());
            } else {
                col[10] = 1;
            }
        }
        p
    }

    #[test]
    fn points_lie_at_their_range_from_the_beam_origin() {
        for profile in Profile::ALL {
            let s = sensor(profile);
            let mut out = Vec::new();
            let t = s.decode(&packet(&s, 128, 10_000), |f| out.push(f)).unwrap();
            assert_eq!(t, Some(128e-3));
            assert_eq!(out.len(), 4 * 8, "{profile:?}: one return a beam");
            for f in &out {
                // Column 128 of 512: encoder angle 270 degrees, toward -y in the lidar frame;
                // the sensor frame turns it half a turn: +y, 270 degrees clockwise from +x.
                let col = 128 + (f.time_s * 1e3 - 128.0).round() as u16;
                let e = std::f64::consts::TAU * (1.0 - f64::from(col) / 512.0);
                let origin = [-15.8e-3 * e.cos(), -15.8e-3 * e.sin(), 36.18e-3];
                let d: f64 = (0..3)
                    .map(|k| (f64::from(f.point[k]) - origin[k]).powi(2))
                    .sum::<f64>()
                    .sqrt();
                assert!((d - (10.0 - 15.8e-3)).abs() < 1e-5, "{profile:?}: {d}");
            }
            assert_eq!(out[0].azimuth, 27_000);
            assert!(out[0].point[1] > 9.0, "{:?}", out[0].point);
        }
    }

    #[test]
    fn bad_packets_are_refused_and_invalid_columns_give_nothing() {
        let s = sensor(Profile::Rng19);
        let mut p = packet(&s, 0, 5_000);
        let mut n = 0;
        assert!(matches!(
            s.decode(&p[1..], |_| n += 1),
            Err(PacketError::Size { .. })
        ));
        p[0] = 2;
        assert_eq!(s.decode(&p, |_| n += 1), Err(PacketError::PacketType(2)));
        p[0] = 1;
        let col1 = 32 + s.layout.column_bytes();
        p[col1 + 8..col1 + 10].copy_from_slice(&600u16.to_le_bytes());
        assert_eq!(
            s.decode(&p, |_| n += 1),
            Err(PacketError::MeasurementId(600))
        );
        assert_eq!(n, 0, "no point of a refused packet");
        p[col1 + 8..col1 + 10].copy_from_slice(&1u16.to_le_bytes());
        p[col1 + 10] = 0;
        s.decode(&p, |_| n += 1).unwrap();
        assert_eq!(n, 3 * 8, "the invalid column gives none");
        assert!((s.frame_start_deg() - 180.0).abs() < 1e-9);
        assert!((s.packet_period_s() - 4.0 / 5120.0).abs() < 1e-15);
    }
}
